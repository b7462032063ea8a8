//! The daemon writing several formats for one scan (issue #28): a recipe with
//! `format = ["obj", "glb"]` publishes the OBJ (with its MTL and texture) and the GLB together
//! in one folder; the sidecar, the report, `show` and `history` list both with their hashes.

mod daemon_support;

use daemon_support::*;
use sha2::{Digest, Sha256};
use std::path::Path;

fn sha256_hex(bytes: &[u8]) -> String {
    hex::encode(Sha256::digest(bytes))
}

#[test]
fn obj_and_glb_are_published_together_and_recorded() {
    let lab = Lab::new(0.3, "");
    std::fs::write(
        lab.dir.path().join("recipe.toml"),
        "[output]\nformat = [\"obj\", \"glb\"]\n\n[[step]]\nkind = \"normals\"\n",
    )
    .unwrap();
    let _d = KillOnDrop(lab.start(&[]));
    copy_james(&lab.inbox().join("s"));
    assert!(
        wait_for(90, || lab.count_state("done") == 1),
        "{:#?}\n{}",
        lab.jobs(),
        lab.logs()
    );

    let job = &lab.jobs()[0];
    let dir = Path::new(job["output"].as_str().unwrap()).to_path_buf();
    let names: Vec<&str> = job["outputs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        ["james.glb", "james.jpg", "james.mtl", "james.obj"],
        "{job}"
    );

    // `show`: every output with the hash of the published file.
    let shown = lab.show(job["id"].as_i64().unwrap());
    let outputs = shown["outputs"].as_array().unwrap();
    for name in ["james.obj", "james.glb"] {
        let row = outputs
            .iter()
            .find(|o| o["path"].as_str().unwrap().ends_with(name))
            .unwrap_or_else(|| panic!("{name} not in {outputs:?}"));
        let bytes = std::fs::read(dir.join(name)).unwrap();
        assert_eq!(row["sha256"], sha256_hex(&bytes), "{name}");
        assert_eq!(row["bytes"], bytes.len(), "{name}");
    }
    // The GLB carries the texture inside, byte for byte.
    let glb = std::fs::read(dir.join("james.glb")).unwrap();
    let jpg = std::fs::read(james_dir().join("james.jpg")).unwrap();
    assert!(
        glb.windows(jpg.len()).any(|w| w == jpg.as_slice()),
        "texture not embedded as it came"
    );

    // The sidecar's report lists both, with hashes.
    let sidecar: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("james.scanmill.json")).unwrap()).unwrap();
    let files = sidecar["report"]["output"]["files"].as_array().unwrap();
    for name in ["james.obj", "james.glb"] {
        let f = files
            .iter()
            .find(|f| f["path"].as_str().unwrap().ends_with(name))
            .unwrap_or_else(|| panic!("{name} not in {files:?}"));
        assert_eq!(
            f["sha256"],
            sha256_hex(&std::fs::read(dir.join(name)).unwrap())
        );
    }

    // `history` in text names both.
    let (code, text, err) = lab.cli(&["history"]);
    assert_eq!(code, 0, "{err}");
    assert!(
        text.contains("james.glb") && text.contains("james.obj"),
        "{text}"
    );
}
