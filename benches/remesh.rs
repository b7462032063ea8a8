//! `remesh` speed: `isotropic` at the edge length of 1 % of the diagonal with 3 iterations (the
//! setting MeshLab was measured at in issue #24: 2.9 s facefuns, 0.9 s james, 2.6 s bunny,
//! 10.9 s igea on this machine) on those four scans, and `patches` with its defaults on igea
//! (269k triangles) and Lucy (100k; the aim is under 5 s for 100k triangles).
//! `isotropic adaptive` is the same with `adaptive = true` (1 % of the diagonal the longest
//! edge, the default tolerance and shortest edge), on the same scans.
//! `isotropic james bake_texture` is James's case with the texture baked (`ops::bake`: 1.3 M
//! texels of its 2400×1600 photo read from the input surface, and the PNG encoded).
//! Each scan is numbered as `scanmill process` numbers it before the step: for locality
//! (`Mesh::reorder_for_locality`) before `isotropic`, in the file's order before `patches`.
//! A scan that is missing fails the bench: the figures must not quietly shrink.

use criterion::{Criterion, criterion_group};
use scanmill::mesh::{LoadOptions, Mesh, load};
use scanmill::ops::remesh::{Method, RemeshParams, remesh};
use std::hint::black_box;
use std::path::Path;

const DATA: &str = "../shared/data/";

fn scan(rel: &str) -> Mesh {
    let options = LoadOptions {
        check_textures: false,
        ..Default::default()
    };
    let path = format!("{DATA}{rel}");
    load(Path::new(&path), &options)
        .unwrap_or_else(|e| panic!("{path}: {e}"))
        .0
}

fn bench(c: &mut Criterion) {
    let isotropic = RemeshParams {
        method: Method::Isotropic,
        edge_fraction: Some(0.01),
        iterations: 3,
        ..Default::default()
    };
    let adaptive = RemeshParams {
        adaptive: true,
        ..isotropic.clone()
    };
    // The cost of the least-squares fit: the same runs with every vertex left on the input.
    let on_surface = RemeshParams {
        on_surface: true,
        ..isotropic.clone()
    };
    let baked = RemeshParams {
        bake_texture: true,
        ..isotropic.clone()
    };
    let patches = RemeshParams {
        method: Method::Patches,
        ..Default::default()
    };
    let cases = [
        (
            "isotropic facefuns",
            "textured/facefuns_di3d_face/example.obj",
            &isotropic,
        ),
        (
            "isotropic james",
            "textured/james_face_stereo_capture/james.obj",
            &isotropic,
        ),
        (
            "isotropic bunny",
            "untextured/stanford_bunny/bun_zipper.ply",
            &isotropic,
        ),
        (
            "isotropic igea",
            "untextured/misc_scans/igea_cyberware_trilist_DERIVED.ply.gz",
            &isotropic,
        ),
        (
            "isotropic james on_surface",
            "textured/james_face_stereo_capture/james.obj",
            &on_surface,
        ),
        (
            "isotropic igea on_surface",
            "untextured/misc_scans/igea_cyberware_trilist_DERIVED.ply.gz",
            &on_surface,
        ),
        (
            "isotropic james bake_texture",
            "textured/james_face_stereo_capture/james.obj",
            &baked,
        ),
        (
            "isotropic adaptive facefuns",
            "textured/facefuns_di3d_face/example.obj",
            &adaptive,
        ),
        (
            "isotropic adaptive james",
            "textured/james_face_stereo_capture/james.obj",
            &adaptive,
        ),
        (
            "isotropic adaptive bunny",
            "untextured/stanford_bunny/bun_zipper.ply",
            &adaptive,
        ),
        (
            "isotropic adaptive igea",
            "untextured/misc_scans/igea_cyberware_trilist_DERIVED.ply.gz",
            &adaptive,
        ),
        (
            "patches igea",
            "untextured/misc_scans/igea_cyberware_trilist_DERIVED.ply.gz",
            &patches,
        ),
        (
            "patches lucy",
            "untextured/misc_scans/stanford_lucy_100k.ply",
            &patches,
        ),
    ];
    let mut group = c.benchmark_group("remesh");
    group.sample_size(10);
    for (name, rel, params) in cases {
        let mut mesh = scan(rel);
        if params.method == Method::Isotropic {
            mesh.reorder_for_locality();
        }
        params.validate().unwrap();
        group.bench_function(name, |b| {
            b.iter(|| remesh(black_box(&mesh), params).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
scanmill::criterion_main_on_pool!(benches);
