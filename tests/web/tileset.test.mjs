// The web viewer opens a 3D Tiles tileset by URL (stipple.html?url=.../tileset.json): nginx on
// loopback serves build-web/ and a tileset made by `stipple tile` (autzen from ../shared/data, or
// a generated cloud where ../shared is absent); headless chromium (WebGPU on SwiftShader) streams
// it through the same plugins, render graph and shaders as `stipple render`, and its canvas
// matches the native render of the same tileset and camera (lavapipe) within the stated
// tolerance; a drag, a key and the wheel move its camera. A 404 tile is an error on the page
// while the other tiles are drawn; a missing tileset is an error on the page. `stipple tile
// --page` writes a folder that opens by link. A LAS file by URL matches `stipple render` of it.
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { spawnSync } from 'node:child_process';
import * as h from './harness.mjs';

const webDir = process.env.STIPPLE_WEB_DIR || path.join(h.sourceDir, 'build-web');
const skip =
  h.skipReason({ modules: ['puppeteer-core'], browser: true, server: true }) ||
  (fs.existsSync(path.join(webDir, 'stipple.wasm')) ? null : `${webDir} not built (scripts/build-web.sh)`);
const work = skip ? null : h.tempDir('tileset');
const autzen = path.join(h.sourceDir, '../shared/data/las/autzen_trim.las');
let server, browser, input;

// Threads (the engine's worker pool, the streamer's) need SharedArrayBuffer: cross-origin
// isolation.
const isolation = {
  'Cross-Origin-Opener-Policy': 'same-origin',
  'Cross-Origin-Embedder-Policy': 'require-corp',
};

before(async () => {
  if (skip) return;
  if (fs.existsSync(autzen)) {
    input = autzen;
  } else {
    console.log(`${autzen} not found (../shared absent): a generated cloud is tiled instead`);
    input = h.generatedLas(work, 200000);
  }
  // The served root: the viewer and the tilesets side by side.
  const root = path.join(work, 'www');
  fs.mkdirSync(root);
  fs.symlinkSync(webDir, path.join(root, 'viewer'));
  h.tile(input, path.join(root, 'tiles'));
  fs.symlinkSync(input, path.join(root, 'cloud.las'));
  // The same tileset with one tile below the root missing (a 404).
  fs.cpSync(path.join(root, 'tiles'), path.join(root, 'broken'), { recursive: true });
  server = await h.startNginx(root, { headers: isolation });
  browser = await h.launchBrowser({ webgpu: true });
});

after(async () => {
  if (browser) await browser.close();
  if (server) await server.stop();
  if (work) fs.rmSync(work, { recursive: true, force: true });
});

// Opens `page_path` of the server (or a full URL) and waits until the program reports done or an
// error.
async function open(page_path) {
  const page = await browser.newPage();
  const log = [];
  page.on('pageerror', (e) => log.push(`page error: ${e}`));
  page.on('console', (m) => log.push(`page ${m.type()}: ${m.text()}`));
  await page.goto(page_path.startsWith('http') ? page_path : server.url(page_path));
  await page
    .waitForFunction(() => window.stipple && (window.stipple.done || window.stipple.error), {
      timeout: 240000,
    })
    .catch((e) => log.push(String(e)));
  const state = await page.evaluate(() => ({
    ...window.stipple,
    isolated: self.crossOriginIsolated,
    shown: document.getElementById('error').textContent,
    problems: document.getElementById('problems').textContent,
    problemsShown: getComputedStyle(document.getElementById('problems')).display !== 'none',
  }));
  return { page, state, log };
}

// The background's colour is dark: a pixel brighter than this is a drawn point.
async function litFraction(page) {
  return page.evaluate(() => {
    const canvas = document.getElementById('canvas');
    const a = canvas.getContext('2d').getImageData(0, 0, canvas.width, canvas.height).data;
    let lit = 0;
    for (let i = 0; i < a.length; i += 4) if (a[i] + a[i + 1] + a[i + 2] > 60) ++lit;
    return lit / (a.length / 4);
  });
}

test('a tileset by URL matches the native render of the same camera', { skip: skip || false }, async () => {
  const ref = path.join(work, 'native.png');
  const tileset = path.join(work, 'www/tiles/tileset.json');
  // --max-sse 1: the root refines, so several tiles stream in.
  const native = h.stipple(['render', tileset, '-o', ref, '--width', '320', '--height', '240',
                            '--max-sse', '1']);
  const { page, state, log } = await open('viewer/stipple.html?url=/tiles/tileset.json&width=320&height=240&max-sse=1');
  assert.equal(state.error, undefined, `the page failed: ${state.error}\n${log.join('\n')}`);
  assert.equal(state.done, '1', log.join('\n'));
  assert.equal(state.errors, '0', state.problems);
  assert.ok(Number(state.points) > 1000, `only ${state.points} points drawn`);
  assert.ok(Number(state.tiles) > 1, `only ${state.tiles} tiles drawn: the root did not refine`);
  // The same renderer as `stipple render --renderer auto` chose.
  assert.match(native, new RegExp(`renderer: ${state.renderer}`));
  const d = await h.compareCanvas(page, fs.readFileSync(ref));
  console.log(`web vs native: ${JSON.stringify(d)}; ${state.tiles} tiles, ${state.points} points, ` +
              `${state.renderer}, point size ${state.pointSize}, ${state.ms} ms, ` +
              `${state.frameMs} ms a frame once streamed, ${state.adapter}`);
  assert.equal(d.size, undefined, `canvas size differs: ${d.size}`);
  assert.ok(d.litFraction > 0.05, `only ${d.litFraction} of the canvas is drawn`);
  // SwiftShader and lavapipe need not rasterize bit for bit alike: the mean per-pixel difference
  // (largest channel, of 255) stays under 3 and under 2% of the pixels differ by more than 48.
  // Measured on autzen (9 tiles, 110,000 points, the compute rasterizer): 0.0002 and 0.
  assert.ok(d.meanDiff < 3, `mean difference ${d.meanDiff} (of 255)`);
  assert.ok(d.offFraction < 0.02, `${d.offFraction} of the pixels differ by more than 48`);
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
  assert.equal(state.error, undefined, `the page failed: ${state.error}\n${log.join('\n')}`);
  assert.equal(state.done, '1', log.join('\n'));
  assert.ok(Number(state.errors) >= 1, `errors: ${state.errors}`);
  const name = path.basename(child.content.uri);
  assert.match(state.problems, new RegExp(`${name.replace('.', '\\.')}: HTTP 404 \\(not found\\)`));
  assert.ok(state.problemsShown, 'the tile error is shown on the page');
  assert.ok(Number(state.points) > 1000, `only ${state.points} points drawn`);
  const lit = await litFraction(page);
  assert.ok(lit > 0.05, `only ${lit} of the canvas is drawn`);
  await page.close();
});

test('a LAS file by URL matches the native render of the file', { skip: skip || false }, async () => {
  const ref = path.join(work, 'native-las.png');
  const native = h.stipple(['render', input, '-o', ref, '--width', '320', '--height', '240']);
  const { page, state, log } = await open('viewer/stipple.html?url=/cloud.las&width=320&height=240');
  assert.equal(state.error, undefined, `the page failed: ${state.error}\n${log.join('\n')}`);
  assert.equal(state.done, '1', log.join('\n'));
  assert.match(native, new RegExp(`renderer: ${state.renderer}`));
  assert.match(native, new RegExp(`rendered ${state.points} points`));
  const d = await h.compareCanvas(page, fs.readFileSync(ref));
  console.log(`LAS web vs native: ${JSON.stringify(d)}; ${state.points} points, ${state.renderer}`);
  assert.equal(d.size, undefined, `canvas size differs: ${d.size}`);
  assert.ok(d.litFraction > 0.05, `only ${d.litFraction} of the canvas is drawn`);
  assert.ok(d.meanDiff < 3, `mean difference ${d.meanDiff} (of 255)`);
  assert.ok(d.offFraction < 0.02, `${d.offFraction} of the pixels differ by more than 48`);
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
    assert.equal(state.error, undefined, `the page failed: ${state.error}\n${log.join('\n')}`);
    assert.equal(state.done, '1', log.join('\n'));
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
