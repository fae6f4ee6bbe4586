// The page's tools (stipple-tools.js over the tools module, the same code as `stipple view`'s),
// driven by the mouse and keys on autzen (or a generated cloud where ../shared is absent): every
// measuring tool's values follow from the records it picked (full-precision source coordinates,
// as the inspect tool reads them) to 1e-6; a vertex dragged moves while the camera stays; a
// class filter and a clip polygon drawn in the page give the canvas `stipple render` draws with
// the same --classes and --clip-polygon (the other web tests' tolerance: mean difference under
// 3 of 255, under 2% of the pixels off by more than 48); the measurements download as GeoJSON;
// the profile's window shows the corridor and its CSV download is `stipple profile`'s, byte for
// byte.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import * as h from './harness.mjs';
import * as c from './common.mjs';

const skip = c.skip;
const W = 400, H = 300;
let input;
const suite = c.viewerSuite('measure', (work) => {
  input = c.sharedOrGenerated(c.autzen, path.join(work, 'gen.las'), 200000);
  const root = c.viewerRoot(work);
  fs.symlinkSync(input, path.join(root, 'cloud.las'));
  return root;
});

const tools = (page) => page.evaluate(() => window.stippleTools.state);
const frames = (page) => page.evaluate(() => Number(window.stipple.viewFrames || 0));

// Waits for the tools' state to satisfy `ok` (the program takes commands before its next frame).
async function until(page, ok, what) {
  for (let i = 0; i < 600; ++i) {
    const s = await tools(page);
    if (s && ok(s)) return s;
    await new Promise((r) => setTimeout(r, 50));
  }
  const s = await tools(page);
  assert.fail(`timed out waiting for ${what}: tool ${s.tool}, active ${s.active}, message '${s.message}', ` +
              `items ${JSON.stringify(s.items.map((m) => [m.tool, m.complete, m.points.length]))}`);
}

// A click at canvas pixel (x, y) (the canvas is drawn 1:1 at W x H CSS pixels). Autzen framed at
// 400x300 is a diagonal band from about (40, 150) to (350, 100): the clicks stay on it.
async function clickAt(page, x, y, button = 'left') {
  const r = await page.evaluate(() => {
    const b = document.getElementById('canvas').getBoundingClientRect();
    return { left: b.left, top: b.top };
  });
  await page.mouse.click(r.left + x, r.top + y, { button });
}

// A key for the view (the panel's buttons keep the focus after a click: it is taken from them).
async function press(page, key) {
  await page.evaluate(() => document.activeElement && document.activeElement.blur());
  await page.keyboard.press(key);
}

async function chooseTool(page, key, name) {
  await press(page, key);
  await until(page, (s) => s.tool === name, `tool ${name}`);
}

const dist = (a, b) => Math.hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
const near = (a, b, what, eps = 1e-6) =>
  assert.ok(Math.abs(a - b) <= eps * Math.max(1, Math.abs(b)), `${what}: ${a} vs ${b}`);

test('every tool measures what it picked, edits, filters, clips and exports as natively',
     { skip: skip || false, timeout: 900000 }, async () => {
  const url = suite.server.url(`viewer/stipple.html?url=../cloud.las&width=${W}&height=${H}`);
  const { page, log, state } = await c.openPage(suite.browser, url);
  c.assertDone(state, log);
  await until(page, (s) => s.legend || s.items, 'the tools state');

  // Inspect: the record under the cursor, read again from the file (full precision).
  await chooseTool(page, '1', 'inspect');
  await clickAt(page, 200, 150);
  let s = await until(page, (s) => s.inspected, 'an inspected point');
  assert.equal(s.inspected.fromSource, true);
  assert.ok('classification' in s.inspected.fields || 'Classification' in s.inspected.fields,
            JSON.stringify(s.inspected.fields));
  const picked = s.inspected.position;

  // Height (two clicks finish it): the difference of the two records' z.
  await chooseTool(page, '3', 'height');
  await clickAt(page, 200, 150);
  await clickAt(page, 120, 150);
  s = await until(page, (s) => s.items.length === 1 && s.items[0].complete, 'a height');
  let m = s.items[0];
  assert.deepEqual(m.points[0], picked, 'the same pixel picks the same record');
  near(m.values.height, m.points[1][2] - m.points[0][2], 'height');
  near(m.values.length3d, dist(m.points[0], m.points[1]), 'slope distance');

  // Distance: a polyline of three points, finished with Enter.
  await chooseTool(page, '2', 'distance');
  for (const [x, y] of [[80, 150], [180, 140], [280, 140]]) await clickAt(page, x, y);
  await press(page, 'Enter');
  s = await until(page, (s) => s.items.length === 2 && s.items[1].complete, 'a distance');
  m = s.items[1];
  near(m.values.length3d, dist(m.points[0], m.points[1]) + dist(m.points[1], m.points[2]), 'length');
  const label = await page.evaluate(() => [...document.querySelectorAll('#overlay text')].map((t) => t.textContent));
  assert.ok(label.some((t) => t.includes(m.values.length3d.toFixed(3))), `labels: ${label}`);

  // Area: a triangle finished with a right click: the shoelace of the picked points.
  await chooseTool(page, '4', 'area');
  for (const [x, y] of [[70, 145], [300, 135], [150, 190]]) await clickAt(page, x, y);
  await clickAt(page, 10, 10, 'right');
  s = await until(page, (s) => s.items.length === 3 && s.items[2].complete, 'an area');
  m = s.items[2];
  const [a, b, cc] = m.points;
  near(m.values.areaHorizontal,
       Math.abs((b[0] - a[0]) * (cc[1] - a[1]) - (cc[0] - a[0]) * (b[1] - a[1])) / 2, 'area');

  // Angle (at the second point) and circle (through three points).
  await chooseTool(page, '5', 'angle');
  for (const [x, y] of [[100, 150], [150, 185], [250, 140]]) await clickAt(page, x, y);
  await chooseTool(page, '6', 'circle');
  for (const [x, y] of [[90, 150], [160, 185], [260, 140]]) await clickAt(page, x, y);
  s = await until(page, (s) => s.items.length === 5 && s.items[4].complete, 'angle and circle');
  const [p0, p1, p2] = s.items[3].points;
  const u = p0.map((v, i) => v - p1[i]), v = p2.map((x, i) => x - p1[i]);
  const cos = (u[0] * v[0] + u[1] * v[1] + u[2] * v[2]) / (Math.hypot(...u) * Math.hypot(...v));
  near(s.items[3].values.angleDegrees, Math.acos(cos) * 180 / Math.PI, 'angle');
  const circle = s.items[4];
  for (const q of circle.points) near(dist(q, circle.values.center), circle.values.radius, 'radius');

  // Volume (reference height, then a box) and an annotation.
  await chooseTool(page, '7', 'volume');
  for (const [x, y] of [[200, 150], [120, 150], [220, 145], [200, 170]]) await clickAt(page, x, y);
  await chooseTool(page, '9', 'annotation');
  await clickAt(page, 200, 150);
  s = await until(page, (s) => s.items.length === 7 && s.items[6].complete, 'volume and annotation');
  assert.ok(s.items[5].values.volumeAbove >= 0 && s.items[5].values.coveredFraction > 0,
            JSON.stringify(s.items[5].values));
  assert.equal(s.items[6].text, 'Annotation 1');

  // Dragging the distance's last vertex (no other vertex within the grab distance) moves it and
  // the length follows; the camera stays.
  const camera = await page.evaluate(() => window.stipple.camera);
  await chooseTool(page, '0', 'none');
  const dot = await page.evaluate(() => {
    const d = document.querySelector('#overlay circle.vertex[data-item="1"][data-vertex="2"]');
    return [Number(d.getAttribute('cx')), Number(d.getAttribute('cy'))];
  });
  const before = s.items[1].points[2];
  const r = await page.evaluate(() => document.getElementById('canvas').getBoundingClientRect().toJSON());
  await page.mouse.move(r.left + dot[0], r.top + dot[1]);
  await page.mouse.down();
  await page.mouse.move(r.left + dot[0] - 40, r.top + dot[1] + 5, { steps: 5 });
  await page.mouse.up();
  s = await until(page, (s) => dist(s.items[1].points[2], before) > 0, 'the vertex moved');
  m = s.items[1];
  near(m.values.length3d, dist(m.points[0], m.points[1]) + dist(m.points[1], m.points[2]), 'length after the drag');
  assert.equal(s.items.length, 7, 'a drag adds nothing');
  assert.equal(await page.evaluate(() => window.stipple.camera), camera, 'the camera stayed');

  // The measurements as GeoJSON: one feature each (and the inspected record).
  await page.click('#save-geojson');
  const saved = await page.evaluate(() => {
    const d = window.stippleDownloads.find((d) => d.name === 'measurements.geojson');
    return d && JSON.parse(d.data);
  });
  assert.equal(saved.features.length, 8);
  assert.deepEqual(saved.features.map((f) => f.properties.tool),
                   ['height', 'distance', 'area', 'angle', 'circle', 'volume', 'annotation', 'inspect']);

  // Classes: ground only, from the legend's checkboxes, against `stipple render --classes 2`.
  await page.click('#clear-measurements');
  await until(page, (s) => s.items.length === 0, 'cleared');
  await page.evaluate(() => { document.getElementById('filters').open = true; });
  await page.click('#filters button');  // all classes
  const boxes = await page.$$('#filter-classes input');
  await page.evaluate(() => {
    for (const b of document.querySelectorAll('#filter-classes input')) b.checked = b.dataset.class === '2';
    document.querySelector('#filter-classes input').dispatchEvent(new Event('change'));
  });
  assert.ok(boxes.length >= 19);
  s = await until(page, (s) => s.filter.classes && s.filter.classes[0] === 2, 'the class filter');
  const ground = path.join(suite.work, 'ground.png');
  h.stipple(['render', input, '-o', ground, '--width', String(W), '--height', String(H), '--classes', '2']);
  await c.assertCanvasMatches(page, ground, { what: 'classes 2', minLit: 0.02 });
  await page.evaluate(() => {
    for (const b of document.querySelectorAll('#filter-classes input')) b.checked = true;
    document.querySelector('#filter-classes input').dispatchEvent(new Event('change'));
  });
  await until(page, (s) => s.filter.classes === null, 'no class filter');

  // A clip polygon drawn on the view (inside), against `stipple render --clip-polygon`.
  await chooseTool(page, 'g', 'clip_polygon');
  for (const [x, y] of [[80, 140], [300, 130], [230, 175], [100, 165]]) await clickAt(page, x, y);
  await press(page, 'Enter');
  s = await until(page, (s) => s.items.length === 1 && s.items[0].complete, 'a clip polygon');
  const ring = s.items[0].points.map((p) => [p[0], p[1]]);
  const polygon = path.join(suite.work, 'clip.geojson');
  fs.writeFileSync(polygon, JSON.stringify({ type: 'FeatureCollection', features: [{
    type: 'Feature', properties: {}, geometry: { type: 'Polygon', coordinates: [[...ring, ring[0]]] } }] }));
  const clipped = path.join(suite.work, 'clipped.png');
  h.stipple(['render', input, '-o', clipped, '--width', String(W), '--height', String(H),
             '--clip-polygon', polygon]);
  // The overlay is the page's (an SVG over the canvas): the capture is the canvas alone.
  await c.assertCanvasMatches(page, clipped, { what: 'clip polygon', minLit: 0.02 });
  await page.click('#clear-measurements');
  await until(page, (s) => s.items.length === 0, 'cleared');

  // A profile: its window shows the corridor; its CSV is `stipple profile`'s.
  await chooseTool(page, '8', 'profile');
  await clickAt(page, 60, 150);
  await clickAt(page, 300, 135);
  await press(page, 'Enter');
  s = await until(page, (s) => s.items.length === 1 && s.items[0].complete, 'a profile');
  await page.waitForFunction(() => !document.getElementById('profile').hidden, { timeout: 60000 });
  const lit = await page.evaluate(() => {
    const cv = document.getElementById('profile-canvas');
    const d = cv.getContext('2d').getImageData(0, 0, cv.width, cv.height).data;
    let n = 0;
    for (let i = 0; i < d.length; i += 4) n += Math.max(d[i], d[i + 1], d[i + 2]) - Math.min(d[i], d[i + 1], d[i + 2]) > 30;
    return n;
  });
  assert.ok(lit > 100, `${lit} coloured pixels in the profile`);
  await page.click('#export-profile-csv');
  await page.waitForFunction(() => (window.stippleDownloads || []).some((d) => d.name === 'profile.csv'),
                             { timeout: 120000 });
  const csv = await page.evaluate(() =>
    new TextDecoder().decode(window.stippleDownloads.find((d) => d.name === 'profile.csv').data));
  const p = s.items[0];
  const native = path.join(suite.work, 'profile.csv');
  h.stipple(['profile', input, '--line', p.points.flatMap((q) => [q[0].toPrecision(17), q[1].toPrecision(17)]).join(','),
             '--width', p.width.toPrecision(17), '--csv', native]);
  const nativeCsv = fs.readFileSync(native, 'utf8');
  assert.ok(nativeCsv.split('\n').length > 10, nativeCsv.slice(0, 200));
  assert.equal(csv, nativeCsv, 'the page\'s profile CSV is stipple profile\'s');
  await page.close();
});

test('the tools on the built-in scene: records made again by index, values from them',
     { skip: skip || false, timeout: 600000 }, async () => {
  const url = suite.server.url(`viewer/stipple.html?scene-points=200000&width=${W}&height=${H}`);
  const { page, log, state } = await c.openPage(suite.browser, url);
  c.assertDone(state, log);
  await until(page, (s) => s.legend, 'the tools state');
  await chooseTool(page, '1', 'inspect');
  await clickAt(page, 150, 150);
  let s = await until(page, (s) => s.inspected, 'an inspected point');
  assert.equal(s.inspected.source, 'procedural scene');
  assert.equal(s.inspected.fromSource, true);
  const picked = s.inspected.position;
  await chooseTool(page, '3', 'height');
  await clickAt(page, 150, 150);
  await clickAt(page, 250, 120);
  await chooseTool(page, '4', 'area');
  for (const [x, y] of [[120, 200], [250, 120], [300, 140]]) await clickAt(page, x, y);
  await clickAt(page, 5, 5, 'right');
  s = await until(page, (s) => s.items.length === 2 && s.items[1].complete, 'height and area');
  const [hgt, area] = s.items;
  assert.deepEqual(hgt.points[0], picked, 'the same pixel picks the same record');
  near(hgt.values.height, hgt.points[1][2] - hgt.points[0][2], 'height');
  const [a, b, cc] = area.points;
  near(area.values.areaHorizontal,
       Math.abs((b[0] - a[0]) * (cc[1] - a[1]) - (cc[0] - a[0]) * (b[1] - a[1])) / 2, 'area');
  // The built-in scene is no file: nothing to export.
  assert.equal(s.canExport, false);
  await page.close();
});

test('a link reopens the tools\' filters, clip and measurements: the same pixels and values',
     { skip: skip || false, timeout: 600000 }, async () => {
  const url = suite.server.url(`viewer/stipple.html?url=../cloud.las&width=${W}&height=${H}`);
  const { page, log, state } = await c.openPage(suite.browser, url);
  c.assertDone(state, log);
  await until(page, (s) => s.legend, 'the tools state');
  // A clip polygon (outside: a hole), a height and an annotation, classes 1 and 2, a turn.
  await chooseTool(page, 'g', 'clip_polygon');
  for (const [x, y] of [[150, 130], [250, 125], [230, 165], [140, 160]]) await clickAt(page, x, y);
  await press(page, 'Enter');
  // Outside: the hole's surroundings are drawn (and picked).
  await page.evaluate(() => window.stippleViewer.tools.setClipMode('outside'));
  await until(page, (s) => s.clipMode === 'outside' && s.items.length === 1, 'a hole');
  await chooseTool(page, '3', 'height');
  await clickAt(page, 100, 150);
  await clickAt(page, 300, 135);
  await chooseTool(page, '9', 'annotation');
  await clickAt(page, 120, 145);
  await until(page, (s) => s.items.length === 3 && s.items.every((m) => m.complete), 'three items');
  await page.evaluate(() => {
    const v = window.stippleViewer;
    v.tools.setFilter({ classes: [1, 2] });
    const c = v.camera;
    v.camera = { position: c.position.map((x, i) => x + (i === 2 ? 50 : 20)), target: c.target };
  });
  const s1 = await until(page, (s) => s.clipMode === 'outside' && s.filter.classes, 'clip mode and filter');
  await page.waitForFunction(() => /measurements=.*clip-mode=outside|clip-mode=outside.*measurements=/.test(location.hash) &&
                                   location.hash.includes('classes=1,2') && location.hash.includes('camera='),
                             { timeout: 30000 });
  const link = await page.evaluate(() => location.href);
  const first = await page.evaluate(async () => Array.from((await window.stippleViewer.pixels()).data));
  // The link in a new page: the same view once its tools took the link's state.
  const second = await c.openPage(suite.browser, link);
  c.assertDone(second.state, second.log);
  const s2 = await until(second.page, (s) => s.items.length === 3 && s.clipMode === 'outside' &&
                                             s.filter.classes, 'the link\'s tools state');
  assert.deepEqual(s2.items.map((m) => [m.tool, m.points, m.text]), s1.items.map((m) => [m.tool, m.points, m.text]));
  assert.deepEqual(s2.filter, s1.filter);
  const again = await second.page.evaluate(async () => Array.from((await window.stippleViewer.pixels()).data));
  assert.equal(again.length, first.length);
  let differ = 0;
  for (let i = 0; i < first.length; i += 4)
    differ += first[i] !== again[i] || first[i + 1] !== again[i + 1] || first[i + 2] !== again[i + 2];
  // The same renderer on the same device with the same inputs: no pixel may differ.
  assert.equal(differ, 0, `${differ} pixels differ`);
  await second.page.close();
  await page.close();
});

test('render\'s options by the same names in the page, and several clouds at once',
     { skip: skip || false, timeout: 600000 }, async () => {
  // The compute rasterizer with a class filter, as `stipple render --renderer compute --classes 2`.
  let { page, log, state } = await c.openPage(suite.browser, suite.server.url(
    `viewer/stipple.html?url=../cloud.las&width=${W}&height=${H}&renderer=compute&classes=2`));
  c.assertDone(state, log);
  assert.equal(state.renderer, 'compute');
  const ref = path.join(suite.work, 'compute-ground.png');
  h.stipple(['render', input, '-o', ref, '--width', String(W), '--height', String(H),
             '--renderer', 'compute', '--classes', '2']);
  await c.assertCanvasMatches(page, ref, { what: 'compute, classes 2', minLit: 0.01 });
  await page.close();
  // Two LAS files drawn together, as `stipple render a.las b.las`.
  const second = path.join(suite.work, 'second.las');
  h.stipple(['generate', '-n', '50000', '-o', second]);
  fs.symlinkSync(second, path.join(suite.work, 'www', 'second.las'));
  ({ page, log, state } = await c.openPage(suite.browser, suite.server.url(
    `viewer/stipple.html?url=../cloud.las&url=../second.las&width=${W}&height=${H}`)));
  c.assertDone(state, log);
  const both = path.join(suite.work, 'both.png');
  const native = h.stipple(['render', input, second, '-o', both, '--width', String(W), '--height', String(H)]);
  c.assertNativeAgrees(native, state, { points: true });
  await c.assertCanvasMatches(page, both, { what: 'two clouds', minLit: 0.005 });
  await page.close();
});
