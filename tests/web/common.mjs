// Shared by the tests of the web viewer (build-web/, scripts/build-web.sh): the skip reason where
// it is not built, the test input from ../shared/data or generated in its place, nginx serving
// it cross-origin isolated and headless chromium on WebGPU for a suite's tests, opening a page
// and reading what it reports, and the comparison of its canvas with `stipple render` of the same
// input within the tolerance every one of these tests states.
import { before, after } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import * as h from './harness.mjs';

export const webDir = process.env.STIPPLE_WEB_DIR || path.join(h.sourceDir, 'build-web');
export const sharedData = path.join(h.sourceDir, '../shared/data');
export const autzen = path.join(sharedData, 'las/autzen_trim.las');

// Why the viewer's tests cannot run here, or null.
export const skip =
  h.skipReason({ modules: ['puppeteer-core'], browser: true, server: true }) ||
  (fs.existsSync(path.join(webDir, 'stipple.wasm')) ? null : `${webDir} not built (scripts/build-web.sh)`);

// Threads (the engine's worker pool, the streamer's) need SharedArrayBuffer: cross-origin
// isolation.
export const isolation = {
  'Cross-Origin-Opener-Policy': 'same-origin',
  'Cross-Origin-Embedder-Policy': 'require-corp',
};

// `file` where it is (../shared/data), else a generated cloud of `points` written to `out`
// (stipple generate: LAS or LAZ by its extension), so the tests run where ../shared is absent.
export function sharedOrGenerated(file, out, points) {
  if (fs.existsSync(file)) return file;
  console.log(`${file} not found (../shared absent): a generated cloud instead`);
  if (!fs.existsSync(out)) h.stipple(['generate', '-n', String(points), '-o', out]);
  return out;
}

// A folder to serve with the viewer in it as viewer/ (viewer/stipple.html).
export function viewerRoot(work) {
  const root = path.join(work, 'www');
  fs.mkdirSync(root);
  fs.symlinkSync(webDir, path.join(root, 'viewer'));
  return root;
}

// The viewer's root (viewerRoot) with autzen, or a generated cloud of 200,000 points in its
// place, as cloud.las and tiled by `stipple tile` into tiles/: the root and the input's path.
export function cloudRoot(work) {
  const input = sharedOrGenerated(autzen, path.join(work, 'gen200000.las'), 200000);
  const root = viewerRoot(work);
  fs.symlinkSync(input, path.join(root, 'cloud.las'));
  h.tile(input, path.join(root, 'tiles'));
  return { root, input };
}

// Registers a suite's before and after: a work folder (tempDir(name)), the folder `prepare(work)`
// returns served by nginx with `isolation`, and the browser; then removes them all. The returned
// object holds work, server and browser once the suite runs; nothing happens where `skip` says.
export function viewerSuite(name, prepare) {
  const s = { work: skip ? null : h.tempDir(name), server: null, browser: null };
  before(async () => {
    if (skip) return;
    const root = await prepare(s.work);
    s.server = await h.startNginx(root, { headers: isolation });
    s.browser = await h.launchBrowser({ webgpu: true });
  });
  after(async () => {
    if (s.browser) await s.browser.close();
    if (s.server) await s.server.stop();
    if (s.work) fs.rmSync(s.work, { recursive: true, force: true });
  });
  return s;
}

// What the page reports (window.stipple, reset when a file is opened) with what it shows, once it
// reports done or an error for the view it opens next: `action` opens it.
export async function settle(page, log, { action = null, timeout = 240000 } = {}) {
  if (action) {
    await page.evaluate(() => { window.stipple.before = 1; });
    await action();
  }
  await page
    .waitForFunction(() => window.stipple && !window.stipple.before &&
                           (window.stipple.done || window.stipple.error), { timeout })
    .catch((e) => log.push(String(e)));
  return page.evaluate(() => {
    const text = (id) => document.getElementById(id)?.textContent;
    const problems = document.getElementById('problems');
    return {
      ...window.stipple,
      isolated: self.crossOriginIsolated,
      shown: text('error'),
      problems: text('problems'),
      problemsShown: problems ? getComputedStyle(problems).display !== 'none' : false,
      statsText: text('stats'),
    };
  });
}

// Opens `url` in a new page of `browser` and settles it: the page, its console and errors
// (`log`) and its state. `before` runs in the page before its scripts.
export async function openPage(browser, url, { before = null, timeout = 240000 } = {}) {
  const page = await browser.newPage();
  if (before) await page.evaluateOnNewDocument(before);
  const log = [];
  page.on('pageerror', (e) => log.push(`page error: ${e}`));
  page.on('console', (m) => log.push(`page ${m.type()}: ${m.text()}`));
  await page.goto(url);
  return { page, log, state: await settle(page, log, { timeout }) };
}

// The page finished its view without an error.
export function assertDone(state, log) {
  assert.equal(state.error, undefined, `the page failed: ${state.error}\n${log.join('\n')}`);
  assert.equal(state.done, '1', log.join('\n'));
}

// What `stipple render` printed (`native`) names the page's renderer and, with `points`, the
// points it drew.
export function assertNativeAgrees(native, state, { points = false, what = undefined } = {}) {
  assert.match(native, new RegExp(`renderer: ${state.renderer}`), what);
  if (points) assert.match(native, new RegExp(`rendered ${state.points} points`), what);
}

// The page's canvas against the PNG `png` of `stipple render`: SwiftShader and lavapipe need not
// rasterize bit for bit alike (edge rules, float order), so the mean per-pixel difference
// (largest channel, of 255) stays under 3 and under 2% of the pixels differ by more than 48; at
// least `minLit` of the canvas is drawn. `describe(d)` is logged first; `what` prefixes the
// messages. Returns the comparison.
export async function assertCanvasMatches(page, png, { minLit = 0.05, what = '', describe = null } = {}) {
  const d = await h.compareCanvas(page, fs.readFileSync(png));
  if (describe) console.log(describe(d));
  const at = what ? `${what}: ` : '';
  assert.equal(d.size, undefined, `${at}canvas size differs: ${d.size}`);
  assert.ok(d.litFraction > minLit, `${at}only ${d.litFraction} of the canvas is drawn`);
  assert.ok(d.meanDiff < 3, `${at}mean difference ${d.meanDiff} (of 255)`);
  assert.ok(d.offFraction < 0.02, `${at}${d.offFraction} of the pixels differ by more than 48`);
  return d;
}
