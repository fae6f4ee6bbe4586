// Gaussian splat files in the page: `stipple.html?url=biker.spz` reads the file through the
// browser (the same readers, scene assembly, radix sort and splat passes as `stipple render`,
// compiled to WebAssembly) and its canvas matches the native render of the same file (lavapipe)
// within common.mjs's tolerance: a page that drew no splats would differ almost everywhere the
// rider is. Measured: mean difference 0.24 of 255, no pixel off by more than 48. The same with
// the tile rasterizer asked for (?splat-rasterizer=tiles; the CPU adapters' default is quads).
// A close-up of large splats with tiles: its first frame wants about 60 times the pairs the
// buffers hold; the count comes back while the page is idle, the buffers grow and the page draws
// once more by itself (quads: no frame after the first), and matches the native render.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import * as h from './harness.mjs';
import * as c from './common.mjs';

const splat = path.join(c.sharedData, 'splats/playcanvas-engine/biker.spz');
const skip = c.skip || (fs.existsSync(splat) ? null : `${splat} not found (../shared absent)`);
// 400 large, faint splats in a unit box (an INRIA PLY: log scales, opacity before the sigmoid),
// as tests/app/splat_render_gpu_test.cpp writes them.
function largeSplats(file) {
  const props = ['x', 'y', 'z', 'f_dc_0', 'f_dc_1', 'f_dc_2', 'opacity', 'scale_0', 'scale_1',
    'scale_2', 'rot_0', 'rot_1', 'rot_2', 'rot_3'];
  const n = 400;
  const header = `ply\nformat binary_little_endian 1.0\nelement vertex ${n}\n` +
    props.map((p) => `property float ${p}\n`).join('') + 'end_header\n';
  const body = Buffer.alloc(n * props.length * 4);
  let seed = 3;
  const u = () => { seed = (seed * 1103515245 + 12345) % 2147483648; return seed / 2147483648; };
  for (let i = 0; i < n; ++i) {
    const opacity = 0.02 + 0.08 * u();
    const v = [u() - 0.5, u() - 0.5, u() - 0.5, u() * 3 - 1.5, u() * 3 - 1.5, u() * 3 - 1.5,
      Math.log(opacity / (1 - opacity)), Math.log(0.3 + 0.3 * u()), Math.log(0.3 + 0.3 * u()),
      Math.log(0.1 + 0.1 * u()), 1, 0, 0, 0];
    v.forEach((x, k) => body.writeFloatLE(x, (i * props.length + k) * 4));
  }
  fs.writeFileSync(file, Buffer.concat([Buffer.from(header), body]));
  return file;
}

const suite = c.viewerSuite('splats', (work) => {
  const root = c.viewerRoot(work);
  fs.symlinkSync(splat, path.join(root, 'biker.spz'));
  largeSplats(path.join(root, 'large.ply'));
  return root;
});
const { work } = suite;

test('a splat file by URL matches the native render', { skip: skip || false }, async () => {
  const ref = path.join(work, 'native-biker.png');
  const out = h.stipple(['render', splat, '-o', ref, '--width', '320', '--height', '240']);
  assert.match(out, /152746 splats/);
  const { page, state, log } = await c.openPage(
    suite.browser, suite.server.url('viewer/stipple.html?url=/biker.spz&width=320&height=240'),
    { timeout: 180000 });
  c.assertDone(state, log);
  // A CPU adapter's default (quads: the faster there, splats.cpp's figures).
  assert.equal(state.splatRasterizer, 'quads', state.adapter);
  await c.assertCanvasMatches(page, ref, {
    minLit: 0.05,
    describe: (d) => `web vs native, splats: ${JSON.stringify(d)}; ${state.renderer}, ${state.adapter}`,
  });
  await page.close();
});

test('the tile rasterizer by URL matches the native render with tiles', { skip: skip || false }, async () => {
  const ref = path.join(work, 'native-biker-tiles.png');
  const out = h.stipple(['render', splat, '-o', ref, '--width', '320', '--height', '240',
    '--splat-rasterizer', 'tiles']);
  assert.match(out, /152746 splats/);
  const { page, state, log } = await c.openPage(
    suite.browser,
    suite.server.url('viewer/stipple.html?url=/biker.spz&width=320&height=240&splat-rasterizer=tiles'),
    { timeout: 180000 });
  c.assertDone(state, log);
  assert.equal(state.splatRasterizer, 'tiles');
  await c.assertCanvasMatches(page, ref, {
    minLit: 0.05,
    describe: (d) => `web vs native, splat tiles: ${JSON.stringify(d)}; ${state.renderer}, ${state.adapter}`,
  });
  await page.close();
});

test('a close-up with tiles grows its pairs while idle and draws once more', { skip: c.skip || false }, async () => {
  const large = path.join(work, 'www', 'large.ply');  // written by the suite's prepare
  const ref = path.join(work, 'native-large-tiles.png');
  h.stipple(['render', large, '-o', ref, '--width', '320', '--height', '240',
    '--splat-rasterizer', 'tiles']);
  for (const rasterizer of ['quads', 'tiles']) {
    const { page, state, log } = await c.openPage(
      suite.browser,
      suite.server.url(`viewer/stipple.html?url=/large.ply&width=320&height=240&splat-rasterizer=${rasterizer}`),
      { timeout: 180000 });
    c.assertDone(state, log);
    assert.equal(state.splatRasterizer, rasterizer);
    if (rasterizer === 'tiles') {
      // No input: the frame after the first is the page's own, once the pair count came back.
      await page.waitForFunction(() => window.stipple.viewFrames === '1', { timeout: 60000 })
        .catch((e) => log.push(String(e)));
      assert.equal(await page.evaluate(() => window.stipple.viewFrames), '1', log.join('\n'));
      await c.assertCanvasMatches(page, ref, {
        minLit: 0.05,
        describe: (d) => `web vs native, large splats with tiles: ${JSON.stringify(d)}`,
      });
    } else {
      // The quads lose nothing: the page stays idle (what the wait above tells apart).
      await new Promise((r) => setTimeout(r, 3000));
      assert.equal(await page.evaluate(() => window.stipple.viewFrames), undefined);
    }
    await page.close();
  }
});
