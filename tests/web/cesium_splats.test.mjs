// CesiumJS (npm cesium 1.145) in headless chromium opens the splat tiler's output (stipple tile
// on a splat PLY: KHR_gaussian_splatting with KHR_gaussian_splatting_compression_spz_2, merged
// inner tiles, REPLACE refinement), served by nginx on loopback: no tile fails, allTilesLoaded
// fires, every leaf's content loads (the view refines everything), every load is one of the
// content files, and the splats cover part of the canvas. The page is cesium.html, as for the
// point tilesets.
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import * as h from './harness.mjs';

const skip = h.skipReason({ modules: ['cesium', 'puppeteer-core'], browser: true, server: true });
const work = skip ? null : h.tempDir('cesium-splats');
let server, browser;

// An INRIA-layout splat PLY of n splats (SH degree 1): two coloured blobs on a sparse shell,
// opaque enough to be seen, from a fixed-seed generator.
function writeSplatPly(file, n) {
  let seed = 12345;
  const rand = () => ((seed = (seed * 1103515245 + 12345) >>> 0) / 4294967296);
  const gauss = () => Math.sqrt(-2 * Math.log(rand() + 1e-12)) * Math.cos(2 * Math.PI * rand());
  const props = ['x', 'y', 'z', 'f_dc_0', 'f_dc_1', 'f_dc_2'];
  for (let k = 0; k < 9; ++k) props.push(`f_rest_${k}`);
  props.push('opacity', 'scale_0', 'scale_1', 'scale_2', 'rot_0', 'rot_1', 'rot_2', 'rot_3');
  const header = 'ply\nformat binary_little_endian 1.0\n' + `element vertex ${n}\n` +
      props.map((p) => `property float ${p}\n`).join('') + 'end_header\n';
  const data = new Float32Array(n * props.length);
  for (let i = 0; i < n; ++i) {
    const o = i * props.length, r = rand();
    const c = r < 0.45 ? [3, 0, 0] : r < 0.9 ? [-3, 1, 0] : null;
    const p = c ? c.map((v) => v + 0.8 * gauss()) : [0, 0, 0].map(() => 8 * (rand() - 0.5));
    const dc = r < 0.45 ? [1.5, -0.5, -1] : r < 0.9 ? [-1, 1.5, -0.5] : [0.5, 0.5, 1.5];
    data.set([...p, ...dc], o);
    for (let k = 0; k < 9; ++k) data[o + 6 + k] = 0.2 * (rand() - 0.5);
    data[o + 15] = 2.5;  // logit: opacity ~0.92
    for (let k = 0; k < 3; ++k) data[o + 16 + k] = Math.log(0.1 + 0.2 * rand());
    const q = [gauss(), gauss(), gauss(), gauss()];
    const len = Math.hypot(...q);
    data.set(q.map((v) => v / len), o + 19);
  }
  fs.writeFileSync(file, Buffer.concat([Buffer.from(header), Buffer.from(data.buffer)]));
}

before(async () => {
  if (skip) return;
  const www = path.join(work, 'www');
  fs.mkdirSync(path.join(www, 'tiles'), { recursive: true });
  // CESIUM_BUILD=CesiumUnminified gives readable stacks when CesiumJS throws.
  fs.symlinkSync(path.join(h.nodePrefix, 'node_modules/cesium/Build/' + (process.env.CESIUM_BUILD || 'Cesium')), path.join(www, 'cesium'));
  fs.copyFileSync(path.join(h.sourceDir, 'tests/web/cesium.html'), path.join(www, 'index.html'));
  const ply = path.join(work, 'splats.ply');
  writeSplatPly(ply, 20000);
  h.tile(ply, path.join(www, 'tiles/splats'), ['--max-leaf-splats', '2000']);
  server = await h.startNginx(www);
  browser = await h.launchBrowser();
});

after(async () => {
  if (browser) await browser.close();
  if (server) await server.stop();
  if (work) fs.rmSync(work, { recursive: true, force: true });
});

test('CesiumJS loads the splat tileset with no failed tile', { skip: skip || false }, async () => {
  const page = await browser.newPage();
  page.on('pageerror', (e) => console.log('page error:', String(e)));
  page.on('response', (r) => {
    if (r.status() >= 400) console.log(`page: HTTP ${r.status()} for ${r.url()}`);
  });
  page.on('console', (m) => {
    if (m.type() === 'error' || m.type() === 'warn') console.log(`page ${m.type()}: ${m.text()}`);
  });
  await page.setViewport({ width: 800, height: 600 });
  await page.goto(server.url('index.html'));
  await page.waitForFunction('window.openTileset', { timeout: 30000 });
  const r = await page.evaluate((url) => window.openTileset(url, 60000), 'tiles/splats/tileset.json');
  assert.equal(r.error, null);
  assert.deepEqual(r.failed, []);
  assert.ok(r.allTilesLoaded, 'allTilesLoaded never fired');
  const dir = path.join(work, 'www/tiles/splats');
  const files = h.contentFiles(dir);
  const tileset = JSON.parse(fs.readFileSync(path.join(dir, 'tileset.json'), 'utf8'));
  const leaves = [];
  const walk = (t) => (t.children ? t.children.forEach(walk) : leaves.push(t.content.uri));
  walk(tileset.root);
  assert.ok(leaves.length >= 8, `only ${leaves.length} leaves`);
  const got = [...new Set(r.loaded.map((u) => decodeURIComponent(new URL(u, 'http://host/tiles/splats/tileset.json').pathname)
      .replace('/tiles/splats/', '')))].sort();
  for (const f of got) assert.ok(files.includes(f), `loaded ${f}, which is not a content file`);
  for (const f of leaves) assert.ok(got.includes(f), `leaf ${f} never loaded`);
  assert.ok(r.drawn > r.pixels * 0.01, `only ${r.drawn} of ${r.pixels} pixels drawn`);
  console.log(`splats: ${got.length} of ${files.length} tiles loaded (${leaves.length} leaves), ` +
      `${r.drawn} px drawn, mean colour ${r.mean.map((v) => v.toFixed(1)).join(',')}, ` +
      `${(r.ms.loaded / 1000).toFixed(1)} s`);
  await page.close();
});
