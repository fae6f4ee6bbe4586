// bench/web_frames.mjs: frame times of a tileset in the web viewer (headless Chromium, WebGPU on
// SwiftShader, the flags of tests/web/harness.mjs) beside `stipple render` of the same tileset
// (native, wgpu on whatever Vulkan the machine has: lavapipe here). The tileset is served by
// nginx on loopback with COOP/COEP headers and opened as
// `stipple.html?url=tileset.json&width=W&height=H&frames=F&max-sse=S`; native is
// `stipple render tileset.json --width W --height H --frames F --max-sse S`. Prints a Markdown
// table: the page's load to done (ms, from the navigation: the wasm fetched and compiled, the
// adapter, the tiles streamed and the frames drawn meanwhile), its median frame once streamed
// on the page's thread (cpuMs, or frameMs for older builds: `engine.update()`, which no longer
// waits for the GPU; builds before it waited for the frame's GPU work, and the readback page
// (--before) copied every frame back into a 2D canvas within it) and the GPU's (gpuMs, from
// timestamp queries in the page, where the adapter has them), the native wall and GPU per frame
// (medians), and logs the canvas against the native image
// (tileset.test.mjs's measure) and the page's GPU time per pass (gpuPassesMs: medians of the
// settled frames; the last frame's for builds without it). bench/RESULTS.md ("A tileset by
// URL", "The page's WebGPU canvas", "The page on SwiftShader") has the figures.
//
//   node bench/web_frames.mjs --points 10000000            generate, tile (cached in --work), run
//   node bench/web_frames.mjs --tileset DIR                an existing tileset folder
//   options: --sizes 320x240,1280x720  --frames 20  --max-sse 1  --work /tmp/stipple-web-frames
//            --timeout-s 1800 (a page's limit)  --skip-native
//            --renderer auto|billboard|compute  both sides (the page's ?renderer=)
//            --before DIR  another build of the page (a folder like build-web), measured in the
//                          same run, before this one at each size (a before/after comparison)
// STIPPLE_BINARY (default build/stipple) and STIPPLE_WEB_DIR (default build-web) as for the tests.
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { parseArgs } from 'node:util';
import * as h from '../tests/web/harness.mjs';

const { values: o } = parseArgs({
  options: {
    points: { type: 'string' },
    tileset: { type: 'string' },
    sizes: { type: 'string', default: '320x240,1280x720' },
    frames: { type: 'string', default: '20' },
    'max-sse': { type: 'string', default: '1' },
    work: { type: 'string', default: path.join(os.tmpdir(), 'stipple-web-frames') },
    'timeout-s': { type: 'string', default: '1800' },
    'skip-native': { type: 'boolean', default: false },
    before: { type: 'string' },
    renderer: { type: 'string' },
  },
});
const webDir = process.env.STIPPLE_WEB_DIR || path.join(h.sourceDir, 'build-web');
const why =
  h.skipReason({ modules: ['puppeteer-core'], browser: true, server: true }) ||
  (fs.existsSync(path.join(webDir, 'stipple.wasm')) ? null : `${webDir} not built (scripts/build-web.sh)`) ||
  (!o.before || fs.existsSync(path.join(o.before, 'stipple.wasm')) ? null : `--before ${o.before} holds no stipple.wasm`) ||
  (o.points || o.tileset ? null : 'give --points N or --tileset DIR');
if (why) {
  console.error(`web_frames: ${why}`);
  process.exit(2);
}

fs.mkdirSync(o.work, { recursive: true });
let tileset = o.tileset && path.resolve(o.tileset);
if (!tileset) {
  // Generated and tiled once per point count (kept in --work: tiling 10M points takes minutes).
  const las = h.generatedLas(o.work, Number(o.points));
  tileset = path.join(o.work, `tiles-${o.points}`);
  if (!fs.existsSync(path.join(tileset, 'tileset.json'))) {
    const t0 = Date.now();
    h.tile(las, tileset);
    console.log(`tiled ${o.points} points in ${((Date.now() - t0) / 1000).toFixed(1)} s`);
  }
}
const root = fs.mkdtempSync(path.join(o.work, 'www-'));
fs.symlinkSync(webDir, path.join(root, 'viewer'));
// The pages measured at each size: the --before build first.
const pages = [['this', 'viewer']];
if (o.before) {
  fs.symlinkSync(path.resolve(o.before), path.join(root, 'before'));
  pages.unshift(['before', 'before']);
}
fs.symlinkSync(tileset, path.join(root, 'tiles'));
const contents = h.contentFiles(tileset);
console.log(`${tileset}: ${contents.length} content files; load average ${os.loadavg().map((l) => l.toFixed(1)).join(' ')}, ${os.cpus().length} cores`);

const server = await h.startNginx(root, {
  headers: {
    'Cross-Origin-Opener-Policy': 'same-origin',
    'Cross-Origin-Embedder-Policy': 'require-corp',
  },
});
const browser = await h.launchBrowser({ webgpu: true });
const rows = [];
try {
  for (const size of o.sizes.split(',')) {
    const [width, height] = size.split('x');
    let native = { wall: '-', gpu: '-', points: '-', renderer: '-' };
    const ref = path.join(o.work, `native-${size}.png`);
    if (!o['skip-native']) {
      const out = h.stipple(['render', path.join(tileset, 'tileset.json'), '-o', ref, '--width',
                             width, '--height', height, '--frames', o.frames, '--max-sse',
                             o['max-sse'], ...(o.renderer ? ['--renderer', o.renderer] : [])]);
      const m = out.match(/frames: GPU ([\d.]+) ms, wall ([\d.]+) ms per frame/);
      if (m) Object.assign(native, { gpu: m[1], wall: m[2] });
      native.points = (out.match(/rendered (\d+) points/) || [])[1] || '?';
      native.renderer = (out.match(/renderer: (\S+)/) || [])[1] || '?';
    }
    for (const [name, dir] of pages) {
      const page = await browser.newPage();
      const log = [];
      page.on('pageerror', (e) => log.push(`page error: ${e}`));
      page.on('console', (m) => log.push(`page ${m.type()}: ${m.text()}`));
      const t0 = Date.now();
      await page.goto(server.url(`${dir}/stipple.html?url=/tiles/tileset.json&width=${width}` +
                                 `&height=${height}&frames=${o.frames}&max-sse=${o['max-sse']}` +
                                 (o.renderer ? `&renderer=${o.renderer}` : '')));
      await page.waitForFunction(() => window.stipple && (window.stipple.done || window.stipple.error),
                                 { timeout: Number(o['timeout-s']) * 1000, polling: 1000 });
      const wallMs = Date.now() - t0;
      const web = await page.evaluate(() => ({
        ...window.stipple,
        lastPasses: window.stippleViewer?.stats ? window.stippleViewer.stats()?.gpuPasses : undefined,
      }));
      if (web.error) throw new Error(`the ${name} page failed at ${size}: ${web.error}\n${log.join('\n')}`);
      // The same image as the native render (tests/web/tileset.test.mjs's measure)?
      const d = o['skip-native'] ? {} : await h.compareCanvas(page, fs.readFileSync(ref));
      await page.close();
      console.log(`${size} (${name} page): web ${web.tiles} tiles, ${web.points} points, ${web.renderer}, ` +
                  `errors ${web.errors}, done in ${web.ms} ms (page opened to done ${wallMs} ms), ` +
                  `frame ${web.cpuMs ?? web.frameMs} ms (GPU ${web.gpuMs ?? '-'} ms); native ${native.renderer}, ${native.points} points: wall ` +
                  `${native.wall} ms, GPU ${native.gpu} ms; web vs native ${JSON.stringify(d)}; ` +
                  (web.gpuPassesMs ? `page passes, medians of the settled frames (ms) ${web.gpuPassesMs}; `
                                   : `page passes, last frame (ms) ${JSON.stringify(web.lastPasses ?? {})}; `) +
                  `load average ${os.loadavg()[0].toFixed(1)}`);
      rows.push(`| ${size} | ${name} | ${web.points} (native ${native.points}) | ` +
                `${wallMs.toLocaleString('en-US')} | ${web.cpuMs ?? web.frameMs} | ${web.gpuMs ?? '-'} | ` +
                `${native.wall} | ${native.gpu} |`);
    }
  }
} finally {
  await browser.close();
  await server.stop();
  fs.rmSync(root, { recursive: true, force: true });
}
console.log('\n| size | page | points drawn | web: page load to done (ms) | web: CPU per frame once ' +
            'streamed (median, ms) | web: GPU per frame (median, ms) | native: wall per frame ' +
            '(median, ms) | native: GPU per frame (ms) |');
console.log('|---|---|---:|---:|---:|---:|---:|---:|');
for (const r of rows) console.log(r);
