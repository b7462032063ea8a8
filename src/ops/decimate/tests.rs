//! Unit tests of the collapse machinery on generated shapes.

use super::*;
use crate::mesh::shapes::{assert_faces_outward, grid, uv_sphere};
use crate::mesh::topology::Topology;
use crate::mesh::{Index, Wedge};
use crate::ops::subdivide::subdivide;
use glam::{DVec2, DVec3};

fn params(method: Method, target: usize) -> DecimateParams {
    DecimateParams {
        method,
        target_faces: Some(target),
        ..Default::default()
    }
}

/// A bumpy grid: z = small sine bumps, so the quadrics are not degenerate everywhere.
fn bumpy_grid(n: usize) -> Mesh {
    let mut m = grid(n, n);
    for p in &mut m.positions {
        p.z = 0.3 * ((p.x * 0.4).sin() * (p.y * 0.3).cos());
    }
    m
}

/// A grid whose left and right halves use separate texture charts: a seam down x = n/2.
fn seamed_grid(n: usize) -> Mesh {
    let mut m = bumpy_grid(n);
    let half = (n / 2) as f64;
    // Right chart: texture coordinates shifted by +2 in u; seam vertices get a second wedge.
    let nv = m.positions.len();
    for v in 0..nv {
        let uv = m.texcoords[v];
        m.texcoords.push(DVec2::new(uv.x + 2.0, uv.y));
    }
    let mut right_wedge = vec![Index::MAX; nv];
    for t in 0..m.triangles.len() {
        let p = m.triangle_positions(t);
        let cx = (p[0].x + p[1].x + p[2].x) / 3.0;
        if cx > half {
            for k in 0..3 {
                let v = m.wedges[m.triangles[t][k] as usize].vertex as usize;
                if m.positions[v].x >= half {
                    if right_wedge[v] == Index::MAX {
                        m.wedges.push(Wedge {
                            vertex: v as Index,
                            texcoord: Some((nv + v) as Index),
                            normal: None,
                        });
                        right_wedge[v] = (m.wedges.len() - 1) as Index;
                    }
                    m.triangles[t][k] = right_wedge[v];
                }
            }
        }
    }
    m.compact();
    m
}

fn counts(m: &Mesh) -> crate::mesh::topology::TopologyCounts {
    Topology::new(m).counts()
}

#[test]
fn grid_reaches_target_and_keeps_border_and_linear_texture() {
    let m = bumpy_grid(40);
    let (out, r) = decimate(&m, &params(Method::FaceCollapse, 800)).unwrap();
    out.check_invariants().unwrap();
    assert!(
        out.triangles.len() <= 800 && out.triangles.len() + 4 >= 800,
        "{r:?}"
    );
    let (a, b) = (counts(&m), counts(&out));
    assert_eq!(b.non_manifold_edges, 0);
    assert_eq!(b.non_manifold_vertices, 0);
    assert_eq!(a.boundary_edges, b.boundary_edges, "keep: border untouched");
    assert_eq!(a.boundary_loops, b.boundary_loops);
    // Texture coordinates are linear in x, y on the input, so the wedge quadric's
    // prediction is exact wherever a vertex goes.
    for w in &out.wedges {
        let p = out.positions[w.vertex as usize];
        let uv = out.texcoords[w.texcoord.unwrap() as usize];
        assert!((uv.x - p.x / 40.0).abs() < 1e-9 && (uv.y - p.y / 40.0).abs() < 1e-9);
    }
    assert_eq!(out.triangle_origins.len(), out.triangles.len());
    assert_eq!(r.faces_after, out.triangles.len());
}

#[test]
fn sphere_stays_closed_manifold_and_unflipped() {
    let m = subdivide(&uv_sphere(1.0, 24, 48));
    let before = counts(&m);
    for method in [Method::FaceCollapse, Method::EdgeCollapse] {
        let (out, r) = decimate(&m, &params(method, 600)).unwrap();
        let c = counts(&out);
        assert!(
            out.triangles.len() <= 600 && out.triangles.len() + 4 >= 600,
            "{method:?} {r:?}"
        );
        assert_eq!(c.boundary_edges, 0, "{method:?}");
        assert_eq!(c.non_manifold_edges, 0);
        assert_eq!(c.non_manifold_vertices, 0);
        assert_eq!(c.euler_characteristic, before.euler_characteristic);
        assert_faces_outward(&out);
        for t in 0..out.triangles.len() {
            assert!(out.triangle_area(t) > 1e-9);
        }
        // Vertices stay near the sphere.
        for p in &out.positions {
            assert!(
                (p.length() - 1.0).abs() < 0.02,
                "{method:?}: {}",
                p.length()
            );
        }
    }
}

#[test]
fn seams_stay_seams_and_charts_do_not_mix() {
    let m = seamed_grid(40);
    let before = counts(&m);
    assert!(before.texture_seam_edges > 0);
    for method in [Method::FaceCollapse, Method::EdgeCollapse] {
        let (out, r) = decimate(&m, &params(method, 600)).unwrap();
        let after = counts(&out);
        assert!(out.triangles.len() <= 600, "{method:?} {r:?}");
        assert!(
            after.texture_seam_edges > 0 && after.texture_seam_edges <= before.texture_seam_edges
        );
        assert_eq!(after.boundary_edges, before.boundary_edges);
        assert_eq!(after.non_manifold_edges, 0);
        for t in 0..out.triangles.len() {
            let uvs = out.triangles[t].map(|w| out.wedge_texcoord(w).unwrap());
            let right = uvs.iter().filter(|uv| uv.x > 1.5).count();
            assert!(
                right == 0 || right == 3,
                "{method:?}: triangle {t} mixes charts: {uvs:?}"
            );
            // Right chart is u = x/40 + 2, left u = x/40: both exact.
            for (k, uv) in uvs.iter().enumerate() {
                let p = out.positions[out.wedges[out.triangles[t][k] as usize].vertex as usize];
                let u = if right == 3 {
                    p.x / 40.0 + 2.0
                } else {
                    p.x / 40.0
                };
                assert!((uv.x - u).abs() < 1e-9, "{method:?}: u {} vs {u}", uv.x);
            }
        }
        // Seam vertices stay on the seam line x = 20.
        for (v, p) in out.positions.iter().enumerate() {
            let wedges = out.wedges.iter().filter(|w| w.vertex as usize == v).count();
            if wedges > 1 {
                assert!((p.x - 20.0).abs() < 1e-9, "seam vertex left the seam: {p}");
            }
        }
        let _ = r;
    }
}

#[test]
fn max_error_alone_stops_early() {
    let m = bumpy_grid(30);
    let p = DecimateParams {
        max_error: Some(1e-4),
        ..Default::default()
    };
    let (out, r) = decimate(&m, &p).unwrap();
    assert!(out.triangles.len() < m.triangles.len());
    assert!(r.error_reached <= 1e-4 + 1e-12, "{}", r.error_reached);
    assert!(r.refused.max_error > 0);
    let (coarse, _) = decimate(
        &m,
        &DecimateParams {
            max_error: Some(1e-2),
            ..Default::default()
        },
    )
    .unwrap();
    assert!(coarse.triangles.len() < out.triangles.len());
}

#[test]
fn boundary_modes() {
    let m = bumpy_grid(30);
    let before = counts(&m);
    for mode in [Border::Weighted, Border::LikeInterior] {
        let p = DecimateParams {
            boundary: mode,
            ..params(Method::FaceCollapse, 300)
        };
        let (out, _) = decimate(&m, &p).unwrap();
        let c = counts(&out);
        assert_eq!(c.boundary_loops, before.boundary_loops, "{mode:?}");
        assert!(
            c.boundary_edges < before.boundary_edges,
            "{mode:?} decimates the border"
        );
        assert_eq!(c.non_manifold_edges, 0);
        if mode == Border::Weighted {
            // Border vertices slide along the border: they stay on the square's sides.
            let topo = Topology::new(&out);
            for e in topo.boundary_edges() {
                for v in topo.edge_vertices(e) {
                    let p = out.positions[v as usize];
                    let on_side = p.x.abs() < 1e-9
                        || (p.x - 30.0).abs() < 1e-9
                        || p.y.abs() < 1e-9
                        || (p.y - 30.0).abs() < 1e-9;
                    assert!(on_side, "border vertex left the border: {p}");
                }
            }
        }
    }
}

/// The same result on one thread and on several, for both collapse operators (the
/// candidates' first keys are computed in parallel).
#[test]
fn deterministic_across_thread_counts() {
    let m = seamed_grid(30);
    for method in [Method::FaceCollapse, Method::EdgeCollapse] {
        let on = |threads: usize| {
            crate::testing::on_threads(threads, || decimate(&m, &params(method, 500)).unwrap().0)
        };
        assert_eq!(on(1), on(3), "{method:?}");
    }
}

#[test]
fn estimate_priority_and_thesis_literal_modes_run() {
    let m = bumpy_grid(20);
    let p = DecimateParams {
        priority: Priority::Estimate,
        conditioning: Conditioning::ThesisLiteral,
        texture_weight: 1e-17,
        ..params(Method::FaceCollapse, 200)
    };
    let (out, r) = decimate(&m, &p).unwrap();
    assert!(out.triangles.len() <= 200);
    // reading R7: read literally, every free collapse falls back.
    assert!(r.ill_conditioned > 0);
}

#[test]
fn params_validate_and_parse() {
    assert!(DecimateParams::default().validate().is_err());
    let p: DecimateParams =
        toml::from_str("method = \"edge-collapse\"\ntarget_faces = 10\nboundary = \"weighted\"\n")
            .unwrap();
    assert_eq!(p.method, Method::EdgeCollapse);
    assert!(p.validate().is_ok());
    assert!(toml::from_str::<DecimateParams>("target = 3").is_err());
    let _ = DVec3::ZERO;
}

#[test]
fn halves_parse_and_say_when_they_cannot_apply() {
    let parse =
        |extra: &str| toml::from_str::<DecimateParams>(&format!("target_faces = 1000\n{extra}"));
    assert_eq!(parse("").unwrap().halves, super::Halves::Auto);
    assert_eq!(
        parse("halves = \"off\"").unwrap().halves,
        super::Halves::Off
    );
    assert!(parse("halves = \"on\"").unwrap().validate().is_ok());
    assert!(parse("halves = \"sometimes\"").is_err());
    // Forced halves need the kept border that holds the cut, and a face target.
    for bad in [
        "halves = \"on\"\nboundary = \"free\"",
        "halves = \"on\"\nmethod = \"face-collapse\"",
        "halves = \"on\"\nmax_error = 0.01",
    ] {
        let e = parse(bad).unwrap().validate().unwrap_err();
        assert!(e.contains("halves"), "{bad}: {e}");
    }
}

/// `halves = "auto"` splits from `AUTO_MIN_FACES` triangles and more than 3 × the target,
/// with the step's defaults (edge collapse, borders kept, a face target).
#[test]
fn halves_auto_applies_from_its_size_and_three_times_the_target() {
    let mesh_of = |n: usize| Mesh {
        triangles: vec![[0, 0, 0]; n],
        ..Mesh::default()
    };
    let at = |target: usize| params(Method::EdgeCollapse, target);
    let min = halves::AUTO_MIN_FACES;
    // The face-scan recipe's 26,000 faces: the 400k scans split, the 100k scans do not.
    assert_eq!(halves::wanted(&mesh_of(400_000), &at(26_000)), Some(26_000));
    assert_eq!(halves::wanted(&mesh_of(100_000), &at(26_000)), None);
    assert_eq!(halves::wanted(&mesh_of(min), &at(min / 4)), Some(min / 4));
    assert_eq!(halves::wanted(&mesh_of(min - 1), &at(1_000)), None);
    // Not more than 3 × the target: one pass.
    assert_eq!(halves::wanted(&mesh_of(min), &at(min / 3)), None);
    let off = DecimateParams {
        halves: super::Halves::Off,
        ..at(26_000)
    };
    assert_eq!(halves::wanted(&mesh_of(400_000), &off), None);
}

/// Work beside the collapse loop has run when the decimation returns, in one pass and in
/// halves, and the output is the plain decimation's.
#[test]
fn work_beside_the_loop_has_run_when_the_decimation_returns() {
    let m = subdivide(&uv_sphere(1.0, 24, 48));
    for halves in [super::Halves::Off, super::Halves::On] {
        let p = DecimateParams {
            halves,
            ..params(Method::EdgeCollapse, 600)
        };
        let runs = std::sync::atomic::AtomicUsize::new(0);
        let beside = || {
            runs.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
        };
        let (out, report) = decimate_beside(&m, &p, &beside).unwrap();
        assert_eq!(report.halves.is_some(), halves == super::Halves::On);
        assert_eq!(
            runs.load(std::sync::atomic::Ordering::SeqCst),
            1,
            "{halves:?}"
        );
        let (plain, plain_report) = decimate(&m, &p).unwrap();
        assert_eq!(out, plain);
        assert_eq!(report.collapses, plain_report.collapses);
    }
}

/// On a small closed mesh the halves keep it closed and reach the target; the cut's
/// vertices are found in both halves and stitched.
#[test]
fn halves_on_a_sphere_stitch_and_reach_the_target() {
    let m = subdivide(&uv_sphere(1.0, 24, 48));
    let p = DecimateParams {
        halves: super::Halves::On,
        ..params(Method::EdgeCollapse, 600)
    };
    let (out, r) = decimate(&m, &p).unwrap();
    out.check_invariants().unwrap();
    let h = r.halves.expect("decimated in halves");
    assert!(h.cut_vertices > 0);
    assert_eq!(h.faces_before[0] + h.faces_before[1], m.triangles.len());
    assert!(out.triangles.len() <= 600 && out.triangles.len() + 2 >= 600);
    let audit = super::audit::audit(&m, &out);
    assert_eq!(audit.after.boundary_edges, 0, "closed: {audit:?}");
    assert_eq!(audit.after.components, 1);
    // Every triangle still faces outwards. (Not the audit's flip count: `subdivide` leaves
    // origins that index the sphere before it was subdivided, which the audit, given the
    // subdivided mesh, reads as its own triangles.)
    assert_faces_outward(&out);
}

#[test]
fn clustering_reaches_about_the_target_with_origins() {
    let m = subdivide(&uv_sphere(1.0, 24, 48));
    for method in [Method::Cluster, Method::ClusterKeep] {
        let (out, r) = decimate(&m, &params(method, 800)).unwrap();
        out.check_invariants().unwrap();
        let n = out.triangles.len();
        assert!(n <= 800 && n > 600, "{method:?}: {n} {r:?}");
        assert_eq!(out.triangle_origins.len(), n);
        assert!(r.clusters.is_some());
        for p in &out.positions {
            assert!(
                (p.length() - 1.0).abs() < 0.05,
                "{method:?}: {}",
                p.length()
            );
        }
        if method == Method::ClusterKeep {
            // Original vertices only.
            for p in &out.positions {
                assert!(m.positions.contains(p));
            }
        }
    }
}

#[test]
fn octahedral_normals_round_trip() {
    use work::{OCT_ZERO, oct_decode, oct_encode};
    let dirs = [
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.3, -0.4, 0.5],
        [-0.7, 0.1, -0.2],
        [1e-9, 2e-9, -3e-9],
    ];
    for d in dirs {
        let n = DVec3::from_array(d).normalize();
        let back = DVec3::from_array(oct_decode(oct_encode(d))).normalize();
        assert!(n.angle_between(back) < 1e-4, "{d:?} → {back:?}");
    }
    assert_eq!(oct_encode([0.0; 3]), OCT_ZERO);
    assert_eq!(oct_decode(OCT_ZERO), [0.0; 3]);
}
