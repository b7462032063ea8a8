use super::corners::Corners;
use super::lines::Lines;
use super::*;
use crate::mesh::shapes;
use crate::ops::decimate::audit::audit;

fn working(mesh: &Mesh) -> (Corners, Lines) {
    let topo = Topology::new(mesh);
    let lines = Lines::new(mesh, &topo, None);
    (build::build(mesh, &topo, &lines), lines)
}

fn fraction(f: f64) -> RemeshParams {
    RemeshParams {
        edge_fraction: Some(f),
        ..RemeshParams::default()
    }
}

#[test]
fn splits_keep_the_table_whole() {
    let mesh = shapes::grid(4, 4);
    let (mut c, lines) = working(&mesh);
    c.check().unwrap();
    let l = mesh.mean_edge_length() / 5.0;
    let n = isotropic::split_long(&mut c, &lines, &mut sizing::Sizing::uniform(l));
    assert!(n > 0);
    c.check().unwrap();
}

/// Every edge is met from both its ends by the in-place walk of the neighbours: a border
/// vertex's last neighbour (whose edge closes no face on that side) included, so the counts
/// sum to twice the edges.
#[test]
fn neighbours_meet_every_edge_from_both_ends() {
    for mesh in [shapes::grid(4, 3), shapes::uv_sphere(1.0, 6, 8)] {
        let (c, _) = working(&mesh);
        let border = (0..c.vtx.len() as u32).filter(|&h| c.is_border(h)).count();
        let edges = (c.vtx.len() - border) / 2 + border;
        let sum: usize = (0..c.pos.len() as u32)
            .map(|v| c.neighbours(v).count())
            .sum();
        assert_eq!(sum, 2 * edges);
    }
}

#[test]
fn sphere_stays_closed_manifold_unflipped_and_regular() {
    let mesh = shapes::uv_sphere(1.0, 24, 48);
    let (out, report) = remesh(&mesh, &fraction(0.05)).unwrap();
    let a = audit(&mesh, &out);
    assert_eq!(a.after.boundary_edges, 0, "{a:?}");
    assert_eq!(a.after.non_manifold_edges, 0);
    assert_eq!(a.after.components, 1);
    assert_eq!(a.after.euler_characteristic, 2);
    assert_eq!(a.flipped_faces, 0);
    assert_eq!(a.zero_area_faces, 0);
    // The uv sphere's pole fans are slivers; the remesh has none.
    assert!(report.quality_before.min_angle < 10.0);
    assert!(
        report.quality_after.share_min_angle_30 >= 0.99,
        "{report:?}"
    );
    // Every vertex is on the input surface (the sphere's chords are within 1e-2).
    for p in &out.positions {
        assert!((p.length() - 1.0).abs() < 1e-2, "{p}");
    }
}

/// On a sphere every triangle of a remesh with its vertices on the surface is a chord,
/// inside the sphere; the least-squares fit moves the vertices out by part of the sag, so
/// that the triangles straddle the surface: their centroids come much closer to it, and no
/// vertex goes farther out than the sag itself (L²/6 for equilateral triangles of side L on
/// the unit sphere, 0.005 here).
#[test]
fn fit_straddles_a_sphere_instead_of_cutting_it() {
    let mesh = shapes::uv_sphere(1.0, 48, 96);
    let centroid_error = |out: &Mesh| {
        let n = out.triangles.len() as f64;
        (0..out.triangles.len())
            .map(|t| {
                let [a, b, c] = out.triangle_positions(t);
                (((a + b + c) / 3.0).length() - 1.0).abs()
            })
            .sum::<f64>()
            / n
    };
    let on = RemeshParams {
        on_surface: true,
        ..fraction(0.05)
    };
    let (on_out, on_report) = remesh(&mesh, &on).unwrap();
    let (fit_out, fit_report) = remesh(&mesh, &fraction(0.05)).unwrap();
    assert_eq!(on_report.counts.fit, fit::FitReport::default());
    assert!(
        fit_report.counts.fit.vertices > 0,
        "{:?}",
        fit_report.counts
    );
    let (e_on, e_fit) = (centroid_error(&on_out), centroid_error(&fit_out));
    assert!(e_fit < 0.5 * e_on, "fit {e_fit} vs on the surface {e_on}");
    let l = fit_report.edge_length;
    for p in &fit_out.positions {
        let r = p.length();
        assert!(
            r > 1.0 - 1e-3 && r < 1.0 + l * l / 6.0,
            "{p}: radius {r}, L {l}"
        );
    }
    assert_eq!(audit(&mesh, &fit_out).flipped_faces, 0);
}

#[test]
fn grid_border_stays_on_the_border_and_texture_is_kept() {
    let mesh = shapes::grid(30, 30);
    assert!(mesh.has_texcoords());
    let (out, _) = remesh(&mesh, &fraction(0.05)).unwrap();
    let a = audit(&mesh, &out);
    assert_eq!(a.after.boundary_loops, 1);
    assert_eq!(a.flipped_faces, 0);
    assert_eq!(a.chart_jumps, 0);
    let (lo, hi) = mesh.bounding_box().unwrap();
    // Border vertices on the square's sides; texture linear in position as on the input.
    let topo = Topology::new(&out);
    for e in topo.boundary_edges() {
        for v in topo.edge_vertices(e) {
            let p = out.positions[v as usize];
            let on_side = [(p.x - lo.x), (hi.x - p.x), (p.y - lo.y), (hi.y - p.y)]
                .iter()
                .any(|d| d.abs() < 1e-9);
            assert!(on_side, "{p}");
        }
    }
    for t in 0..out.triangles.len() {
        for &w in &out.triangles[t] {
            let p = out.positions[out.wedges[w as usize].vertex as usize];
            let uv = out.wedge_texcoord(w).unwrap();
            let want = glam::DVec2::new((p.x - lo.x) / (hi.x - lo.x), (p.y - lo.y) / (hi.y - lo.y));
            assert!(uv.distance(want) < 1e-6, "{uv} {want}");
        }
    }
}

#[test]
fn deterministic_across_thread_counts() {
    let mesh = shapes::torus(1.0, 0.3, 40, 20);
    let run =
        |threads| crate::testing::on_threads(threads, || remesh(&mesh, &fraction(0.03)).unwrap().0);
    let (a, b) = (run(1), run(3));
    assert_eq!(a, b);
}

#[test]
fn a_length_that_would_make_too_many_triangles_is_refused_before_any_work() {
    let mesh = shapes::torus(1.0, 0.3, 40, 20);
    let tiny = RemeshParams {
        edge_length: Some(1e-9),
        ..RemeshParams::default()
    };
    match remesh(&mesh, &tiny) {
        Err(RemeshError::TooDense {
            expected, limit, ..
        }) => {
            assert!(expected > limit, "{expected} {limit}");
        }
        other => panic!(
            "expected TooDense, got {:?}",
            other.map(|(m, _)| m.triangles.len())
        ),
    }
    let e = remesh(&mesh, &tiny).unwrap_err().to_string();
    assert!(e.contains("edge_length") && e.contains("triangles"), "{e}");
    // The same torus at a sane length is remeshed.
    assert!(remesh(&mesh, &fraction(0.03)).is_ok());
}

/// Validates the parameters of 1 % of the diagonal after `change`.
fn validate_changed(change: impl FnOnce(&mut RemeshParams)) -> Result<(), String> {
    let mut p = fraction(0.01);
    change(&mut p);
    p.validate()
}

#[test]
fn params_validate() {
    assert!(RemeshParams::default().validate().is_err());
    assert!(fraction(0.0).validate().is_err());
    assert!(validate_changed(|_| ()).is_ok());
    assert!(validate_changed(|p| p.edge_length = Some(1.0)).is_err());
    let patches = validate_changed(|p| p.method = Method::Patches);
    assert!(patches.unwrap_err().contains("isotropic"));
    assert!(validate_changed(|p| p.iterations = 0).is_err());
}

fn adaptive(f: f64) -> RemeshParams {
    RemeshParams {
        adaptive: true,
        ..fraction(f)
    }
}

/// Every edge of `mesh` once: its two ends.
fn edges(mesh: &Mesh) -> Vec<(glam::DVec3, glam::DVec3)> {
    let topo = Topology::new(mesh);
    (0..topo.edge_count() as u32)
        .map(|e| {
            let [a, b] = topo.edge_vertices(e);
            (mesh.positions[a as usize], mesh.positions[b as usize])
        })
        .collect()
}

fn mean_and_cv(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    let var = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
    (mean, var.sqrt() / mean)
}

#[test]
fn square_plate_keeps_its_four_corners_with_feature_angle() {
    let mesh = shapes::grid(30, 30);
    let params = RemeshParams {
        feature_angle: Some(45.0),
        ..fraction(0.07)
    };
    let (out, _) = remesh(&mesh, &params).unwrap();
    for corner in [[0.0, 0.0], [30.0, 0.0], [0.0, 30.0], [30.0, 30.0]] {
        let p = glam::DVec3::new(corner[0], corner[1], 0.0);
        assert!(
            out.positions.contains(&p),
            "corner {p} cut; border: {:?}",
            out.positions
                .iter()
                .filter(|q| q.distance(p) < 5.0)
                .collect::<Vec<_>>()
        );
    }
    let a = audit(&mesh, &out);
    assert_eq!(a.after.boundary_loops, 1);
    assert_eq!(a.flipped_faces, 0);
}

#[test]
fn cube_keeps_the_corners_where_feature_lines_meet() {
    let mesh = shapes::cube();
    let params = RemeshParams {
        feature_angle: Some(45.0),
        ..fraction(0.05)
    };
    let (out, _) = remesh(&mesh, &params).unwrap();
    for &p in &mesh.positions {
        assert!(out.positions.contains(&p), "cube corner {p} moved");
    }
    let a = audit(&mesh, &out);
    assert_eq!(a.after.boundary_edges, 0);
    assert_eq!(a.after.euler_characteristic, 2);
    assert_eq!(a.flipped_faces, 0);
    // From 12 triangles whose edges are 8–16 target lengths long: every edge of the cube
    // split evenly and well-shaped triangles on its sides (before the splits went in
    // passes, whole cube edges stayed unsplit and 20 % of the triangles were below 10°).
    let q = quality::AngleQuality::of(&out);
    assert!(q.share_min_angle_30 >= 0.99 && q.min_angle >= 20.0, "{q:?}");
    let on_x_edges = |y: f64, z: f64| {
        out.positions
            .iter()
            .filter(|p| (p.y - y).abs() < 1e-12 && (p.z - z).abs() < 1e-12)
            .count()
    };
    let counts =
        [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)].map(|(y, z)| on_x_edges(y, z));
    assert!(
        counts.iter().all(|&n| n == counts[0] && n >= 10),
        "{counts:?}"
    );
    // Every vertex on the cube's surface.
    for p in &out.positions {
        assert!((p.abs().max_element() - 1.0).abs() < 1e-9, "{p}");
    }
}

#[test]
fn adaptive_sphere_gets_uniform_edges_of_the_curvature_size() {
    let mesh = shapes::uv_sphere(1.0, 48, 96);
    let params = adaptive(0.1);
    let (out, report) = remesh(&mesh, &params).unwrap();
    let sizing = report.sizing.expect("adaptive report");
    // L = 0.1 · 2√3, ε = L/100, r = 1: sqrt(6εr − 3ε²).
    let l = 0.1 * 2.0 * 3f64.sqrt();
    let e = l / 100.0;
    let want = (6.0 * e - 3.0 * e * e).sqrt();
    assert!(
        (sizing.mean_size - want).abs() < 0.1 * want,
        "{sizing:?} want {want}"
    );
    let lengths: Vec<f64> = edges(&out).iter().map(|(a, b)| a.distance(*b)).collect();
    let (mean, cv) = mean_and_cv(&lengths);
    assert!(
        (mean - want).abs() < 0.15 * want,
        "mean {mean}, want {want}"
    );
    assert!(cv < 0.2, "coefficient of variation {cv}");
    assert!(
        report.quality_after.share_min_angle_30 >= 0.99,
        "{report:?}"
    );
    let a = audit(&mesh, &out);
    assert_eq!(a.after.euler_characteristic, 2);
    assert_eq!(a.flipped_faces, 0);
}

/// A 40 × 40 plate (edges 0.5) with a Gaussian bump of height 4 and width 3 in the middle.
fn bump() -> Mesh {
    let mut mesh = shapes::grid(80, 80);
    for p in &mut mesh.positions {
        *p *= 0.5;
        let r2 = (p.x - 20.0).powi(2) + (p.y - 20.0).powi(2);
        p.z = 4.0 * (-r2 / 18.0).exp();
    }
    mesh
}

#[test]
fn adaptive_bump_gets_shorter_edges_than_the_flat_part() {
    let mesh = bump();
    // The curvature alone: the plate's border is not refined (see the border tests).
    let params = RemeshParams {
        border_edge_ratio: Some(1.0),
        ..adaptive(0.04)
    };
    let (out, report) = remesh(&mesh, &params).unwrap();
    let centre = glam::DVec2::new(20.0, 20.0);
    let (mut top, mut flat) = (Vec::new(), Vec::new());
    for (a, b) in edges(&out) {
        let m = 0.5 * (a + b);
        let d = m.truncate().distance(centre);
        if d < 2.0 {
            top.push(a.distance(b));
        } else if d > 12.0 {
            flat.push(a.distance(b));
        }
    }
    let (top, _) = mean_and_cv(&top);
    let (flat, _) = mean_and_cv(&flat);
    assert!(top < 0.5 * flat, "bump top {top}, flat {flat}");
    // The flat part is at the longest edge (within the remesher's 4/5..4/3 band).
    let l = report.edge_length;
    assert!(flat > 0.75 * l && flat < 1.2 * l, "flat {flat}, L {l}");
    // The uniform remesh at the same L does not refine the bump.
    let uniform = RemeshParams {
        border_edge_ratio: Some(1.0),
        ..fraction(0.04)
    };
    let (uni, _) = remesh(&mesh, &uniform).unwrap();
    assert!(
        out.triangles.len() > uni.triangles.len(),
        "{}",
        uni.triangles.len()
    );
    let a = audit(&mesh, &out);
    assert_eq!(a.flipped_faces, 0);
    assert_eq!(a.after.boundary_loops, 1);
    assert!(
        report.quality_after.share_min_angle_30 >= 0.98,
        "{report:?}"
    );
}

#[test]
fn adaptive_is_deterministic_across_thread_counts() {
    let mesh = shapes::torus(1.0, 0.3, 40, 20);
    let run =
        |threads| crate::testing::on_threads(threads, || remesh(&mesh, &adaptive(0.05)).unwrap());
    let ((a, ra), (b, rb)) = (run(1), run(3));
    assert_eq!(a, b);
    assert_eq!(ra.counts.splits, rb.counts.splits);
    // The torus' inner side is curved more (radius 0.3 across, 0.7 around): it is refined.
    let (uniform, _) = remesh(&mesh, &fraction(0.05)).unwrap();
    assert!(a.triangles.len() > uniform.triangles.len());
}

#[test]
fn adaptive_params_validate() {
    let adaptive_changed = |change: &dyn Fn(&mut RemeshParams)| {
        validate_changed(|p| {
            p.adaptive = true;
            change(p)
        })
    };
    assert!(adaptive_changed(&|_| ()).is_ok());
    let stray = validate_changed(|p| p.tolerance = Some(0.1));
    assert!(stray.unwrap_err().contains("adaptive = true"));
    let faces = RemeshParams {
        adaptive: true,
        target_faces: Some(1000),
        ..RemeshParams::default()
    };
    assert!(faces.validate().unwrap_err().contains("target_faces"));
    let both = adaptive_changed(&|p| {
        p.tolerance = Some(0.1);
        p.tolerance_fraction = Some(0.001);
    });
    assert!(both.is_err());
    for bad in [0.0, -1.0, f64::NAN, 2.0] {
        assert!(
            adaptive_changed(&|p| p.tolerance_fraction = Some(bad)).is_err(),
            "{bad}"
        );
    }
    let above = adaptive_changed(&|p| p.min_edge_fraction = Some(0.02));
    assert!(above.unwrap_err().contains("must not exceed"));
    // Mixed units: found when the scan is known.
    assert!(adaptive_changed(&|p| p.min_edge_length = Some(10.0)).is_ok());
    let mixed = RemeshParams {
        min_edge_length: Some(10.0),
        ..adaptive(0.01)
    };
    let e = remesh(&shapes::cube(), &mixed).unwrap_err();
    assert!(matches!(e, RemeshError::MinEdgeAboveMax { .. }), "{e}");
    let patches = RemeshParams {
        method: Method::Patches,
        adaptive: true,
        ..RemeshParams::default()
    };
    assert!(patches.validate().unwrap_err().contains("isotropic"));
}

#[test]
fn adaptive_keys_stay_out_of_the_resolved_recipe_when_absent() {
    let v = serde_json::to_value(fraction(0.01)).unwrap();
    for key in [
        "adaptive",
        "tolerance",
        "tolerance_fraction",
        "min_edge_length",
        "min_edge_fraction",
    ] {
        assert!(v.get(key).is_none(), "{key} in {v}");
    }
    let v = serde_json::to_value(adaptive(0.01)).unwrap();
    assert_eq!(v["adaptive"], true);
}

fn repaired(c: &mut Corners, lines: &Lines, mesh: &Mesh) -> repair::Repairs {
    let bvh = crate::geom::bvh::TriangleBvh::new(mesh, (0..mesh.triangles.len() as u32).collect());
    repair::repair(c, lines, &bvh, mesh, &mut ops::Scratch::default(), None)
}

#[test]
fn repair_turns_faces_back_to_the_input() {
    let mesh = shapes::grid(8, 8);
    let (mut c, lines) = working(&mesh);
    // An inner vertex dragged past its right-hand neighbour: its faces on that side face -z.
    let v = 4 * 9 + 4;
    c.pos[v] = glam::DVec3::new(5.6, 4.3, 0.0);
    let turned = |c: &Corners| {
        (0..c.face_count())
            .filter(|&f| !c.face_dead[f] && c.face_cross(f).z <= 0.0)
            .count()
    };
    assert!(turned(&c) > 0);
    let r = repaired(&mut c, &lines, &mesh);
    assert_eq!(r.turned, turned_before(&mesh, v));
    assert_eq!((r.left, r.left_unmovable), (0, 0), "{r:?}");
    assert!(r.changed());
    assert_eq!(turned(&c), 0);
    c.check().unwrap();
}

/// The faces of the grid turned or degenerate with vertex `v` moved as in the test above.
fn turned_before(mesh: &Mesh, v: usize) -> usize {
    let mut m = mesh.clone();
    m.positions[v] = glam::DVec3::new(5.6, 4.3, 0.0);
    (0..m.triangles.len())
        .filter(|&t| m.triangle_cross(t).z <= 1e-9)
        .count()
}

#[test]
fn repair_leaves_a_mesh_that_agrees_untouched() {
    let mesh = shapes::uv_sphere(1.0, 12, 24);
    let (mut c, lines) = working(&mesh);
    let before = c.pos.clone();
    let r = repaired(&mut c, &lines, &mesh);
    assert_eq!(r, repair::Repairs::default());
    assert_eq!(c.pos, before);
}

/// The adaptive size's warning: only past eight times the triangles of a uniform remesh at
/// the longest edge (the scans' 3–5 times pass), and it says how many and what to change.
#[test]
fn growth_note_only_for_many_more_triangles() {
    assert_eq!(super::growth_note(24_000.0, 111_000.0), None);
    let note = super::growth_note(61_000.0, 639_316.0).unwrap();
    assert!(note.contains("639316") && note.contains("10.5×"), "{note}");
    assert!(note.contains("tolerance"), "{note}");
}

/// Mean length of the edges of `mesh` whose middle is within `near` of the square
/// [lo, hi]²'s sides (`true`) or further in than `far` (`false`).
fn edge_lengths_by_border_distance(
    mesh: &Mesh,
    lo: f64,
    hi: f64,
    near: f64,
    far: f64,
) -> (f64, f64) {
    let (mut border, mut inside) = (Vec::new(), Vec::new());
    for (a, b) in edges(mesh) {
        let m = 0.5 * (a + b);
        let d = [m.x - lo, hi - m.x, m.y - lo, hi - m.y]
            .into_iter()
            .fold(f64::INFINITY, f64::min);
        if d < near {
            border.push(a.distance(b));
        } else if d > far {
            inside.push(a.distance(b));
        }
    }
    (mean_and_cv(&border).0, mean_and_cv(&inside).0)
}

/// The default refines the border: edges along the square's sides at about half the
/// target, those more than 2·L in at the target, and every angle still at 30° or more
/// almost everywhere; `border_edge_ratio = 1` leaves the border at the target.
#[test]
fn a_border_gets_edges_of_half_the_target_length() {
    let mesh = shapes::grid(60, 60);
    let (lo, hi) = mesh.bounding_box().unwrap();
    let (lo, hi) = (lo.x, hi.x);
    let (out, report) = remesh(&mesh, &fraction(0.02)).unwrap();
    let l = report.edge_length;
    assert_eq!(report.border_edge, Some(0.5 * l));
    let (border, inside) = edge_lengths_by_border_distance(&out, lo, hi, 0.1 * l, 2.5 * l);
    assert!(
        (0.4 * l..0.7 * l).contains(&border),
        "border {border}, L {l}"
    );
    assert!(
        (0.85 * l..1.2 * l).contains(&inside),
        "inside {inside}, L {l}"
    );
    assert!(
        report.quality_after.share_min_angle_30 >= 0.99,
        "{report:?}"
    );
    let a = audit(&mesh, &out);
    assert_eq!(a.after.boundary_loops, 1);
    assert_eq!(a.flipped_faces, 0);

    let off = RemeshParams {
        border_edge_ratio: Some(1.0),
        ..fraction(0.02)
    };
    let (uniform, report) = remesh(&mesh, &off).unwrap();
    assert_eq!(report.border_edge, None);
    let (border, _) = edge_lengths_by_border_distance(&uniform, lo, hi, 0.1 * l, 2.5 * l);
    assert!(border > 0.85 * l, "border {border}, L {l}");
    assert!(out.triangles.len() > uniform.triangles.len());
}

/// A closed mesh has no border to refine: the default's result is the one without.
#[test]
fn a_closed_mesh_is_not_affected_by_the_border_refinement() {
    let mesh = shapes::torus(1.0, 0.3, 40, 20);
    let off = RemeshParams {
        border_edge_ratio: Some(1.0),
        ..fraction(0.05)
    };
    let (a, ra) = remesh(&mesh, &fraction(0.05)).unwrap();
    let (b, _) = remesh(&mesh, &off).unwrap();
    assert_eq!(a, b);
    assert_eq!(ra.border_edge, None);
}

/// With `target_faces` a refined border does not add to the count asked for: the whole
/// field is scaled so the expected count is the target.
#[test]
fn target_faces_holds_with_a_refined_border() {
    let mesh = shapes::grid(60, 60);
    let params = RemeshParams {
        target_faces: Some(4000),
        ..RemeshParams::default()
    };
    let (out, report) = remesh(&mesh, &params).unwrap();
    let n = out.triangles.len() as f64;
    assert!((3600.0..4400.0).contains(&n), "{n} faces");
    let border = report.border_edge.unwrap();
    assert!(
        (border - 0.5 * report.edge_length).abs() < 1e-9 * border,
        "{report:?}"
    );
}

#[test]
fn border_edge_ratio_validates() {
    for bad in [0.0, 0.1, 1.5, f64::NAN] {
        let e = validate_changed(|p| p.border_edge_ratio = Some(bad)).unwrap_err();
        assert!(e.contains("border_edge_ratio"), "{bad}: {e}");
    }
    assert!(validate_changed(|p| p.border_edge_ratio = Some(0.3)).is_ok());
    // Patches refuse it (their borders are not refined).
    let patches = RemeshParams {
        method: Method::Patches,
        border_edge_ratio: Some(0.5),
        ..RemeshParams::default()
    };
    let e = patches.validate().unwrap_err();
    assert!(e.contains("border_edge_ratio"), "{e}");
}

#[test]
fn bake_texture_is_isotropic_only() {
    assert!(validate_changed(|p| p.bake_texture = true).is_ok());
    let patches = RemeshParams {
        method: Method::Patches,
        bake_texture: true,
        ..RemeshParams::default()
    };
    let e = patches.validate().unwrap_err();
    assert!(e.contains("bake_texture"), "{e}");
}

/// The sliver pass on a flat grid (its own input) with vertex `v` moved to `to`, at a
/// uniform size `l`: what it did, and the working mesh after it.
fn slivers_cleaned(v: usize, to: glam::DVec3, l: f64) -> (slivers::Slivers, Corners) {
    let mesh = shapes::grid(6, 6);
    let (mut c, lines) = working(&mesh);
    c.pos[v] = to;
    let bvh = crate::geom::bvh::TriangleBvh::new(&mesh, (0..mesh.triangles.len() as u32).collect());
    let input = repair::Input {
        bvh: &bvh,
        mesh: &mesh,
        lines: &lines,
    };
    let sizing = sizing::Sizing::uniform(l);
    let r = slivers::clean(&mut c, &input, &sizing, &mut ops::Scratch::default());
    c.check().unwrap();
    (r, c)
}

/// The smallest angle of the live faces, and whether they all still face +z (the input's
/// way).
fn smallest_and_facing(c: &Corners) -> (f64, bool) {
    let live = (0..c.face_count()).filter(|&f| !c.face_dead[f]);
    let smallest = live
        .clone()
        .map(|f| quality::min_angle(c.face_positions(f)))
        .fold(f64::INFINITY, f64::min);
    (smallest, live.into_iter().all(|f| c.face_cross(f).z > 0.0))
}

/// A needle (an inner vertex 0.05 from its right-hand neighbour) is collapsed; a cap (an
/// inner vertex close to the middle of its neighbours' edge) is flipped; both leave no face
/// under 10°, none turned, the table whole.
#[test]
fn slivers_inside_are_collapsed_or_flipped() {
    let v = 3 * 7 + 3;
    let (r, c) = slivers_cleaned(v, glam::DVec3::new(3.95, 3.0, 0.0), 2.0);
    assert!(r.found > 0 && r.collapses > 0 && r.left == 0, "{r:?}");
    let (smallest, facing) = smallest_and_facing(&c);
    assert!(
        smallest >= slivers::SLIVER_ANGLE && facing,
        "{smallest} {r:?}"
    );
    // The face (3,3) (4,3) (4,4) with its corner (3,3) near the middle of (4,3)–(4,4).
    let (r, c) = slivers_cleaned(v, glam::DVec3::new(3.95, 3.5, 0.0), 1.0);
    assert!(r.found > 0 && r.flips > 0 && r.left == 0, "{r:?}");
    let (smallest, facing) = smallest_and_facing(&c);
    assert!(
        smallest >= slivers::SLIVER_ANGLE && facing,
        "{smallest} {r:?}"
    );
}

/// A sliver with a corner on the border is left: a border vertex may not leave its line.
#[test]
fn slivers_at_a_border_are_left() {
    // (1,0) on the bottom border, pulled up close to its neighbour (1,1).
    let (r, c) = slivers_cleaned(1, glam::DVec3::new(1.0, 0.9, 0.0), 2.0);
    assert_eq!(r, slivers::Slivers::default());
    assert!(smallest_and_facing(&c).0 < slivers::SLIVER_ANGLE);
}
