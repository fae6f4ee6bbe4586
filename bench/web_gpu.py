#!/usr/bin/env python3
"""bench/web_gpu.py: the web viewer in headless Chromium on whatever GPU the machine has, without
node or nginx (the GPU machine has neither): a Python server on loopback serves the viewer
(build-web/) under /viewer/ and a data folder under /data/ (byte ranges too: the Potree, COPC and
EPT readers ask for them), cross-origin isolated (COOP/COEP), and adds to stipple.html a script
that, once the page reports done or an error, posts what it reports (window.stipple) and the
WebGPU adapter the page was given to /__report; then Chromium is closed and the report printed
as JSON (and written to --out).

  bench/web_gpu.py --chromium CMD [--web build-web] [--data DIR] [--query 'url=/data/t/tileset.json&frames=20']
                   [--window 1280x720] [--timeout-s 600] [--out report.json] [--swiftshader] [--moves N]
                   [--flight N] [--page stipple|potree] [--modules DIR] [--bench K] [--screenshot F]

--moves N: N camera turns once drawn, the page's CPU and GPU ms per frame (timestamp queries in the
page); --flight N: N steps of a flight down over a streamed set (tiles stream in meanwhile);
with --flight-seconds S the flight takes S seconds of wall time, a step per animation frame.
--screenshot F: the view once done (viewer.screenshot(), a PNG) written to F, before any moves, to
compare with `stipple render` of the same scene and size.
--bench K (bench/web_vs_potree.mjs's measurement, for bench/web_vs_potree_device.sh): once the
page is ready bench/web_vs_potree.js (served with the rest of bench/ under /bench/) turns the
camera K frames and the report holds what it measured (`bench`): the page is stipple.html, or with
--page potree the potree-core page bench/web_vs_potree.html, whose three and potree-core come from
--modules DIR (DIR/three, DIR/potree-core) under /modules/.

On the GPU machine (bench/RESULTS.md, "The page on a GPU"): CMD is the runner that
bench/device-chromium-pack.sh packs, VK_ICD_FILENAMES names the NVIDIA driver's manifest.
"""
import argparse, http.server, json, os, shlex, signal, subprocess, sys, threading, time

p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
p.add_argument('--chromium', required=True)
p.add_argument('--web', default=os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', 'build-web'))
p.add_argument('--data', default=None)
p.add_argument('--query', default='')
p.add_argument('--window', default='1280x720')
p.add_argument('--timeout-s', type=float, default=600)
p.add_argument('--out', default=None)
p.add_argument('--swiftshader', action='store_true', help="the tests' flags: WebGPU on SwiftShader")
p.add_argument('--flags', default='', help='more Chromium flags')
p.add_argument('--moves', type=int, default=0, help='camera turns after the view is done (frames to time)')
p.add_argument('--flight', type=int, default=0, help='steps of a flight down over the data (streamed sets)')
p.add_argument('--flight-seconds', type=float, default=0,
               help='the flight over this many seconds of wall time instead (needs --flight > 0)')
p.add_argument('--flight-to', type=float, default=0.4,
               help="where the flight ends, as a fraction of the first framing's distance")
p.add_argument('--retry-adapter', action='store_true', help='ask again where requestAdapter gives null')
p.add_argument('--page', choices=['stipple', 'potree'], default='stipple')
p.add_argument('--modules', default=None, help='a folder with three/ and potree-core/ (--page potree)')
p.add_argument('--bench', type=int, default=0, help="bench/web_vs_potree.js's frames to time once ready")
p.add_argument('--bench-warmup', type=int, default=5)
p.add_argument('--screenshot', default=None, help='write the finished view as a PNG here')
p.add_argument('--bench-dx', type=float, default=2)
a = p.parse_args()
bench_dir = os.path.dirname(os.path.abspath(__file__))

# Polls the page's report; posts it with the adapter's description once done or failed.
REPORTER = b"""<script>
const stippleMoves = MOVES;
const stippleFlight = FLIGHT;
const stippleFlightSeconds = FLIGHTSECONDS;
const stippleFlightTo = FLIGHTTO;
const stippleStats = () => JSON.parse(window.stipple.stats || '{}');
const stippleFrame = () => new Promise((r) => requestAnimationFrame(() => r()));
const stippleMedian = (v) => { const s = [...v].sort((a, b) => a - b); return s.length ? s[s.length >> 1] : null; };
const stippleP90 = (v) => { const s = [...v].sort((a, b) => a - b); return s.length ? s[Math.floor(s.length * 0.9)] : null; };
// Per drawn frame: the page's CPU time (its engine update: recording and submitting the frame,
// no GPU wait) and the GPU time from timestamp queries of each frame whose times came back.
function stippleSampler() {
  const cpu = [], gpu = new Map();
  let lastFrames = stippleStats().frames;
  return {
    sample() {
      const s = stippleStats();
      if (s.frames !== lastFrames) { cpu.push(s.cpuMs); lastFrames = s.frames; }
      if (s.gpuFrame && s.gpuMs !== null) gpu.set(s.gpuFrame, s.gpuMs);
    },
    result() {
      const g = [...gpu.values()];
      return { cpuMsMedian: stippleMedian(cpu), cpuMsP90: stippleP90(cpu), gpuMsMedian: stippleMedian(g),
               gpuMsP90: stippleP90(g), cpuSamples: cpu.length, gpuSamples: g.length };
    },
  };
}
// After the view is done: `stippleMoves` turns of the camera (ArrowLeft, one an animation frame),
// so that the page draws that many frames; the page's own time per frame (CPU and GPU) and the
// frames drawn per second of them.
async function stippleMeasureMoves() {
  const f0 = stippleStats().frames, t0 = performance.now(), ms = [];
  const sampler = stippleSampler();
  for (let i = 0; i < stippleMoves; ++i) {
    window.dispatchEvent(new KeyboardEvent('keydown', { key: 'ArrowLeft', code: 'ArrowLeft' }));
    await stippleFrame();
    await stippleFrame();
    ms.push(stippleStats().frameMs);
    sampler.sample();
  }
  const seconds = (performance.now() - t0) / 1000;
  for (let i = 0; i < 10; ++i) { await stippleFrame(); sampler.sample(); }
  const frames = stippleStats().frames - f0;
  return { moves: stippleMoves, framesDrawn: frames, seconds, fps: frames / seconds,
           pageFrameMsMedian: stippleMedian(ms), pageFrameMsSamples: ms, ...sampler.result(),
           camera: window.stippleViewer && window.stippleViewer.camera };
}
// A flight over a streamed set: the camera dollies from the first framing down its view axis to
// `stippleFlightTo` of the first distance (the framing's target is the point of the axis nearest
// the data's centre, under the surface of a flat survey seen from above: flown to a twentieth of
// the distance the camera ends underground, where nothing below the root is drawn), one step an
// animation frame, `stippleFlight` steps, or over `stippleFlightSeconds` of wall time (the step
// from the time elapsed, so tiles stream in as a user's flight would see them: a flight of a few
// hundred frames at hundreds a second ends before any tile below the root arrives); per frame the
// page's CPU and GPU time, the points drawn, the tiles loading; the last camera (to draw
// natively).
async function stippleFly() {
  const v = window.stippleViewer;
  const c0 = v.camera, t0c = c0.target;
  const d = c0.position.map((x, i) => x - t0c[i]);
  const sampler = stippleSampler();
  const loading = [], points = [];
  const start = performance.now(), f0 = stippleStats().frames;
  const duration = stippleFlightSeconds * 1000;
  for (let i = 1; ; ++i) {
    const k = duration > 0 ? Math.min(1, (performance.now() - start) / duration) : i / stippleFlight;
    const target = t0c;
    const scale = 1 - (1 - stippleFlightTo) * k;
    const position = [target[0] + d[0] * scale, target[1] + d[1] * scale, target[2] + d[2] * scale];
    v.camera = { position, target };
    await stippleFrame();
    sampler.sample();
    const s = stippleStats();
    loading.push(s.tilesLoading || 0);
    points.push(s.pointsDrawn || 0);
    if (duration > 0 ? k >= 1 : i >= stippleFlight) break;
  }
  const seconds = (performance.now() - start) / 1000;
  const frames = stippleStats().frames - f0;
  const fps = frames / seconds;
  for (let i = 0; i < 10; ++i) { await stippleFrame(); sampler.sample(); }
  return { steps: points.length, framesDrawn: frames, seconds, fps, ...sampler.result(),
           pointsDrawnMean: points.reduce((x, y) => x + y, 0) / Math.max(1, points.length),
           pointsDrawnMax: Math.max(...points), tilesLoadingMax: Math.max(...loading),
           last: v.camera, stats: stippleStats() };
}
(function poll() {
  const s = window.stipple;
  if (!s || !(s.done || s.error)) { setTimeout(poll, 250); return; }
  (async () => {
    let adapter = null;
    try {
      const ad = await navigator.gpu.requestAdapter({ powerPreference: 'high-performance' });
      const i = ad && (ad.info || (ad.requestAdapterInfo && await ad.requestAdapterInfo()));
      adapter = i ? { vendor: i.vendor, architecture: i.architecture, device: i.device,
                      description: i.description } : null;
    } catch (e) { adapter = String(e); }
    if (SHOT && !s.error && window.stippleViewer) {
      try {
        await fetch('/__screenshot', { method: 'POST', body: await window.stippleViewer.screenshot() });
      } catch (e) { console.log(`screenshot: ${e}`); }
    }
    let moves = null, flight = null;
    try { if (stippleMoves > 0 && !s.error) moves = await stippleMeasureMoves(); } catch (e) { moves = String(e); }
    try { if (stippleFlight > 0 && !s.error) flight = await stippleFly(); } catch (e) { flight = String(e); }
    await fetch('/__report', { method: 'POST', body: JSON.stringify({ stipple: { ...window.stipple }, adapter,
      moves, flight, devicePixelRatio: window.devicePixelRatio, inner: [innerWidth, innerHeight] }) });
  })();
})();
</script>
"""
# With --bench: bench/web_vs_potree.js once the page (stipple's or potree-core's) is ready; its
# result posted with the adapter and what the page reports.
BENCH = b"""<script src="/bench/web_vs_potree.js"></script>
<script>
(function poll() {
  if (!window.vsPotree || !window.vsPotree.ready()) { setTimeout(poll, 250); return; }
  (async () => {
    const timing = { ready: performance.now() };
    let adapter = null;
    try {
      const ad = navigator.gpu && await navigator.gpu.requestAdapter({ powerPreference: 'high-performance' });
      const i = ad && (ad.info || (ad.requestAdapterInfo && await ad.requestAdapterInfo()));
      adapter = i ? { vendor: i.vendor, architecture: i.architecture, device: i.device,
                      description: i.description } : null;
    } catch (e) { adapter = String(e); }
    let webgl = null;
    try {
      const gl = document.createElement('canvas').getContext('webgl2');
      const x = gl && gl.getExtension('WEBGL_debug_renderer_info');
      webgl = x ? gl.getParameter(x.UNMASKED_RENDERER_WEBGL) : gl && gl.getParameter(gl.RENDERER);
    } catch (e) { webgl = String(e); }
    timing.described = performance.now();
    const error = window.vsPotree.error();
    let bench = null;
    try { if (!error) bench = await window.vsPotree.measure(FRAMES, { dx: DX, warmup: WARMUP }); } catch (e) { bench = String(e); }
    timing.measured = performance.now();
    const page = window.potreePage ? { error: window.potreePage.error, material: window.potreePage.material }
                                   : { ...window.stipple };
    await fetch('/__report', { method: 'POST', body: JSON.stringify({ bench, adapter, webgl, error, timing,
      [window.potreePage ? 'potree' : 'stipple']: page, devicePixelRatio: window.devicePixelRatio,
      inner: [innerWidth, innerHeight] }) });
  })();
})();
</script>
"""
# With --retry-adapter: requestAdapter asked again (5 times, 200 ms apart) where it returns null.
# Chromium 156 with ANGLE on Vulkan answered the page's first request with null ("A valid
# external Instance reference no longer exists.") and a later one with the NVIDIA adapter.
RETRY = b"""<script>
{
  const request = GPU.prototype.requestAdapter;
  GPU.prototype.requestAdapter = async function (options) {
    for (let i = 0; i < 5; ++i) {
      const adapter = await request.call(this, options);
      if (adapter) return adapter;
      console.log(`requestAdapter returned null (try ${i + 1})`);
      await new Promise((r) => setTimeout(r, 200));
    }
    return null;
  };
}
</script>
"""
report = {}
done = threading.Event()


class Handler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args):
        pass

    def end_headers(self):
        self.send_header('Cross-Origin-Opener-Policy', 'same-origin')
        self.send_header('Cross-Origin-Embedder-Policy', 'require-corp')
        self.send_header('Cross-Origin-Resource-Policy', 'same-origin')
        self.send_header('Cache-Control', 'no-store')
        super().end_headers()

    def translate_path(self, path):
        path = path.split('?', 1)[0]
        for prefix, root in (('/viewer/', a.web), ('/data/', a.data), ('/bench/', bench_dir),
                             ('/modules/', a.modules)):
            if root and path.startswith(prefix):
                return os.path.join(os.path.abspath(root), path[len(prefix):])
        return '/nonexistent'

    def do_GET(self):
        path = self.path.split('?', 1)[0]
        if path in ('/viewer/stipple.html', '/bench/web_vs_potree.html'):
            with open(os.path.join(a.web, 'stipple.html') if path.startswith('/viewer/')
                      else os.path.join(bench_dir, 'web_vs_potree.html'), 'rb') as f:
                body = f.read()
            if a.bench > 0:
                script = (BENCH.replace(b'FRAMES', str(a.bench).encode()).replace(b'WARMUP', str(a.bench_warmup).encode())
                          .replace(b'DX', str(a.bench_dx).encode()))
            else:
                script = (REPORTER.replace(b'MOVES', str(a.moves).encode()).replace(b'FLIGHTSECONDS', str(a.flight_seconds).encode()).replace(b'FLIGHTTO', str(a.flight_to).encode()).replace(b'FLIGHT', str(a.flight).encode())
                          .replace(b'SHOT', b'true' if a.screenshot else b'false'))
            body = body.replace(b'</body>', script + b'</body>')
            if a.retry_adapter:
                body = body.replace(b'<head>', b'<head>' + RETRY, 1)
            self.send_response(200)
            self.send_header('Content-Type', 'text/html')
            self.send_header('Content-Length', str(len(body)))
            self.end_headers()
            self.wfile.write(body)
            return
        rng = self.headers.get('Range')
        file = self.translate_path(self.path)
        if rng and os.path.isfile(file):
            self.send_range(file, rng)
            return
        super().do_GET()

    # Byte ranges (bytes=a-b, a-, -n): the Potree, COPC and EPT readers read parts of files.
    def send_range(self, file, rng):
        size = os.path.getsize(file)
        try:
            unit, spec = rng.split('=', 1)
            first, last = spec.split(',')[0].strip().split('-')
            if unit.strip() != 'bytes':
                raise ValueError(unit)
            if first == '':
                start, end = max(0, size - int(last)), size - 1
            else:
                start, end = int(first), min(size - 1, int(last)) if last else size - 1
        except ValueError:
            self.send_error(400, 'bad Range')
            return
        if start > end or start >= size:
            self.send_response(416)
            self.send_header('Content-Range', f'bytes */{size}')
            self.end_headers()
            return
        with open(file, 'rb') as f:
            f.seek(start)
            body = f.read(end - start + 1)
        self.send_response(206)
        self.send_header('Content-Type', self.guess_type(file))
        self.send_header('Content-Range', f'bytes {start}-{end}/{size}')
        self.send_header('Content-Length', str(len(body)))
        self.send_header('Accept-Ranges', 'bytes')
        self.end_headers()
        self.wfile.write(body)

    def do_POST(self):
        body = self.rfile.read(int(self.headers.get('Content-Length', '0')))
        self.send_response(204)
        self.end_headers()
        if self.path == '/__screenshot':
            with open(a.screenshot, 'wb') as f:
                f.write(body)
            return
        report.update(json.loads(body))
        done.set()


Handler.extensions_map = {**http.server.SimpleHTTPRequestHandler.extensions_map,
                          '.wasm': 'application/wasm', '.js': 'text/javascript',
                          '.mjs': 'text/javascript', '.json': 'application/json'}
server = http.server.ThreadingHTTPServer(('127.0.0.1', 0), Handler)
threading.Thread(target=server.serve_forever, daemon=True).start()
page = '/bench/web_vs_potree.html' if a.page == 'potree' else '/viewer/stipple.html'
url = f'http://127.0.0.1:{server.server_address[1]}{page}?{a.query}'
w, h = a.window.split('x')
flags = ['--headless=new', '--no-sandbox', '--enable-unsafe-webgpu', '--ignore-gpu-blocklist',
         f'--window-size={w},{h}', '--user-data-dir=/tmp/web-gpu-profile', '--enable-logging=stderr',
         '--v=0', '--no-first-run', '--disable-dev-shm-usage']
if a.swiftshader:
    flags += ['--enable-features=Vulkan', '--use-vulkan=native']
flags += shlex.split(a.flags)
print('opening', url, file=sys.stderr, flush=True)
t0 = time.time()
log_path = (a.out or '/tmp/web-gpu') + '.chromium.log'
with open(log_path, 'w') as log:
    proc = subprocess.Popen(shlex.split(a.chromium) + flags + [url], stdout=log, stderr=log,
                            start_new_session=True)
    ok = done.wait(a.timeout_s)
    os.killpg(proc.pid, signal.SIGKILL)
report['wallS'] = round(time.time() - t0, 2)
report['url'] = url
if not ok:
    report['timeout'] = True
out = json.dumps(report, indent=1)
print(out)
if a.out:
    with open(a.out, 'w') as f:
        f.write(out)
sys.exit(0 if ok and 'error' not in report.get('stipple', {}) and not report.get('error') else 1)
