// Validates glTF/GLB files with the Khronos glTF-Validator (npm package
// gltf-validator, pinned in .ci/package.json).
//
//   npm ci --prefix .ci && node .ci/validate_gltf.mjs out/a.glb out/b.glb
//
// Prints each file's counts and messages; exits 1 if any file has an error or
// a warning (or cannot be read or validated), 0 otherwise. Infos and hints are
// printed but do not fail.
import fs from "node:fs";
import path from "node:path";
import { createRequire } from "node:module";

const require = createRequire(import.meta.url);
const validator = require("gltf-validator");

const SEVERITY = ["error", "warning", "info", "hint"];

const files = process.argv.slice(2);
if (files.length === 0) {
  console.error("usage: node .ci/validate_gltf.mjs FILE.glb...");
  process.exit(2);
}

let failed = false;
for (const file of files) {
  let bytes;
  try {
    bytes = new Uint8Array(fs.readFileSync(file));
  } catch (e) {
    console.error(`${file}: cannot read: ${e.message}`);
    failed = true;
    continue;
  }
  let report;
  try {
    report = await validator.validateBytes(bytes, {
      uri: file,
      maxIssues: 0, // no limit
      externalResourceFunction: (uri) =>
        new Promise((resolve, reject) => {
          const resolved = path.resolve(path.dirname(file), decodeURIComponent(uri));
          fs.readFile(resolved, (err, data) => (err ? reject(err.toString()) : resolve(new Uint8Array(data))));
        }),
    });
  } catch (e) {
    console.error(`${file}: the validator could not process it: ${e}`);
    failed = true;
    continue;
  }
  const issues = report.issues;
  const v = report.validatorVersion ?? "?";
  console.log(
    `${file}: numErrors=${issues.numErrors} numWarnings=${issues.numWarnings} ` +
      `numInfos=${issues.numInfos} numHints=${issues.numHints} (glTF-Validator ${v})`,
  );
  for (const m of issues.messages) {
    const where = m.pointer ? ` at ${m.pointer}` : m.offset !== undefined ? ` at byte ${m.offset}` : "";
    console.log(`  ${SEVERITY[m.severity] ?? m.severity} ${m.code}${where}: ${m.message}`);
  }
  if (issues.numErrors > 0 || issues.numWarnings > 0) {
    failed = true;
  }
}
if (failed) {
  console.error("glTF validation failed");
  process.exit(1);
}
console.log(`glTF validation passed: ${files.length} file(s)`);
