// Gaussian splat files in the page: `stipple.html?url=biker.spz` reads the file through the
// browser (the same readers, scene assembly, radix sort and splat passes as `stipple render`,
// compiled to WebAssembly) and its canvas matches the native render of the same file (lavapipe)
// within common.mjs's tolerance: a page that drew no splats would differ almost everywhere the
// rider is. Measured: mean difference 0.24 of 255, no pixel off by more than 48. The same with
// the tile rasterizer asked for (?splat-rasterizer=tiles; the CPU adapters' default is quads).
import { test } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import * as h from './harness.mjs';
import * as c from './common.mjs';

const splat = path.join(c.sharedData, 'splats/playcanvas-engine/biker.spz');
const skip = c.skip || (fs.existsSync(splat) ? null : `${splat} not found (../shared absent)`);
const suite = c.viewerSuite('splats', (work) => {
  const root = c.viewerRoot(work);
  fs.symlinkSync(splat, path.join(root, 'biker.spz'));
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
