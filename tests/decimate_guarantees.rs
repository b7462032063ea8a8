//! Issue #5's guarantees on the real textured scans, at 26,000 and 5,000 faces, for face
//! and edge collapse: no new non-manifold edges or vertices, no new border edges (cracks),
//! no flipped or zero-area faces, seams stay seams (seam vertices on input seam edges),
//! texture coordinates stay in their chart, border loops kept (`boundary = "fixed"`), the
//! target reached within 4 faces unless every remaining collapse was refused (then the
//! refusals are reported), and every output triangle knows its input triangle.

mod common;

use scanmill::mesh::Mesh;
use scanmill::ops::decimate::audit::audit;
use scanmill::ops::decimate::{
    DecimateParams, Halves, Method, StopReason, decimate, decimate_with_origin,
};

const SCANS: &[&str] = &[
    "textured/james_face_stereo_capture/james.obj",
    "textured/facefuns_di3d_face/example.obj",
    "textured/esp32cam_meshroom_raw/texturedMesh.obj",
    "textured/pizza_rigsters_photogrammetry/pizza.obj",
    "textured/smithsonian_usnm1145291_draco/usnm1145291_converted.obj.gz",
    "textured/ict_facekit_neutral/generic_neutral_mesh.obj",
];

use common::scan;

fn check(rel: &str, mesh: &Mesh, method: Method, target: usize) {
    check_with(rel, mesh, method, target, Halves::Auto);
}

fn check_with(rel: &str, mesh: &Mesh, method: Method, target: usize, halves: Halves) {
    let params = DecimateParams {
        method,
        target_faces: Some(target),
        halves,
        ..Default::default()
    };
    let (out, r) = decimate(mesh, &params).unwrap();
    out.check_invariants().unwrap();
    let what = format!("{rel} {method:?} {halves:?} → {target}");
    if halves == Halves::On && mesh.triangles.len() > 3 * target {
        assert!(r.halves.is_some(), "{what}: decimated in one pass");
    }
    let a = audit(mesh, &out);
    let (b, c) = (a.before, a.after);
    assert!(
        c.non_manifold_edges <= b.non_manifold_edges,
        "{what}: {a:?}"
    );
    assert!(
        c.non_manifold_vertices <= b.non_manifold_vertices,
        "{what}: {a:?}"
    );
    assert_eq!(c.boundary_edges, b.boundary_edges, "{what}: border kept");
    assert_eq!(c.boundary_loops, b.boundary_loops, "{what}: loops kept");
    assert_eq!(a.border_edges_off_border, 0, "{what}: cracks");
    assert_eq!(c.components, b.components, "{what}: components");
    assert_eq!(a.flipped_faces, 0, "{what}");
    assert_eq!(a.zero_area_faces, 0, "{what}");
    assert_eq!(a.chart_jumps, 0, "{what}");
    assert_eq!(a.seam_vertices_off_seam, 0, "{what}");
    if b.texture_seam_edges > 0 {
        assert!(c.texture_seam_edges > 0, "{what}: seams gone");
    }
    assert_eq!(out.triangle_origins.len(), out.triangles.len());
    assert!(
        out.triangle_origins
            .iter()
            .all(|&o| (o as usize) < mesh.triangles.len())
    );
    let n = out.triangles.len();
    if mesh.triangles.len() <= target {
        assert_eq!(n, mesh.triangles.len(), "{what}");
    } else if r.stopped_by == StopReason::Target {
        assert!(n <= target && n + 4 >= target, "{what}: {n} faces");
    } else {
        // Only when every remaining collapse would break a guarantee; say which.
        assert_eq!(r.stopped_by, StopReason::NoCandidates, "{what}");
        let refused = r.refused;
        assert!(
            refused.seam + refused.locked + refused.link + refused.flip > 0,
            "{what}"
        );
        eprintln!("{what}: stopped at {n} faces, refused {refused:?}");
    }
}

#[test]
fn face_collapse_guarantees_on_real_scans() {
    for rel in SCANS {
        let mesh = scan(rel);
        for target in [26_000, 5_000] {
            check(rel, &mesh, Method::FaceCollapse, target);
        }
    }
}

#[test]
fn edge_collapse_guarantees_on_real_scans() {
    for rel in SCANS {
        let mesh = scan(rel);
        for target in [26_000, 5_000] {
            check(rel, &mesh, Method::EdgeCollapse, target);
        }
    }
}

/// The same guarantees when the halves are decimated first, on both cores (the default
/// for scans of 150,000 triangles or more and 3 × the target; it is forced here, so that every
/// scan and target large enough goes through them).
#[test]
fn edge_collapse_in_halves_keeps_the_guarantees_on_real_scans() {
    for rel in SCANS {
        let mesh = scan(rel);
        for target in [26_000, 5_000] {
            check_with(rel, &mesh, Method::EdgeCollapse, target, Halves::On);
        }
    }
}

/// The halves give the same mesh on one thread as on two.
#[test]
fn halves_do_not_depend_on_the_thread_count() {
    let rel = "textured/esp32cam_meshroom_raw/texturedMesh.obj";
    let mesh = scan(rel);
    let params = DecimateParams {
        target_faces: Some(5_000),
        halves: Halves::On,
        ..Default::default()
    };
    let on = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| decimate(&mesh, &params).unwrap())
    };
    let ((one, r1), (two, r2)) = (on(1), on(2));
    assert!(r1.halves.is_some());
    assert_eq!(one, two);
    assert_eq!(r1, r2);
}

#[test]
fn face_scans_reach_the_labs_target() {
    // The face scans have few seams: the target must be met exactly (within 4 faces).
    for rel in [SCANS[1], SCANS[5]] {
        let mesh = scan(rel);
        let p = DecimateParams {
            target_faces: Some(26_000),
            ..Default::default()
        };
        let (out, r) = decimate(&mesh, &p).unwrap();
        assert_eq!(r.stopped_by, StopReason::Target, "{rel}");
        assert!(out.triangles.len() <= 26_000 && out.triangles.len() >= 25_996);
    }
}

/// A decimated mesh decimated again (the second half of the two-phase experiment in
/// docs/decimation.md): with `decimate_with_origin` the flip guard holds each triangle
/// against its triangle in the first input, so the audit against that input stays clean.
/// Without it the guard only sees the intermediate mesh, and on the coral some output
/// triangles end up facing against their input triangle (the test checks that too, so
/// that it shows what the origin is for).
#[test]
fn second_decimation_keeps_the_flip_guarantee_against_the_first_input() {
    let rel = "textured/smithsonian_usnm1145291_draco/usnm1145291_converted.obj.gz";
    let mesh = scan(rel);
    let params = |target| DecimateParams {
        target_faces: Some(target),
        ..Default::default()
    };
    let (half, _) = decimate(&mesh, &params(40_000)).unwrap();
    let (plain, _) = decimate(&half, &params(5_000)).unwrap();
    let (held, _) = decimate_with_origin(&half, &params(5_000), Some(&mesh)).unwrap();
    let (a_plain, a_held) = (audit(&mesh, &plain), audit(&mesh, &held));
    eprintln!(
        "flipped against the first input: {} without the origin, {} with",
        a_plain.flipped_faces, a_held.flipped_faces
    );
    assert_eq!(a_held.flipped_faces, 0, "{a_held:?}");
    assert!(a_plain.flipped_faces > 0, "{a_plain:?}");
    assert!(
        held.triangle_origins
            .iter()
            .all(|&o| (o as usize) < mesh.triangles.len())
    );
}
