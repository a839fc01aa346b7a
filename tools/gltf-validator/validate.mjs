#!/usr/bin/env node
// Validates glTF 2.0 / GLB files with the Khronos glTF validator (npm package gltf-validator).
//
//   node tools/gltf-validator/validate.mjs FILE...
//
// Prints one summary line per file ("FILE: E errors, W warnings, I infos, H hints") followed by every
// error and warning (code, JSON pointer, message). Exit status: 0 when no file has an error, 1 when
// some file has at least one error, 2 when a file cannot be read or validated at all. Warnings,
// infos and hints never fail. External resources (.bin buffers, images) are read relative to the
// file. Install once with `npm ci` in this folder (scripts/setup.sh does it).
import { readFile } from 'node:fs/promises';
import path from 'node:path';
import * as validator from 'gltf-validator';

async function validateFile(file) {
  const bytes = await readFile(file);
  const report = await validator.validateBytes(new Uint8Array(bytes), {
    uri: path.basename(file),
    maxIssues: 0,
    writeTimestamp: false,
    externalResourceFunction: async (uri) =>
      new Uint8Array(await readFile(path.resolve(path.dirname(file), decodeURIComponent(uri)))),
  });
  const issues = report.issues;
  console.log(`${file}: ${issues.numErrors} errors, ${issues.numWarnings} warnings, ` +
              `${issues.numInfos} infos, ${issues.numHints} hints (glTF validator ${validator.version()})`);
  const severityNames = ['error', 'warning'];
  for (const message of issues.messages) {
    if (message.severity > 1) continue;
    const where = message.pointer !== undefined ? ` at ${message.pointer}` : '';
    console.log(`  ${severityNames[message.severity]} ${message.code}${where}: ${message.message}`);
  }
  return issues.numErrors;
}

const files = process.argv.slice(2);
if (files.length === 0) {
  console.error('usage: node validate.mjs FILE...');
  process.exit(2);
}
let status = 0;
for (const file of files) {
  try {
    if ((await validateFile(file)) > 0) status = Math.max(status, 1);
  } catch (error) {
    console.log(`${file}: cannot validate: ${error}`);
    status = 2;
  }
}
process.exit(status);
