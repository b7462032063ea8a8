// Runs the Khronos glTF validator (npm package `gltf-validator`) on one file and prints its
// issue summary as JSON. Exit 0 when the report has no errors, 1 when it has, 2 when the
// validator cannot run. `.ci/run` installs the package globally; NODE_PATH finds it.
const fs = require("fs");
let validator;
try {
    validator = require("gltf-validator");
} catch (e) {
    console.error("gltf-validator is not installed (npm install -g gltf-validator): " + e.message);
    process.exit(2);
}
const file = process.argv[2];
validator
    .validateBytes(new Uint8Array(fs.readFileSync(file)), { maxIssues: 50 })
    .then((report) => {
        console.log(JSON.stringify({
            numErrors: report.issues.numErrors,
            numWarnings: report.issues.numWarnings,
            numInfos: report.issues.numInfos,
            messages: report.issues.messages.slice(0, 20),
        }));
        process.exit(report.issues.numErrors > 0 ? 1 : 0);
    })
    .catch((e) => {
        console.error("validator failed: " + e);
        process.exit(2);
    });
