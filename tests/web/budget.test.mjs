// A real cloud converted to Potree 2.0 in the page at a point budget from a given camera (what
// bench/web_vs_potree.mjs gives stipple's page and potree-core alike): autzen (../shared/data, or
// a generated cloud in its place) converted by the tests' writer (`stipple_write_potree DIR
// INPUT.las`), served by nginx on loopback, opened by URL in headless chromium (WebGPU on
// SwiftShader) with ?budget= below the cloud and ?camera=: the page draws the points `stipple
// render` draws with the same options (no more than the budget, fewer than the cloud), its canvas
// matches the native render (lavapipe) within the tolerance of common.mjs, the camera reported
// is the one given, and a turn of the arrow keys keeps its target and distance.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { spawnSync } from 'node:child_process';
import * as h from './harness.mjs';
import * as c from './common.mjs';

const writer = process.env.STIPPLE_WRITE_POTREE || path.join(h.sourceDir, 'build/tests/stipple_write_potree');
const skip = c.skip || (fs.existsSync(writer) ? null : `${writer} not built`);
let written = null;
const suite = c.viewerSuite('budget', (work) => {
  const root = c.viewerRoot(work);
  const input = c.sharedOrGenerated(c.autzen, path.join(work, 'gen200000.las'), 200000);
  const r = spawnSync(writer, [path.join(root, 'cloud'), input, '4000', '2'], { encoding: 'utf8' });
  if (r.status !== 0) throw new Error(`${writer} failed: ${r.stderr}`);
  written = JSON.parse(r.stdout);
  return root;
});
const { work } = suite;

test('a converted LAS file at ?budget= from ?camera= draws as render --budget --camera', { skip: skip || false }, async () => {
  const budget = Math.floor(written.points / 3);
  // Eye south-east of the cloud and above it, looking at its centre (data coordinates, Z up).
  const t = [0, 1, 2].map((k) => (written.min[k] + written.max[k]) / 2);
  const size = Math.max(written.max[0] - written.min[0], written.max[1] - written.min[1]);
  const camera = [t[0] + 0.4 * size, t[1] - 0.9 * size, t[2] + 0.8 * size, ...t].map((v) => v.toFixed(3)).join(',');
  const given = camera.split(',').map(Number), eye = given.slice(0, 3), target = given.slice(3);
  const ref = path.join(work, 'native.png');
  const native = h.stipple(['render', path.join(work, 'www/cloud/metadata.json'), '-o', ref, '--width', '320',
                            '--height', '240', '--max-sse', '0.01', '--budget', String(budget), '--camera', camera]);
  const { page, state, log } = await c.openPage(
    suite.browser, suite.server.url(`viewer/stipple.html?url=/cloud/metadata.json&width=320&height=240` +
                                    `&max-sse=0.01&budget=${budget}&camera=${camera}`));
  c.assertDone(state, log);
  console.log(`budget ${budget} of ${written.points}: ${state.points} points in ${state.tiles} nodes; ` +
              `camera ${state.camera}`);
  assert.ok(Number(state.points) <= budget, `${state.points} points drawn, over the budget ${budget}`);
  assert.ok(Number(state.points) > 0);
  c.assertNativeAgrees(native, state, { points: true });
  await c.assertCanvasMatches(page, ref, { describe: (d) => `web vs native: ${JSON.stringify(d)}` });
  // The camera given (the data's coordinates, Z up): its position, and a target on its view axis.
  const dist = (p, q) => Math.hypot(p[0] - q[0], p[1] - q[1], p[2] - q[2]);
  const before = JSON.parse(state.camera);
  assert.ok(dist(before.position, eye) < 1e-6 * size, `position ${before.position} vs ${eye}`);
  const axis = target.map((x, k) => x - eye[k]), toTarget = before.target.map((x, k) => x - eye[k]);
  const cross = [axis[1] * toTarget[2] - axis[2] * toTarget[1], axis[2] * toTarget[0] - axis[0] * toTarget[2],
                 axis[0] * toTarget[1] - axis[1] * toTarget[0]];
  assert.ok(Math.hypot(...cross) / (Math.hypot(...axis) * Math.hypot(...toTarget)) < 1e-6,
            `target ${before.target} is off the view axis towards ${target}`);
  // A turn keeps the target and the distance, and moves the camera.
  await page.keyboard.press('ArrowLeft');
  await page.waitForFunction((p) => JSON.parse(window.stipple.camera).position[0] !== p, { timeout: 60000 },
                             before.position[0]);
  const after = JSON.parse(await page.evaluate(() => window.stipple.camera));
  assert.ok(dist(after.target, before.target) < 1e-6 * size, `target moved: ${after.target} vs ${before.target}`);
  assert.ok(Math.abs(dist(after.position, after.target) - dist(before.position, before.target)) < 1e-6 * size,
            'the distance changed');
  assert.ok(dist(after.position, before.position) > 1e-3 * size, 'the camera did not turn');
  await page.close();
});
