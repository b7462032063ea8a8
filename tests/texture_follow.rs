//! The texture stays on the surface: when `relax` and `fair` slide vertices along it
//! (src/ops/texture_follow.rs, on james_face_stereo_capture), and when `seam_fix` repairs a
//! decimation inside one chart (src/ops/seam_fix.rs, on facefuns).

mod common;

use scanmill::mesh::{InputLimits, LoadOptions};

const JAMES: &str = "textured/james_face_stereo_capture/james.obj";

fn texture_deviation_after(step: &str) -> (f64, serde_json::Value) {
    let mut mesh = common::scan(JAMES);
    let text = format!("[metrics]\nsamples = 20000\n[[step]]\nkind = \"{step}\"\n");
    let out = common::run_recipe_text(&text, &mut mesh, &InputLimits::default());
    let topology = &out.metrics["topology"];
    // Seams and wedges are untouched: only texture coordinate values change.
    assert_eq!(
        topology["before"]["texture_seam_edges"],
        topology["after"]["texture_seam_edges"]
    );
    assert_eq!(topology["before"]["wedges"], topology["after"]["wedges"]);
    (
        out.metrics["texture"]["mean"].as_f64().unwrap(),
        out.steps[0].figures["texture_follow"].clone(),
    )
}

#[test]
fn relax_and_fair_keep_the_photo_on_the_face() {
    // Without following, relax left a mean colour deviation of 6.0 and fair 7.5 (0–255).
    for step in ["relax", "fair"] {
        let (deviation, follow) = texture_deviation_after(step);
        assert!(deviation < 2.0, "{step}: texture deviation {deviation}");
        assert!(follow["corners"].as_u64().unwrap() > 6000, "{follow}");
        assert!(follow["mean_shift"].as_f64().unwrap() > 0.0, "{follow}");
    }
}

#[test]
fn relax_then_fair_carry_the_texture_once_from_the_scanned_surface() {
    let mut mesh = common::scan(JAMES);
    let text = "[metrics]\nsamples = 20000\n[[step]]\nkind = \"relax\"\n[[step]]\nkind = \"fair\"\n[[step]]\nkind = \"normals\"\n";
    let out = common::run_recipe_text(text, &mut mesh, &InputLimits::default());
    // One read-back, after the last vertex-moving step of the run.
    assert!(out.steps[0].figures.get("texture_follow").is_none());
    let follow = &out.steps[1].figures["texture_follow"];
    assert!(follow["corners"].as_u64().unwrap() > 6000, "{follow}");
    assert!(out.steps[2].figures.get("texture_follow").is_none());
    let deviation = out.metrics["texture"]["mean"].as_f64().unwrap();
    assert!(
        deviation < 2.0,
        "relax + fair: texture deviation {deviation}"
    );
}

#[test]
fn seam_fix_cuts_no_seams_into_a_seamless_face() {
    // facefuns has one texture chart and no seams. The thesis' per-triangle repair gave
    // its decimation 12,763 seam edges; corners inside one chart are now fixed in place.
    let options = LoadOptions {
        texture_override: Some(common::data("textured/facefuns_di3d_face/example.png")),
        ..LoadOptions::default()
    };
    let mut mesh = common::scan_with("textured/facefuns_di3d_face/example.obj", &options);
    let text = "[metrics]\nsamples = 20000\n[[step]]\nkind = \"decimate\"\ntarget_faces = 26000\n[[step]]\nkind = \"seam_fix\"\n";
    let out = common::run_recipe_text(text, &mut mesh, &InputLimits::default());
    let fix = &out.steps[1].figures;
    assert!(fix["repaired"].as_u64().unwrap() > 0, "{fix}");
    assert_eq!(fix["corners_split"], 0, "{fix}");
    assert_eq!(out.metrics["topology"]["after"]["texture_seam_edges"], 0);
    assert_eq!(out.metrics["topology"]["cracks"], 0);
}

#[test]
fn the_run_decodes_textures_within_the_limits_it_is_given() {
    // The metrics and the preview decode the photo again after the load; they must hold
    // the job's limits, not the defaults. James's photo has more pixels than this allowance.
    let text = "[metrics]\nsamples = 20000\n[[step]]\nkind = \"normals\"\n";
    let tight = InputLimits {
        max_texture_pixels: 1000,
        ..InputLimits::default()
    };
    let measured = |limits: &InputLimits| {
        let mut mesh = common::scan(JAMES);
        let out = common::run_recipe_text(text, &mut mesh, limits);
        out.metrics["texture"].clone()
    };
    let within_defaults = measured(&InputLimits::default());
    assert!(within_defaults["mean"].is_number(), "{within_defaults}");
    let within_tight = measured(&tight);
    let reason = within_tight["reason"].as_str().unwrap_or_default();
    assert!(reason.contains("pixels"), "{within_tight}");
}
