// loaders.gl (npm @loaders.gl/3d-tiles) reads the tiler's output in node: the tileset tree names
// exactly the content files written, every tile parses, its positions decode, and the points
// of all tiles add up to the input's count, for every output option.
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import * as h from './harness.mjs';

const skip = h.skipReason({ modules: ['@loaders.gl/core', '@loaders.gl/3d-tiles'] });
const kPoints = 30000;
const variants = JSON.parse(process.env.STIPPLE_LOADERS_VARIANTS || 'null') || {
  glb: [],
  pnts: ['--format', 'pnts'],
};
const work = skip ? null : h.tempDir('loaders');
let las;

before(() => {
  if (!skip) las = h.generatedLas(work, kPoints);
});
after(() => {
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
    const { parse } = h.require('@loaders.gl/core');
    const { Tiles3DLoader } = h.require('@loaders.gl/3d-tiles');
    const dir = h.tile(las, path.join(work, name), ['--max-node-points', '4000', ...args]);
    const files = h.contentFiles(dir);
    const tileset = await parse(arrayBuffer(path.join(dir, 'tileset.json')), Tiles3DLoader, {
      worker: false,
      '3d-tiles': { isTileset: true },
    });
    if (!tileset.root.implicitTiling) {
      // Without a URL, loaders.gl resolves content URIs against the working directory.
      const named = treeContents(tileset.root, [])
        .map((u) => path.relative(process.cwd(), u))
        .sort();
      assert.deepEqual(named, files, 'the tree names other files than were written');
    }
    let points = 0;
    for (const f of files) {
      const t = await parse(arrayBuffer(path.join(dir, f)), Tiles3DLoader, {
        worker: false,
        '3d-tiles': { loadGLTF: true },
      });
      if (t.type === 'pnts') {
        assert.equal(t.attributes.positions.value.length, t.pointsLength * 3, f);
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
