// A splat tileset in the page: `stipple.html?url=tiles/tileset.json` of `stipple tile` on a
// generated splat file streams it (tiles3d::SplatTilesetPlugin, compiled to WebAssembly, the
// drawn tiles' splats sorted together) until idle, and its canvas matches the native render of
// the same tileset (lavapipe) within common.mjs's tolerance: a page that drew no splats, or the
// tiles in another frame, would differ almost everywhere the scene is. Measured (swiftshader
// against lavapipe): mean difference 0.21 of 255, no pixel off by more than common.mjs's bound.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import path from 'node:path';
import * as h from './harness.mjs';
import * as c from './common.mjs';

const skip = c.skip;
const suite = c.viewerSuite('splat-stream', (work) => {
  const root = c.viewerRoot(work);
  const spz = path.join(work, 'scene.spz');
  h.stipple(['generate', '-o', spz, '-n', '20000', '--sh-degree', '1', '--threads', '2']);
  h.stipple(['tile', spz, '-o', path.join(root, 'tiles'), '--max-leaf-splats', '2000',
             '--threads', '2']);
  return root;
});
const { work } = suite;

test('a splat tileset by URL streams and matches the native render', { skip: skip || false }, async () => {
  const ref = path.join(work, 'native-splats.png');
  const tileset = path.join(work, 'www/tiles/tileset.json');
  const out = h.stipple(['render', tileset, '-o', ref, '--width', '320', '--height', '240',
                         '--max-sse', '1']);
  const drawn = Number(out.match(/and (\d+) splats/)[1]);
  assert.ok(drawn > 0, out);
  const { page, state, log } = await c.openPage(
    suite.browser,
    suite.server.url('viewer/stipple.html?url=/tiles/tileset.json&width=320&height=240&max-sse=1'),
    { timeout: 180000 });
  c.assertDone(state, log);
  // The same tiles as natively: the same view, the same traversal.
  assert.equal(Number(state.splats), drawn,
               `page ${state.splats} splats, native ${drawn}: ${state.progress}\n${log.join("\n")}`);
  await c.assertCanvasMatches(page, ref, {
    describe: (d) => `web vs native, splat tileset: ${JSON.stringify(d)}; ${state.splats} splats, ` +
                     `${state.renderer}, ${state.adapter}`,
  });
  await page.close();
});

// Tiles that arrive after a camera move are drawn without more input: the page draws a frame when
// a load finishes (as for point tilesets), not only when the camera or an option changes. The page
// opens coarse (max-sse 8), the camera moves to a quarter of its distance, and with no more
// events the drawn splats grow to what `stipple render` draws from that camera at the same
// max-sse. Before, the page drew the move's frame (the parent tiles, the children requested) and
// then nothing: the count stayed, the loads never reported done.
test('a splat tileset refines as its tiles arrive after a camera move, with no more input', { skip: skip || false }, async () => {
  const { page, state, log } = await c.openPage(
    suite.browser,
    suite.server.url('viewer/stipple.html?url=/tiles/tileset.json&width=320&height=240&max-sse=8'),
    { timeout: 180000 });
  c.assertDone(state, log);
  const before = Number(state.splats);
  const camera = await page.evaluate(() => {
    const v = window.stippleViewer;
    const { position, target } = v.camera;
    const closer = position.map((x, i) => target[i] + (x - target[i]) * 0.25);
    v.camera = { position: closer, target };
    return { position: closer, target };
  });
  await page.waitForFunction(() => window.stipple.splatsIdle === '1', { timeout: 60000 })
    .catch((e) => assert.fail(`the loads for the new view never showed as done: ${e}; ` +
                              `${JSON.stringify(window.stipple ?? {})}\n${log.join('\n')}`));
  const after = await page.evaluate(() => Number(window.stipple.streamedSplats));
  const out = h.stipple(['render', path.join(work, 'www/tiles/tileset.json'), '-o',
                         path.join(work, 'native-closer.png'), '--width', '320', '--height', '240',
                         '--max-sse', '8', '--camera', [...camera.position, ...camera.target].join(',')]);
  const native = Number(out.match(/and (\d+) splats/)[1]);
  console.log(`splats: ${before} at the first view, ${after} after the move, native ${native}`);
  assert.ok(after > before, `the move drew no finer tiles: ${before} -> ${after}`);
  assert.equal(after, native, `page ${after} splats after the move, native ${native}`);
  await page.close();
});
