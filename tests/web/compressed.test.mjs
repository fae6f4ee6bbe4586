// Compressed tiles in the browser: autzen (../shared/data) tiled by `stipple tile --compress
// meshopt` (glb, EXT_meshopt_compression) and `--format pnts --compress draco`
// (3DTILES_draco_point_compression), served by nginx on loopback, opened by URL in headless
// chromium (WebGPU on SwiftShader). The web build decodes them with the native build's
// meshoptimizer and Draco compiled to WebAssembly (scripts/build-web.sh --deps): every tile is
// drawn, none fails, and the canvas matches `stipple render` of the same tileset and camera
// (lavapipe) within the tolerance of tileset.test.mjs. Skipped where ../shared is absent.
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import * as h from './harness.mjs';

const webDir = process.env.STIPPLE_WEB_DIR || path.join(h.sourceDir, 'build-web');
const autzen = path.join(h.sourceDir, '../shared/data/las/autzen_trim.las');
const skip =
  h.skipReason({ modules: ['puppeteer-core'], browser: true, server: true }) ||
  (fs.existsSync(path.join(webDir, 'stipple.wasm')) ? null : `${webDir} not built (scripts/build-web.sh)`) ||
  (fs.existsSync(autzen) ? null : `${autzen} not found (../shared absent)`);
const work = skip ? null : h.tempDir('compressed');
let server, browser;

// Each tileset: the tiler's options, the extension its content must name (or the test would pass
// on uncompressed tiles) and the content's extension.
const tilesets = {
  meshopt: { args: ['--compress', 'meshopt'], marker: 'EXT_meshopt_compression', ext: '.glb' },
  draco: {
    args: ['--format', 'pnts', '--compress', 'draco'],
    marker: '3DTILES_draco_point_compression',
    ext: '.pnts',
  },
};

const isolation = {
  'Cross-Origin-Opener-Policy': 'same-origin',
  'Cross-Origin-Embedder-Policy': 'require-corp',
};

before(async () => {
  if (skip) return;
  const root = path.join(work, 'www');
  fs.mkdirSync(root);
  fs.symlinkSync(webDir, path.join(root, 'viewer'));
  for (const [name, t] of Object.entries(tilesets)) h.tile(autzen, path.join(root, name), t.args);
  server = await h.startNginx(root, { headers: isolation });
  browser = await h.launchBrowser({ webgpu: true });
});

after(async () => {
  if (browser) await browser.close();
  if (server) await server.stop();
  if (work) fs.rmSync(work, { recursive: true, force: true });
});

for (const [name, t] of Object.entries(tilesets)) {
  test(`a ${name} tileset by URL matches the native render`, { skip: skip || false }, async () => {
    const dir = path.join(work, 'www', name);
    const contents = h.contentFiles(dir);
    assert.ok(contents.length > 1, `${contents.length} content files`);
    for (const f of contents) {
      assert.equal(path.extname(f), t.ext, f);
      assert.ok(fs.readFileSync(path.join(dir, f)).includes(t.marker), `${f} does not use ${t.marker}`);
    }
    const ref = path.join(work, `native-${name}.png`);
    const native = h.stipple(['render', path.join(dir, 'tileset.json'), '-o', ref, '--width', '320',
                              '--height', '240', '--max-sse', '1']);
    const page = await browser.newPage();
    const log = [];
    page.on('pageerror', (e) => log.push(`page error: ${e}`));
    page.on('console', (m) => log.push(`page ${m.type()}: ${m.text()}`));
    await page.goto(server.url(`viewer/stipple.html?url=/${name}/tileset.json&width=320&height=240&max-sse=1`));
    await page
      .waitForFunction(() => window.stipple && (window.stipple.done || window.stipple.error), {
        timeout: 240000,
      })
      .catch((e) => log.push(String(e)));
    const state = await page.evaluate(() => ({
      ...window.stipple,
      problems: document.getElementById('problems').textContent,
    }));
    assert.equal(state.error, undefined, `the page failed: ${state.error}\n${log.join('\n')}`);
    assert.equal(state.done, '1', log.join('\n'));
    // A tile the build cannot decode would be a listed problem with the others drawn.
    assert.equal(state.errors, '0', state.problems);
    assert.ok(Number(state.tiles) > 1, `only ${state.tiles} tiles drawn: the root did not refine`);
    assert.ok(Number(state.points) > 1000, `only ${state.points} points drawn`);
    assert.match(native, new RegExp(`renderer: ${state.renderer}`));
    const d = await h.compareCanvas(page, fs.readFileSync(ref));
    console.log(`${name}: web vs native: ${JSON.stringify(d)}; ${state.tiles} tiles, ` +
                `${state.points} points, ${state.renderer}, ${state.ms} ms`);
    assert.equal(d.size, undefined, `canvas size differs: ${d.size}`);
    assert.ok(d.litFraction > 0.05, `only ${d.litFraction} of the canvas is drawn`);
    // As tileset.test.mjs: SwiftShader and lavapipe need not rasterize bit for bit alike; the
    // mean per-pixel difference (largest channel, of 255) stays under 3 and under 2% of the
    // pixels differ by more than 48.
    assert.ok(d.meanDiff < 3, `mean difference ${d.meanDiff} (of 255)`);
    assert.ok(d.offFraction < 0.02, `${d.offFraction} of the pixels differ by more than 48`);
    await page.close();
  });
}
