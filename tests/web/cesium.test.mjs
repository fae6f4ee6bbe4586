// CesiumJS (npm cesium) in headless chromium opens the tiler's output, served by nginx on
// loopback, for every output option: every content file loads (tileLoad URLs = the files on
// disk), none fails, allTilesLoaded fires, and the canvas shows points. The glb output's
// colours match the pnts output's (glTF COLOR_0 is linear: a writer storing sRGB bytes there
// is drawn washed out, about +60 per channel).
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import * as h from './harness.mjs';

const skip = h.skipReason({ modules: ['cesium', 'puppeteer-core'], browser: true, server: true });
// name -> extra `stipple tile` arguments. Every output option is opened.
const variants = JSON.parse(process.env.STIPPLE_CESIUM_VARIANTS || 'null') || {
  glb: [],
  pnts: ['--format', 'pnts'],
  'glb-meshopt': ['--compress', 'meshopt'],
  'pnts-draco': ['--format', 'pnts', '--compress', 'draco'],
  'glb-meshopt-implicit': ['--compress', 'meshopt', '--implicit', '--subtree-levels', '2'],
  'pnts-implicit': ['--format', 'pnts', '--implicit'],
};
const work = skip ? null : h.tempDir('cesium');
let server, browser;
const results = {};

before(async () => {
  if (skip) return;
  const www = path.join(work, 'www');
  fs.mkdirSync(path.join(www, 'tiles'), { recursive: true });
  fs.symlinkSync(path.join(h.nodePrefix, 'node_modules/cesium/Build/Cesium'), path.join(www, 'cesium'));
  fs.copyFileSync(path.join(h.sourceDir, 'tests/web/cesium.html'), path.join(www, 'index.html'));
  const las = h.generatedLas(work, 60000);
  for (const [name, args] of Object.entries(variants))
    h.tile(las, path.join(www, 'tiles', name), ['--max-node-points', '5000', ...args]);
  server = await h.startNginx(www);
  browser = await h.launchBrowser();
});

after(async () => {
  if (browser) await browser.close();
  if (server) await server.stop();
  if (work) fs.rmSync(work, { recursive: true, force: true });
});

let page;
async function open(name) {
  if (!page) {
    page = await browser.newPage();
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
  }
  return page.evaluate((url) => window.openTileset(url, 40000), `tiles/${name}/tileset.json`);
}

for (const name of Object.keys(variants)) {
  test(`CesiumJS loads every tile of the ${name} output`, { skip: skip || false }, async () => {
    const r = await open(name);
    results[name] = r;
    assert.equal(r.error, null);
    assert.deepEqual(r.failed, []);
    assert.ok(r.allTilesLoaded, 'allTilesLoaded never fired');
    const dir = path.join(work, 'www/tiles', name);
    const want = h.contentFiles(dir);
    const got = r.loaded
      // Implicit tiles' URLs are relative to the tileset.
      .map((u) => new URL(u, `http://host/tiles/${name}/tileset.json`).pathname)
      .map((p) => decodeURIComponent(p).replace(`/tiles/${name}/`, ''))
      .filter((p) => !p.endsWith('.subtree'))  // implicit tiling: a subtree is a tile load too
      .sort();
    assert.ok(want.length > 5, `only ${want.length} content files`);
    assert.deepEqual(got, want, 'tileLoad events differ from the content files');
    // Points cover a good part of the 800x600 view (the whole tileset is framed).
    assert.ok(r.drawn > r.pixels * 0.02, `only ${r.drawn} of ${r.pixels} pixels drawn`);
    console.log(`${name}: ${got.length} tiles, ${r.drawn} px drawn, mean colour ` +
        r.mean.map((v) => v.toFixed(1)).join(',') + `, ${(r.ms.loaded / 1000).toFixed(1)} s`);
  });
}

const both = 'glb' in variants && 'pnts' in variants;
test('CesiumJS draws the glb output in the colours of the pnts output', { skip: skip || (!both && 'glb and pnts not both opened') }, () => {
  const glb = results.glb, pnts = results.pnts;
  assert.ok(glb && pnts, 'both outputs must have been drawn');
  // The same points from the same view: coverage within 10%, mean colour within 6 of 255 per
  // channel (pnts RGB is sRGB; an sRGB-in-COLOR_0 glb measured about +60).
  assert.ok(Math.abs(glb.drawn - pnts.drawn) < 0.1 * pnts.drawn, `${glb.drawn} vs ${pnts.drawn}`);
  for (let k = 0; k < 3; ++k)
    assert.ok(Math.abs(glb.mean[k] - pnts.mean[k]) <= 6,
        `channel ${k}: glb ${glb.mean[k].toFixed(1)}, pnts ${pnts.mean[k].toFixed(1)}`);
});
