//! Decimation speed against meshoptimizer (issues #5 and #27): scanmill's decimate step as
//! the face-scan recipe runs it (edge collapse to 26,000 faces, borders kept, halves
//! `auto`) beside meshoptimizer's `simplify_with_attributes` (texture coordinates as
//! attributes, weight 1) on the same input, in one run, on every scan of 50,000 triangles or
//! more in ../shared/data and on two 400,000-triangle scans:
//!
//! - face400k: facefuns made scanner-sized with noise (benches/common, as the face_scan
//!   bench makes it);
//! - coral-400k: the USNM coral made scanner-sized at 399,972 triangles, which is the whole
//!   coral subdivided once (one chart per texture island: 41,280 seam edges).
//!
//! Every input is renumbered for locality first (`Mesh::reorder_for_locality`), as
//! `scanmill process` does before a recipe that decimates, and loses the scan's own normals,
//! as the face-scan recipe's runner drops them (its `normals` step replaces them); both
//! decimators get that mesh, with texture coordinates as the only attributes.
//! On the coral the other methods (face collapse, the two clusterings) and edge collapse in
//! one pass run too.
//!
//! cargo bench --bench decimate                                  # everything (~4 min)
//! cargo bench --bench decimate -- '/(meshopt|scanmill)$'         # the side-by-side only
//! cargo bench --bench decimate -- 'coral-400k/'                 # one scan, every method

mod common;

use criterion::{Criterion, criterion_group};
use scanmill::mesh::io::load;
use scanmill::mesh::{LoadOptions, Mesh};
use scanmill::ops::decimate::{DecimateParams, Halves, Method, decimate};
use scanmill::ops::subdivide::scanner_sized;
use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

const TARGET: usize = 26_000;

/// The scans of ../shared/data with 50,000 triangles or more (SOURCES.md; igea once, the
/// tristrip file holds the same triangles), with the name the bench gives each.
const SCANS: [(&str, &str); 11] = [
    ("facefuns-60k", "textured/facefuns_di3d_face/example.obj"),
    (
        "esp32cam-53k",
        "textured/esp32cam_meshroom_raw/texturedMesh.obj",
    ),
    (
        "ict-52k",
        "textured/ict_facekit_neutral/generic_neutral_mesh.obj",
    ),
    (
        "usnm-coral-100k",
        "textured/smithsonian_usnm1145291_draco/usnm1145291_converted.obj.gz",
    ),
    ("bunny-69k", "untextured/stanford_bunny/bun_zipper.ply"),
    (
        "bunny-range-79k",
        "untextured/stanford_bunny_range_scans/bun000_grid_triangulated_DERIVED.ply",
    ),
    (
        "nefertiti-70k",
        "untextured/misc_scans/nefertiti_hack_lowres.obj",
    ),
    (
        "armadillo-86k",
        "untextured/misc_scans/stanford_armadillo_libigl.obj.gz",
    ),
    ("lucy-100k", "untextured/misc_scans/stanford_lucy_100k.ply"),
    (
        "castle-175k",
        "raw_photogrammetry/openmvs_sceaux_castle_scene_mesh_refine.ply",
    ),
    (
        "igea-269k",
        "untextured/misc_scans/igea_cyberware_trilist_DERIVED.ply.gz",
    ),
];

const CORAL: &str = "textured/smithsonian_usnm1145291_draco/usnm1145291_converted.obj.gz";
/// The coral's 99,993 triangles subdivided once: `scanner_sized` keeps them all.
const CORAL_400K: usize = 399_972;

fn scan(rel: &str) -> Mesh {
    load(
        &Path::new("../shared/data").join(rel),
        &LoadOptions::default(),
    )
    .expect("scan")
    .0
}

/// The mesh as `scanmill process` hands it to the face-scan recipe's decimation: without the
/// scan's own normals (the recipe's `normals` step replaces them, so the runner drops them
/// first; meshoptimizer below gets no normals either) and numbered for locality.
fn as_the_recipe_runs(mut mesh: Mesh) -> Mesh {
    mesh.drop_normals();
    mesh.reorder_for_locality();
    mesh
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

/// The inputs in the order they are benched: the two 400k scans first.
fn inputs() -> Vec<(String, Mesh)> {
    let mut inputs = vec![(
        "coral-400k".to_string(),
        as_the_recipe_runs(scanner_sized(&scan(CORAL), CORAL_400K)),
    )];
    if let Some(face) = common::face400k() {
        inputs.push(("face400k".to_string(), as_the_recipe_runs(face)));
    }
    for (name, rel) in SCANS {
        inputs.push((name.to_string(), as_the_recipe_runs(scan(rel))));
    }
    inputs
}

/// The coral's other methods: every decimator this crate has, on the multi-chart scan.
fn other_methods(
    g: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    coral: &Mesh,
) {
    for method in [Method::FaceCollapse, Method::Cluster, Method::ClusterKeep] {
        let p = DecimateParams {
            method,
            target_faces: Some(TARGET),
            ..Default::default()
        };
        g.bench_function(format!("coral-400k/{}", method.name()), |b| {
            b.iter(|| black_box(decimate(coral, &p).unwrap().0.triangles.len()))
        });
    }
    // The default edge collapse decimates a large scan's halves on two cores first
    // (`halves = "auto"`); this is the single pass beside it.
    let one_pass = DecimateParams {
        target_faces: Some(TARGET),
        halves: Halves::Off,
        ..Default::default()
    };
    g.bench_function("coral-400k/edge-collapse-one-pass", |b| {
        b.iter(|| black_box(decimate(coral, &one_pass).unwrap().0.triangles.len()))
    });
}

fn bench(c: &mut Criterion) {
    let inputs = inputs();
    let mut g = c.benchmark_group("decimate");
    g.sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(5));
    // The face-scan recipe's step: edge collapse, borders kept, halves `auto`.
    let step = DecimateParams {
        target_faces: Some(TARGET),
        ..Default::default()
    };
    for (name, mesh) in &inputs {
        g.bench_function(format!("{name}/meshopt"), |b| {
            b.iter(|| black_box(meshopt_simplify(mesh, TARGET)))
        });
        g.bench_function(format!("{name}/scanmill"), |b| {
            b.iter(|| black_box(decimate(mesh, &step).unwrap().0.triangles.len()))
        });
    }
    other_methods(&mut g, &inputs[0].1);
    g.finish();
}

criterion_group!(benches, bench);
scanmill::criterion_main_on_pool!(benches);
