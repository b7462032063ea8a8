//! Makes a scanner-sized test scan from a real one: subdivides it with the seam-keeping
//! `ops::subdivide` until it has at least `FACES` triangles, keeps the `FACES` triangles
//! nearest the scan's centre (one coherent patch, as a scanner's field of view would give,
//! rather than the first `FACES` in file order, which leaves hundreds of scattered pieces),
//! optionally adds scanner-like noise along the normals (σ = NOISE × mean edge length, the
//! smoothing thesis' protocol), and writes it (OBJ with MTL and texture, or PLY).
//!
//! cargo run --release --example scanner_sized -- IN OUT [FACES=400000] [NOISE=0] [TEXTURE]

use scanmill::mesh::{LoadOptions, SaveOptions, load, save};
use scanmill::metrics::noise::{NoiseOptions, add_noise};
use scanmill::ops::subdivide::scanner_sized;
use std::path::PathBuf;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 {
        eprintln!("usage: scanner_sized IN OUT [FACES=400000] [NOISE=0] [TEXTURE]");
        std::process::exit(2);
    }
    let faces: usize = args
        .get(2)
        .map(|s| s.parse().expect("FACES must be a whole number"))
        .unwrap_or(400_000);
    let noise: f64 = args
        .get(3)
        .map(|s| s.parse().expect("NOISE must be a number"))
        .unwrap_or(0.0);
    let options = LoadOptions {
        texture_override: args.get(4).map(PathBuf::from),
        ..LoadOptions::default()
    };
    let (mut mesh, _) = load(args[0].as_ref(), &options).unwrap_or_else(|e| panic!("{e}"));
    mesh = scanner_sized(&mesh, faces);
    if noise > 0.0 {
        let report = add_noise(
            &mut mesh,
            &NoiseOptions {
                sigma_factor: noise,
                ..NoiseOptions::default()
            },
        );
        eprintln!("noise: {report:?}");
    }
    if let Some(parent) = std::path::Path::new(&args[1]).parent() {
        std::fs::create_dir_all(parent).expect("cannot create the output folder");
    }
    let written =
        save(&mesh, args[1].as_ref(), &SaveOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    eprintln!("{} triangles → {written:?}", mesh.triangles.len());
}
