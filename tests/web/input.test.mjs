// The web viewer's inputs other than a tileset URL: a LAS file dropped on the page (a drop event
// carrying a File, as the browser makes one from a file dragged onto it) and a COPC file chosen
// with the page's button open through the same path as a ?url= of them, and LAZ and COPC files
// open by URL (LASzip compiled to WebAssembly); each canvas matches `stipple render` of the same file
// (lavapipe) within the stated tolerance. Touch (Chromium's input events through the DevTools
// protocol, which the page sees as pointer events) turns the view with one finger, zooms with a
// pinch and pans with two fingers (the page's camera readout, window.stipple.camera, says so).
// Autzen and lone-star from ../shared/data, or generated clouds where ../shared is absent.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import * as h from './harness.mjs';
import * as c from './common.mjs';

const skip = c.skip;
const files = {};  // served name -> local path
const suite = c.viewerSuite('input', (work) => {
  const real = {
    'cloud.las': path.join(c.sharedData, 'las/autzen_trim.las'),
    'cloud.laz': path.join(c.sharedData, 'laz/autzen_trim.laz'),
    'cloud.copc.laz': path.join(c.sharedData, 'laz/lone-star.copc.laz'),
  };
  const root = c.viewerRoot(work);
  for (const [name, file] of Object.entries(real)) {
    files[name] = c.sharedOrGenerated(file, path.join(work, name), 100000);
    fs.symlinkSync(files[name], path.join(root, name));
  }
  return root;
});
const { work } = suite;

// What the page reports, once it reports done or an error for the view it opens next: `action`
// opens it (window.stipple is reset when a file is opened).
const settle = (page, log, action = null) => c.settle(page, log, { action });

const open = (query) => c.openPage(suite.browser, suite.server.url(`viewer/stipple.html?${query}`));

// The canvas against `stipple render FILE` at 320x240: the same renderer, points and image
// within the tolerance of the other web tests (common.mjs).
async function matchesNative(page, state, log, name) {
  c.assertDone(state, log);
  const ref = path.join(work, `${name}.png`);
  const native = h.stipple(['render', files[name], '-o', ref, '--width', '320', '--height', '240']);
  c.assertNativeAgrees(native, state, { points: true });
  return c.assertCanvasMatches(page, ref, {
    describe: (d) => `${name} web vs native: ${JSON.stringify(d)}; ${state.points} points, ` +
                     `${state.renderer}, read in ${state.loadMs} ms, drawn in ${state.ms} ms`,
  });
}

const camera = (page) => page.evaluate(() => JSON.parse(window.stipple.camera));

// Touches through the DevTools protocol: `from` and `to` are lists of points (one per finger),
// moved in `steps` steps.
async function touchDrag(cdp, from, to, steps = 6) {
  const at = (t) => from.map((p, i) => ({ x: p.x + (to[i].x - p.x) * t, y: p.y + (to[i].y - p.y) * t, id: i }));
  await cdp.send('Input.dispatchTouchEvent', { type: 'touchStart', touchPoints: at(0) });
  for (let s = 1; s <= steps; ++s)
    await cdp.send('Input.dispatchTouchEvent', { type: 'touchMove', touchPoints: at(s / steps) });
  await cdp.send('Input.dispatchTouchEvent', { type: 'touchEnd', touchPoints: [] });
}

// The camera once the program has taken the gesture's input (it zeroes the viewer's sums).
async function moved(page) {
  await page.waitForFunction(() => {
    const i = window.stippleViewer._program.stippleInput;
    return !i.dx && !i.dy && !i.zoom && !i.panX && !i.panY;
  }, { timeout: 30000 });
  return camera(page);
}

test('a LAS file dropped on the page matches its native render; touch turns, pinches and pans', { skip: skip || false }, async () => {
  // A small built-in scene first: the dropped file replaces it.
  const { page, state: first, log } = await open('width=320&height=240&scene-points=1000');
  assert.equal(first.done, '1', `${first.error}\n${log.join('\n')}`);
  const state = await settle(page, log, () =>
    page.evaluate(async () => {
      const bytes = await (await fetch('/cloud.las')).arrayBuffer();
      const dt = new DataTransfer();
      dt.items.add(new File([bytes], 'cloud.las'));
      document.getElementById('canvas').dispatchEvent(
        new DragEvent('drop', { dataTransfer: dt, bubbles: true, cancelable: true }));
    }));
  const d = await matchesNative(page, state, log, 'cloud.las');

  const cdp = await page.createCDPSession();
  await cdp.send('Emulation.setTouchEmulationEnabled', { enabled: true, maxTouchPoints: 5 });
  const c0 = await camera(page);
  // One finger across the canvas turns the view; the distance stays.
  await touchDrag(cdp, [{ x: 100, y: 120 }], [{ x: 220, y: 140 }]);
  const c1 = await moved(page);
  console.log(`camera: ${JSON.stringify(c0)} -> one-finger drag ${JSON.stringify(c1)}`);
  // 120 pixels across at 0.005 radians a pixel.
  assert.ok(Math.abs(Math.abs(c1.yaw - c0.yaw) - 0.6) < 1e-3, `the view turned ${c0.yaw} -> ${c1.yaw}`);
  assert.ok(Math.abs(c1.distance / c0.distance - 1) < 1e-6, 'a one-finger drag zoomed');
  // Two fingers apart zoom in (the camera comes closer), about by their spread's ratio.
  await touchDrag(cdp, [{ x: 130, y: 120 }, { x: 190, y: 120 }], [{ x: 70, y: 120 }, { x: 250, y: 120 }]);
  const c2b = await moved(page);
  console.log(`pinch: ${JSON.stringify(c2b)}`);
  // Spread 60 -> 180 pixels: a third of the distance.
  assert.ok(Math.abs(c2b.distance / c1.distance - 1 / 3) < 0.01,
            `a pinch from 60 to 180 pixels zoomed ${c1.distance} -> ${c2b.distance}`);
  assert.ok(Math.abs(c2b.yaw - c1.yaw) < 1e-9, 'a pinch turned the view');
  // Two fingers dragged together pan: the target moves, the distance stays.
  await touchDrag(cdp, [{ x: 130, y: 100 }, { x: 190, y: 100 }], [{ x: 130, y: 180 }, { x: 190, y: 180 }]);
  const c3 = await moved(page);
  console.log(`two-finger drag: ${JSON.stringify(c3)}`);
  const shift = Math.hypot(...c3.target.map((v, i) => v - c2b.target[i]));
  assert.ok(shift > c2b.distance * 0.05, `the target moved ${shift} only`);
  assert.ok(Math.abs(c3.distance / c2b.distance - 1) < 1e-6, 'a two-finger drag zoomed');
  // The view drawn follows the camera.
  let after = d;
  for (let i = 0; i < 60 && after.meanDiff < 5; ++i) {
    await new Promise((r) => setTimeout(r, 250));
    after = await h.compareCanvas(page, fs.readFileSync(path.join(work, 'cloud.las.png')));
  }
  assert.ok(after.meanDiff >= 5, `the canvas did not change: ${JSON.stringify(after)}`);
  // A file that is neither LAS nor LAZ is an error on the page.
  await page.evaluate(() => {
    const dt = new DataTransfer();
    dt.items.add(new File(['x'], 'notes.txt'));
    window.dispatchEvent(new DragEvent('drop', { dataTransfer: dt, bubbles: true, cancelable: true }));
  });
  await page.waitForFunction(() => window.stipple.error, { timeout: 30000 });
  assert.match(await page.evaluate(() => window.stipple.error), /notes\.txt: not a LAS or LAZ file/);
  await page.close();
});

// COPC streams as `stipple render` streams it (the hierarchy, nodes for the view): by URL through
// the browser's range requests, chosen with the button from the page's file system.
test('LAZ and COPC files by URL and a COPC file chosen with the button match their native renders', { skip: skip || false }, async () => {
  const { page, state, log } = await open('width=320&height=240&url=/cloud.laz');
  await matchesNative(page, state, log, 'cloud.laz');
  const button = await page.$('#file');
  const chosen = await settle(page, log, () => button.uploadFile(files['cloud.copc.laz']));
  await matchesNative(page, chosen, log, 'cloud.copc.laz');
  await page.close();
  const byUrl = await open('width=320&height=240&url=/cloud.copc.laz');
  await matchesNative(byUrl.page, byUrl.state, byUrl.log, 'cloud.copc.laz');
  await byUrl.page.close();
});
