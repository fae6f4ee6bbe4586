// Validates glb files with the Khronos glTF-Validator (npm gltf-validator): node validate_glb.js NODE_PREFIX FILES...
const v = require(process.argv[2] + '/node_modules/gltf-validator');
const fs = require('fs');
(async () => {
  let errors = 0;
  for (const f of process.argv.slice(3)) {
    const r = await v.validateBytes(new Uint8Array(fs.readFileSync(f)), {uri: f});
    const i = r.issues;
    if (i.numErrors || i.numWarnings) console.log(f, JSON.stringify(i.messages.slice(0, 5)));
    errors += i.numErrors;
  }
  console.log('errors', errors);
  process.exit(errors ? 1 : 0);
})();
