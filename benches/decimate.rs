//! Decimation speed against meshoptimizer (issue #5): a 400,000-triangle textured scan (the
//! USNM coral, 100k triangles, subdivided once with `ops::subdivide`) to 26,000 faces, with
//! face collapse, edge collapse, the two clustering methods and meshoptimizer's
//! `simplify_with_attributes` (texture coordinates as attributes, weight 1) in one run.
//! Also the 59,697-triangle facefuns face to 26,000 faces.

use criterion::{Criterion, criterion_group, criterion_main};
use scanmill::mesh::io::load;
use scanmill::mesh::{LoadOptions, Mesh};
use scanmill::ops::decimate::{DecimateParams, Halves, Method, decimate};
use scanmill::ops::subdivide::subdivide;
use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

fn scan(rel: &str) -> Mesh {
    load(
        &Path::new("../shared/data").join(rel),
        &LoadOptions::default(),
    )
    .expect("scan")
    .0
}

/// meshoptimizer on the wedge buffer, texture coordinates as attributes.
fn meshopt_simplify(mesh: &Mesh, target: usize) -> usize {
    let verts: Vec<[f32; 3]> = mesh
        .wedges
        .iter()
        .map(|w| mesh.positions[w.vertex as usize].as_vec3().to_array())
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
    let bytes: Vec<u8> = verts
        .iter()
        .flatten()
        .flat_map(|f| f.to_le_bytes())
        .collect();
    let adapter = meshopt::VertexDataAdapter::new(&bytes, 12, 0).expect("adapter");
    let locks = vec![false; verts.len()];
    meshopt::simplify_with_attributes_and_locks(
        &indices,
        &adapter,
        &attrs,
        &[1.0, 1.0],
        8,
        &locks,
        target * 3,
        1.0,
        meshopt::SimplifyOptions::None,
        None,
    )
    .len()
        / 3
}

fn bench(c: &mut Criterion) {
    let coral = subdivide(&scan(
        "textured/smithsonian_usnm1145291_draco/usnm1145291_converted.obj.gz",
    ));
    let face = scan("textured/facefuns_di3d_face/example.obj");
    let mut g = c.benchmark_group("decimate");
    g.sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(8));
    for (name, mesh) in [("coral-400k", &coral), ("facefuns-60k", &face)] {
        g.bench_function(format!("{name}/meshopt"), |b| {
            b.iter(|| black_box(meshopt_simplify(mesh, 26_000)))
        });
        for method in [
            Method::FaceCollapse,
            Method::EdgeCollapse,
            Method::Cluster,
            Method::ClusterKeep,
        ] {
            let p = DecimateParams {
                method,
                target_faces: Some(26_000),
                ..Default::default()
            };
            g.bench_function(format!("{name}/{}", method.name()), |b| {
                b.iter(|| black_box(decimate(mesh, &p).unwrap().0.triangles.len()))
            });
        }
        // The default edge collapse decimates a large scan's halves on two cores first
        // (`halves = "auto"`); this is the single pass beside it.
        let one_pass = DecimateParams {
            target_faces: Some(26_000),
            halves: Halves::Off,
            ..Default::default()
        };
        g.bench_function(format!("{name}/edge-collapse-one-pass"), |b| {
            b.iter(|| black_box(decimate(mesh, &one_pass).unwrap().0.triangles.len()))
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
