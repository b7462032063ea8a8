//! The daemon writing several formats for one scan (issue #28): a recipe with
//! `format = ["obj", "glb"]` publishes the OBJ (with its MTL and texture) and the GLB together
//! in one folder; the sidecar, the report, `show` and `history` list both with their hashes.

mod common;
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

/// The GLB `scanmill process` makes of james, taken apart into a `.gltf` scan set as
/// photogrammetry tools write it: `james.gltf` (JSON) naming `james.bin` (the GLB's binary
/// chunk) and `james.jpg` (the photo) beside it. Returns the three files' contents.
fn james_as_gltf_set(work: &Path) -> [(&'static str, Vec<u8>); 3] {
    let recipe = work.join("glb.toml");
    std::fs::write(
        &recipe,
        "[output]\nformat = \"glb\"\n\n[[step]]\nkind = \"normals\"\n",
    )
    .unwrap();
    let out = work.join("glb");
    let status = std::process::Command::new(BIN)
        .args(["process", "--recipe"])
        .arg(&recipe)
        .arg("--out")
        .arg(&out)
        .arg(james_dir().join("james.obj"))
        .status()
        .unwrap();
    assert!(status.success());
    let glb = std::fs::read(out.join("james.glb")).unwrap();
    let chunk = |at: usize| {
        let len = u32::from_le_bytes(glb[at..at + 4].try_into().unwrap()) as usize;
        (&glb[at + 8..at + 8 + len], at + 8 + len)
    };
    let (json, next) = chunk(12);
    let (bin, _) = chunk(next);
    let mut doc: serde_json::Value = serde_json::from_slice(json).unwrap();
    doc["buffers"][0]["uri"] = "james.bin".into();
    for image in doc["images"].as_array_mut().unwrap() {
        let map = image.as_object_mut().unwrap();
        map.remove("bufferView");
        map.remove("mimeType");
        map.insert("uri".into(), "james.jpg".into());
    }
    [
        ("james.gltf", serde_json::to_vec(&doc).unwrap()),
        ("james.bin", bin.to_vec()),
        (
            "james.jpg",
            std::fs::read(james_dir().join("james.jpg")).unwrap(),
        ),
    ]
}

#[test]
fn a_gltf_scan_waits_for_its_buffer_and_image_then_runs_with_them_as_members() {
    let lab = Lab::new(0.3, "incomplete_report_secs = 0.5");
    let [gltf, bin, jpg] = james_as_gltf_set(lab.dir.path());
    // A .gltf naming a buffer outside the watched folder: refused, never read.
    std::fs::write(lab.dir.path().join("outside.bin"), &bin.1).unwrap();
    let evil = String::from_utf8(gltf.1.clone())
        .unwrap()
        .replace("\"james.bin\"", "\"../../outside.bin\"");
    let _d = KillOnDrop(lab.start(&[]));
    let scan = lab.inbox().join("g");
    std::fs::create_dir_all(lab.inbox().join("h")).unwrap();
    std::fs::write(lab.inbox().join("h/evil.gltf"), evil).unwrap();
    std::fs::create_dir_all(&scan).unwrap();
    std::fs::write(scan.join(gltf.0), &gltf.1).unwrap();

    let waiting = |name: &str| {
        lab.jobs_with(&["--status", "waiting"])
            .into_iter()
            .find(|w| w["input"].as_str().unwrap_or("").ends_with(name))
    };
    let mut row = None;
    assert!(
        wait_for(60, || {
            row = waiting("g/james.gltf");
            row.is_some()
        }),
        "{}",
        lab.logs()
    );
    let reason = row.unwrap()["error"].as_str().unwrap().to_string();
    assert!(
        reason.contains("james.bin") && reason.contains("james.jpg"),
        "{reason}"
    );
    assert_eq!(lab.jobs().len(), 0, "no job before the set is complete");

    std::fs::write(scan.join(bin.0), &bin.1).unwrap();
    std::fs::write(scan.join(jpg.0), &jpg.1).unwrap();
    assert!(
        wait_for(90, || lab.count_state("done") == 1),
        "{:#?}\n{}",
        lab.jobs(),
        lab.logs()
    );
    let job = &lab.jobs()[0];
    let shown = lab.show(job["id"].as_i64().unwrap());
    let inputs: Vec<(String, String)> = shown["inputs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|i| {
            (
                i["rel_path"].as_str().unwrap().to_string(),
                i["role"].as_str().unwrap().to_string(),
            )
        })
        .collect();
    let expected = [
        ("g/james.gltf", "mesh"),
        ("g/james.bin", "buffer"),
        ("g/james.jpg", "texture"),
    ]
    .map(|(p, r)| (p.to_string(), r.to_string()));
    assert_eq!(inputs, expected);
    let dir = Path::new(job["output"].as_str().unwrap()).to_path_buf();
    assert!(dir.join("james.obj").is_file() && dir.join("james.jpg").is_file());

    let evil = waiting("h/evil.gltf").expect("the outside reference is recorded as waiting");
    let reason = evil["error"].as_str().unwrap();
    assert!(reason.contains("outside the watched folder"), "{reason}");
    assert_eq!(lab.jobs().len(), 1, "{:#?}", lab.jobs());
}
