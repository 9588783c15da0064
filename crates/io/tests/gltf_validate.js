// Validates a glTF or GLB file with the Khronos glTF validator (npm `gltf-validator`, found
// through NODE_PATH) and prints its issue counts and messages as one JSON line.
// Usage: node gltf_validate.js FILE
const fs = require("fs");
const path = require("path");
const validator = require("gltf-validator");

const file = process.argv[2];
validator
  .validateBytes(new Uint8Array(fs.readFileSync(file)), {
    uri: path.basename(file),
    maxIssues: 100,
  })
  .then((report) => {
    const issues = report.issues;
    console.log(
      JSON.stringify({
        errors: issues.numErrors,
        warnings: issues.numWarnings,
        infos: issues.numInfos,
        hints: issues.numHints,
        messages: issues.messages.map((m) => `${m.severity} ${m.code} ${m.pointer || ""}: ${m.message}`),
        animations: report.info ? report.info.animationCount : null,
        nodes: report.info ? report.info.nodeCount : null,
      })
    );
  })
  .catch((e) => {
    console.error(`validator failed: ${e}`);
    process.exit(1);
  });
