// loaders.gl (npm @loaders.gl/3d-tiles) reads the tiler's output in node, over HTTP from nginx on
// loopback: the tileset tree (implicit tiling expanded from its subtrees) names exactly the
// content files written, every tile parses, its positions decode (Draco through npm draco3d,
// meshopt through loaders.gl's own decoder), and the points of all tiles add up to the input's
// count, for every output option.
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import * as h from './harness.mjs';

const skip = h.skipReason({
  modules: ['@loaders.gl/core', '@loaders.gl/3d-tiles', 'draco3d'],
  server: true,
});
const kPoints = 30000;
const variants = JSON.parse(process.env.STIPPLE_LOADERS_VARIANTS || 'null') || {
  glb: [],
  pnts: ['--format', 'pnts'],
  'glb-meshopt': ['--compress', 'meshopt'],
  'pnts-draco': ['--format', 'pnts', '--compress', 'draco'],
  // One subtree: loaders.gl 4.5 reads past a subtree's last level where no child subtree is
  // available (it then takes a constant availability for tiles that do not exist); CesiumJS
  // and stipple read child subtrees right (the CesiumJS test uses two levels a subtree).
  'glb-meshopt-implicit': ['--compress', 'meshopt', '--implicit'],
};
const work = skip ? null : h.tempDir('loaders');
let las, server;

before(async () => {
  if (skip) return;
  las = h.generatedLas(work, kPoints);
  server = await h.startNginx(work);
});
after(async () => {
  if (server) await server.stop();
  if (work) fs.rmSync(work, { recursive: true, force: true });
});

function arrayBuffer(file) {
  const b = fs.readFileSync(file);
  return b.buffer.slice(b.byteOffset, b.byteOffset + b.byteLength);
}

// Content URIs of an explicit tile tree, as loaders.gl resolved them.
function treeContents(tile, out) {
  if (tile.contentUrl) out.push(tile.contentUrl);
  for (const c of tile.children || []) treeContents(c, out);
  return out;
}

for (const [name, args] of Object.entries(variants)) {
  test(`loaders.gl parses every tile of the ${name} output`, { skip: skip || false }, async () => {
    const { load, parse } = h.require('@loaders.gl/core');
    const { Tiles3DLoader } = h.require('@loaders.gl/3d-tiles');
    const dir = h.tile(las, path.join(work, name), ['--max-node-points', '4000', ...args]);
    const files = h.contentFiles(dir);
    const base = server.url(`${name}/`);
    const tileset = await load(`${base}tileset.json`, Tiles3DLoader, { worker: false });
    const named = treeContents(tileset.root, [])
      .map((u) => decodeURIComponent(u.slice(base.length)))
      .sort();
    assert.deepEqual(named, files, 'the tree names other files than were written');
    let points = 0;
    for (const f of files) {
      const t = await parse(arrayBuffer(path.join(dir, f)), Tiles3DLoader, {
        worker: false,
        '3d-tiles': { loadGLTF: true },
        modules: { draco3d: h.require('draco3d') },  // else its decoder is fetched from a CDN
      });
      if (t.type === 'pnts') {
        // Draco-decoded positions are a typed array, others an accessor-like {value}.
        const positions = t.attributes.positions.value || t.attributes.positions;
        assert.equal(positions.length, t.pointsLength * 3, f);
        points += t.pointsLength;
      } else {
        assert.equal(t.type, 'glTF', `${f}: ${t.type}`);
        for (const mesh of t.gltf.meshes)
          for (const p of mesh.primitives) {
            assert.equal(p.mode, 0, `${f}: not points`);
            const pos = p.attributes.POSITION;
            assert.equal(pos.value.length, pos.count * 3, `${f}: positions not decoded`);
            points += pos.count;
          }
      }
    }
    assert.equal(points, kPoints);
  });
}
