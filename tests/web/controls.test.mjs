// The web viewer's colour modes, eye-dome lighting and point size, set by the query string
// (?color=&no-edl=&edl-strength=&point-size=, `stipple render`'s options of the same names) and
// by the page's controls while the view runs: headless chromium (WebGPU on SwiftShader) draws
// autzen (../shared/data, or a generated cloud where ../shared is absent) as the native
// `stipple render` of the same file and options does (lavapipe), within the tolerance of
// tileset.test.mjs; a control's change changes the pixels. The stats panel shows the points
// drawn (as `stipple render` counts them) and, for a tileset, its tiles and memory.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import * as h from './harness.mjs';
import * as c from './common.mjs';

const skip = c.skip;
let input;
const suite = c.viewerSuite('controls', (work) => {
  // The served root: the viewer, the file and its tileset side by side.
  let root;
  ({ root, input } = c.cloudRoot(work));
  return root;
});

// Opens the viewer with `query` and waits until it reports done or an error.
async function open(query) {
  const r = await c.openPage(suite.browser, suite.server.url(`viewer/stipple.html?${query}`));
  c.assertDone(r.state, r.log);
  return r;
}

// The native render of the LAS file at 320x240 with `args`: the PNG's path and what it printed.
const natives = new Map();
function nativeRender(args) {
  const key = args.join(' ');
  if (!natives.has(key)) {
    const png = path.join(suite.work, `native${natives.size}.png`);
    const printed = h.stipple(['render', input, '-o', png, '--width', '320', '--height', '240', ...args]);
    natives.set(key, { png, printed });
  }
  return natives.get(key);
}

// The page's canvas against a native render: the same renderer, within the tolerance of
// common.mjs (tileset.test.mjs's).
async function assertMatches(page, state, native, what) {
  c.assertNativeAgrees(native.printed, state, { what });
  return c.assertCanvasMatches(page, native.png, {
    what,
    describe: (d) => `${what}: web vs native ${JSON.stringify(d)}; ${state.renderer}`,
  });
}

// Each query option and the native flags that ask for the same.
const cases = [
  ['color=rgb', ['--color', 'rgb']],
  ['color=intensity', ['--color', 'intensity']],
  ['color=classification', ['--color', 'classification']],
  ['color=elevation', ['--color', 'elevation']],
  ['color=return', ['--color', 'return']],
  ['color=constant', ['--color', 'constant']],
  ['no-edl=1', ['--no-edl']],
  ['edl-strength=250', ['--edl-strength', '250']],
  ['point-size=4', ['--point-size', '4']],
];

for (const [query, args] of cases) {
  test(`?${query} matches stipple render ${args.join(' ')}`, { skip: skip || false }, async () => {
    const { page, state } = await open(`url=/cloud.las&width=320&height=240&interactive=0&${query}`);
    await assertMatches(page, state, nativeRender(args), `?${query}`);
    await page.close();
  });
}

test('a bad colour mode is an error shown on the page', { skip: skip || false }, async () => {
  const page = await suite.browser.newPage();
  await page.goto(suite.server.url('viewer/stipple.html?width=64&height=64&color=purple'));
  await page.waitForFunction(() => window.stipple && window.stipple.error, { timeout: 60000 });
  const shown = await page.evaluate(() => document.getElementById('error').textContent);
  assert.match(shown, /unknown colour mode 'purple'/);
  await page.close();
});

// Sets a control as a user would (its value, then the event the page listens to) and waits for
// the frame drawn after it.
async function setControl(page, id, value) {
  const before = await page.evaluate(() => Number(window.stipple.viewFrames || 0));
  await page.evaluate((id, value) => {
    const e = document.getElementById(id);
    if (e.type === 'checkbox') e.checked = value;
    else e.value = String(value);
    e.dispatchEvent(new Event(e.tagName === 'SELECT' || e.type === 'checkbox' ? 'change' : 'input'));
  }, id, value);
  await page.waitForFunction((n) => Number(window.stipple.viewFrames || 0) > n, { timeout: 60000 }, before);
}

test('the controls change the running view as the same options do natively', { skip: skip || false }, async () => {
  // A fixed point size: billboards, as `stipple render --point-size 2` draws them.
  const { page, state } = await open('url=/cloud.las&width=320&height=240&point-size=2');
  const controls = JSON.parse(state.controls);
  assert.deepEqual([controls.color, controls.edl, controls.pointSize], ['auto', 1, 2]);
  const base = nativeRender(['--point-size', '2']);
  await assertMatches(page, state, base, 'the first view');
  // The stats panel: the points `stipple render` draws, the renderer and adapter.
  const drawn = base.printed.match(/rendered (\d+) points/)[1];
  const stats = JSON.parse(state.stats);
  assert.equal(String(stats.pointsDrawn), drawn);
  assert.equal(stats.renderer, state.renderer);
  assert.match(state.statsText, new RegExp(`${Number(drawn).toLocaleString('en-US')} of`));
  assert.match(state.statsText, new RegExp(`${state.renderer} on `));
  const reset = async () => {
    await setControl(page, 'color', 'auto');
    await setControl(page, 'edl', true);
    await setControl(page, 'edl-strength', 60);
    await setControl(page, 'point-size', 2);
  };
  // Each control against the native render of the same options; all but rgb (what auto shows
  // for autzen) change the first view's pixels (measured on autzen: mean differences of 4.2, EDL
  // off, to 29, constant colour).
  const steps = [
    ['color', 'rgb', ['--color', 'rgb']],
    ['color', 'intensity', ['--color', 'intensity']],
    ['color', 'classification', ['--color', 'classification']],
    ['color', 'elevation', ['--color', 'elevation']],
    ['color', 'return', ['--color', 'return']],
    ['color', 'constant', ['--color', 'constant']],
    ['edl', false, ['--no-edl']],
    ['edl-strength', 250, ['--edl-strength', '250']],
    ['point-size', 4, ['--point-size', '4']],
  ];
  for (const [id, value, args] of steps) {
    await reset();
    await setControl(page, id, value);
    const what = `control ${id} = ${value}`;
    await assertMatches(page, state, nativeRender(id === 'point-size' ? args : ['--point-size', '2', ...args]), what);
    const changed = await h.compareCanvas(page, fs.readFileSync(base.png));
    console.log(`${what}: against the first view ${JSON.stringify(changed)}`);
    if (!(id === 'color' && value === 'rgb'))
      assert.ok(changed.meanDiff > 1, `${what} did not change the pixels: ${JSON.stringify(changed)}`);
  }
  const after = await page.evaluate(() => JSON.parse(window.stipple.controls));
  assert.equal(after.pointSize, 4);
  await page.close();
});

test('the controls change the colour and EDL on the compute rasterizer too', { skip: skip || false }, async () => {
  // Sized by the data: 1-pixel points, the compute rasterizer (as `stipple render` chooses).
  const { page, state } = await open('url=/cloud.las&width=320&height=240');
  assert.equal(state.renderer, 'compute');
  for (const [id, value, args] of [['color', 'elevation', ['--color', 'elevation']],
                                   ['edl', false, ['--color', 'elevation', '--no-edl']]]) {
    await setControl(page, id, value);
    await assertMatches(page, state, nativeRender(args), `compute, control ${id} = ${value}`);
  }
  await page.close();
});

test('the stats panel shows a tileset\'s tiles and memory against its budget', { skip: skip || false }, async () => {
  const { page, state } = await open('url=/tiles/tileset.json&width=320&height=240&max-sse=1&memory-mb=256');
  const stats = JSON.parse(state.stats);
  console.log(`tileset stats: ${JSON.stringify(stats)}`);
  assert.equal(String(stats.pointsDrawn), state.points);
  assert.equal(String(stats.tilesDrawn), state.tiles);
  assert.ok(stats.tilesResident >= stats.tilesDrawn, `resident ${stats.tilesResident}`);
  assert.equal(stats.tilesLoading, 0);
  assert.equal(stats.tilesFailed, 0);
  assert.equal(stats.budgetBytes, 256 * 1048576);
  assert.ok(stats.residentBytes > 0 && stats.residentBytes <= stats.budgetBytes, `${stats.residentBytes} bytes`);
  assert.ok(stats.gpuBytes > 0, `GPU ${stats.gpuBytes} bytes`);
  assert.match(state.statsText, /tiles: \d+ drawn, \d+ resident, 0 loading, 0 failed/);
  assert.match(state.statsText, /of 256\.0 MiB, GPU \d/);
  await page.close();
});
