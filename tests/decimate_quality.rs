//! Quality against the input with `metrics::compare`, side by side with meshoptimizer's
//! `simplify_with_attributes` (texture coordinates as attributes, weight 1) at the same
//! target (issue #5), and the effect of `seam_fix` after clustering.

mod common;

use scanmill::mesh::io::load;
use scanmill::mesh::{LoadOptions, Material, Mesh, Texture};
use scanmill::metrics::{FinalMetrics, MetricsOptions, TextureDeviation, compare};
use scanmill::ops::decimate::{DecimateParams, Method, decimate};
use scanmill::ops::seam_fix::{SeamFixParams, seam_fix};

fn scan(rel: &str, texture: Option<&str>) -> Mesh {
    let dir = common::data("textured");
    let mut m = load(&dir.join(rel), &LoadOptions::default()).unwrap().0;
    if let Some(t) = texture {
        // facefuns has no MTL: pair it with its PNG (data/SOURCES.md).
        m.materials = vec![Material {
            name: "texture".into(),
            diffuse_texture: Some(Texture {
                name: t.into(),
                path: dir.join(t),
                size: None,
                embedded: None,
            }),
            ..Default::default()
        }];
        m.triangle_materials.clear();
    }
    m
}

fn meshopt(mesh: &Mesh, target: usize) -> Mesh {
    let verts: Vec<u8> = mesh
        .wedges
        .iter()
        .flat_map(|w| mesh.positions[w.vertex as usize].as_vec3().to_array())
        .flat_map(f32::to_le_bytes)
        .collect();
    let attrs: Vec<f32> = mesh
        .wedges
        .iter()
        .flat_map(|w| {
            let uv = w
                .texcoord
                .map(|t| mesh.texcoords[t as usize])
                .unwrap_or_default();
            [uv.x as f32, uv.y as f32]
        })
        .collect();
    let indices: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
    let adapter = meshopt::VertexDataAdapter::new(&verts, 12, 0).unwrap();
    let out = meshopt::simplify_with_attributes_and_locks(
        &indices,
        &adapter,
        &attrs,
        &[1.0, 1.0],
        8,
        &vec![false; mesh.wedges.len()],
        target * 3,
        1.0,
        meshopt::SimplifyOptions::None,
        None,
    );
    let mut m = mesh.clone();
    m.triangles = out.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    m.triangle_materials.clear();
    m.triangle_origins.clear();
    m.compact();
    m
}

fn metrics(result: &Mesh, input: &Mesh) -> FinalMetrics {
    let options = MetricsOptions {
        samples: 50_000,
        ..Default::default()
    };
    compare(result, input, &options).unwrap()
}

fn texture_mean(m: &FinalMetrics) -> f64 {
    match &m.texture {
        TextureDeviation::Measured { mean, .. } => *mean,
        other => panic!("texture deviation not measured: {other:?}"),
    }
}

#[test]
fn facefuns_beats_meshopt_and_meshlab_reference() {
    let input = scan(
        "facefuns_di3d_face/example.obj",
        Some("facefuns_di3d_face/example.png"),
    );
    let p = DecimateParams {
        target_faces: Some(26_000),
        ..Default::default()
    };
    // Mean / RMS distance in % of the diagonal, texture deviation.
    let (a, b) = against_meshopt(&input, &p);
    assert!(
        a[0] < b[0] && a[1] < b[1],
        "distance: ours {a:?}, meshopt {b:?}"
    );
    // MeshLab's textured quadric decimation on this scan (issue #5): 0.0049 % / 0.0064 %.
    assert!(a[0] < 0.0049 && a[1] < 0.0064, "{a:?}");
    assert!(a[2] < b[2], "texture: ours {a:?}, meshopt {b:?}");
}

#[test]
fn seam_fix_repairs_clustering_across_charts() {
    let input = scan("esp32cam_meshroom_raw/texturedMesh.obj", None);
    let p = DecimateParams {
        method: Method::Cluster,
        target_faces: Some(26_000),
        ..Default::default()
    };
    let (mut out, _) = decimate(&input, &p).unwrap();
    let m = metrics(&out, &input);
    // A cell's representative stays near its vertices: before that guard, cells with a
    // nearly singular quadric put vertices up to 20 % of the diagonal away from the input
    // (one-sided, result to input; 0.2 % with it).
    let away = m.distance.result_to_reference.max / m.distance.bbox_diagonal;
    assert!(
        away < 0.01,
        "cluster result → input max distance {away} of the diagonal"
    );
    let before = texture_mean(&m);
    let r = seam_fix(&mut out, &input, &SeamFixParams::default());
    let after = texture_mean(&metrics(&out, &input));
    eprintln!("cluster texture deviation {before:.2} → {after:.2} ({r:?})");
    assert!(r.repaired > 0 && after < before / 2.0, "{before} → {after}");
}

/// Distance and texture deviation of ours and meshoptimizer's, both → 26,000 faces.
fn against_meshopt(input: &Mesh, p: &DecimateParams) -> ([f64; 3], [f64; 3]) {
    let (ours, _) = decimate(input, p).unwrap();
    let theirs = meshopt(input, 26_000);
    let figures = |m: &FinalMetrics| {
        let diag = m.distance.bbox_diagonal;
        [
            m.distance.result_to_reference.mean / diag * 100.0,
            m.distance.result_to_reference.rms / diag * 100.0,
            texture_mean(m),
        ]
    };
    let (a, b) = (
        figures(&metrics(&ours, input)),
        figures(&metrics(&theirs, input)),
    );
    eprintln!("ours mean/RMS % / texture {a:?}; meshopt {b:?}");
    (a, b)
}

/// Scans whose texture atlas has many small charts (on esp32cam two thirds of the area
/// touches a seam vertex): the seam planes (`seam_weight`) keep the seams where they are,
/// so ours is below meshoptimizer in distance and in texture deviation; without them the
/// seams straighten and the texture deviation is the higher.
#[test]
fn seam_heavy_scans_beat_meshopt_with_seam_planes() {
    let p = DecimateParams {
        target_faces: Some(26_000),
        ..Default::default()
    };
    for rel in [
        "esp32cam_meshroom_raw/texturedMesh.obj",
        "smithsonian_usnm1145291_draco/usnm1145291_converted.obj.gz",
    ] {
        let input = scan(rel, None);
        let (a, b) = against_meshopt(&input, &p);
        assert!(a[0] < b[0] && a[1] < b[1], "{rel}: distance {a:?} vs {b:?}");
        assert!(a[2] < b[2], "{rel}: texture {a:?} vs {b:?}");
    }
    let input = scan("esp32cam_meshroom_raw/texturedMesh.obj", None);
    let without = DecimateParams {
        seam_weight: Some(0.0),
        ..p.clone()
    };
    let (with_planes, _) = against_meshopt(&input, &p);
    let (no_planes, _) = against_meshopt(&input, &without);
    assert!(
        with_planes[2] < no_planes[2],
        "texture with seam planes {with_planes:?}, without {no_planes:?}"
    );
}
