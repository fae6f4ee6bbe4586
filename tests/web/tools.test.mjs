// 3d-tiles-tools (npm, Cesium's) converts every pnts tile of the tiler's output to glb
// (convertPntsToGlb, which maps the batch table to EXT_structural_metadata and refuses
// properties glTF cannot hold, such as float64); the results pass the Khronos glTF validator
// and hold the tile's points. The command line is run once, the library on every tile.
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { spawnSync } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import * as h from './harness.mjs';

const skip = h.skipReason({ modules: ['3d-tiles-tools', 'gltf-validator'] });
const work = skip ? null : h.tempDir('tools');
let dir;

before(() => {
  if (skip) return;
  const las = h.generatedLas(work, 30000);
  dir = h.tile(las, path.join(work, 'pnts'), ['--format', 'pnts', '--max-node-points', '4000']);
});
after(() => {
  if (work) fs.rmSync(work, { recursive: true, force: true });
});

test('3d-tiles-tools convertPntsToGlb (command line) accepts the pnts output', { skip: skip || false }, () => {
  const cli = path.join(h.nodePrefix, 'node_modules/3d-tiles-tools/build/src/cli.mjs');
  const out = path.join(work, 'root.glb');
  const r = spawnSync(process.execPath, [cli, 'convertPntsToGlb', '-i',
    path.join(dir, h.contentFiles(dir)[0]), '-o', out, '-f'], { encoding: 'utf8' });
  assert.equal(r.status, 0, r.stdout + r.stderr);
  assert.ok(fs.statSync(out).size > 1000);
});

test('3d-tiles-tools converts every pnts tile to a valid glb with its points', { skip: skip || false }, async () => {
  const { TileFormatsMigration } = h.require('3d-tiles-tools');
  const validator = h.require('gltf-validator');
  let tiles = 0, points = 0;
  for (const f of h.contentFiles(dir)) {
    const pnts = fs.readFileSync(path.join(dir, f));
    const ftJson = pnts.readUInt32LE(12);
    const pointsLength = JSON.parse(pnts.subarray(28, 28 + ftJson).toString()).POINTS_LENGTH;
    const glb = await TileFormatsMigration.convertPntsToGlb(pnts);
    const report = await validator.validateBytes(new Uint8Array(glb), { uri: f });
    assert.equal(report.issues.numErrors, 0, `${f}: ${JSON.stringify(report.issues.messages.slice(0, 3))}`);
    const json = JSON.parse(glb.subarray(20, 20 + glb.readUInt32LE(12)).toString());
    const pos = json.accessors[json.meshes[0].primitives[0].attributes.POSITION];
    assert.equal(pos.count, pointsLength, f);
    // Every batch-table property became a property attribute.
    const classes = json.extensions.EXT_structural_metadata.schema.classes;
    const names = Object.values(classes).flatMap((c) => Object.keys(c.properties));
    for (const p of ['GPS_TIME', 'INTENSITY', 'CLASSIFICATION', 'RETURN_NUMBER'])
      assert.ok(names.includes(p), `${f}: ${p} missing from ${names}`);
    ++tiles;
    points += pointsLength;
  }
  assert.ok(tiles > 5);
  assert.equal(points, 30000);
});
