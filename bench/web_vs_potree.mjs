// bench/web_vs_potree.mjs: stipple's page beside potree-core (WebGL Potree, what LiDAR teams share
// clouds with today) in one browser, one run: both open the same Potree 2.0 cloud (a LAS/LAZ file
// converted by the tests' Potree 2.0 writer, `stipple_write_potree DIR INPUT.las`), in a canvas of
// the same size, from the same camera (eye and target in the data's coordinates: the cloud's
// bounds seen from azimuth 30 and elevation 40 degrees, 50 degrees of vertical field of view, as
// stipple frames a scene), at the same point budget (stipple's ?budget=, Potree's pointBudget).
// Once each page has loaded what its view wants, the camera turns about the target by the same
// angle every animation frame (set in the data's coordinates: stipple's viewer.camera, the
// potree-core page's setCamera; both draw when the camera changed) for --warmup frames, then
// --frames more, timed by bench/web_vs_potree.js in the page: the intervals between animation
// frames (Chromium with --disable-gpu-vsync --disable-frame-rate-limit: not capped by a display),
// median and 90th percentile, the frames each page drew, the points each drew a frame as it
// reports them; and, since on SwiftShader the animation frames run ahead of the frames' GPU work,
// the sustained frame time (the GPU drained before and after the K frames, the time between
// divided by K + 1: bench/web_vs_potree.js says how); the ratios stipple / potree of both. The
// level of detail is left to the budget on both (stipple ?max-sse=0.01, Potree minNodePixelSize
// 0: otherwise each stops refining by its own rule, and the points drawn differ).
//
//   node bench/web_vs_potree.mjs                         autzen_trim (../shared/data), budgets 50000,all
//   options: --input FILE.las|laz  --cloud DIR (an existing Potree 2.0 folder instead)
//            --budgets 50000,all (all: the cloud's points)  --frames 30  --warmup 5  --dx 2
//            --size 1280x720  --rounds 1 (each budget's pair of pages again, in turn)
//            --node-cap 10000 --step 3 (the writer's nodes)  --max-sse 0.01
//            --stipple-options 'edl=0'  more of the stipple page's options (its EDL is on by
//                         default; potree-core's page draws without)
//            --work /tmp/stipple-web-vs-potree  --out FILE.json  --timeout-s 900 (a page's limit)
//            --pack DIR   write what the GPU machine needs instead of running (DIR/cloud,
//                         DIR/modules/{three,potree-core}, DIR/queries.txt: a budget and the query
//                         both pages take, a line each), for bench/web_vs_potree_device.sh
// Prints a line per page and a Markdown table (a row per budget), and writes the JSON (--out, else
// WORK/web_vs_potree.json): every interval, the pages' stats. STIPPLE_WEB_DIR (default build-web),
// STIPPLE_WRITE_POTREE (default build/tests/stipple_write_potree) and STIPPLE_NODE_PREFIX as for
// the tests. bench/RESULTS.md ("The page against potree-core") has the figures.
import { spawnSync } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { parseArgs } from 'node:util';
import * as h from '../tests/web/harness.mjs';

const { values: o } = parseArgs({
  options: {
    input: { type: 'string', default: path.join(h.sourceDir, '../shared/data/las/autzen_trim.las') },
    cloud: { type: 'string' },
    budgets: { type: 'string', default: '50000,all' },
    frames: { type: 'string', default: '30' },
    warmup: { type: 'string', default: '5' },
    dx: { type: 'string', default: '2' },
    size: { type: 'string', default: '1280x720' },
    rounds: { type: 'string', default: '1' },
    'node-cap': { type: 'string', default: '10000' },
    step: { type: 'string', default: '3' },
    'max-sse': { type: 'string', default: '0.01' },
    'stipple-options': { type: 'string', default: '' },
    work: { type: 'string', default: path.join(os.tmpdir(), 'stipple-web-vs-potree') },
    out: { type: 'string' },
    'timeout-s': { type: 'string', default: '900' },
    pack: { type: 'string' },
  },
});
const webDir = process.env.STIPPLE_WEB_DIR || path.join(h.sourceDir, 'build-web');
const writer = process.env.STIPPLE_WRITE_POTREE || path.join(h.sourceDir, 'build/tests/stipple_write_potree');
const modules = ['three', 'potree-core'];
const why =
  (modules.find((m) => !h.has(m)) ? `npm packages ${modules.join(', ')} not installed (scripts/setup.sh --deps)` : null) ||
  (o.pack ? null : h.skipReason({ modules: ['puppeteer-core'], browser: true, server: true })) ||
  (o.pack || fs.existsSync(path.join(webDir, 'stipple.wasm')) ? null : `${webDir} not built (scripts/build-web.sh)`) ||
  (o.cloud ? (fs.existsSync(path.join(o.cloud, 'metadata.json')) ? null : `${o.cloud} holds no metadata.json`)
    : fs.existsSync(writer) ? (fs.existsSync(o.input) ? null : `${o.input} not found`)
    : `${writer} not built`);
if (why) {
  console.error(`web_vs_potree: ${why}`);
  process.exit(2);
}
const [width, height] = o.size.split('x').map(Number);
fs.mkdirSync(o.work, { recursive: true });

// The cloud: converted once per input and node shape (kept in --work).
let cloud = o.cloud && path.resolve(o.cloud);
if (!cloud) {
  cloud = path.join(o.work, `cloud-${path.basename(o.input).replace(/\W/g, '_')}-${o['node-cap']}-${o.step}`);
  if (!fs.existsSync(path.join(cloud, 'metadata.json'))) {
    const t0 = Date.now();
    const r = spawnSync(writer, [cloud, path.resolve(o.input), o['node-cap'], o.step], { encoding: 'utf8' });
    if (r.status !== 0) throw new Error(`${writer} failed: ${r.stderr}`);
    console.log(`converted ${o.input} in ${((Date.now() - t0) / 1000).toFixed(1)} s: ${r.stdout.trim()}`);
  }
}
const meta = JSON.parse(fs.readFileSync(path.join(cloud, 'metadata.json'), 'utf8'));
const position = meta.attributes.find((a) => a.name === 'position');
const lo = position ? position.min : meta.boundingBox.min, hi = position ? position.max : meta.boundingBox.max;

// The camera: the bounds' corners inside the view from azimuth 30, elevation 40 degrees (5 %
// margin), looking at their centre.
function frameBounds(fovDeg = 50, azimuthDeg = 30, elevationDeg = 40) {
  const t = [0, 1, 2].map((k) => (lo[k] + hi[k]) / 2);
  const az = (azimuthDeg * Math.PI) / 180, el = (elevationDeg * Math.PI) / 180;
  // From the target to the eye, in the data's coordinates (Z up); the camera's right and up.
  const dir = [Math.cos(el) * Math.sin(az), -Math.cos(el) * Math.cos(az), Math.sin(el)];
  const right = [Math.cos(az), Math.sin(az), 0];
  const up = [-Math.sin(el) * Math.sin(az), Math.sin(el) * Math.cos(az), Math.cos(el)];
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const tanV = Math.tan((fovDeg * Math.PI) / 360), tanH = tanV * (width / height);
  let d = 0;
  for (let c = 0; c < 8; ++c) {
    const r = [0, 1, 2].map((k) => ((c >> k) & 1 ? hi[k] : lo[k]) - t[k]);
    d = Math.max(d, dot(r, dir) + Math.abs(dot(r, right)) / tanH, dot(r, dir) + Math.abs(dot(r, up)) / tanV);
  }
  d *= 1.05;
  const eye = [0, 1, 2].map((k) => t[k] + d * dir[k]);
  return [...eye, ...t].map((v) => Number(v.toFixed(4))).join(',');
}
const camera = frameBounds();
const budgets = o.budgets.split(',').map((b) => (b === 'all' ? Number(meta.points) : Number(b)));
// The query both pages take (stipple's page: its own options of these names).
const query = (budget) =>
  `url=/data/cloud/metadata.json&width=${width}&height=${height}&budget=${budget}&camera=${camera}`;
const pageQuery = {
  stipple: (b) => `/viewer/stipple.html?${query(b)}&max-sse=${o['max-sse']}&frames=3` +
                  (o['stipple-options'] ? `&${o['stipple-options']}` : ''),
  potree: (b) => `/bench/web_vs_potree.html?${query(b)}&min-node-pixel-size=0&timeout-s=${o['timeout-s']}`,
};
console.log(`${cloud}: ${meta.points} points, camera ${camera}; budgets ${budgets.join(', ')}; ` +
            `load average ${os.loadavg().map((l) => l.toFixed(1)).join(' ')}, ${os.cpus().length} cores`);

if (o.pack) {
  // What bench/web_vs_potree_device.sh serves on the GPU machine (web_gpu.py --data DIR
  // --modules DIR/modules): the cloud, the two npm packages' files the page loads, the queries.
  const dir = path.resolve(o.pack);
  fs.rmSync(dir, { recursive: true, force: true });
  fs.cpSync(cloud, path.join(dir, 'cloud'), { recursive: true });
  const nm = path.join(h.nodePrefix, 'node_modules');
  for (const f of ['build/three.module.js', 'build/three.core.js', 'package.json'])
    fs.cpSync(path.join(nm, 'three', f), path.join(dir, 'modules/three', f));
  fs.cpSync(path.join(nm, 'potree-core/dist'), path.join(dir, 'modules/potree-core/dist'), { recursive: true });
  fs.cpSync(path.join(nm, 'potree-core/package.json'), path.join(dir, 'modules/potree-core/package.json'));
  fs.writeFileSync(path.join(dir, 'queries.txt'),
                   budgets.map((b) => `${b}\t${query(b)}&max-sse=${o['max-sse']}` +
                                     `${o['stipple-options'] ? `&${o['stipple-options']}` : ''}\n`).join(''));
  console.log(`packed ${dir}: ${spawnSync('du', ['-sh', dir], { encoding: 'utf8' }).stdout.trim()}`);
  process.exit(0);
}

const root = fs.mkdtempSync(path.join(o.work, 'www-'));
fs.symlinkSync(webDir, path.join(root, 'viewer'));
fs.symlinkSync(path.join(h.sourceDir, 'bench'), path.join(root, 'bench'));
fs.mkdirSync(path.join(root, 'modules'));
for (const m of modules) fs.symlinkSync(path.join(h.nodePrefix, 'node_modules', m), path.join(root, 'modules', m));
fs.mkdirSync(path.join(root, 'data'));
fs.symlinkSync(cloud, path.join(root, 'data', 'cloud'));
const server = await h.startNginx(root, {
  headers: {
    'Cross-Origin-Opener-Policy': 'same-origin',
    'Cross-Origin-Embedder-Policy': 'require-corp',
  },
});
const flags = ['--disable-gpu-vsync', '--disable-frame-rate-limit', `--window-size=${width},${height}`];
const browser = await h.launchBrowser({ webgpu: true, args: flags, protocolTimeout: Number(o['timeout-s']) * 1000 });
const version = await browser.version();
const results = [];
try {
  for (let round = 1; round <= Number(o.rounds); ++round) {
    for (const budget of budgets) {
      for (const name of ['stipple', 'potree']) {
        const page = await browser.newPage();
        await page.setViewport({ width, height, deviceScaleFactor: 1 });
        const log = [];
        page.on('pageerror', (e) => log.push(`page error: ${e}`));
        page.on('console', (m) => log.push(`page ${m.type()}: ${m.text()}`));
        const t0 = Date.now();
        await page.goto(server.url(pageQuery[name](budget).slice(1)));
        await page.addScriptTag({ url: '/bench/web_vs_potree.js' });
        await page.waitForFunction(() => window.vsPotree.ready(),
                                   { timeout: Number(o['timeout-s']) * 1000, polling: 500 });
        const readyMs = Date.now() - t0;
        const error = await page.evaluate(() => window.vsPotree.error());
        if (error) throw new Error(`the ${name} page failed at budget ${budget}: ${error}\n${log.join('\n')}`);
        const m = await page.evaluate((k, dx, warmup) => window.vsPotree.measure(k, { dx, warmup }),
                                      Number(o.frames), Number(o.dx), Number(o.warmup));
        m.info = await page.evaluate(() => (window.potreePage
          ? { material: window.potreePage.material }
          : (({ renderer, adapter, pointSize, tiles, points }) => ({ renderer, adapter, pointSize, tiles, points }))(window.stipple)));
        await page.close();
        Object.assign(m, { round, budget, readyMs, query: pageQuery[name](budget),
                           loadAverage: Number(os.loadavg()[0].toFixed(2)) });
        results.push(m);
        console.log(`round ${round}, budget ${budget}, ${name}: ready in ${readyMs} ms; animation frames ` +
                    `median ${m.medianMs} ms, p90 ${m.p90Ms} ms (${m.framesDrawn} drawn of ${m.frames}); ` +
                    `sustained ${m.sustainedMs} ms a frame; lit ${m.litFraction}; points ` +
                    `${m.pointsDrawn} (${m.pointsMin}-${m.pointsMax}); page thread ${m.cpuMsMedian} ms` +
                    `${m.gpuMsMedian != null ? `, GPU ${m.gpuMsMedian} ms` : ''}; ${JSON.stringify(m.info)}; ` +
                    `load average ${m.loadAverage}`);
      }
    }
  }
} finally {
  await browser.close();
  await server.stop();
  fs.rmSync(root, { recursive: true, force: true });
}
const out = o.out || path.join(o.work, 'web_vs_potree.json');
fs.writeFileSync(out, JSON.stringify({ cloud, points: meta.points, camera, size: o.size, browser: version,
                                       flags, date: new Date().toISOString(), results }, null, 1));
console.log(`\n${version}; ${out}`);
console.log('\n| budget | round | points drawn: stipple / potree-core | stipple: frame interval median / p90 (ms) | ' +
            'potree-core: frame interval median / p90 (ms) | stipple: sustained frame (ms) | ' +
            'potree-core: sustained frame (ms) | stipple / potree-core, sustained | stipple / potree-core, interval medians |');
console.log('|---:|---:|---:|---:|---:|---:|---:|---:|---:|');
const n = (v) => v.toLocaleString('en-US');
for (let i = 0; i + 1 < results.length; i += 2) {
  const [s, p] = [results[i], results[i + 1]];
  console.log(`| ${n(s.budget)} | ${s.round} | ${n(s.pointsDrawn)} / ${n(p.pointsDrawn)} | ${s.medianMs} / ${s.p90Ms} | ` +
              `${p.medianMs} / ${p.p90Ms} | ${s.sustainedMs} | ${p.sustainedMs} | ` +
              `${(s.sustainedMs / p.sustainedMs).toFixed(2)} | ${(s.medianMs / p.medianMs).toFixed(2)} |`);
}
