// Validates a .glb with Khronos' glTF-Validator (npm `gltf-validator`, from .tools/node_modules via NODE_PATH)
// and prints its report as JSON.
"use strict";
const fs = require("fs");
const validator = require("gltf-validator");
const file = process.argv[2];
validator
  .validateBytes(new Uint8Array(fs.readFileSync(file)), { maxIssues: 100 })
  .then((report) => console.log(JSON.stringify(report)))
  .catch((e) => {
    console.error(`gltf-validator failed on ${file}: ${e}`);
    process.exit(2);
  });
