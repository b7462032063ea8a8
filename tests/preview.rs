//! The preview picture on a real scan: `scanmill process` with the face-scan recipe writes
//! `<stem>.preview.png` beside the result, three panels of the configured size, each with a
//! drawn surface, and the report names it.

use std::process::Command;

mod common;

use common::DATA;
const RECIPE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/config/recipes/face-scan.toml");

#[test]
fn process_on_james_writes_a_preview_that_is_not_blank() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let report = tmp.path().join("report.json");
    let input = format!("{DATA}/textured/james_face_stereo_capture/james.obj");
    let run = Command::new(env!("CARGO_BIN_EXE_scanmill"))
        .args(["process", &input, "--recipe", RECIPE, "--out"])
        .arg(&out)
        .arg("--report")
        .arg(&report)
        .env("SCANMILL_LOG", "error")
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let png = out.join("james.preview.png");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(json["preview"]["file"]["path"], png.to_str().unwrap());
    assert_eq!(json["preview"]["figures"]["view"], "-z");
    assert!(json["preview"]["figures"]["max_percent"].as_f64().unwrap() > 0.0);

    let image = image::open(&png).unwrap().to_rgb8();
    assert_eq!(image.dimensions(), (3 * 512, 512));
    let background = *image.get_pixel(0, 256);
    for panel in 0..3 {
        let mut drawn = 0;
        let mut colours = std::collections::BTreeSet::new();
        for y in 0..512 {
            for x in panel * 512..(panel + 1) * 512 {
                let p = *image.get_pixel(x, y);
                if p != background {
                    drawn += 1;
                    colours.insert(p.0);
                }
            }
        }
        // The face fills a good part of each panel, with many colours (texture, shading).
        assert!(drawn > 512 * 512 / 5, "panel {panel}: {drawn} pixels drawn");
        assert!(
            colours.len() > 500,
            "panel {panel}: {} colours",
            colours.len()
        );
    }
}

#[test]
fn a_preview_that_cannot_be_drawn_does_not_fail_the_job() {
    use scanmill::recipe::Recipe;
    use scanmill::recipe::runner::NoProgress;
    let mut recipe = Recipe::from_toml(
        "[metrics]\nenabled = false\n[[step]]\nkind = \"normals\"\n",
        std::path::Path::new("r.toml"),
    )
    .unwrap();
    // Options the recipe parser would refuse: the renderer refuses them too.
    recipe.preview.size = 8;
    let tmp = tempfile::tempdir().unwrap();
    let input = format!("{DATA}/textured/james_face_stereo_capture/james.obj");
    let report = scanmill::process::process_scan_with_options(
        input.as_ref(),
        &scanmill::process::ProcessOptions::default(),
        &recipe,
        None,
        tmp.path(),
        &NoProgress,
    )
    .unwrap();
    assert!(report.preview.is_none());
    assert!(tmp.path().join("james.obj").is_file());
    assert!(!tmp.path().join("james.preview.png").exists());
}
