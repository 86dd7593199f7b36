#!/usr/bin/env node
// Validates a glTF/GLB file with the Khronos glTF-Validator (npm package gltf-validator) and
// prints its counts and messages as one JSON object; exit status 1 when it reports an error
// or a warning, 2 when it cannot run.
//
//   npm install --prefix tools gltf-validator     # once (tools/node_modules is git-ignored)
//   node tools/gltf_validate.js asset.glb
'use strict';
const fs = require('fs');
const path = require('path');
let validator;
try {
  validator = require(path.join(__dirname, 'node_modules', 'gltf-validator'));
} catch (e) {
  validator = require('gltf-validator');
}
const file = process.argv[2];
if (!file) {
  console.error('usage: node tools/gltf_validate.js FILE.glb');
  process.exit(2);
}
const bytes = new Uint8Array(fs.readFileSync(file));
validator
  .validateBytes(bytes, { uri: path.basename(file), maxIssues: 200 })
  .then((report) => {
    const i = report.issues;
    console.log(JSON.stringify({
      validator: report.validatorVersion,
      errors: i.numErrors,
      warnings: i.numWarnings,
      infos: i.numInfos,
      hints: i.numHints,
      messages: i.messages.slice(0, 30),
    }));
    process.exit(i.numErrors > 0 || i.numWarnings > 0 ? 1 : 0);
  }, (e) => {
    console.error(String(e));
    process.exit(2);
  });
