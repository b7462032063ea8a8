//! Bad STL and glTF/GLB input (issue #28): truncated files, lying counts, NaN coordinates,
//! URIs that leave the scan's folder, data URIs larger than they say or than the limits
//! allow, features scanmill does not read. Each is refused by `scanmill process` and
//! `scanmill inspect` with exit 65 and a one-line error, and nothing is written.

mod common;
mod hostile_support;

use base64::Engine;
use hostile_support::*;
use scanmill::mesh::{LoadOptions, load};
use serde_json::json;
use std::path::Path;

/// Refused by both commands with exit 65, one line holding every needle, nothing written.
fn refused(dir: &Path, out: &Path, file: &str, needles: &[&str]) {
    let input = dir.join(file);
    assert_refused(&process(&input, out), out, needles);
    let r = inspect(&input);
    assert_eq!(r.code, Some(65), "{}", r.stderr);
    assert_eq!(r.stderr.trim_end().lines().count(), 1, "{}", r.stderr);
}

// ---------------------------------------------------------------------------------------
// STL

fn binary_stl(facets: &[[f32; 9]]) -> Vec<u8> {
    let mut out = vec![b' '; 80];
    out.extend_from_slice(&(facets.len() as u32).to_le_bytes());
    for f in facets {
        out.extend_from_slice(&[0u8; 12]);
        f.iter()
            .for_each(|v| out.extend_from_slice(&v.to_le_bytes()));
        out.extend_from_slice(&[0, 0]);
    }
    out
}

const FACETS: [[f32; 9]; 2] = [
    [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0],
    [1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0],
];

#[test]
fn good_stl_loads_and_is_welded() {
    let (_tmp, dir, out) = scan_dir(&[("scan.stl", &binary_stl(&FACETS))]);
    let r = run(&["inspect", dir.join("scan.stl").to_str().unwrap()]);
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    assert!(r.stdout.contains("2 vertices welded"), "{}", r.stdout);
    assert!(r.stdout.contains("Loaded as stl-binary"), "{}", r.stdout);
    let p = process(&dir.join("scan.stl"), &out);
    assert_eq!(p.code, Some(0), "{}", p.stderr);
}

#[test]
fn stl_truncated_lying_or_nan_is_refused() {
    let good = binary_stl(&FACETS);
    let mut lying = good.clone();
    lying[80] = 200;
    let mut nan = FACETS;
    nan[1][4] = f32::NAN;
    let ascii = "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid s\n";
    let (_tmp, dir, out) = scan_dir(&[
        ("cut.stl", &good[..good.len() - 7]),
        ("lying.stl", &lying),
        ("nan.stl", &binary_stl(&nan)),
        (
            "cut-ascii.stl",
            ascii
                .strip_suffix("endloop\nendfacet\nendsolid s\n")
                .unwrap()
                .as_bytes(),
        ),
        (
            "nan-ascii.stl",
            ascii.replace("vertex 1 0 0", "vertex 1 NaN 0").as_bytes(),
        ),
    ]);
    refused(
        &dir,
        &out,
        "cut.stl",
        &["binary STL declares 2 triangles (184 bytes) but the file has 177 bytes"],
    );
    refused(
        &dir,
        &out,
        "lying.stl",
        &["declares 200 triangles (10084 bytes) but the file has 184 bytes"],
    );
    refused(
        &dir,
        &out,
        "nan.stl",
        &["facet 1: coordinate is not a finite number"],
    );
    refused(&dir, &out, "cut-ascii.stl", &["ends inside a solid"]);
    refused(
        &dir,
        &out,
        "nan-ascii.stl",
        &["line 5: coordinate is not a finite number: NaN"],
    );
}

// ---------------------------------------------------------------------------------------
// glTF

/// Three positions, one triangle's indices, little-endian.
fn triangle_bin(positions: [[f32; 3]; 3]) -> Vec<u8> {
    let mut bin: Vec<u8> = positions
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    bin.extend([0u16, 1, 2, 0].iter().flat_map(|i| i.to_le_bytes()));
    bin
}

const GOOD: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

/// A one-triangle glTF whose buffer is `uri` (of `byte_length` bytes), changed by `edit`.
fn gltf(uri: &str, byte_length: usize, edit: impl FnOnce(&mut serde_json::Value)) -> Vec<u8> {
    let mut doc = json!({
        "asset": { "version": "2.0" },
        "scene": 0, "scenes": [{ "nodes": [0] }], "nodes": [{ "mesh": 0 }],
        "meshes": [{ "primitives": [{ "attributes": { "POSITION": 0 }, "indices": 1 }] }],
        "accessors": [
            { "bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
              "min": [0, 0, 0], "max": [1, 1, 0] },
            { "bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR" },
        ],
        "bufferViews": [
            { "buffer": 0, "byteOffset": 0, "byteLength": 36 },
            { "buffer": 0, "byteOffset": 36, "byteLength": 6 },
        ],
        "buffers": [{ "uri": uri, "byteLength": byte_length }],
    });
    edit(&mut doc);
    serde_json::to_vec(&doc).unwrap()
}

fn data_uri(bytes: &[u8]) -> String {
    let b64 = base64::engine::general_purpose::STANDARD.encode(bytes);
    format!("data:application/octet-stream;base64,{b64}")
}

#[test]
fn good_gltf_with_data_uri_and_external_buffer_load() {
    let bin = triangle_bin(GOOD);
    let (_tmp, dir, out) = scan_dir(&[
        ("inline.gltf", &gltf(&data_uri(&bin), bin.len(), |_| {})),
        ("outside.gltf", &gltf("tri%20angle.bin", bin.len(), |_| {})),
        ("tri angle.bin", &bin),
    ]);
    for file in ["inline.gltf", "outside.gltf"] {
        let r = inspect(&dir.join(file));
        assert_eq!(r.code, Some(0), "{file}: {}", r.stderr);
        assert!(r.stdout.contains("Loaded as gltf"), "{}", r.stdout);
    }
    let p = process(&dir.join("outside.gltf"), &out);
    assert_eq!(p.code, Some(0), "{}", p.stderr);
}

#[test]
fn gltf_lying_counts_nan_and_unsupported_features_are_refused() {
    let bin = triangle_bin(GOOD);
    let uri = data_uri(&bin);
    let nan = triangle_bin([[0.0, 0.0, 0.0], [f32::NAN, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    let (_tmp, dir, out) = scan_dir(&[
        (
            "count.gltf",
            &gltf(&uri, bin.len(), |d| {
                d["accessors"][0]["count"] = json!(1000)
            }),
        ),
        (
            "offset.gltf",
            &gltf(&uri, bin.len(), |d| {
                d["bufferViews"][1]["byteOffset"] = json!(4_000_000_000u64)
            }),
        ),
        ("length.gltf", &gltf(&uri, 9999, |_| {})),
        ("nan.gltf", &gltf(&data_uri(&nan), nan.len(), |_| {})),
        (
            "index.gltf",
            &gltf(
                &data_uri(
                    &triangle_bin(GOOD)[..36]
                        .iter()
                        .chain(&[7u8, 0, 1, 0, 2, 0, 0, 0])
                        .copied()
                        .collect::<Vec<u8>>(),
                ),
                44,
                |_| {},
            ),
        ),
        (
            "points.gltf",
            &gltf(&uri, bin.len(), |d| {
                d["meshes"][0]["primitives"][0]["mode"] = json!(0)
            }),
        ),
        (
            "sparse.gltf",
            &gltf(&uri, bin.len(), |d| {
                d["accessors"][0]["sparse"] = json!({
            "count": 1, "indices": { "bufferView": 1, "componentType": 5123 }, "values": { "bufferView": 0 } })
            }),
        ),
        (
            "draco.gltf",
            &gltf(&uri, bin.len(), |d| {
                d["extensionsUsed"] = json!(["KHR_draco_mesh_compression"]);
                d["extensionsRequired"] = json!(["KHR_draco_mesh_compression"]);
            }),
        ),
        (
            "not-json.gltf",
            b"{\"asset\": {\"version\": \"2.0\"}, \"meshes\": [" as &[u8],
        ),
    ]);
    refused(
        &dir,
        &out,
        "count.gltf",
        &[
            "mesh 0 primitive 0",
            "1000 elements of 12 bytes",
            "run past the end of buffer view 0",
        ],
    );
    refused(
        &dir,
        &out,
        "offset.gltf",
        &["buffer view 1 (offset 4000000000, length 6) lies outside its buffer of 44 bytes"],
    );
    refused(
        &dir,
        &out,
        "length.gltf",
        &["buffer 0: byteLength is 9999 but the data holds 44 bytes"],
    );
    refused(
        &dir,
        &out,
        "nan.gltf",
        &["coordinate is not a finite number: NaN"],
    );
    refused(
        &dir,
        &out,
        "index.gltf",
        &["index 7 is out of range (the primitive has 3 vertices)"],
    );
    refused(
        &dir,
        &out,
        "points.gltf",
        &["primitive mode Points is not supported (only triangles)"],
    );
    refused(
        &dir,
        &out,
        "sparse.gltf",
        &["sparse accessors are not supported"],
    );
    refused(
        &dir,
        &out,
        "draco.gltf",
        &["Draco-compressed meshes are not supported"],
    );
    refused(&dir, &out, "not-json.gltf", &["not a glTF 2.0 document"]);
}

#[test]
fn the_real_draco_glb_is_a_clear_error() {
    let file = common::data(
        "textured/smithsonian_usnm1145291_draco/USNM_1145291-150k-2048-medium-100k-2048_draco.glb",
    );
    let r = inspect(&file);
    assert_eq!(r.code, Some(65), "{}", r.stderr);
    assert!(
        r.stderr
            .contains("Draco-compressed meshes are not supported"),
        "{}",
        r.stderr
    );
}

#[test]
fn gltf_uris_that_leave_the_scan_folder_are_refused() {
    let bin = triangle_bin(GOOD);
    let with_image = |uri: &str| {
        gltf(&data_uri(&bin), bin.len(), |d| {
            d["images"] = json!([{ "uri": uri }]);
            d["textures"] = json!([{ "source": 0 }]);
            d["materials"] =
                json!([{ "pbrMetallicRoughness": { "baseColorTexture": { "index": 0 } } }]);
            d["meshes"][0]["primitives"][0]["material"] = json!(0);
        })
    };
    let (_tmp, dir, out) = scan_dir(&[
        ("buffer-up.gltf", &gltf("../../../etc/passwd", 42, |_| {})),
        ("buffer-abs.gltf", &gltf("file:///etc/passwd", 42, |_| {})),
        ("image-up.gltf", &with_image("..%2F..%2F..%2Fetc%2Fpasswd")),
    ]);
    std::fs::write(dir.parent().unwrap().join("secret.bin"), &bin).unwrap();
    std::os::unix::fs::symlink(
        dir.parent().unwrap().join("secret.bin"),
        dir.join("link.bin"),
    )
    .unwrap();
    std::fs::write(dir.join("buffer-link.gltf"), gltf("link.bin", 42, |_| {})).unwrap();
    refused(
        &dir,
        &out,
        "buffer-up.gltf",
        &["buffer path \"../../../etc/passwd\" resolves outside the scan's folder"],
    );
    refused(
        &dir,
        &out,
        "buffer-abs.gltf",
        &["only relative file names and data: URIs are read"],
    );
    refused(
        &dir,
        &out,
        "image-up.gltf",
        &["texture path", "resolves outside the scan's folder"],
    );
    refused(
        &dir,
        &out,
        "buffer-link.gltf",
        &["buffer path \"link.bin\" resolves outside the scan's folder"],
    );
}

#[test]
fn data_uris_are_bounded_by_the_limits_before_decoding() {
    // Buffer 0 is a 3 MiB file beside the scan, buffer 1 a data URI of 3 MiB more: the two
    // together are above a 5 MiB limit that each fits.
    let mut big = triangle_bin(GOOD);
    big.resize(3 << 20, 0);
    let two_buffers = |d: &mut serde_json::Value| {
        d["buffers"] = json!([
            { "uri": "big.bin", "byteLength": big.len() },
            { "uri": data_uri(&big), "byteLength": big.len() },
        ]);
    };
    let (_tmp, dir, _out) = scan_dir(&[("big.bin", &big), ("two.gltf", &gltf("", 0, two_buffers))]);
    let mut options = LoadOptions::default();
    load(&dir.join("two.gltf"), &options).unwrap();
    options.limits.max_file_bytes = 5 << 20;
    let e = load(&dir.join("two.gltf"), &options).unwrap_err();
    let text = e.to_string();
    assert!(
        text.contains("buffer 1: ") && text.contains(
            "a data URI of about 3145728 bytes after 3145728 bytes of buffers exceeds limits.max_file_bytes = 5242880"
        ),
        "{text}"
    );
    assert!(!text.contains('\n'));
}

#[test]
fn glb_truncated_or_lying_about_its_length_is_refused() {
    // A real GLB written by scanmill, then damaged.
    let (_tmp, dir, out) = scan_dir(&[("tri.stl", &binary_stl(&FACETS))]);
    let (mesh, _) = load(&dir.join("tri.stl"), &LoadOptions::default()).unwrap();
    scanmill::mesh::save(&mesh, &dir.join("good.glb"), &Default::default()).unwrap();
    let good = std::fs::read(dir.join("good.glb")).unwrap();
    std::fs::write(dir.join("cut.glb"), &good[..good.len() / 2]).unwrap();
    let mut chunk = good.clone();
    chunk[12..16].copy_from_slice(&100_000u32.to_le_bytes());
    std::fs::write(dir.join("chunk.glb"), &chunk).unwrap();
    assert_eq!(inspect(&dir.join("good.glb")).code, Some(0));
    refused(
        &dir,
        &out,
        "cut.glb",
        &["byte 8: GLB header declares", "but the file has"],
    );
    refused(&dir, &out, "chunk.glb", &["chunk declares 100000 bytes"]);
}
