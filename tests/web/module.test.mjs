// The viewer as an ES module (build-web/stipple.mjs, issue 45 parts 4 and 5): the example page
// embeds a viewer in an ordinary layout through the module, and a second viewer on the same page
// draws too; the API's camera round-trips in the data's coordinates, setOptions changes the
// pixels (a colour mode; the point budget, as `stipple render --budget`), screenshot() is a PNG
// of the canvas's size and destroy() ends the program and removes its canvas. The stock page
// keeps its view in the link's hash: a second page opened with that link draws the same pixels
// (every channel of every pixel), and editing the hash changes the view. Its point budget control
// thins a tileset to coarser tiles and back, and a link with the budget opens the same tiles
// (streamed, then the budget applied: the same pixels too). The TypeScript
// declarations check a page's use of the API (tsc, where npm's typescript is installed), and the
// hash format round-trips (in node). Headless chromium (WebGPU on SwiftShader) as in the other
// web tests; native renders on lavapipe, compared within common.mjs's tolerance.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { spawnSync } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import * as h from './harness.mjs';
import * as c from './common.mjs';

const skip = c.skip;
const suite = c.viewerSuite('module', (work) => c.cloudRoot(work).root);

// Resolves after `n` animation frames of the page.
const animationFrames = (page, n = 30) =>
  page.evaluate((n) => new Promise((resolve) => {
    let left = n;
    const tick = () => (--left <= 0 ? resolve() : requestAnimationFrame(tick));
    requestAnimationFrame(tick);
  }), n);

// Per-pixel comparison of two viewers' pixels, or of a viewer's with a PNG (decoded by the
// browser): `a` and `b` are expressions in the page giving a viewer or a PNG's base64. Returns
// the mean largest channel difference (of 255), the fraction of pixels off by more than 48, the
// fraction of pixels that differ at all, the largest difference, and the fraction of each image
// that is lit (brighter than the dark background); `size` where the sizes differ.
async function compare(page, a, b) {
  return page.evaluate(async (a, b) => {
    const read = async (what) => {
      if (typeof what !== 'string') return what.pixels();
      const bytes = Uint8Array.from(atob(what), (ch) => ch.charCodeAt(0));
      const bitmap = await createImageBitmap(new Blob([bytes], { type: 'image/png' }));
      const ctx = new OffscreenCanvas(bitmap.width, bitmap.height).getContext('2d');
      ctx.drawImage(bitmap, 0, 0);
      return ctx.getImageData(0, 0, bitmap.width, bitmap.height);
    };
    const [x, y] = [await read(eval(a)), await read(eval(b))];
    if (x.width !== y.width || x.height !== y.height)
      return { size: `${x.width}x${x.height} vs ${y.width}x${y.height}` };
    let sum = 0, off = 0, differ = 0, max = 0, litA = 0, litB = 0;
    for (let i = 0; i < x.data.length; i += 4) {
      let d = 0;
      for (let k = 0; k < 3; ++k) d = Math.max(d, Math.abs(x.data[i + k] - y.data[i + k]));
      sum += d;
      max = Math.max(max, d);
      if (d > 48) ++off;
      if (d > 0) ++differ;
      if (x.data[i] + x.data[i + 1] + x.data[i + 2] > 60) ++litA;
      if (y.data[i] + y.data[i + 1] + y.data[i + 2] > 60) ++litB;
    }
    const n = x.data.length / 4;
    return { meanDiff: sum / n, offFraction: off / n, differFraction: differ / n, maxDiff: max,
             litA: litA / n, litB: litB / n };
  }, a, b);
}

const png64 = (file) => `'${fs.readFileSync(file).toString('base64')}'`;

// `stipple render` of the built-in scene at the size of `viewer`'s canvas, with `args`.
async function nativeScene(page, viewer, name, args) {
  const [width, height] = await page.evaluate((v) => [eval(v).canvas.width, eval(v).canvas.height], viewer);
  const png = path.join(suite.work, `${name}.png`);
  h.stipple(['render', '-o', png, '--width', String(width), '--height', String(height),
             '--scene-points', '50000', '--point-size', '2', ...args]);
  return png;
}

// The canvas matches the native render within common.mjs's tolerance (mean difference under 3,
// under 2% of the pixels off by more than 48).
function assertMatches(d, what) {
  console.log(`${what}: ${JSON.stringify(d)}`);
  assert.equal(d.size, undefined, `${what}: sizes differ: ${d.size}`);
  assert.ok(d.meanDiff < 3, `${what}: mean difference ${d.meanDiff}`);
  assert.ok(d.offFraction < 0.02, `${what}: ${d.offFraction} of the pixels differ by more than 48`);
}

// Runs `change` in the page and waits for the frame the viewer `v` draws after it.
async function redrawn(page, v, change) {
  const before = await page.evaluate((v) => eval(v).stats().frames, v);
  await page.evaluate(change);
  await page.waitForFunction((v, n) => eval(v).stats().frames > n, { timeout: 60000 }, v, before);
}

test('the example page embeds a viewer; a second viewer on the page; camera, options, screenshot, destroy', { skip: skip || false }, async () => {
  const page = await suite.browser.newPage();
  await page.setViewport({ width: 1000, height: 800 });
  const log = [];
  page.on('pageerror', (e) => log.push(`page error: ${e}`));
  page.on('console', (m) => log.push(`console ${m.type()}: ${m.text()}`));
  await page.goto(suite.server.url('viewer/example.html?scene-points=50000&point-size=2'));
  // window.viewer is the <div id="viewer"> (the document's named access) until the page sets it
  // to the viewer: wait for the viewer's own `loaded`.
  await page.waitForFunction(() => window.viewer?.loaded || document.getElementById('error').textContent,
                             { timeout: 240000 });
  const load = await page.evaluate(() => window.viewer.loaded.then((info) => info, (e) => ({ error: e.message })));
  assert.equal(load.error, undefined, log.join('\n'));
  assert.equal(load.points, 50000);
  assert.equal(load.renderer, 'billboard');
  // The canvas is the module's, inside the page's box, its drawing buffer the box's size in
  // device pixels; the view is drawn (stats) and matches `stipple render` at that size.
  const layout = await page.evaluate(() => {
    const box = document.getElementById('viewer');
    const canvas = box.querySelector('canvas');
    return { inBox: canvas === window.viewer.canvas, inMain: !!box.closest('main'),
             size: [canvas.width, canvas.height],
             want: [Math.round(box.clientWidth * devicePixelRatio), Math.round(box.clientHeight * devicePixelRatio)],
             stats: window.viewer.stats() };
  });
  console.log(`example page: ${JSON.stringify(layout)}`);
  assert.ok(layout.inBox && layout.inMain, 'the canvas is not in the page\'s box');
  assert.deepEqual(layout.size, layout.want);
  assert.ok(layout.stats.frames > 0, `frames: ${layout.stats.frames}`);
  assert.equal(layout.stats.pointsDrawn, 50000);
  assert.match(layout.stats.canvas, new RegExp(`^${layout.size[0]}x${layout.size[1]} `));
  const first = await nativeScene(page, 'window.viewer', 'example', []);
  assertMatches(await compare(page, 'window.viewer', png64(first)), 'the example page against stipple render');
  // Not the background: the native render of no points (a budget of 1, below the one chunk)
  // differs from it.
  const background = await nativeScene(page, 'window.viewer', 'background', ['--budget', '1']);
  const drawn = await compare(page, 'window.viewer', png64(background));
  console.log(`the example page against the background: ${JSON.stringify(drawn)}`);
  assert.ok(drawn.meanDiff > 5 && drawn.differFraction > 0.1, 'the example page shows the background only');

  // A second viewer in a box added to the page: both draw, each its own canvas.
  await page.evaluate(async () => {
    const { createViewer } = await import('./stipple.mjs');
    const box = document.createElement('div');
    box.id = 'second';
    box.style.cssText = 'width: 320px; height: 240px';
    document.querySelector('main').appendChild(box);
    window.second = await createViewer(box, { scenePoints: 50000, pointSize: 2 });
    await window.second.loaded;
  });
  const ids = await page.evaluate(() => [window.viewer.canvas.id, window.second.canvas.id,
                                         window.second.canvas.width, window.second.canvas.height]);
  console.log(`canvases: ${JSON.stringify(ids)}`);
  assert.notEqual(ids[0], ids[1]);
  assert.deepEqual(ids.slice(2), [320, 240]);
  const d2 = await compare(page, 'window.second', png64(await nativeScene(page, 'window.second', 'second', [])));
  assertMatches(d2, 'the second viewer against stipple render');
  const drawn2 = await compare(page, 'window.second', png64(await nativeScene(page, 'window.second', 'background2', ['--budget', '1'])));
  assert.ok(drawn2.meanDiff > 5 && drawn2.differFraction > 0.1, 'the second viewer shows the background only');
  // The first still draws: the same pixels as before.
  assertMatches(await compare(page, 'window.viewer', png64(first)), 'the first viewer after the second came');

  // The camera, set then read back: the same position, target and fov (to 1e-6 relative), drawn
  // once (the view changed).
  const c0 = await page.evaluate(() => window.second.camera);
  console.log(`second viewer's camera: ${JSON.stringify(c0)}`);
  assert.equal(c0.position.length, 3);
  assert.ok(Math.abs(c0.fov - 50) < 1e-9, `fov ${c0.fov}`);
  const set = { position: c0.position.map((x, i) => c0.target[i] + (x - c0.target[i]) * 0.6 + [2, -1, 0.5][i]),
                target: c0.target.map((x, i) => x + [1, 0.5, -0.25][i]), fov: 40 };
  await page.evaluate(async () => { window.beforeMove = await window.second.pixels(); });
  const framesBefore = await page.evaluate(() => window.second.stats().frames);
  await page.evaluate((s) => {
    window.cameraEvent = new Promise((resolve) => window.second.on('camera', resolve));
    window.second.camera = JSON.parse(s);
  }, JSON.stringify(set));
  const reported = await page.evaluate(() => window.cameraEvent);
  await page.waitForFunction((n) => window.second.stats().frames > n, { timeout: 60000 }, framesBefore);
  await animationFrames(page);
  const c1 = await page.evaluate(() => window.second.camera);
  console.log(`set ${JSON.stringify(set)}, read ${JSON.stringify(c1)}`);
  const near = (a, b) => Math.abs(a - b) <= 1e-6 * Math.max(1, Math.abs(b));
  for (const key of ['position', 'target'])
    for (let i = 0; i < 3; ++i) assert.ok(near(c1[key][i], set[key][i]), `${key}[${i}]: ${c1[key][i]} vs ${set[key][i]}`);
  assert.ok(near(c1.fov, 40), `fov ${c1.fov}`);
  assert.deepEqual(reported, c1, 'the camera event gives the camera');
  assert.equal(await page.evaluate(() => window.second.stats().frames), framesBefore + 1, 'a camera set draws once');
  const moved = await page.evaluate(async () => {
    const before = window.beforeMove;
    const after = await window.second.pixels();
    let sum = 0;
    for (let i = 0; i < after.data.length; ++i) sum += Math.abs(after.data[i] - before.data[i]);
    return sum / after.data.length;
  });
  console.log(`the camera set changed the pixels by a mean of ${moved}`);
  assert.ok(moved > 1, 'setting the camera did not change the view');

  // setOptions: a colour mode changes the pixels (classification against the scene's RGB) and
  // matches `stipple render --color classification`; bad options throw.
  await redrawn(page, 'window.viewer', () => window.viewer.setOptions({ color: 'classification' }));
  const classes = await compare(page, 'window.viewer', png64(first));
  console.log(`classification against the first view: ${JSON.stringify(classes)}`);
  assert.ok(classes.meanDiff > 1, 'the colour mode did not change the pixels');
  assertMatches(await compare(page, 'window.viewer', png64(await nativeScene(page, 'window.viewer', 'classes', ['--color', 'classification']))),
                'setOptions({ color: classification }) against stipple render --color classification');
  assert.equal(await page.evaluate(() => window.viewer.options.color), 'classification');
  const thrown = await page.evaluate(() => {
    const errors = [];
    for (const o of [{ colour: 'rgb' }, { pointSize: 100 }, { color: 'purple' }, { budget: -1 }])
      try { window.viewer.setOptions(o); } catch (e) { errors.push(`${e.name}: ${e.message}`); }
    return errors;
  });
  assert.equal(thrown.length, 4, JSON.stringify(thrown));
  assert.match(thrown[0], /^TypeError: .*unknown option 'colour'/);
  assert.match(thrown[1], /^RangeError: pointSize/);
  // The point budget while the view runs: one chunk of 50,000 points is over a budget of 1, so
  // nothing is drawn (the nearest whole chunks, as `stipple render --budget 1`); 0 draws all.
  await redrawn(page, 'window.viewer', () => window.viewer.setOptions({ budget: 1 }));
  assert.equal(await page.evaluate(() => window.viewer.stats().pointsDrawn), 0);
  assertMatches(await compare(page, 'window.viewer', png64(await nativeScene(page, 'window.viewer', 'budget1', ['--color', 'classification', '--budget', '1']))),
                'setOptions({ budget: 1 }) against stipple render --budget 1');
  await redrawn(page, 'window.viewer', () => window.viewer.setOptions({ budget: 0 }));
  assert.equal(await page.evaluate(() => window.viewer.stats().pointsDrawn), 50000);

  // screenshot(): a PNG of the canvas's size, the pixels the view shows.
  const shot = await page.evaluate(async () => {
    const blob = await window.second.screenshot();
    const bitmap = await createImageBitmap(blob);
    const ctx = new OffscreenCanvas(bitmap.width, bitmap.height).getContext('2d');
    ctx.drawImage(bitmap, 0, 0);
    const png = ctx.getImageData(0, 0, bitmap.width, bitmap.height).data;
    const view = (await window.second.pixels()).data;
    let differ = 0;
    for (let i = 0; i < png.length; ++i) if (png[i] !== view[i]) ++differ;
    const head = new Uint8Array(await blob.slice(0, 8).arrayBuffer());
    return { type: blob.type, size: blob.size, width: bitmap.width, height: bitmap.height,
             canvas: [window.second.canvas.width, window.second.canvas.height], differ,
             signature: Array.from(head) };
  });
  console.log(`screenshot: ${JSON.stringify(shot)}`);
  assert.equal(shot.type, 'image/png');
  assert.deepEqual(shot.signature, [137, 80, 78, 71, 13, 10, 26, 10]);
  assert.deepEqual([shot.width, shot.height], shot.canvas);
  assert.equal(shot.differ, 0, 'the PNG holds other pixels than the view');

  // destroy(): the program ends (the promise resolves), the canvas leaves the page, the viewer
  // refuses further calls; the other viewer goes on drawing.
  const destroyed = await page.evaluate(async () => {
    const v = window.second;
    const id = v.canvas.id;
    const frames = v.stats().frames;
    const ended = await Promise.race([v.destroy().then(() => 'ended'),
                                      new Promise((r) => setTimeout(() => r('still running'), 30000))]);
    const refused = [];
    for (const call of [() => v.setOptions({ color: 'rgb' }), () => v.pixels(), () => { v.camera = v.camera; }])
      try { call(); } catch (e) { refused.push(e.message); }
    return { ended, canvas: !!document.getElementById(id), inBox: !!document.getElementById('second').querySelector('canvas'),
             frames, quit: v._program.stippleQuit, refused };
  });
  console.log(`destroyed: ${JSON.stringify(destroyed)}`);
  assert.equal(destroyed.ended, 'ended');
  assert.equal(destroyed.canvas, false);
  assert.equal(destroyed.inBox, false);
  assert.equal(destroyed.refused.length, 3);
  // No frames after it: its input reaches nothing, and its program is gone.
  await page.evaluate(() => window.second._program.stippleInput.dx = 100);
  await animationFrames(page);
  assert.equal(await page.evaluate(() => window.second.stats().frames), destroyed.frames);
  assert.equal(await page.evaluate(() => window.second._program.stippleInput.dx), 100, 'the ended program took input');
  await redrawn(page, 'window.viewer', () => window.viewer.setOptions({ color: 'auto' }));
  assertMatches(await compare(page, 'window.viewer', png64(first)), 'the first viewer after the second was destroyed');
  assert.deepEqual(log.filter((l) => l.startsWith('page error')), []);
  await page.close();
});

// Sets a control of the stock page as a user would (its value, then the event the page listens
// to) and waits for the frame drawn after it.
async function setControl(page, id, value) {
  const before = await page.evaluate(() => Number(window.stipple.viewFrames || 0));
  await page.evaluate((id, value) => {
    const e = document.getElementById(id);
    if (e.type === 'checkbox') e.checked = value;
    else e.value = String(value);
    e.dispatchEvent(new Event(e.tagName === 'SELECT' || e.type === 'checkbox' || e.type === 'number' ? 'change' : 'input'));
  }, id, value);
  await page.waitForFunction((n) => Number(window.stipple.viewFrames || 0) > n, { timeout: 60000 }, before);
}

// The stock page's view as a PNG (screenshot(): lossless), base64.
const viewPng = (page) => page.evaluate(async () => {
  const png = new Uint8Array(await (await window.stippleViewer.screenshot()).arrayBuffer());
  let text = '';
  for (const byte of png) text += String.fromCharCode(byte);
  return btoa(text);
});

// The stock page's view against a PNG (base64): the pixels that differ at all, the largest
// difference (of 255), the fraction lit and both sizes.
const exactly = (page, png) => page.evaluate(async (png) => {
  const bytes = Uint8Array.from(atob(png), (ch) => ch.charCodeAt(0));
  const bitmap = await createImageBitmap(new Blob([bytes], { type: 'image/png' }));
  const ctx = new OffscreenCanvas(bitmap.width, bitmap.height).getContext('2d');
  ctx.drawImage(bitmap, 0, 0);
  const y = ctx.getImageData(0, 0, bitmap.width, bitmap.height);
  const x = await window.stippleCapture();
  let differ = 0, lit = 0, max = 0;
  for (let i = 0; i < x.data.length; i += 4) {
    let m = 0;
    for (let k = 0; k < 3; ++k) m = Math.max(m, Math.abs(x.data[i + k] - y.data[i + k]));
    if (m > 0) ++differ;
    max = Math.max(max, m);
    if (x.data[i] + x.data[i + 1] + x.data[i + 2] > 60) ++lit;
  }
  return { differ, max, lit: lit / (x.data.length / 4), size: [x.width, x.height, y.width, y.height] };
}, png);

// The hash once it holds the viewer's view state (it follows at most four times a second).
async function settledHash(page) {
  await page.waitForFunction(async () => {
    const { encodeViewState } = await import('./stipple.mjs');
    return location.hash.slice(1) === encodeViewState(window.stippleViewer.viewState());
  }, { timeout: 30000, polling: 100 });
  return page.evaluate(() => location.href);
}

test('a link reopens the view: the same camera, options and pixels', { skip: skip || false }, async () => {
  const query = 'url=/cloud.las&width=320&height=240';
  const a = await c.openPage(suite.browser, suite.server.url(`viewer/stipple.html?${query}`));
  c.assertDone(a.state, a.log);
  // The sender turns the view and changes the colour and EDL strength.
  await a.page.keyboard.press('ArrowLeft');
  await a.page.keyboard.press('ArrowUp');
  // Once the program has taken both keys' input (it zeroes the viewer's sums).
  await a.page.waitForFunction(() => {
    const i = window.stippleViewer._program.stippleInput;
    return Number(window.stipple.cameraMoves) >= 1 && !i.dx && !i.dy;
  }, { timeout: 30000 });
  await setControl(a.page, 'color', 'classification');
  await setControl(a.page, 'edl-strength', 150);
  const link = await settledHash(a.page);
  console.log(`link: ${link}`);
  const hash = new URL(link).hash;
  assert.match(hash, /^#camera=[-0-9.e,]+&color=classification&edl-strength=150$/);
  // The sender's view as a PNG (screenshot(): lossless), read back in the receiver's page.
  const sent = { camera: await a.page.evaluate(() => window.stippleViewer.camera), png: await viewPng(a.page) };
  // The receiver opens the link.
  const b = await c.openPage(suite.browser, link);
  c.assertDone(b.state, b.log);
  const got = await b.page.evaluate(() => ({ camera: window.stippleViewer.camera,
                                             options: window.stippleViewer.options,
                                             hash: location.hash, frames: window.stippleViewer.stats().frames }));
  console.log(`received: ${JSON.stringify(got)}`);
  assert.deepEqual(got.camera, sent.camera, 'the camera differs');
  assert.equal(got.options.color, 'classification');
  assert.equal(got.options.edlStrength, 150);
  assert.equal(got.hash, hash, 'the receiver\'s hash differs');
  assert.equal(got.frames, 1, 'the link\'s view is the first frame drawn');
  // The same pixels: the same program, scene, camera bits and options on the same browser draw
  // the same frame. Tolerance: none (every channel of every pixel equal).
  const d = await exactly(b.page, sent.png);
  console.log(`sender vs receiver: ${JSON.stringify(d)}`);
  assert.deepEqual(d.size.slice(0, 2), d.size.slice(2));
  assert.ok(d.lit > 0.05, `only ${d.lit} of the canvas is drawn`);
  assert.equal(d.differ, 0, `${d.differ} pixels differ (by up to ${d.max})`);
  // Editing the hash changes the view too.
  await b.page.evaluate(() => { location.hash = '#color=elevation'; });
  await b.page.waitForFunction(() => window.stippleViewer.options.color === 'elevation', { timeout: 30000 });
  await a.page.close();
  await b.page.close();
});

test('the point budget control thins a tileset to coarser tiles and back', { skip: skip || false }, async () => {
  const { page, state, log } = await c.openPage(
    suite.browser, suite.server.url('viewer/stipple.html?url=/tiles/tileset.json&width=320&height=240&max-sse=1'));
  c.assertDone(state, log);
  const stats = () => page.evaluate(() => window.stippleViewer.stats());
  const full = await stats();
  const before = await page.evaluate(() => window.stippleCapture());
  const budget = Math.floor(full.pointsDrawn / 2);
  console.log(`tileset: ${full.pointsDrawn} points in ${full.tilesDrawn} tiles; budget ${budget}`);
  // The control sets the running view's budget: coarser tiles stream in until it holds.
  await setControl(page, 'budget', budget);
  await page.waitForFunction((b) => {
    const s = window.stippleViewer.stats();
    return s.tilesLoading === 0 && s.pointsDrawn <= b;
  }, { timeout: 120000 }, budget);
  const thin = await stats();
  console.log(`with the budget: ${JSON.stringify(thin)}`);
  assert.ok(thin.pointsDrawn > 0 && thin.pointsDrawn <= budget, `${thin.pointsDrawn} points drawn`);
  assert.equal(await page.evaluate(() => window.stippleViewer.options.budget), budget);
  assert.equal(await page.evaluate(() => document.getElementById('budget').value), String(budget));
  const d = await page.evaluate(async (b) => {
    const a = await window.stippleCapture();
    let sum = 0, lit = 0;
    for (let i = 0; i < a.data.length; i += 4) {
      let m = 0;
      for (let k = 0; k < 3; ++k) m = Math.max(m, Math.abs(a.data[i + k] - b.data[i + k]));
      sum += m;
      if (a.data[i] + a.data[i + 1] + a.data[i + 2] > 60) ++lit;
    }
    return { meanDiff: sum / (a.data.length / 4), lit: lit / (a.data.length / 4) };
  }, before);
  console.log(`thinned against the full view: ${JSON.stringify(d)}`);
  assert.ok(d.lit > 0.05, `only ${d.lit} of the canvas is drawn`);
  assert.ok(d.meanDiff > 0.5, 'the budget did not change the pixels');
  const link = await settledHash(page);
  assert.match(link, new RegExp(`#budget=${budget}$`));
  // The link opens the tileset with the budget applied once it is streamed: the same tiles.
  const b = await c.openPage(suite.browser, link);
  c.assertDone(b.state, b.log);
  const got = await b.page.evaluate(() => ({ stats: window.stippleViewer.stats(), options: window.stippleViewer.options }));
  console.log(`the link's page: ${JSON.stringify(got)}`);
  assert.equal(got.options.budget, budget);
  assert.equal(got.stats.pointsDrawn, thin.pointsDrawn);
  assert.equal(got.stats.tilesDrawn, thin.tilesDrawn);
  const same = await exactly(b.page, await viewPng(page));
  console.log(`the link's page against the sender's: ${JSON.stringify(same)}`);
  assert.equal(same.differ, 0, `${same.differ} pixels differ (by up to ${same.max})`);
  await b.page.close();
  // 0: every tile the view wants again.
  await setControl(page, 'budget', 0);
  await page.waitForFunction((n) => {
    const s = window.stippleViewer.stats();
    return s.tilesLoading === 0 && s.pointsDrawn === n;
  }, { timeout: 120000 }, full.pointsDrawn);
  await page.close();
});

// The declarations type a page's use of the API (the compile fails for a misuse), and the hash
// format reads back what it writes. In node: tsc from npm's typescript where installed.
test('the TypeScript declarations check a page\'s use of the module; the hash format round-trips', { skip: c.skip || false }, async () => {
  const m = await import(path.join(c.webDir, 'stipple.mjs'));
  assert.deepEqual(Object.keys(m).sort(), ['Viewer', 'colorModes', 'createViewer', 'decodeViewState', 'encodeViewState']);
  const state = { camera: { position: [637012.3456789012, 851234.5, 120.0001], target: [1e-7, -2, 3.5] },
                  color: 'elevation', pointSize: 2.5, edl: false, edlStrength: 80, edlRadius: 1.5,
                  budget: 1000000, maxSse: 4, memoryMb: 256 };
  const hash = m.encodeViewState(state);
  console.log(`hash: ${hash}`);
  assert.equal(hash, 'camera=637012.3456789012,851234.5,120.0001,1e-7,-2,3.5&color=elevation&point-size=2.5' +
                     '&edl=0&edl-strength=80&edl-radius=1.5&budget=1000000&max-sse=4&memory-mb=256');
  assert.deepEqual(m.decodeViewState(`#${hash}&later-tool={"a":1}`), state);
  assert.deepEqual(m.decodeViewState('#camera=1,2,3,4,5,6&fov=30').camera, { position: [1, 2, 3], target: [4, 5, 6], fov: 30 });
  assert.throws(() => m.decodeViewState('#color=purple'), RangeError);
  assert.throws(() => m.decodeViewState('#camera=1,2,3'), RangeError);

  const tsc = process.env.STIPPLE_TSC || path.join(h.nodePrefix, 'node_modules/typescript/bin/tsc');
  if (!fs.existsSync(tsc)) {
    // (Not node's skip: ctest would count the whole file as skipped.)
    console.log('tsc not run: npm package typescript not installed (scripts/setup.sh --deps installs it)');
    return;
  }
  const dir = h.tempDir('types');
  try {
    for (const f of ['stipple.mjs', 'stipple.d.mts', 'stipple.d.ts']) fs.copyFileSync(path.join(c.webDir, f), path.join(dir, f));
    const use = fs.readFileSync(path.join(path.dirname(new URL(import.meta.url).pathname), 'module_use.ts'), 'utf8');
    const check = (source) => {
      fs.writeFileSync(path.join(dir, 'use.ts'), source);
      return spawnSync(process.execPath, [tsc, '--noEmit', '--strict', '--target', 'es2022', '--module', 'es2022',
                                          '--moduleResolution', 'bundler', '--lib', 'es2022,dom', 'use.ts'],
                       { cwd: dir, encoding: 'utf8' });
    };
    const ok = check(use);
    assert.equal(ok.status, 0, ok.stdout + ok.stderr);
    // A misuse is a type error: the declarations are read, not an implicit any.
    const bad = check(use.replace("color: 'classification'", "color: 'purple'"));
    assert.notEqual(bad.status, 0, 'a colour mode that does not exist compiled');
    assert.match(bad.stdout, /'"purple"' is not assignable/);
  } finally {
    fs.rmSync(dir, { recursive: true, force: true });
  }
});
