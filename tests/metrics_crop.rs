//! Crop and metrics on the real scans: james (textured face, open borders, a UV seam) and
//! the three GGG SfM photogrammetry meshes (many holes, non-manifold edges).

mod common;

use glam::DVec3;
use scanmill::geom::segment_distance;
use scanmill::mesh::{InputLimits, Mesh, Topology};
use scanmill::metrics::{self, MetricsOptions, TextureDeviation};
use scanmill::ops::crop::{CropMode, CropParams, crop};
use scanmill::recipe::Recipe;
use scanmill::recipe::runner::NoProgress;
use std::collections::HashSet;
use std::path::Path;

const SCANS: [&str; 4] = [
    "textured/james_face_stereo_capture/james.obj",
    "raw_photogrammetry/ggg_sfm_Angel_decimated.ply",
    "raw_photogrammetry/ggg_sfm_birdBath_decimated.ply",
    "raw_photogrammetry/ggg_sfm_blackVase_decimated.ply",
];

use common::{DATA, scan};

/// The middle of the bounding box: 15 % off each side in x and y, 5 % in z.
fn middle_box(mesh: &Mesh) -> (DVec3, DVec3) {
    let (lo, hi) = mesh.bounding_box().unwrap();
    let margin = (hi - lo) * DVec3::new(0.15, 0.15, 0.05);
    (lo + margin, hi - margin)
}

fn params(lo: DVec3, hi: DVec3, mode: CropMode) -> CropParams {
    CropParams {
        min: Some(lo.to_array()),
        max: Some(hi.to_array()),
        mode,
        ..Default::default()
    }
}

fn on_box_plane(p: DVec3, lo: DVec3, hi: DVec3) -> bool {
    (0..3).any(|a| (p[a] - lo[a]).abs() <= 1e-9 || (p[a] - hi[a]).abs() <= 1e-9)
}

#[test]
fn crop_each_mode_on_real_scans() {
    for rel in SCANS {
        let input = scan(rel);
        let before = Topology::new(&input).counts();
        let (lo, hi) = middle_box(&input);
        let mut faces = Vec::new();
        for mode in [
            CropMode::AnyCornerOutside,
            CropMode::AllCornersOutside,
            CropMode::Clip,
        ] {
            let mut mesh = input.clone();
            let report = crop(&mut mesh, &params(lo, hi, mode)).unwrap();
            mesh.check_invariants().unwrap();
            let after = Topology::new(&mesh).counts();
            assert_eq!(report.faces_after, mesh.triangles.len(), "{rel} {mode:?}");
            assert_eq!(
                report.faces_kept + report.faces_clipped + report.faces_removed,
                input.triangles.len()
            );
            assert!(
                report.faces_removed > 0 && report.faces_kept > 0,
                "{rel} {mode:?}"
            );
            assert!(
                after.non_manifold_edges <= before.non_manifold_edges,
                "{rel} {mode:?}"
            );
            assert_eq!(mesh.triangle_origins.len(), mesh.triangles.len());
            assert_eq!(
                mesh.triangle_materials.len(),
                if input.triangle_materials.is_empty() {
                    0
                } else {
                    mesh.triangles.len()
                }
            );
            // Nothing unused is left behind.
            assert_eq!(mesh.compact(), Default::default(), "{rel} {mode:?}");
            if mode != CropMode::AllCornersOutside {
                assert!(
                    mesh.positions
                        .iter()
                        .all(|p| p.cmpge(lo).all() && p.cmple(hi).all())
                );
            }
            faces.push(mesh.triangles.len());
            eprintln!(
                "{rel} {mode:?}: faces {} -> {} (kept {}, clipped {}, removed {}); boundary edges {} -> {}, loops {} -> {}, components {} -> {}, texture seams {} -> {}",
                input.triangles.len(),
                mesh.triangles.len(),
                report.faces_kept,
                report.faces_clipped,
                report.faces_removed,
                before.boundary_edges,
                after.boundary_edges,
                before.boundary_loops,
                after.boundary_loops,
                before.components,
                after.components,
                before.texture_seam_edges,
                after.texture_seam_edges
            );
            if mode == CropMode::Clip {
                check_clip_border(rel, &input, &mesh, lo, hi);
            }
        }
        // any-corner removes the most, all-corners the least, clip keeps pieces of both.
        assert!(faces[0] < faces[1], "{rel}: {faces:?}");
        assert!(faces[0] <= faces[2], "{rel}: {faces:?}");
    }
}

/// Every vertex the clip made lies on a box plane; every result boundary edge is either on
/// a box plane (the new, straight border) or on an input boundary edge (no crack opened).
fn check_clip_border(rel: &str, input: &Mesh, mesh: &Mesh, lo: DVec3, hi: DVec3) {
    let key = |p: DVec3| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
    let old: HashSet<[u64; 3]> = input.positions.iter().map(|&p| key(p)).collect();
    for p in &mesh.positions {
        if !old.contains(&key(*p)) {
            assert!(
                on_box_plane(*p, lo, hi),
                "{rel}: new vertex {p} off the box"
            );
        }
    }
    let input_topology = Topology::new(input);
    let input_boundary: Vec<[DVec3; 2]> = input_topology
        .boundary_edges()
        .map(|e| {
            input_topology
                .edge_vertices(e)
                .map(|v| input.positions[v as usize])
        })
        .collect();
    let topology = Topology::new(mesh);
    for e in topology.boundary_edges() {
        let [a, b] = topology
            .edge_vertices(e)
            .map(|v| mesh.positions[v as usize]);
        let on_plane = (0..3).any(|ax| {
            [lo[ax], hi[ax]]
                .iter()
                .any(|&v| (a[ax] - v).abs() <= 1e-9 && (b[ax] - v).abs() <= 1e-9)
        });
        let m = (a + b) * 0.5;
        let on_old_border = input_boundary
            .iter()
            .any(|[p, q]| segment_distance(m, *p, *q) <= 1e-9);
        assert!(on_plane || on_old_border, "{rel}: crack at {a} - {b}");
    }
}

#[test]
fn report_carries_topology_before_and_after_and_texture_is_unchanged_by_crop() {
    let input = scan(SCANS[0]);
    let (lo, hi) = middle_box(&input);
    let text = format!(
        "[metrics]\nsamples = 20000\n\n[[step]]\nkind = \"crop\"\nmin = {:?}\nmax = {:?}\nmode = \"clip\"\nmetrics = true\n",
        lo.to_array(),
        hi.to_array()
    );
    let mut mesh = input.clone();
    let out = common::run_recipe_text(&text, &mut mesh, &InputLimits::default());
    let step = out.steps[0].metrics.as_ref().unwrap();
    let topo = &step["topology"];
    assert_eq!(topo["before"]["boundary_edges"], 552);
    assert_eq!(topo["before"]["texture_seam_edges"], 281);
    assert!(topo["after"]["boundary_edges"].as_u64().unwrap() > 0);
    assert!(topo["after"]["components"].as_u64().unwrap() >= 1);
    // The clipped surface is part of the input: samples on it are on the input, and the
    // texture it shows is the input's (interpolated texture coordinates).
    let forward = &step["distance"]["result_to_reference"];
    assert!(forward["max"].as_f64().unwrap() < 1e-9, "{forward}");
    assert_eq!(step["texture"]["status"], "measured", "{}", step["texture"]);
    assert!(
        step["texture"]["rms"].as_f64().unwrap() < 1e-6,
        "{}",
        step["texture"]
    );
    assert_eq!(step["normals"]["flipped_faces"], 0);
    // The final metrics compare with the cropped input: nothing else happened.
    assert_eq!(out.metrics["reference"], "input-after-crop");
    assert!(out.metrics["distance"]["max"].as_f64().unwrap() < 1e-9);
}

#[test]
fn noisy_copy_of_james_moves_every_metric() {
    let input = scan(SCANS[0]);
    let (noisy, noise) = metrics::noise::noisy_copy(&input, &Default::default());
    let m = metrics::compare(
        &noisy,
        &input,
        &MetricsOptions {
            samples: 20_000,
            ..Default::default()
        },
    )
    .unwrap();
    eprintln!(
        "james vs noisy copy (σ = {:.4}): {}",
        noise.sigma,
        serde_json::to_string(&m).unwrap()
    );
    // σ along the normals: the vertices move by |N(0, σ²)|, mean σ·sqrt(2/π); the surface
    // between them moves less.
    let v = m.vertex_deviation.unwrap();
    let expected = noise.sigma * (2.0 / std::f64::consts::PI).sqrt();
    assert!(
        (v.abs_mean / expected - 1.0).abs() < 0.05,
        "{v:?} vs {expected}"
    );
    assert!(m.distance.mean > 0.2 * noise.sigma && m.distance.mean < noise.sigma);
    assert!(m.normals.mean > 0.05 && m.normals.flipped_faces < input.triangles.len() / 20);
    assert!(matches!(m.texture, TextureDeviation::Measured { rms, .. } if rms > 0.1));
    assert_eq!(m.topology.cracks, 0);
}

#[test]
fn process_report_carries_final_metrics() {
    let out = tempfile::tempdir().unwrap();
    let recipe = Recipe::from_toml(
        "[metrics]\nsamples = 20000\n\n[[step]]\nkind = \"normals\"\n",
        Path::new("normals.toml"),
    )
    .unwrap();
    let report = scanmill::process::process_scan_with_options(
        &Path::new(DATA).join(SCANS[0]),
        &scanmill::process::ProcessOptions::default(),
        &recipe,
        None,
        out.path(),
        &NoProgress,
    )
    .unwrap();
    let m = serde_json::to_value(&report).unwrap()["metrics"].clone();
    assert_eq!(m["reference"], "input");
    // Normals move no vertex: the surface, its texture and its topology are unchanged.
    assert!(
        m["distance"]["max"].as_f64().unwrap() < 1e-9,
        "{}",
        m["distance"]
    );
    assert_eq!(m["texture"]["status"], "measured");
    assert!(m["texture"]["rms"].as_f64().unwrap() < 1e-6);
    assert_eq!(m["normals"]["correspondence"], "same-faces");
    assert_eq!(m["topology"]["before"]["boundary_edges"], 552);
    assert_eq!(m["topology"]["after"]["boundary_edges"], 552);
    assert_eq!(m["topology"]["cracks"], 0);
    assert_eq!(m["volume"]["change_percent"], serde_json::Value::Null);
}
