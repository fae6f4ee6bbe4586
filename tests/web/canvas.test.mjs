// The web viewer's presentation (issue 45, part 1): the program draws straight into the page's
// WebGPU canvas, which fills the window and follows its resizes and devicePixelRatio (?scale=
// renders below it), and draws only when something changed. Headless chromium (WebGPU on
// SwiftShader) against `stipple render` of the same scene at each size (lavapipe), within the
// tolerance of common.mjs: the canvas's size follows the window's, a resize redraws exactly once,
// an idle page's frame counter (window.stipple.stats.frames) stops, a key press draws again,
// and a tileset's page stops drawing once its tiles are in. Frames are not waited for: the stats
// give the page's thread's time per frame (cpuMs) and, from timestamp queries that come back
// later, the GPU time of the newest frame timed (gpuMs, gpuFrame).
import { test } from 'node:test';
import assert from 'node:assert/strict';
import path from 'node:path';
import * as h from './harness.mjs';
import * as c from './common.mjs';

const skip = c.skip;
const suite = c.viewerSuite('canvas', (work) => c.cloudRoot(work).root);

// Billboards of a fixed size, as `stipple render --point-size 2` draws them (a size fitted to the
// data would depend on the first canvas's size).
const scene = 'scene-points=50000&point-size=2';

const stats = (page) => page.evaluate(() => JSON.parse(window.stipple.stats));

// Resolves after `n` animation frames of the page: time for a frame the program would draw.
const animationFrames = (page, n = 30) =>
  page.evaluate((n) => new Promise((resolve) => {
    let left = n;
    const tick = () => (--left <= 0 ? resolve() : requestAnimationFrame(tick));
    requestAnimationFrame(tick);
  }), n);

// The frame counter once nothing has been drawn for a while (asserted: it does not move).
async function assertIdle(page, what) {
  const before = await stats(page);
  await animationFrames(page);
  const after = await stats(page);
  assert.equal(after.frames, before.frames,
               `${what}: the page drew ${after.frames - before.frames} frames while idle: ` +
               `${JSON.stringify(before)} then ${JSON.stringify(after)}`);
  return after.frames;
}

// The page's frame times: the page's thread's (cpuMs) and, where the adapter has timestamp
// queries, the GPU's for the newest frame whose timestamps came back (they do while the page is
// idle: waited for here), which is one of the frames drawn. Returns the stats.
async function assertTimes(page, what) {
  let s = await stats(page);
  assert.ok(Number.isFinite(s.cpuMs) && s.cpuMs > 0, `${what}: cpuMs ${s.cpuMs}`);
  assert.equal(s.frameMs, s.cpuMs, `${what}: frameMs is cpuMs's older name`);
  if (!s.gpuTiming) {
    console.log(`${what}: no timestamp queries on this adapter: ${JSON.stringify(s)}`);
    assert.equal(s.gpuMs, null);
    return s;
  }
  await page.waitForFunction((n) => JSON.parse(window.stipple.stats).gpuFrame === n,
                             { timeout: 60000 }, s.frames);
  s = await stats(page);
  console.log(`${what}: CPU ${s.cpuMs} ms, GPU ${s.gpuMs} ms (frame ${s.gpuFrame} of ${s.frames})`);
  assert.ok(Number.isFinite(s.gpuMs) && s.gpuMs >= 0, `${what}: gpuMs ${s.gpuMs}`);
  return s;
}

// The canvas against `stipple render` of the built-in scene at its size. Its pixels are read
// back by drawing the view once more (harness.compareCanvas): returns the frame counter after.
async function assertMatchesNative(page, width, height, what) {
  const ref = path.join(suite.work, `native-${width}x${height}.png`);
  h.stipple(['render', '-o', ref, '--width', String(width), '--height', String(height),
             '--scene-points', '50000', '--point-size', '2']);
  await c.assertCanvasMatches(page, ref, {
    minLit: 0.1,
    what,
    describe: (d) => `${what}: web vs native ${JSON.stringify(d)}`,
  });
  return assertIdle(page, `after reading ${what}`);
}

// Resizes the page's viewport and waits for the frame drawn at the canvas's new size: exactly one.
async function resize(page, viewport, width, height, framesBefore) {
  await page.setViewport(viewport);
  await page.waitForFunction((size) => window.stipple.stats &&
                                       JSON.parse(window.stipple.stats).canvas.startsWith(size),
                             { timeout: 60000 }, `${width}x${height} `);
  const size = await page.evaluate(() => [document.getElementById('canvas').width,
                                          document.getElementById('canvas').height]);
  assert.deepEqual(size, [width, height], `the canvas after resizing to ${JSON.stringify(viewport)}`);
  const frames = await assertIdle(page, `after resizing to ${width}x${height}`);
  assert.equal(frames, framesBefore + 1, `a resize to ${width}x${height} drew ${frames - framesBefore} frames`);
  return frames;
}

test('the canvas fills the window and follows its resizes and devicePixelRatio, drawing once each', { skip: skip || false }, async () => {
  const page = await suite.browser.newPage();
  await page.setViewport({ width: 800, height: 600 });
  const log = [];
  page.on('pageerror', (e) => log.push(`page error: ${e}`));
  await page.goto(suite.server.url(`viewer/stipple.html?${scene}`));
  const state = await c.settle(page, log);
  c.assertDone(state, log);
  assert.equal(state.renderer, 'billboard');
  const first = await stats(page);
  console.log(`first view: ${JSON.stringify(first)}`);
  assert.match(first.canvas, /^800x600 (bgra8unorm|rgba8unorm)$/);
  assert.equal(first.frames, 1, 'the first view is one frame');
  await assertIdle(page, 'the first view');
  await assertTimes(page, 'the first view');
  let frames = await assertMatchesNative(page, 800, 600, 'the window at 800x600');
  // The window's size in CSS pixels, then devicePixelRatio 2: the canvas's drawing buffer follows
  // in device pixels (all 4:3, the first view's framing, so the native renders frame alike).
  frames = await resize(page, { width: 480, height: 360 }, 480, 360, frames);
  frames = await assertMatchesNative(page, 480, 360, 'resized to 480x360');
  frames = await resize(page, { width: 320, height: 240, deviceScaleFactor: 2 }, 640, 480, frames);
  frames = await assertMatchesNative(page, 640, 480, '320x240 at devicePixelRatio 2');
  // Something that changes the view draws a frame again; then the page is idle again.
  await page.keyboard.press('ArrowLeft');
  await page.waitForFunction((n) => JSON.parse(window.stipple.stats).frames > n, { timeout: 60000 }, frames);
  frames = await assertIdle(page, 'after a key press');
  const timed = await assertTimes(page, 'after a key press');
  if (timed.gpuTiming) assert.equal(timed.gpuFrame, frames, 'the idle page shows its last frame\'s GPU time');
  assert.deepEqual(log, []);
  await page.close();
});

test('?scale= renders below the window\'s resolution', { skip: skip || false }, async () => {
  const page = await suite.browser.newPage();
  await page.setViewport({ width: 800, height: 600 });
  const log = [];
  await page.goto(suite.server.url(`viewer/stipple.html?${scene}&scale=0.5`));
  const state = await c.settle(page, log);
  c.assertDone(state, log);
  // The drawing buffer is half the window's size; the canvas still covers the window.
  const shown = await page.evaluate(() => {
    const canvas = document.getElementById('canvas');
    return [canvas.width, canvas.height, canvas.clientWidth, canvas.clientHeight];
  });
  assert.deepEqual(shown, [400, 300, 800, 600]);
  await assertMatchesNative(page, 400, 300, '?scale=0.5 at 800x600');
  await page.close();
  const bad = await c.openPage(suite.browser, suite.server.url(`viewer/stipple.html?${scene}&scale=3`),
                               { timeout: 30000 });
  assert.match(bad.state.shown, /\?scale=3: not a number in \[0\.05 - 1\]/);
  await bad.page.close();
});

test('a tileset\'s page stops drawing once its tiles are in', { skip: skip || false }, async () => {
  const page = await suite.browser.newPage();
  await page.setViewport({ width: 400, height: 300 });
  const log = [];
  await page.goto(suite.server.url('viewer/stipple.html?url=/tiles/tileset.json&max-sse=1'));
  const state = await c.settle(page, log);
  c.assertDone(state, log);
  // A turn: the tiles for the new view stream in, each arrival drawn; then nothing. (The stats
  // are published after each frame: those of a frame drawn since the key press.)
  const before = (await stats(page)).frames;
  await page.keyboard.press('ArrowLeft');
  await page.waitForFunction((n) => {
    const s = JSON.parse(window.stipple.stats);
    return s.frames > n && s.tilesLoading === 0;
  }, { timeout: 120000 }, before);
  const frames = await assertIdle(page, 'the tileset once streamed');
  const s = await stats(page);
  console.log(`tileset: ${frames} frames drawn, ${JSON.stringify(s)}`);
  assert.ok(s.tilesDrawn > 1, `${s.tilesDrawn} tiles drawn`);
  assert.deepEqual(log.filter((l) => l.startsWith('page error')), []);
  await page.close();
});
