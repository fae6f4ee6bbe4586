// bench/web_vs_potree.js: the frame measurement that bench/web_vs_potree.mjs (node, puppeteer)
// and bench/web_gpu.py --bench (Python, on the GPU machine) run inside either page: stipple's page
// (window.stipple, window.stippleViewer) or the potree-core page (bench/web_vs_potree.html,
// window.potreePage). Once the page is ready, window.vsPotree.measure(K) turns the camera about
// the target of the page's ?camera=eye,target by the same angle every animation frame (yaw, about
// the vertical, of `dx` * 0.005 rad: what a drag of dx pixels turns in stipple's page), setting
// it on either page in the data's coordinates (stipple: viewer.camera; potree: setCamera), after
// `warmup` turns, for K more, and resolves with the intervals between the animation frames'
// timestamps (the frame rate the page gets: with --disable-gpu-vsync --disable-frame-rate-limit
// it is not capped by a display), their median and 90th percentile, the frames each page counts
// as drawn, the points it drew each frame as it reports them, and its own time on the page's
// thread per frame (stipple: cpuMs, the engine's update; potree: updatePointClouds and render)
// and, where the adapter has timestamp queries, stipple's GPU time per frame (gpuMs).
// The animation frames are paced by the GPU only where the browser holds the page back while its
// frames are still being drawn; on SwiftShader it does not (its Vulkan queue runs behind the
// page's submissions: a WebGPU frame of a second or more at 8 ms intervals), so the frames are also
// timed to their completion: the GPU's work is drained (one more frame drawn and read back whole:
// stipple's window.stippleCapture(), the potree page's drain(), each of which returns once every
// frame before it is done), the K frames drawn, drained again, and the time between the drains
// divided by K + 1 (`sustainedMs`: the frame time the GPU sustains, the readback's share included).
(() => {
  const kind = () => (window.potreePage ? 'potree' : window.stipple ? 'stipple' : null);
  const stats = () => {
    if (kind() === 'potree') return window.potreePage.stats();
    return JSON.parse((window.stipple && window.stipple.stats) || '{}');
  };
  const quantile = (values, q) => {
    const s = values.filter((v) => typeof v === 'number' && Number.isFinite(v)).sort((a, b) => a - b);
    return s.length ? s[Math.min(s.length - 1, Math.floor(q * s.length))] : null;
  };
  const nextFrame = () => new Promise((resolve) => requestAnimationFrame(resolve));
  window.vsPotree = {
    kind,
    // Whether the page has drawn its first settled view (or failed: then error() says why).
    ready() {
      const p = kind() === 'potree' ? window.potreePage : window.stipple;
      return !!(p && (p.done || p.error));
    },
    error() {
      const p = kind() === 'potree' ? window.potreePage : window.stipple;
      return (p && p.error) || null;
    },
    async measure(frames = 30, { dx = 2, warmup = 5 } = {}) {
      // The orbit as stipple's page keeps it: yaw and pitch about the target in its Y-up world,
      // whose axes are the data's (x, z, -y).
      const v = (new URLSearchParams(location.search).get('camera') || '').split(',').map(Number);
      if (v.length !== 6 || v.some((x) => !Number.isFinite(x))) throw new Error('the page has no ?camera=eye,target');
      const target = v.slice(3);
      const o = [0, 1, 2].map((k) => v[k] - target[k]);
      const distance = Math.hypot(...o);
      let yaw = Math.atan2(o[0], -o[1]);
      const pitch = Math.asin(Math.max(-1, Math.min(1, o[2] / distance)));
      const turn = (d) => {
        yaw -= d * 0.005;
        const position = [target[0] + distance * Math.cos(pitch) * Math.sin(yaw),
                          target[1] - distance * Math.cos(pitch) * Math.cos(yaw),
                          target[2] + distance * Math.sin(pitch)];
        if (kind() === 'potree') window.potreePage.setCamera(position, target);
        else window.stippleViewer.camera = { position, target };
      };
      for (let i = 0; i < warmup; ++i) {
        turn(dx);
        await nextFrame();
      }
      // Returns the fraction of the drawn frame's pixels that differ from its corner's (the
      // background) by more than 24 in a channel: both pages should show about the same.
      const drain = async () => {
        const a = kind() === 'potree' ? window.potreePage.drain() : (await window.stippleCapture()).data;
        let lit = 0;
        for (let i = 0; i < a.length; i += 4)
          if (Math.max(Math.abs(a[i] - a[0]), Math.abs(a[i + 1] - a[1]), Math.abs(a[i + 2] - a[2])) > 24) ++lit;
        return lit / (a.length / 4);
      };
      await drain();
      const before = stats();
      const intervals = [], points = [], cpu = [], gpu = [];
      const t0 = performance.now();
      let last = await nextFrame();
      for (let i = 0; i < frames; ++i) {
        turn(dx);
        const now = await nextFrame();
        intervals.push(now - last);
        last = now;
        const s = stats();
        points.push(s.pointsDrawn);
        cpu.push(s.cpuMs);
        if (s.gpuMs != null) gpu.push(s.gpuMs);
      }
      const after = stats();
      const lit = await drain();
      const wallMs = performance.now() - t0;
      const round = (v, d = 2) => (v == null ? null : Number(v.toFixed(d)));
      return {
        page: kind(), frames, dx, warmup, wallMs: round(wallMs, 1),
        medianMs: round(quantile(intervals, 0.5)), p90Ms: round(quantile(intervals, 0.9)),
        sustainedMs: round(wallMs / (frames + 1)), litFraction: round(lit, 4),
        meanMs: round(intervals.reduce((a, b) => a + b, 0) / intervals.length),
        framesDrawn: (after.frames || 0) - (before.frames || 0),
        pointsDrawn: quantile(points, 0.5), pointsMin: quantile(points, 0), pointsMax: quantile(points, 1),
        cpuMsMedian: round(quantile(cpu, 0.5)), gpuMsMedian: round(quantile(gpu, 0.5), 3),
        intervalsMs: intervals.map((v) => round(v)),
        stats: after,
      };
    },
  };
})();
