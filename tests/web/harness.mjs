// Shared by the web interop tests: tiling with the stipple binary, nginx on loopback serving a
// folder, and Debian's chromium driven headless through puppeteer-core (WebGL on SwiftShader).
// Tests skip, with the reason, where a piece is missing (see skipReason).
import { spawn, spawnSync, execFileSync } from 'node:child_process';
import fs from 'node:fs';
import net from 'node:net';
import os from 'node:os';
import path from 'node:path';
import { createRequire } from 'node:module';

export const sourceDir = path.resolve(path.dirname(new URL(import.meta.url).pathname), '../..');
export const nodePrefix = process.env.STIPPLE_NODE_PREFIX || path.join(sourceDir, '.deps/node');
export const stippleBinary = process.env.STIPPLE_BINARY || path.join(sourceDir, 'build/stipple');
export const require = createRequire(path.join(nodePrefix, 'package.json'));

export function has(module) {
  return fs.existsSync(path.join(nodePrefix, 'node_modules', module, 'package.json'));
}

export function findBinary(candidates) {
  return candidates.find((p) => fs.existsSync(p)) || null;
}
export const chromiumPath = findBinary(['/usr/bin/chromium', '/usr/bin/chromium-browser']);
export const nginxPath = findBinary(['/usr/sbin/nginx', '/usr/bin/nginx']);

// Why a test cannot run here, or null.
export function skipReason({ modules = [], browser = false, server = false } = {}) {
  if (!fs.existsSync(stippleBinary)) return `${stippleBinary} not built`;
  for (const m of modules)
    if (!has(m)) return `npm package ${m} not installed (scripts/setup.sh --deps installs it)`;
  if (browser && !chromiumPath) return 'chromium not installed (Debian chromium)';
  if (server && !nginxPath) return 'nginx not installed (Debian nginx-light)';
  return null;
}

export function tempDir(name) {
  return fs.mkdtempSync(path.join(os.tmpdir(), `stipple-web-${name}-`));
}

export function stipple(args) {
  const r = spawnSync(stippleBinary, args, { encoding: 'utf8' });
  if (r.status !== 0)
    throw new Error(`stipple ${args.join(' ')} failed (${r.status}):\n${r.stdout}\n${r.stderr}`);
  return r.stdout;
}

// A generated LAS file (the built-in scan: RGB, intensity, classes, returns, GPS time).
export function generatedLas(dir, points) {
  const las = path.join(dir, `gen${points}.las`);
  if (!fs.existsSync(las)) stipple(['generate', '-n', String(points), '-o', las]);
  return las;
}

export function tile(input, out, extra = []) {
  stipple(['tile', input, '-o', out, '--force', ...extra]);
  return out;
}

// Content files of a tileset folder (glb, pnts), relative to it.
export function contentFiles(dir) {
  const out = [];
  const walk = (d) => {
    for (const e of fs.readdirSync(d, { withFileTypes: true })) {
      const p = path.join(d, e.name);
      if (e.isDirectory()) walk(p);
      else if (/\.(glb|pnts)$/.test(e.name)) out.push(path.relative(dir, p));
    }
  };
  walk(dir);
  return out.sort();
}

function freePort() {
  return new Promise((resolve, reject) => {
    const s = net.createServer();
    s.listen(0, '127.0.0.1', () => {
      const { port } = s.address();
      s.close(() => resolve(port));
    });
    s.on('error', reject);
  });
}

function canConnect(port) {
  return new Promise((resolve) => {
    const c = net.connect(port, '127.0.0.1', () => {
      c.end();
      resolve(true);
    });
    c.on('error', () => resolve(false));
  });
}

// nginx serving `root` on 127.0.0.1; `stop()` ends it. `headers` are added to every response
// (the web viewer's threads need cross-origin isolation: COOP and COEP).
export async function startNginx(root, { headers = {} } = {}) {
  const dir = tempDir('nginx');
  const port = await freePort();
  fs.mkdirSync(path.join(dir, 'tmp'));
  const conf = path.join(dir, 'nginx.conf');
  fs.writeFileSync(
    conf,
    `daemon off;\nworker_processes 1;\nerror_log ${dir}/error.log;\npid ${dir}/nginx.pid;\n` +
      `user root;\nevents { worker_connections 256; }\nhttp {\n access_log off;\n` +
      ` client_body_temp_path ${dir}/tmp;\n proxy_temp_path ${dir}/tmp;\n` +
      ` fastcgi_temp_path ${dir}/tmp;\n uwsgi_temp_path ${dir}/tmp;\n scgi_temp_path ${dir}/tmp;\n` +
      ` include /etc/nginx/mime.types;\n` +
      ` types { application/octet-stream pnts glb subtree bin laz zst hrc; application/wasm wasm;` +
      ` text/javascript mjs; }\n` +
      ` server {\n  listen 127.0.0.1:${port};\n  root ${root};\n` +
      Object.entries(headers).map(([k, v]) => `  add_header ${k} "${v}" always;\n`).join('') +
      ` }\n}\n`,
  );
  const child = spawn(nginxPath, ['-p', dir + '/', '-c', conf], { stdio: 'ignore' });
  for (let i = 0; i < 100 && !(await canConnect(port)); ++i)
    await new Promise((r) => setTimeout(r, 50));
  if (!(await canConnect(port))) {
    child.kill();
    throw new Error(`nginx did not start: ${fs.readFileSync(path.join(dir, 'error.log'), 'utf8')}`);
  }
  return {
    url: (p) => `http://127.0.0.1:${port}/${p}`,
    stop: () =>
      new Promise((resolve) => {
        child.on('exit', resolve);
        child.kill('SIGTERM');
      }),
  };
}

// Headless chromium with WebGL on SwiftShader; with `webgpu`, WebGPU on SwiftShader's Vulkan
// (Chromium 156 runs it headless with these flags). The compositor is on SwiftShader too
// (ANGLE): without it a WebGPU canvas has no shared image to present through and its device is
// lost at the first frame ("Could not find SharedImageBackingFactory" in the GPU process's log).
// `args`: more flags (the benches' --disable-gpu-vsync --disable-frame-rate-limit);
// `protocolTimeout`: ms a call into the page may take (puppeteer's default is 180 s; a bench's
// page on SwiftShader can be busy longer).
export async function launchBrowser({ webgpu = false, args: more = [], protocolTimeout = undefined } = {}) {
  const puppeteer = require('puppeteer-core');
  const args = webgpu
    ? ['--no-sandbox', '--enable-unsafe-webgpu', '--enable-features=Vulkan', '--use-vulkan=native',
       '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist',
       '--window-size=800,600']
    : ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
       '--ignore-gpu-blocklist', '--window-size=800,600'];
  return puppeteer.launch({ executablePath: chromiumPath, headless: true, args: [...args, ...more], protocolTimeout });
}

// The fraction of the page's canvas (#canvas) that is lit (brighter than the dark background).
// Its pixels are read as in compareCanvas.
export async function litFraction(page) {
  return page.evaluate(async () => {
    const a = (await window.stippleCapture()).data;
    let lit = 0;
    for (let i = 0; i < a.length; i += 4) if (a[i] + a[i + 1] + a[i + 2] > 60) ++lit;
    return lit / (a.length / 4);
  });
}

// Per-pixel comparison of the page's canvas (#canvas) with a PNG (decoded by the browser): the
// mean largest channel difference, the fraction of pixels off by more than 48, and the fraction
// of each image that is lit (brighter than the dark background). The web viewer's canvas is
// WebGPU, which headless Chromium on SwiftShader reads blank (drawImage, toDataURL, screenshots):
// its pixels come from the page (window.stippleCapture: the view drawn again and read back, only
// when asked).
export async function compareCanvas(page, png) {
  return page.evaluate(async (b64) => {
    const bytes = Uint8Array.from(atob(b64), (c) => c.charCodeAt(0));
    const bitmap = await createImageBitmap(new Blob([bytes], { type: 'image/png' }));
    const ref = new OffscreenCanvas(bitmap.width, bitmap.height).getContext('2d');
    ref.drawImage(bitmap, 0, 0);
    const canvas = document.getElementById('canvas');
    if (canvas.width !== bitmap.width || canvas.height !== bitmap.height)
      return { size: `${canvas.width}x${canvas.height} vs ${bitmap.width}x${bitmap.height}` };
    // (A page without it, the readback page that bench/web_frames.mjs --before measures, draws
    // into a 2D canvas.)
    const frame = window.stippleCapture ? await window.stippleCapture()
      : canvas.getContext('2d').getImageData(0, 0, canvas.width, canvas.height);
    if (frame.width !== canvas.width || frame.height !== canvas.height)
      return { size: `the frame read back is ${frame.width}x${frame.height}, the canvas ${canvas.width}x${canvas.height}` };
    const a = frame.data;
    const b = ref.getImageData(0, 0, bitmap.width, bitmap.height).data;
    let sum = 0, off = 0, lit = 0, refLit = 0;
    for (let i = 0; i < a.length; i += 4) {
      let d = 0;
      for (let c = 0; c < 3; ++c) d = Math.max(d, Math.abs(a[i + c] - b[i + c]));
      sum += d;
      if (d > 48) ++off;
      if (a[i] + a[i + 1] + a[i + 2] > 60) ++lit;
      if (b[i] + b[i + 1] + b[i + 2] > 60) ++refLit;
    }
    const n = a.length / 4;
    return { meanDiff: sum / n, offFraction: off / n, litFraction: lit / n, refLit: refLit / n };
  }, png.toString('base64'));
}
