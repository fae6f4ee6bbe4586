// potree-core (npm) reads the Potree 2.0 cloud that the tests' writer makes
// (tests/common/potree_writer.hpp, which stipple's reader tests use): in headless chromium, served
// by nginx on loopback, every node of the octree (across hierarchy chunks behind proxy nodes)
// loads and decodes, and the points add up to the count written. This proves the writer, and so
// stipple's reader tests that rely on it, against Potree's own reader. Without the int64 and
// uint64 attributes here: potree-core's decoder has no 64-bit integers (stipple's test has them).
// The writer also converts a real LAS file (`stipple_write_potree DIR INPUT.las`, for
// bench/web_vs_potree.mjs): potree-core decodes all of autzen_trim's points from it, within the
// LAS header's bounds.
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { spawnSync } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import * as h from './harness.mjs';

const writer = process.env.STIPPLE_WRITE_POTREE || path.join(h.sourceDir, 'build/tests/stipple_write_potree');
let skip = h.skipReason({ modules: ['potree-core', 'three', 'puppeteer-core'], browser: true, server: true });
if (!skip && !fs.existsSync(writer)) skip = `${writer} not built`;
const work = skip ? null : h.tempDir('potree');
let server, browser, written, convertedLas;
const kPoints = 30000;
const las = path.join(h.sourceDir, '../shared/data/las/autzen_trim.las');

before(async () => {
  if (skip) return;
  const www = path.join(work, 'www');
  fs.mkdirSync(www);
  for (const m of ['three', 'potree-core'])
    fs.symlinkSync(path.join(h.nodePrefix, 'node_modules', m), path.join(www, m));
  fs.copyFileSync(path.join(h.sourceDir, 'tests/web/potree.html'), path.join(www, 'index.html'));
  const r = spawnSync(writer, [path.join(www, 'cloud'), String(kPoints), '400', '2', 'no-int64'], { encoding: 'utf8' });
  assert.equal(r.status, 0, r.stderr);
  written = JSON.parse(r.stdout);
  if (fs.existsSync(las)) {
    const c = spawnSync(writer, [path.join(www, 'autzen'), las, '4000', '2'], { encoding: 'utf8' });
    assert.equal(c.status, 0, c.stderr);
    convertedLas = JSON.parse(c.stdout);
  }
  server = await h.startNginx(www);
  browser = await h.launchBrowser();
});
after(async () => {
  if (browser) await browser.close();
  if (server) await server.stop();
  if (work) fs.rmSync(work, { recursive: true, force: true });
});

test('potree-core loads every node and point of the test writer\'s Potree 2.0 cloud', { skip: skip || false }, async () => {
  const page = await browser.newPage();
  page.on('pageerror', (e) => console.log('page error:', String(e.stack || e)));
  await page.goto(server.url('index.html'));
  await page.waitForFunction('window.openPotree', { timeout: 30000 });
  const r = await page.evaluate((u) => window.openPotree(u, 40000), server.url('cloud/metadata.json'));
  console.log(JSON.stringify(r), JSON.stringify(written));
  assert.equal(r.error, null);
  assert.ok(written.chunks > 2, 'the cloud should have several hierarchy chunks');
  assert.equal(r.nodes, written.nodes, 'nodes in the hierarchy');
  assert.equal(r.loaded, written.nodes, 'nodes loaded');
  assert.equal(r.points, kPoints);
});

test('potree-core decodes every point of a LAS file converted by the writer, within its bounds',
     { skip: skip || (fs.existsSync(las) ? false : `${las} not found (../shared/data)`) }, async () => {
  // The LAS header's point count and bounds (stipple info), independent of the writer.
  const info = h.stipple(['info', las]);
  console.log(info);
  const count = Number(info.match(/points:\s*(\d+)/)[1]);
  const header = ['min', 'max'].map((m) => info.match(new RegExp(`bounds ${m}:\\s*(\\S+) (\\S+) (\\S+)`)).slice(1, 4).map(Number));
  const page = await browser.newPage();
  page.on('pageerror', (e) => console.log('page error:', String(e.stack || e)));
  await page.goto(server.url('index.html'));
  await page.waitForFunction('window.openPotree', { timeout: 30000 });
  const r = await page.evaluate((u) => window.openPotree(u, 60000), server.url('autzen/metadata.json'));
  console.log(JSON.stringify({ ...r, box: undefined }), JSON.stringify(convertedLas));
  assert.equal(r.error, null);
  assert.equal(count, 110000);
  assert.equal(convertedLas.points, count);
  assert.ok(convertedLas.chunks > 1, 'the cloud should have several hierarchy chunks');
  assert.equal(r.nodes, convertedLas.nodes, 'nodes in the hierarchy');
  assert.equal(r.loaded, convertedLas.nodes, 'nodes loaded');
  assert.equal(r.points, count, 'points decoded');
  // The decoded positions (float32 within a node) and the points the writer read, against the
  // header's bounds (0.01 ft steps).
  for (let k = 0; k < 3; ++k)
    for (const [i, m] of [[0, 'min'], [1, 'max']]) {
      assert.ok(Math.abs(r.bounds[i][k] - header[i][k]) < 0.02, `${m} ${k}: decoded ${r.bounds[i][k]}, header ${header[i][k]}`);
      assert.ok(Math.abs(convertedLas[m][k] - header[i][k]) < 1e-6, `${m} ${k}: written ${convertedLas[m][k]}, header ${header[i][k]}`);
    }
});
