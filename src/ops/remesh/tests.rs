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
    let n = isotropic::split_long(&mut c, &lines, 4.0 / 3.0 * l);
    assert!(n > 0);
    c.check().unwrap();
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
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| remesh(&mesh, &fraction(0.03)).unwrap().0)
    };
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

#[test]
fn params_validate() {
    assert!(RemeshParams::default().validate().is_err());
    assert!(fraction(0.01).validate().is_ok());
    let both = RemeshParams {
        edge_length: Some(1.0),
        ..fraction(0.01)
    };
    assert!(both.validate().is_err());
    let patches = RemeshParams {
        method: Method::Patches,
        ..fraction(0.01)
    };
    assert!(patches.validate().unwrap_err().contains("isotropic"));
    assert!(fraction(0.0).validate().is_err());
    let zero = RemeshParams {
        iterations: 0,
        ..fraction(0.01)
    };
    assert!(zero.validate().is_err());
}
