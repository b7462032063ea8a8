//! Makes a scanner-sized test scan from a real one: subdivides it with the seam-keeping
//! `ops::subdivide` until it has at least `--faces` triangles, keeps the first that many
//! triangles, and writes it (OBJ with MTL and texture, or PLY) to the output path.
//!
//! cargo run --release --example scanner_sized -- IN OUT [FACES] [TEXTURE]

use scanmill::mesh::{LoadOptions, SaveOptions, load, save};
use scanmill::ops::subdivide::subdivide;
use std::path::PathBuf;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 {
        eprintln!("usage: scanner_sized IN OUT [FACES=400000] [TEXTURE]");
        std::process::exit(2);
    }
    let faces: usize = args
        .get(2)
        .map(|s| s.parse().expect("FACES"))
        .unwrap_or(400_000);
    let options = LoadOptions {
        texture_override: args.get(3).map(PathBuf::from),
        ..LoadOptions::default()
    };
    let (mut mesh, _) = load(args[0].as_ref(), &options).unwrap_or_else(|e| panic!("{e}"));
    while mesh.triangles.len() < faces {
        mesh = subdivide(&mesh);
    }
    mesh.triangles.truncate(faces);
    mesh.triangle_materials
        .truncate(faces.min(mesh.triangle_materials.len()));
    mesh.triangle_origins.clear();
    mesh.compact();
    let written =
        save(&mesh, args[1].as_ref(), &SaveOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    eprintln!("{} triangles → {written:?}", mesh.triangles.len());
}
