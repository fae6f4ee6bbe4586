// Compressed content in the browser: autzen (../shared/data) tiled by `stipple tile --compress
// meshopt` (glb, EXT_meshopt_compression) and `--format pnts --compress draco`
// (3DTILES_draco_point_compression), and generated EPT (zstandard nodes) and Potree 2.0 (BROTLI
// nodes) clouds from the tests' writers, served by nginx on loopback, opened by URL in headless
// chromium (WebGPU on SwiftShader). The web build decodes them with the native build's
// meshoptimizer, Draco, zstd and Brotli compiled to WebAssembly (scripts/build-web.sh --deps):
// none fails, the page draws as many points as `stipple render` of the same input and camera,
// and its canvas matches the native render (lavapipe) within the tolerance of tileset.test.mjs.
// The autzen tilesets are skipped where ../shared is absent, EPT and Potree where the writers
// are not built.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { spawnSync } from 'node:child_process';
import * as h from './harness.mjs';
import * as c from './common.mjs';

const { skip, autzen } = c;
const noAutzen = fs.existsSync(autzen) ? null : `${autzen} not found (../shared absent)`;
const writers = {
  ept: process.env.STIPPLE_WRITE_EPT || path.join(h.sourceDir, 'build/tests/stipple_write_ept'),
  potree: process.env.STIPPLE_WRITE_POTREE || path.join(h.sourceDir, 'build/tests/stipple_write_potree'),
};

function write(writer, args) {
  const r = spawnSync(writer, args, { encoding: 'utf8' });
  if (r.status !== 0) throw new Error(`${writer} ${args.join(' ')} failed (${r.status}): ${r.stderr}`);
}

// Each input: how it is made, what the page opens, and the compression its content must use (or
// the test would pass on uncompressed content): a marker in every content file, or in the
// cloud's metadata.
const inputs = {
  meshopt: {
    skip: noAutzen,
    make: (dir) => h.tile(autzen, dir, ['--compress', 'meshopt']),
    open: 'tileset.json',
    marker: 'EXT_meshopt_compression',
    ext: '.glb',
  },
  draco: {
    skip: noAutzen,
    make: (dir) => h.tile(autzen, dir, ['--format', 'pnts', '--compress', 'draco']),
    open: 'tileset.json',
    marker: '3DTILES_draco_point_compression',
    ext: '.pnts',
  },
  ept: {
    skip: fs.existsSync(writers.ept) ? null : `${writers.ept} not built`,
    make: (dir) => write(writers.ept, [dir, '20000', 'zstandard']),
    open: 'ept.json',
    metadata: /"dataType":\s*"zstandard"/,
  },
  potree: {
    skip: fs.existsSync(writers.potree) ? null : `${writers.potree} not built`,
    make: (dir) => write(writers.potree, [dir, '20000', '500', '2', 'int64', 'brotli']),
    open: 'metadata.json',
    metadata: /"encoding":\s*"BROTLI"/,
  },
};

const suite = c.viewerSuite('compressed', (work) => {
  const root = c.viewerRoot(work);
  for (const [name, t] of Object.entries(inputs)) if (!t.skip) t.make(path.join(root, name));
  return root;
});
const { work } = suite;

for (const [name, t] of Object.entries(inputs)) {
  test(`${name}: the page matches the native render`, { skip: skip || t.skip || false }, async () => {
    const dir = path.join(work, 'www', name);
    if (t.marker) {
      const contents = h.contentFiles(dir);
      assert.ok(contents.length > 1, `${contents.length} content files`);
      for (const f of contents) {
        assert.equal(path.extname(f), t.ext, f);
        assert.ok(fs.readFileSync(path.join(dir, f)).includes(t.marker), `${f} does not use ${t.marker}`);
      }
    } else {
      assert.match(fs.readFileSync(path.join(dir, t.open), 'utf8'), t.metadata);
    }
    const ref = path.join(work, `native-${name}.png`);
    const native = h.stipple(['render', path.join(dir, t.open), '-o', ref, '--width', '320',
                              '--height', '240', '--max-sse', '1']);
    const { page, state, log } = await c.openPage(
      suite.browser, suite.server.url(`viewer/stipple.html?url=/${name}/${t.open}&width=320&height=240&max-sse=1`));
    c.assertDone(state, log);
    // Content the build cannot decode would be a listed problem, the rest drawn.
    assert.equal(state.errors, '0', state.problems);
    assert.ok(Number(state.tiles) > 1, `only ${state.tiles} tiles (nodes) drawn: the root did not refine`);
    assert.ok(Number(state.points) > 1000, `only ${state.points} points drawn`);
    c.assertNativeAgrees(native, state, { points: true });
    // As tileset.test.mjs: the tolerance of common.mjs.
    await c.assertCanvasMatches(page, ref, {
      describe: (d) => `${name}: web vs native: ${JSON.stringify(d)}; ${state.tiles} tiles, ` +
                       `${state.points} points, ${state.renderer}, ${state.ms} ms`,
    });
    await page.close();
  });
}
