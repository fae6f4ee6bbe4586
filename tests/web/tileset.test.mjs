// The web viewer opens a 3D Tiles tileset by URL (stipple.html?url=.../tileset.json): nginx on
// loopback serves build-web/ and a tileset made by `stipple tile` (autzen from ../shared/data, or
// a generated cloud where ../shared is absent); headless chromium (WebGPU on SwiftShader) streams
// it through the same plugins, render graph and shaders as `stipple render`, and its canvas
// matches the native render of the same tileset and camera (lavapipe) within the stated
// tolerance; a drag, a key and the wheel move its camera. A 404 tile is an error on the page
// while the other tiles are drawn; a missing tileset is an error on the page. `stipple tile
// --page` writes a folder that opens by link. A LAS file by URL matches `stipple render` of it.
// Translucent points (pnts RGBA) are blended in the page as natively.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { spawnSync } from 'node:child_process';
import * as h from './harness.mjs';
import * as c from './common.mjs';

const skip = c.skip;
let input;
const suite = c.viewerSuite('tileset', (work) => {
  // The served root: the viewer, the file and its tileset side by side.
  let root;
  ({ root, input } = c.cloudRoot(work));
  // The same tileset with one tile below the root missing (a 404).
  fs.cpSync(path.join(root, 'tiles'), path.join(root, 'broken'), { recursive: true });
  return root;
});
const { work } = suite;

// Opens `page_path` of the server (or a full URL) and waits until the program reports done or an
// error.
function open(page_path) {
  return c.openPage(suite.browser, page_path.startsWith('http') ? page_path : suite.server.url(page_path));
}

test('a tileset by URL matches the native render of the same camera', { skip: skip || false }, async () => {
  const ref = path.join(work, 'native.png');
  const tileset = path.join(work, 'www/tiles/tileset.json');
  // --max-sse 1: the root refines, so several tiles stream in.
  const native = h.stipple(['render', tileset, '-o', ref, '--width', '320', '--height', '240',
                            '--max-sse', '1']);
  const { page, state, log } = await open('viewer/stipple.html?url=/tiles/tileset.json&width=320&height=240&max-sse=1');
  c.assertDone(state, log);
  assert.equal(state.errors, '0', state.problems);
  assert.ok(Number(state.points) > 1000, `only ${state.points} points drawn`);
  assert.ok(Number(state.tiles) > 1, `only ${state.tiles} tiles drawn: the root did not refine`);
  // The same renderer as `stipple render --renderer auto` chose.
  c.assertNativeAgrees(native, state);
  // Measured on autzen (9 tiles, 110,000 points, the compute rasterizer): 0.0002 and 0.
  const d = await c.assertCanvasMatches(page, ref, {
    describe: (d) => `web vs native: ${JSON.stringify(d)}; ${state.tiles} tiles, ${state.points} points, ` +
                     `${state.renderer}, point size ${state.pointSize}, ${state.ms} ms, ` +
                     `${state.frameMs} ms a frame once streamed, ${state.adapter}`,
  });
  // Camera controls: a drag across the canvas turns the view (the image changes, still drawn).
  await page.mouse.move(160, 120);
  await page.mouse.down();
  await page.mouse.move(260, 140, { steps: 5 });
  await page.mouse.up();
  await page.waitForFunction(() => Number(window.stipple.cameraMoves) >= 1, { timeout: 30000 });
  let turned = d;
  for (let i = 0; i < 60 && turned.meanDiff < 5; ++i) {
    await new Promise((r) => setTimeout(r, 500));
    turned = await h.compareCanvas(page, fs.readFileSync(ref));
  }
  console.log(`after a drag: ${JSON.stringify(turned)}`);
  assert.ok(turned.meanDiff >= 5, `the view did not change: ${JSON.stringify(turned)}`);
  assert.ok(turned.litFraction > 0.05, `only ${turned.litFraction} drawn after the drag`);
  // The keyboard turns it, the wheel zooms.
  await page.keyboard.press('ArrowLeft');
  await page.waitForFunction(() => Number(window.stipple.cameraMoves) >= 2, { timeout: 30000 });
  await page.mouse.move(160, 120);
  await page.mouse.wheel({ deltaY: 100 });
  await page.waitForFunction(() => Number(window.stipple.cameraMoves) >= 3, { timeout: 30000 });
  const errors = await page.evaluate(() => window.stipple.error);
  assert.equal(errors, undefined);
  await page.close();
});

test('a tile that is not found (404) is an error on the page; the other tiles are drawn', { skip: skip || false }, async () => {
  // A child of the root: requested at this view (--max-sse 1: the root refines), its parent and
  // siblings drawn anyway (additive refinement).
  const dir = path.join(work, 'www/broken');
  const ts = JSON.parse(fs.readFileSync(path.join(dir, 'tileset.json'), 'utf8'));
  const child = (ts.root.children || []).find((c) => c.content && c.content.uri);
  assert.ok(child, 'the tileset has a child tile with content');
  fs.rmSync(path.join(dir, child.content.uri));
  const { page, state, log } = await open('viewer/stipple.html?url=/broken/tileset.json&width=320&height=240&max-sse=1');
  c.assertDone(state, log);
  assert.ok(Number(state.errors) >= 1, `errors: ${state.errors}`);
  const name = path.basename(child.content.uri);
  assert.match(state.problems, new RegExp(`${name.replace('.', '\\.')}: HTTP 404 \\(not found\\)`));
  assert.ok(state.problemsShown, 'the tile error is shown on the page');
  assert.ok(Number(state.points) > 1000, `only ${state.points} points drawn`);
  const lit = await h.litFraction(page);
  assert.ok(lit > 0.05, `only ${lit} of the canvas is drawn`);
  await page.close();
});

test('a LAS file by URL matches the native render of the file', { skip: skip || false }, async () => {
  const ref = path.join(work, 'native-las.png');
  const native = h.stipple(['render', input, '-o', ref, '--width', '320', '--height', '240']);
  const { page, state, log } = await open('viewer/stipple.html?url=/cloud.las&width=320&height=240');
  c.assertDone(state, log);
  c.assertNativeAgrees(native, state, { points: true });
  await c.assertCanvasMatches(page, ref, {
    describe: (d) => `LAS web vs native: ${JSON.stringify(d)}; ${state.points} points, ${state.renderer}`,
  });
  await page.close();
});

test('a missing tileset is an error shown on the page', { skip: skip || false }, async () => {
  const { page, state } = await open('viewer/stipple.html?url=/nowhere/tileset.json&width=64&height=64');
  assert.equal(state.done, undefined);
  assert.match(state.error || '', /\/nowhere\/tileset\.json: HTTP 404 \(not found\)/);
  assert.match(state.shown, /nowhere\/tileset\.json: HTTP 404/);
  await page.close();
});

test('stipple tile --page writes a folder that opens by link', { skip: skip || false }, async () => {
  const out = path.join(work, 'www/paged');
  const printed = h.stipple(['tile', input, '-o', out, '--force', '--page']);
  assert.match(printed, /web viewer copied from/);
  for (const f of ['tileset.json', 'index.html', 'stipple.html', 'stipple.js', 'stipple.wasm'])
    assert.ok(fs.existsSync(path.join(out, f)), `${f} is not in the folder`);
  // Served as is, without COOP/COEP headers: the page isolates itself (stipple-isolation.js,
  // a service worker) and runs.
  const plain = await h.startNginx(out);
  try {
    const { page, state, log } = await open(plain.url('index.html'));
    c.assertDone(state, log);
    assert.ok(state.isolated, 'the page is not cross-origin isolated');
    assert.ok(Number(state.points) > 1000, `only ${state.points} points drawn`);
    await page.close();
  } finally {
    await plain.stop();
  }
  // Without the viewer: a clear error naming where it was looked for, before any tiling.
  const r = spawnSync(h.stippleBinary, ['tile', input, '-o', path.join(work, 'nopage'), '--page'], {
    encoding: 'utf8',
    env: { ...process.env, STIPPLE_WEB_DIR: path.join(work, 'no-viewer') },
  });
  assert.notEqual(r.status, 0);
  assert.match(r.stderr, /STIPPLE_WEB_DIR=.*no-viewer does not hold the web viewer/);
  assert.ok(!fs.existsSync(path.join(work, 'nopage')), 'nothing is tiled without the viewer');
});

// A pnts tile of two 40 x 40 layers over 20 x 20 m, 3 m apart: the bottom one opaque blue, the
// top one red at alpha 0.4 (RGBA), and its tileset.json, written into `dir`.
function writeTranslucentTileset(dir) {
  fs.mkdirSync(dir, { recursive: true });
  const n = 3200;
  const bin = Buffer.alloc(n * 16);
  for (let i = 0; i < n; ++i) {
    const top = i >= n / 2, k = i % (n / 2);
    bin.writeFloatLE(0.25 + 0.5 * (k % 40), i * 12);
    bin.writeFloatLE(0.25 + 0.5 * Math.floor(k / 40), i * 12 + 4);
    bin.writeFloatLE(top ? 3 : 0, i * 12 + 8);
    const rgba = top ? [250, 20, 20, 102] : [30, 60, 250, 255];
    for (let j = 0; j < 4; ++j) bin[n * 12 + i * 4 + j] = rgba[j];
  }
  // The feature table's JSON padded so that the binary starts on 8 bytes.
  let json = JSON.stringify({ POINTS_LENGTH: n, POSITION: { byteOffset: 0 }, RGBA: { byteOffset: n * 12 } });
  json += ' '.repeat((8 - ((28 + json.length) % 8)) % 8);
  const header = Buffer.alloc(28);
  header.write('pnts', 0, 'ascii');
  header.writeUInt32LE(1, 4);
  header.writeUInt32LE(28 + json.length + bin.length, 8);
  header.writeUInt32LE(json.length, 12);
  header.writeUInt32LE(bin.length, 16);
  fs.writeFileSync(path.join(dir, 'layers.pnts'), Buffer.concat([header, Buffer.from(json), bin]));
  const box = [10, 10, 1.5, 10, 0, 0, 0, 10, 0, 0, 0, 1.5];
  fs.writeFileSync(path.join(dir, 'tileset.json'), JSON.stringify({
    asset: { version: '1.0' },
    geometricError: 100,
    root: { boundingVolume: { box }, geometricError: 0, refine: 'ADD', content: { uri: 'layers.pnts' } },
  }));
}

test('translucent points are blended in the page as natively', { skip: skip || false }, async () => {
  const dir = path.join(work, 'www/translucent');
  writeTranslucentTileset(dir);
  const ref = path.join(work, 'translucent.png');
  const native = h.stipple(['render', path.join(dir, 'tileset.json'), '-o', ref, '--width', '320',
                            '--height', '240']);
  const { page, state, log } = await open('viewer/stipple.html?url=/translucent/tileset.json&width=320&height=240');
  c.assertDone(state, log);
  assert.equal(state.errors, '0', state.problems);
  assert.equal(state.points, '3200');
  c.assertNativeAgrees(native, state);
  // Drawn opaque, the red layer hides the blue one: natively that image differs from the blended
  // one by a mean of 40 (of 255), 31 % of the pixels by more than 48.
  await c.assertCanvasMatches(page, ref, {
    what: 'translucent layers',
    describe: (d) => `translucent, web vs native: ${JSON.stringify(d)}; ${state.renderer}`,
  });
  await page.close();
});
