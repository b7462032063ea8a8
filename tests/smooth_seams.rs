//! The smooth step on a real textured scan with texture seams and an open border (James,
//! 12k triangles): only positions move, seams and texture coordinates stay as they were,
//! fixed border vertices do not move, and the result is the same for any thread count.

mod common;

use scanmill::mesh::Mesh;
use scanmill::ops::smooth::{MethodName, SmoothParams, smooth};

const JAMES: &str = "textured/james_face_stereo_capture/james.obj";

fn james() -> Mesh {
    common::scan_untextured(JAMES)
}

#[test]
fn only_positions_move_on_a_textured_scan() {
    let original = james();
    let topology = original.topology();
    let counts = topology.counts();
    assert!(counts.texture_seam_edges > 0 && counts.boundary_edges > 0);
    let border: Vec<usize> = (0..original.positions.len())
        .filter(|&v| topology.is_boundary_vertex(v as u32))
        .collect();
    for method in [
        MethodName::Laplace,
        MethodName::Hc,
        MethodName::Taubin,
        MethodName::Bilateral,
    ] {
        let params = SmoothParams::defaults(method);
        let mut mesh = original.clone();
        let report = smooth(&mut mesh, &params);
        assert_eq!(report.fixed_boundary_vertices, border.len());
        assert!(report.mean_displacement > 0.0, "{method:?} moved nothing");
        assert!(mesh.positions.iter().all(|p| p.is_finite()));
        for &v in &border {
            assert_eq!(
                mesh.positions[v], original.positions[v],
                "{method:?}: border moved"
            );
        }
        let mut same = mesh.clone();
        same.positions = original.positions.clone();
        assert_eq!(same, original, "{method:?} changed more than positions");
        assert_eq!(mesh.topology().counts(), counts, "{method:?}");

        // Deterministic whatever the thread count.
        let single = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let mut again = original.clone();
        single.install(|| smooth(&mut again, &params));
        assert_eq!(again.positions, mesh.positions, "{method:?}");
    }
}
