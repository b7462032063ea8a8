//! Fairing on the real scans in ../shared/data.
//!
//! Always run: surfaces with boundary (james, the ggg_sfm meshes): borders come out
//! smooth, holes neither close nor grow, no triangle is turned over; and one noise-protocol
//! scan (the bunny) against Taubin smoothing.
//!
//! `#[ignore]`d, for the figures (`cargo test --release --test fair_scans -- --ignored
//! --nocapture`): the noise protocol on the four scans of the issue, against Taubin, with
//! times; and the speed on a 200k-vertex scan.

mod common;

use glam::DVec3;
use scanmill::mesh::{Mesh, Topology};
use scanmill::metrics::distance::surface_distance;
use scanmill::metrics::noise::{NoiseOptions, noisy_copy};
use scanmill::metrics::volume;
use scanmill::ops::fair::{self, FairParams, FairReport, RelaxParams, guards};
use scanmill::ops::smooth::{MethodName, SmoothParams, smooth};
use scanmill::recipe::{Recipe, Step};
use std::path::Path;

use common::scan as load;

fn noise() -> NoiseOptions {
    NoiseOptions {
        sigma_factor: 0.2,
        seed: 1,
        ..NoiseOptions::default()
    }
}

/// Mean surface distance (both ways) to the clean scan.
fn distance(result: &Mesh, clean: &Mesh, samples: usize) -> f64 {
    surface_distance(result, clean, samples, 7).unwrap().mean
}

fn volume_change_percent(result: &Mesh, clean: &Mesh) -> Option<f64> {
    volume::compare(result, clean).change_percent
}

/// relax then fair with the defaults.
fn relax_and_fair(mesh: &mut Mesh) -> (FairReport, FairReport) {
    let r = fair::relax(mesh, &RelaxParams::default());
    let f = fair::fair(mesh, &FairParams::default());
    (r, f)
}

/// The `relax` and `fair` steps of config/recipes/face-scan.toml, as the recipe sets them
/// (fair: curvature criterion only after the pre-pass, thesis §4.6.3; docs/fairing.md).
fn face_scan_recipe() -> (RelaxParams, FairParams) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/recipes/face-scan.toml");
    let recipe = Recipe::from_path(&path).unwrap();
    let relax = recipe.steps.iter().find_map(|s| match s {
        Step::Relax(p) => Some(p.clone()),
        _ => None,
    });
    let fair = recipe.steps.iter().find_map(|s| match s {
        Step::Fair(p) => Some(p.clone()),
        _ => None,
    });
    (relax.unwrap(), fair.unwrap())
}

// ------------------------------------------------------------------------------------
// Surfaces with boundary
// ------------------------------------------------------------------------------------

struct Loop {
    perimeter: f64,
    area: f64,
    turning: f64,
}

fn loop_shape(pts: &[DVec3]) -> Loop {
    let n = pts.len();
    let c = pts.iter().copied().sum::<DVec3>() / n as f64;
    Loop {
        perimeter: (0..n).map(|i| (pts[(i + 1) % n] - pts[i]).length()).sum(),
        area: (0..n)
            .map(|i| (pts[i] - c).cross(pts[(i + 1) % n] - c))
            .sum::<DVec3>()
            .length()
            / 2.0,
        turning: (0..n)
            .map(|i| {
                let a = pts[i] - pts[(i + n - 1) % n];
                let b = pts[(i + 1) % n] - pts[i];
                a.angle_between(b)
            })
            .sum::<f64>()
            / n as f64,
    }
}

fn check_borders(rel: &str) {
    let input = load(rel);
    let topo: Topology = input.topology();
    let triangles = guards::triangle_vertices(&input);
    let normals = guards::triangle_normals(&triangles, &input.positions);
    let references =
        guards::triangle_references(&triangles, &input.positions, |v| topo.is_boundary_vertex(v));
    let mut m = input.clone();
    let (r, f) = relax_and_fair(&mut m);
    // Neither step turns a triangle over from its own input.
    assert_eq!((r.flipped_vs_input, f.flipped_vs_input), (0, 0), "{rel}");
    // Both together: nothing turned over but folds of the input (triangles facing away
    // from the surface around them) turned back, and, in the crumpled raw
    // reconstructions, a few triangles that relax turned by up to 45° and fair by up to
    // 90° more (20 of 36,000 on the Angel; none on james).
    let folds = |t: usize| normals[t].dot(references[t].around.as_dvec3()) < 0.0;
    let final_normals = guards::triangle_normals(&triangles, &m.positions);
    let turned: Vec<usize> = (0..normals.len())
        .filter(|&t| final_normals[t].dot(normals[t]) < 0.0)
        .collect();
    let unfolded = turned.iter().filter(|&&t| folds(t)).count();
    let others = turned.len() - unfolded;
    eprintln!(
        "{rel}: turned over {} ({unfolded} were folds)",
        turned.len()
    );
    assert!(
        others as f64 <= 1e-3 * normals.len() as f64,
        "{rel}: {others} turned over"
    );
    assert!(f.boundary_curves > 0, "{rel}");
    let mut loops: Vec<(Loop, Loop)> = topo
        .boundary_chains()
        .iter()
        .filter(|c| c.closed && c.vertices.len() >= fair::boundary::MIN_CURVE_VERTICES)
        .map(|c| {
            let at = |m: &Mesh| -> Vec<DVec3> {
                c.vertices
                    .iter()
                    .map(|&v| m.positions[v as usize])
                    .collect()
            };
            (loop_shape(&at(&input)), loop_shape(&at(&m)))
        })
        .collect();
    loops.sort_by(|a, b| b.0.perimeter.total_cmp(&a.0.perimeter));
    // The outer border (the longest loop) comes out smooth: its mean turning angle at
    // least halves.
    let (outer0, outer1) = &loops[0];
    assert!(
        outer1.turning < 0.5 * outer0.turning,
        "{rel}: outer border turning {:.1}° -> {:.1}°",
        outer0.turning.to_degrees(),
        outer1.turning.to_degrees()
    );
    // Holes neither close nor grow by more than 2% of their perimeter: the mean shift of
    // the loop across itself, |ΔA| / P, stays within 0.02 P; the perimeter does not grow
    // by 2% either (straightening a ragged border shortens it).
    for (i, (a, b)) in loops.iter().enumerate() {
        assert!(
            (b.area - a.area).abs() <= 0.02 * a.perimeter * a.perimeter && b.area > 0.0,
            "{rel} loop {i}: area {} -> {} (perimeter {})",
            a.area,
            b.area,
            a.perimeter
        );
        assert!(
            b.perimeter <= 1.02 * a.perimeter,
            "{rel} loop {i}: perimeter {} -> {}",
            a.perimeter,
            b.perimeter
        );
    }
    eprintln!(
        "{rel}: {} loops faired; outer turning {:.1}° -> {:.1}°; guards relax {}+{} fair {}+{}; {:.0}+{:.0} ms",
        f.boundary_curves,
        outer0.turning.to_degrees(),
        outer1.turning.to_degrees(),
        r.flips_avoided,
        r.degenerate_avoided,
        f.flips_avoided,
        f.degenerate_avoided,
        r.time_ms,
        f.time_ms
    );
}

#[test]
fn james_borders_are_smoothed_and_holes_kept() {
    check_borders("textured/james_face_stereo_capture/james.obj");
}

#[test]
fn ggg_sfm_borders_are_smoothed_and_holes_kept() {
    for name in ["Angel", "birdBath", "blackVase"] {
        check_borders(&format!("raw_photogrammetry/ggg_sfm_{name}_decimated.ply"));
    }
}

// ------------------------------------------------------------------------------------
// The noise protocol
// ------------------------------------------------------------------------------------

struct Row {
    name: &'static str,
    vertices: usize,
    noisy: f64,
    /// The project's `smooth` step, method Taubin, its defaults (13 λ|μ pairs, borders
    /// fixed): what issue #26 calls Taubin.
    taubin: f64,
    taubin_volume: Option<f64>,
    /// relax then fair as the face-scan recipe sets them.
    ours: f64,
    ours_volume: Option<f64>,
    relax: FairReport,
    fair: FairReport,
    /// relax then fair with both steps' defaults.
    defaults: f64,
    defaults_volume: Option<f64>,
    /// fair alone, its defaults.
    fair_only: f64,
}

fn protocol(name: &'static str, rel: &str, samples: usize) -> Row {
    let clean = load(rel);
    let (noisy, _) = noisy_copy(&clean, &noise());
    let mut t = noisy.clone();
    smooth(&mut t, &SmoothParams::defaults(MethodName::Taubin));
    let (relax_params, fair_params) = face_scan_recipe();
    let mut ours = noisy.clone();
    let relax = fair::relax(&mut ours, &relax_params);
    let fair = fair::fair(&mut ours, &fair_params);
    let mut defaults = noisy.clone();
    relax_and_fair(&mut defaults);
    let mut fair_only = noisy.clone();
    fair::fair(&mut fair_only, &FairParams::default());
    Row {
        name,
        vertices: clean.positions.len(),
        noisy: distance(&noisy, &clean, samples),
        taubin: distance(&t, &clean, samples),
        taubin_volume: volume_change_percent(&t, &clean),
        ours: distance(&ours, &clean, samples),
        ours_volume: volume_change_percent(&ours, &clean),
        relax,
        fair,
        defaults: distance(&defaults, &clean, samples),
        defaults_volume: volume_change_percent(&defaults, &clean),
        fair_only: distance(&fair_only, &clean, samples),
    }
}

#[test]
fn noisy_bunny_is_faired_better_than_taubin_by_the_face_scan_recipe() {
    let row = protocol("bunny", "untextured/stanford_bunny/bun_zipper.ply", 30_000);
    eprintln!(
        "bunny: noisy {:.3e}, Taubin {:.3} of noisy; face-scan relax+fair {:.3} ({:.3} of Taubin); defaults relax+fair {:.3}, fair {:.3}",
        row.noisy,
        row.taubin / row.noisy,
        row.ours / row.noisy,
        row.ours / row.taubin,
        row.defaults / row.noisy,
        row.fair_only / row.noisy
    );
    // The noise protocol is seeded and fairing is deterministic, so these are fixed
    // numbers, not timings. Measured (30k samples): see docs/fairing.md.
    assert!(
        row.ours < row.taubin,
        "recipe relax + fair not below Taubin"
    );
    assert!(row.fair_only < 0.7 * row.noisy);
    assert!(row.fair_only < 1.1 * row.taubin);
    assert_eq!(row.relax.flipped_vs_input, 0);
    assert_eq!(row.fair.flipped_vs_input, 0);
}

fn pct(x: Option<f64>) -> String {
    x.map_or("open".into(), |v| format!("{v:+.3}%"))
}

fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_default()
}

use scanmill::geom::timing::cpu_seconds;

#[test]
#[ignore = "figures: run with --release -- --ignored --nocapture"]
fn figures_noise_protocol_against_taubin() {
    let scans: [(&'static str, &str); 4] = [
        ("facefuns", "textured/facefuns_di3d_face/example.obj"),
        ("lucy", "untextured/misc_scans/stanford_lucy_100k.ply"),
        (
            "igea",
            "untextured/misc_scans/igea_cyberware_trilist_DERIVED.ply.gz",
        ),
        ("bunny", "untextured/stanford_bunny/bun_zipper.ply"),
    ];
    println!(
        "noise protocol: sigma 0.2 x mean edge along normals, seed 1; distance = mean surface distance to the clean scan (200k samples each way); load average at start {}",
        load_average()
    );
    println!(
        "| scan | V | noisy dist | Taubin (x noisy) | Taubin vol | ours: face-scan relax+fair (x noisy) | ours / Taubin | ours vol | relax ms | fair ms | iterations relax+fair | defaults relax+fair / Taubin | defaults vol | fair alone / Taubin |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for (name, rel) in scans {
        let r = protocol(name, rel, 200_000);
        println!(
            "| {} | {} | {:.3e} | {:.3} | {} | {:.3} | **{:.3}** | {} | {:.0} | {:.0} | {}+{} | {:.3} | {} | {:.3} |",
            r.name,
            r.vertices,
            r.noisy,
            r.taubin / r.noisy,
            pct(r.taubin_volume),
            r.ours / r.noisy,
            r.ours / r.taubin,
            pct(r.ours_volume),
            r.relax.time_ms,
            r.fair.time_ms,
            r.relax.iterations * r.relax.time_scale,
            r.fair.iterations * r.fair.time_scale,
            r.defaults / r.taubin,
            pct(r.defaults_volume),
            r.fair_only / r.taubin,
        );
        // What the table must show whatever the figures: the recipe denoises and turns no
        // triangle over (docs/fairing.md has the figures against Taubin).
        assert!(
            r.ours < r.noisy && r.defaults < r.noisy,
            "{}: not denoised",
            r.name
        );
        assert_eq!(
            r.relax.flipped_vs_input + r.fair.flipped_vs_input,
            0,
            "{}",
            r.name
        );
    }
    println!("load average at end {}", load_average());
}

#[test]
#[ignore = "figures: run with --release -- --ignored --nocapture"]
fn figures_speed_on_200k_vertices() {
    // Lucy subdivided once: 200k vertices, 400k triangles; then the noise protocol.
    let lucy =
        scanmill::ops::subdivide::subdivide(&load("untextured/misc_scans/stanford_lucy_100k.ply"));
    let (noisy, _) = noisy_copy(&lucy, &noise());
    let (_, recipe_fair) = face_scan_recipe();
    println!("load average {}", load_average());
    for (label, params) in [
        ("defaults", FairParams::default()),
        ("face-scan recipe", recipe_fair),
    ] {
        let mut results: Vec<Mesh> = Vec::new();
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut m = noisy.clone();
            let cpu = cpu_seconds();
            let r = pool.install(|| fair::fair(&mut m, &params));
            let cpu = cpu_seconds() - cpu;
            println!(
                "{} vertices, fair {label}, {threads} thread(s): {:.0} ms wall, {:.0} ms CPU, {} iterations (×{}), {:.1} M vertex updates/s, distance {:.3} of noisy",
                m.positions.len(),
                r.time_ms,
                cpu * 1e3,
                r.iterations,
                r.time_scale,
                r.updates_per_second / 1e6,
                distance(&m, &lucy, 100_000) / distance(&noisy, &lucy, 100_000)
            );
            results.push(m);
        }
        // The fast schedule's result does not depend on the thread count.
        assert_eq!(results[0].positions, results[1].positions, "fair {label}");
    }
    println!("load average {}", load_average());
}
