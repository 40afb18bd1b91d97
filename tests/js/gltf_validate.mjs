// Validates a glTF (.gltf or .glb) with the Khronos glTF-Validator and prints its report's
// issue counts and messages as JSON. External resources (buffers, images) beside the file are read.
// Usage: node gltf_validate.mjs FILE
import { readFileSync } from 'node:fs';
import { dirname, join } from 'node:path';
import validator from 'gltf-validator';

const file = process.argv[2];
const report = await validator.validateBytes(new Uint8Array(readFileSync(file)), {
  uri: file,
  maxIssues: 0,
  externalResourceFunction: (uri) =>
    new Promise((resolve, reject) => {
      try {
        resolve(new Uint8Array(readFileSync(join(dirname(file), decodeURIComponent(uri)))));
      } catch (e) {
        reject(e.toString());
      }
    }),
});
const i = report.issues;
process.stdout.write(JSON.stringify({
  validator: report.validatorVersion, errors: i.numErrors, warnings: i.numWarnings, infos: i.numInfos,
  hints: i.numHints, messages: i.messages.map((m) => ({ code: m.code, severity: m.severity, pointer: m.pointer, message: m.message })),
}) + '\n');
