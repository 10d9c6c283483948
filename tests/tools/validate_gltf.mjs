// Validates glTF/GLB files with the Khronos glTF Validator (npm package `gltf-validator`).
// Usage: node validate_gltf.mjs FILE...
// The validator is loaded from $KG_GLTF_VALIDATOR_DIR (a folder where `npm install
// gltf-validator` was run), else where .ci/run installs it:
// ${KG_TOOLS_DIR:-$HOME/.cache/kinegraph-tools}/khronos-validator.
// Prints "FILE: errors=N warnings=M" per file (plus each error) and exits 1 if any file has
// errors, 2 on bad usage or a missing validator.
import { createRequire } from 'node:module';
import { readFileSync } from 'node:fs';
import { join } from 'node:path';
import { homedir } from 'node:os';

const tools = process.env.KG_TOOLS_DIR || join(homedir(), '.cache', 'kinegraph-tools');
const dir = process.env.KG_GLTF_VALIDATOR_DIR || join(tools, 'khronos-validator');
let validator;
try {
  validator = createRequire(join(dir, 'package.json'))('gltf-validator');
} catch (e) {
  console.error(`gltf-validator not found under ${dir}: ${e.message}`);
  process.exit(2);
}
const files = process.argv.slice(2);
if (files.length === 0) {
  console.error('usage: node validate_gltf.mjs FILE...');
  process.exit(2);
}
let failed = false;
for (const file of files) {
  const report = await validator.validateBytes(new Uint8Array(readFileSync(file)), {
    maxIssues: 100,
    externalResourceFunction: () => Promise.reject(new Error('external resources are not loaded')),
  });
  const { numErrors, numWarnings, messages } = report.issues;
  console.log(`${file}: errors=${numErrors} warnings=${numWarnings}`);
  for (const m of messages) {
    if (m.severity <= 1) console.log(`  ${m.severity === 0 ? 'error' : 'warning'} ${m.code} ${m.pointer ?? ''}: ${m.message}`);
  }
  if (numErrors > 0) failed = true;
}
process.exit(failed ? 1 : 0);
