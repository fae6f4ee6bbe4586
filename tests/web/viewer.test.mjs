// The web viewer (scripts/build-web.sh: libstipple compiled to WebAssembly on the browser's
// WebGPU) served by nginx on loopback and opened in headless chromium (WebGPU on SwiftShader):
// the page renders the built-in scene through the same engine, plugins, render graph and
// shaders as `stipple render`, and its canvas matches the native render of the same camera
// (lavapipe) within the stated tolerance. Bad options are an error shown on the page.
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import * as h from './harness.mjs';

const webDir = process.env.STIPPLE_WEB_DIR || path.join(h.sourceDir, 'build-web');
const skip =
  h.skipReason({ modules: ['puppeteer-core'], browser: true, server: true }) ||
  (fs.existsSync(path.join(webDir, 'stipple.wasm')) ? null : `${webDir} not built (scripts/build-web.sh)`);
const work = skip ? null : h.tempDir('viewer');
let server, browser;

// Threads (the engine's worker pool) need SharedArrayBuffer: a cross-origin isolated page.
const isolation = {
  'Cross-Origin-Opener-Policy': 'same-origin',
  'Cross-Origin-Embedder-Policy': 'require-corp',
};

before(async () => {
  if (skip) return;
  server = await h.startNginx(webDir, { headers: isolation });
  browser = await h.launchBrowser({ webgpu: true });
});

after(async () => {
  if (browser) await browser.close();
  if (server) await server.stop();
  if (work) fs.rmSync(work, { recursive: true, force: true });
});

// Opens the viewer with `query` and waits until it reports done or an error. `before` runs in
// the page before its scripts.
async function open(query, before = null) {
  const page = await browser.newPage();
  if (before) await page.evaluateOnNewDocument(before);
  const log = [];
  page.on('pageerror', (e) => log.push(`page error: ${e}`));
  page.on('console', (m) => log.push(`page ${m.type()}: ${m.text()}`));
  await page.goto(server.url(`stipple.html?${query}`));
  await page
    .waitForFunction(() => window.stipple && (window.stipple.done || window.stipple.error), {
      timeout: 180000,
    })
    .catch((e) => log.push(String(e)));
  const state = await page.evaluate(() => ({
    ...window.stipple,
    shown: document.getElementById('error').textContent,
  }));
  return { page, state, log };
}

// Two sizes of the built-in scene: 200,000 points at 320x240 are 1-pixel points (the compute
// rasterizer, as `stipple render --renderer auto` chooses), 50,000 larger ones (billboards).
for (const [points, renderer] of [['200000', 'compute'], ['50000', 'billboard']]) {
  test(`the built-in scene (${points} points, ${renderer}) matches the native render`, { skip: skip || false }, async () => {
    const ref = path.join(work, `native${points}.png`);
    h.stipple(['render', '-o', ref, '--width', '320', '--height', '240', '--scene-points', points]);
    const { page, state, log } = await open(`width=320&height=240&scene-points=${points}`);
    assert.equal(state.error, undefined, `the page failed: ${state.error}\n${log.join('\n')}`);
    assert.equal(state.done, '1', log.join('\n'));
    assert.equal(state.points, points);
    assert.equal(state.renderer, renderer);
    const d = await h.compareCanvas(page, fs.readFileSync(ref));
    console.log(`web vs native: ${JSON.stringify(d)}; ${state.renderer}, ${state.ms} ms, ${state.adapter}`);
    assert.equal(d.size, undefined, `canvas size differs: ${d.size}`);
    // The scene covers most of the image, not a blank canvas.
    assert.ok(d.litFraction > 0.2, `only ${d.litFraction} of the canvas is drawn`);
    // SwiftShader and lavapipe need not rasterize bit for bit alike (edge rules, float order):
    // the mean per-pixel difference (largest channel, of 255) stays under 3 and under 2% of
    // the pixels differ by more than 48. Measured: compute 0.0002 and 0, billboards 1.13 and
    // 0.7% (point edges).
    assert.ok(d.meanDiff < 3, `mean difference ${d.meanDiff} (of 255)`);
    assert.ok(d.offFraction < 0.02, `${d.offFraction} of the pixels differ by more than 48`);
    await page.close();
  });
}

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
