//! No quadratic corners (issue #22, finding 6): the closest-point index behind the metrics,
//! the preview, `seam_fix` and texture follow, and the decimation set-up, on inputs made to
//! defeat them (tests/hostile_shapes). The tests count work (nodes visited, set-up steps),
//! never time: the machine's speed drifts, the counts do not.

mod common;

mod hostile_shapes;

use glam::DVec3;
use hostile_shapes::{fan, fan_with_seams, soup, stacked};
use scanmill::mesh::Mesh;
use scanmill::metrics::bvh::{BUDGET_PER_LEVEL, TriangleBvh};
use scanmill::metrics::surface::{counterparts, sample_surface};
use scanmill::metrics::topology::ReferenceTopology;
use scanmill::ops::decimate::quadric::Weights;
use scanmill::ops::decimate::work::{Config, Work};
use scanmill::ops::decimate::{Conditioning, DecimateParams, Fallback, Method, decimate};
use std::path::Path;
use std::process::Command;

const RECIPE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/config/recipes/face-scan.toml");

/// What `queries` searches cost together on `mesh`'s index: nodes visited, searches cut
/// short, the most nodes one search visited, and the budget.
struct SearchWork {
    nodes: u64,
    cut_short: usize,
    most: u32,
    budget: u32,
}

/// Searches as the metrics make them: for each query point, its own triangle's hit as the
/// start.
fn search_all(mesh: &Mesh, queries: &[(DVec3, u32)]) -> SearchWork {
    let bvh = TriangleBvh::new(mesh, (0..mesh.triangles.len() as u32).collect());
    let mut w = SearchWork {
        nodes: 0,
        cut_short: 0,
        most: 0,
        budget: bvh.budget(),
    };
    for &(p, own) in queries {
        let s = bvh.search(p, Some(bvh.hit_on(p, own)));
        assert!(s.hit.is_some());
        w.nodes += u64::from(s.cost.nodes);
        w.most = w.most.max(s.cost.nodes);
        w.cut_short += usize::from(!s.complete);
    }
    w
}

/// `n` query points a little off the surface (along each triangle's normal by 1 % of the
/// box), each with its triangle: no triangle is then at rounding distance, so the searches
/// must prune by boxes, which on these shapes barely prune at all.
fn off_surface(mesh: &Mesh, n: usize) -> Vec<(DVec3, u32)> {
    sample_surface(mesh, n, 3)
        .into_iter()
        .map(|s| {
            let normal = mesh.triangle_cross(s.triangle as usize).normalize_or_zero();
            (s.point + normal * 0.01, s.triangle)
        })
        .collect()
}

/// The ratio of the work at 4n to the work at n stays near 4 (n log n: ~4.5 here), where a
/// search visiting most of the tree would make it 16.
fn assert_n_log_n(shape: &str, make: impl Fn(usize) -> Mesh, defeats_boxes: bool) {
    let n = 2000;
    let small = make(n);
    let large = make(4 * n);
    let (a, b) = (
        search_all(&small, &off_surface(&small, n)),
        search_all(&large, &off_surface(&large, 4 * n)),
    );
    let ratio = b.nodes as f64 / a.nodes as f64;
    assert!(
        ratio < 6.0,
        "{shape}: {} nodes for {n} queries on {n} triangles, {} for 4x: ratio {ratio:.2}",
        a.nodes,
        b.nodes
    );
    for w in [&a, &b] {
        assert!(
            w.most <= w.budget,
            "{shape}: {} > budget {}",
            w.most,
            w.budget
        );
    }
    // The budget is what held them where the shape defeats the boxes.
    assert!(
        !defeats_boxes || b.cut_short > 0,
        "{shape}: no search reached the budget"
    );
}

#[test]
fn searches_on_a_soup_cost_n_log_n() {
    assert_n_log_n("soup", |n| soup(n, 1), true);
}

#[test]
fn searches_on_stacked_triangles_cost_n_log_n() {
    assert_n_log_n("stacked", |n| stacked(n, 1), false);
}

#[test]
fn searches_on_a_fan_cost_n_log_n() {
    assert_n_log_n("fan", fan, true);
}

/// Distances measured by the crack metric's probes at the midpoints of every edge of `mesh`
/// (in a soup, every edge is a boundary edge), against `mesh` itself as the reference.
fn crack_probe_work(mesh: &Mesh) -> u64 {
    let reference = ReferenceTopology::of(mesh, 2.0);
    let mut measured = 0;
    for t in 0..mesh.triangles.len() {
        let [a, b, c] = mesh.triangle_positions(t);
        for (p, q) in [(a, b), (b, c), (c, a)] {
            let probe = reference.probe((p + q) * 0.5);
            assert!(probe.near);
            measured += u64::from(probe.measured);
        }
    }
    measured
}

/// The crack metric on a soup of large overlapping triangles, where every edge's box holds
/// most query points: its work grows near linearly (it grew with the square before).
#[test]
fn crack_probes_on_a_soup_are_near_linear() {
    let n = 2000;
    let (a, b) = (
        crack_probe_work(&soup(n, 1)),
        crack_probe_work(&soup(4 * n, 1)),
    );
    let ratio = b as f64 / a as f64;
    assert!(
        ratio < 6.0,
        "{a} distances for {n} triangles, {b} for 4x: ratio {ratio:.2}"
    );
}

use common::scan as load_scan;

/// On real scans the budget never bites, with room to spare: the metrics' searches of a
/// decimated scan against its input, both ways, with their hints, all end proven, well
/// under the budget ([`BUDGET_PER_LEVEL`] is chosen from this).
#[test]
fn scans_never_reach_the_budget() {
    for rel in [
        "textured/james_face_stereo_capture/james.obj",
        "textured/esp32cam_meshroom_raw/texturedMesh.obj",
    ] {
        let input = load_scan(rel);
        let params = DecimateParams {
            target_faces: Some(input.triangles.len() / 4),
            ..DecimateParams::default()
        };
        let (result, _) = decimate(&input, &params).unwrap();
        for (from, to) in [(&result, &input), (&input, &result)] {
            let near = counterparts(from, to).unwrap();
            let queries: Vec<(DVec3, u32)> = sample_surface(from, 20_000, 7)
                .into_iter()
                .filter(|s| near[s.triangle as usize] != u32::MAX)
                .map(|s| (s.point, near[s.triangle as usize]))
                .collect();
            let w = search_all(to, &queries);
            assert_eq!(w.cut_short, 0, "{rel}");
            assert!(
                w.most * 3 <= w.budget,
                "{rel}: a search visited {} nodes, the budget is {} ({BUDGET_PER_LEVEL} per level)",
                w.most,
                w.budget
            );
        }
    }
}

/// The classification steps of the decimation set-up on a mesh.
fn classify_steps(mesh: &Mesh) -> u64 {
    let cfg = Config {
        boundary: scanmill::ops::border::Border::Fixed,
        boundary_weight: 1.0,
        seam_weight: 1.0,
        conditioning: Conditioning::Reduced,
        max_condition: 1e8,
        fallback: Fallback::Regularised,
        cos_max_normal_change: 0.5,
        guards: true,
    };
    if mesh.texcoords.is_empty() {
        let w = Weights::<0> {
            geom: 1.0,
            attr: [],
        };
        Work::<0>::new(mesh, w, cfg, None).classify_steps
    } else {
        let w = Weights::<2> {
            geom: 1.0,
            attr: [0.0025; 2],
        };
        Work::<2>::new(mesh, w, cfg, None).classify_steps
    }
}

/// The set-up at a vertex of valence k costs about k log k, not k²: the fan's steps at 4n
/// are near 4 × those at n (O(k²) would make them 16 ×), with and without a seam on every
/// spoke (k wedges at the centre).
#[test]
fn decimation_set_up_around_a_hub_is_near_linear() {
    for (shape, make) in [
        ("fan", fan as fn(usize) -> Mesh),
        ("fan with seams", fan_with_seams),
    ] {
        let (a, b) = (classify_steps(&make(5000)), classify_steps(&make(20_000)));
        let ratio = b as f64 / a as f64;
        assert!(
            ratio < 5.0,
            "{shape}: {a} steps at 5000, {b} at 20000: {ratio:.2}"
        );
    }
}

/// The collapse loop never walks the hub's star: every merge with it is refused by its
/// size before any walk, so the evaluations stay at one per triangle.
#[test]
fn decimating_a_fan_refuses_the_hub_at_once() {
    let n = 50_000;
    let params = DecimateParams {
        method: Method::EdgeCollapse,
        target_faces: Some(n / 2),
        ..DecimateParams::default()
    };
    let (out, report) = decimate(&fan(n), &params).unwrap();
    assert_eq!(out.triangles.len(), n, "nothing can collapse: {report:?}");
    assert!(
        report.evaluations <= n + 1,
        "{} evaluations",
        report.evaluations
    );
    let blocked = report.blocked.expect("short of the target");
    assert_eq!(
        blocked.valence, n,
        "every spoke is refused by the hub's size"
    );
    assert!(
        report
            .stop_note
            .unwrap()
            .contains("more triangles around them")
    );
}

fn process(input: &Path, out: &Path) -> (i32, String) {
    let run = Command::new(env!("CARGO_BIN_EXE_scanmill"))
        .args(["process", input.to_str().unwrap(), "--recipe", RECIPE])
        .args(["--out", out.to_str().unwrap()])
        .args(["--report", out.with_extension("json").to_str().unwrap()])
        .env("SCANMILL_LOG", "error")
        .output()
        .unwrap();
    (
        run.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&run.stderr).into_owned(),
    )
}

/// A soup, stacked triangles and a fan through `scanmill process` with the face-scan
/// recipe: each ends with a result (exit 0, the mesh written, the report's metrics there,
/// the preview drawn or refused by its overdraw budget) or a clean one-line error, never a
/// panic.
#[test]
fn hostile_shapes_go_through_process_end_to_end() {
    let tmp = tempfile::tempdir().unwrap();
    for (name, mesh) in [
        ("soup", soup(3000, 4)),
        ("stacked", stacked(3000, 4)),
        ("fan", fan(20_000)),
    ] {
        let input = tmp.path().join(format!("{name}.obj"));
        scanmill::mesh::save(&mesh, &input, &Default::default()).unwrap();
        let out = tmp.path().join(format!("{name}-out"));
        let (code, stderr) = process(&input, &out);
        assert!(!stderr.contains("panicked"), "{name}: {stderr}");
        match code {
            0 => {
                assert!(out.join(format!("{name}.obj")).is_file(), "{name}");
                let report: serde_json::Value = serde_json::from_str(
                    &std::fs::read_to_string(out.with_extension("json")).unwrap(),
                )
                .unwrap();
                // The preview is drawn, or refused by its overdraw budget (soups): then
                // the report says there is none and no file claims to be one.
                let preview = out.join(format!("{name}.preview.png"));
                assert_eq!(
                    preview.is_file(),
                    !report["preview"].is_null(),
                    "{name}: {}",
                    report["preview"]
                );
                let distance = &report["metrics"]["distance"];
                assert!(distance["max"].as_f64().unwrap().is_finite(), "{name}");
            }
            65 => assert_eq!(stderr.trim().lines().count(), 1, "{name}: {stderr}"),
            other => panic!("{name}: exit {other}: {stderr}"),
        }
    }
}
