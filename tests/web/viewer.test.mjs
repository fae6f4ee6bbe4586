// The web viewer (scripts/build-web.sh: libstipple compiled to WebAssembly on the browser's
// WebGPU) served by nginx on loopback and opened in headless chromium (WebGPU on SwiftShader):
// the page renders the built-in scene through the same engine, plugins, render graph and
// shaders as `stipple render`, and its canvas matches the native render of the same camera
// (lavapipe) within the stated tolerance. Bad options are an error shown on the page.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import path from 'node:path';
import * as h from './harness.mjs';
import * as c from './common.mjs';

const skip = c.skip;
// The viewer's folder served as it is.
const suite = c.viewerSuite('viewer', () => c.webDir);
const { work } = suite;

// Opens the viewer with `query` and waits until it reports done or an error. `before` runs in
// the page before its scripts.
const open = (query, before = null) =>
  c.openPage(suite.browser, suite.server.url(`stipple.html?${query}`), { before, timeout: 180000 });

// Two sizes of the built-in scene: 200,000 points at 320x240 are 1-pixel points (the compute
// rasterizer, as `stipple render --renderer auto` chooses), 50,000 larger ones (billboards).
for (const [points, renderer] of [['200000', 'compute'], ['50000', 'billboard']]) {
  test(`the built-in scene (${points} points, ${renderer}) matches the native render`, { skip: skip || false }, async () => {
    const ref = path.join(work, `native${points}.png`);
    h.stipple(['render', '-o', ref, '--width', '320', '--height', '240', '--scene-points', points]);
    const { page, state, log } = await open(`width=320&height=240&scene-points=${points}`);
    c.assertDone(state, log);
    assert.equal(state.points, points);
    assert.equal(state.renderer, renderer);
    // The scene covers most of the image, not a blank canvas. Measured: compute 0.0002 and 0,
    // billboards 1.13 and 0.7% (point edges), against common.mjs's 3 and 2%.
    await c.assertCanvasMatches(page, ref, {
      minLit: 0.2,
      describe: (d) => `web vs native: ${JSON.stringify(d)}; ${state.renderer}, ${state.ms} ms, ${state.adapter}`,
    });
    await page.close();
  });
}

// The Nishita sky on the page (?sky=1&sun=AZ,EL, as `stipple render --sky --sun`): the same
// image as the native render, the sky filling what the points leave (the default framing looks
// down on the scene: below the horizon, the horizon's darkened light), within common.mjs's
// tolerance (a page that ignored the option would differ from the native sky almost everywhere).
// Measured: mean difference 1.11, 0.7% of the pixels off by more than 48.
test('the sky (?sky=1&sun=) matches the native render', { skip: skip || false }, async () => {
  const ref = path.join(work, 'native-sky.png');
  h.stipple(['render', '-o', ref, '--width', '320', '--height', '240', '--scene-points', '50000',
             '--sky', '--sun', '90,20']);
  const { page, state, log } = await open('width=320&height=240&scene-points=50000&sky=1&sun=90,20');
  c.assertDone(state, log);
  await c.assertCanvasMatches(page, ref, {
    minLit: 0.9,
    describe: (d) => `web vs native, sky: ${JSON.stringify(d)}; ${state.renderer}, ${state.adapter}`,
  });
  await page.close();
});

test('a bad option is an error shown on the page', { skip: skip || false }, async () => {
  const { page, state } = await open('width=abc');
  assert.match(state.error || '', /--width: not a number: 'abc'/);
  assert.match(state.shown, /--width/);
  await page.close();
});

test('a browser without WebGPU is told so on the page', { skip: skip || false }, async () => {
  const { page, state } = await open('width=64&height=64', () => {
    delete Navigator.prototype.gpu;
  });
  assert.match(state.shown, /no WebGPU/);
  assert.equal(state.done, undefined);
  await page.close();
});
