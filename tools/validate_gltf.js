#!/usr/bin/env node
// Validates glTF 2.0 files (.glb / .gltf) with the Khronos glTF validator (npm package `gltf-validator`,
// third_party_notes/tools.md). Usage: node tools/validate_gltf.js FILE... ; prints one summary line per file
// (errors, warnings, infos, hints) and the first messages; exit 1 when any file has an error, 2 when the validator
// package is not installed.
'use strict';
const fs = require('fs');
const path = require('path');
let validator;
try {
	validator = require('gltf-validator');
} catch (e) {
	try {
		const root = require('child_process').execSync('npm root -g').toString().trim();
		validator = require(path.join(root, 'gltf-validator'));
	} catch (e2) {
		console.error('validate_gltf: the gltf-validator package is not installed (npm install -g gltf-validator)');
		process.exit(2);
	}
}

async function validate(file) {
	const data = new Uint8Array(fs.readFileSync(file));
	const report = await validator.validateBytes(data, { uri: path.basename(file), maxIssues: 50 });
	const issues = report.issues;
	console.log(`${file}: ${issues.numErrors} errors, ${issues.numWarnings} warnings, ${issues.numInfos} infos, ` +
		`${issues.numHints} hints (gltf-validator ${report.validatorVersion})`);
	for (const m of issues.messages.slice(0, 10))
		console.log(`  ${['error', 'warning', 'info', 'hint'][m.severity]} ${m.code} ${m.pointer || ''}: ${m.message}`);
	return issues.numErrors;
}

(async () => {
	const files = process.argv.slice(2);
	if (files.length === 0) {
		console.error('usage: node tools/validate_gltf.js FILE...');
		process.exit(2);
	}
	let errors = 0;
	for (const f of files)
		errors += await validate(f);
	process.exit(errors > 0 ? 1 : 0);
})().catch((e) => {
	console.error('validate_gltf: ' + e.message);
	process.exit(1);
});
