// Validates splat glb files (KHR_gaussian_splatting) with the Khronos glTF-Validator (npm
// gltf-validator): node validate_splat_glb.js NODE_PREFIX FILES...
// The validator does not know the splat extensions, so it reports what follows from that alone
// (as it does for cesium-native's own splat glb): the extensions as unsupported, their
// "KHR_gaussian_splatting:" attribute semantics as invalid names, and the SPZ buffer view (which
// only the compression extension names) as unused. Those are accepted; any other error or
// warning fails.
const v = require(process.argv[2] + '/node_modules/gltf-validator');
const fs = require('fs');
const splatExtensions = ['KHR_gaussian_splatting', 'KHR_gaussian_splatting_compression_spz_2'];
function expected(m, gltf) {
  if (m.code === 'MESH_PRIMITIVE_INVALID_ATTRIBUTE')
    return /\/attributes\/KHR_gaussian_splatting:/.test(m.pointer);
  if (m.code === 'UNSUPPORTED_EXTENSION')
    return splatExtensions.some((e) => m.message.includes(`'${e}'`));
  if (m.code === 'UNUSED_OBJECT') {
    const view = /^\/bufferViews\/(\d+)$/.exec(m.pointer);
    const spz = gltf.meshes[0].primitives[0].extensions?.KHR_gaussian_splatting?.extensions
      ?.KHR_gaussian_splatting_compression_spz_2;
    return view !== null && spz !== undefined && spz.bufferView === Number(view[1]);
  }
  return false;
}
(async () => {
  let failures = 0;
  for (const f of process.argv.slice(3)) {
    const bytes = new Uint8Array(fs.readFileSync(f));
    const jsonLength = new DataView(bytes.buffer).getUint32(12, true);
    const gltf = JSON.parse(new TextDecoder().decode(bytes.subarray(20, 20 + jsonLength)));
    const r = await v.validateBytes(bytes, { uri: f, maxIssues: 0 });
    const bad = r.issues.messages.filter((m) => m.severity <= 1 && !expected(m, gltf));
    if (bad.length) console.log(f, JSON.stringify(bad.slice(0, 5)));
    failures += bad.length;
  }
  console.log('unexpected errors and warnings', failures);
  process.exit(failures ? 1 : 0);
})();
