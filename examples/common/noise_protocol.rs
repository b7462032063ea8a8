//! The noise protocol of issue #4, shared by the fairing probes (`fair_probe`,
//! `bilap_probe`): the four scans, their noisy copies (Gaussian along the vertex normals,
//! σ = 0.2 × mean edge length, seed 1) and the Taubin reference (the `smooth` step's).

use scanmill::mesh::{LoadOptions, Mesh, io};
use scanmill::metrics::noise::{NoiseOptions, noisy_copy};
use scanmill::ops::smooth::{
    MethodName, SmoothMethod, SmoothParams, TaubinCount, TaubinParams, smooth,
};
use std::path::Path;

const DATA: &str = "../shared/data";

/// The scans of the issue, by short name.
pub const SCANS: [(&str, &str); 4] = [
    ("facefuns", "textured/facefuns_di3d_face/example.obj"),
    ("lucy", "untextured/misc_scans/stanford_lucy_100k.ply"),
    (
        "igea",
        "untextured/misc_scans/igea_cyberware_trilist_DERIVED.ply.gz",
    ),
    ("bunny", "untextured/stanford_bunny/bun_zipper.ply"),
];

/// Whether `FP_SCANS` (a comma list of short names; all when unset) asks for `name`.
pub fn wanted(name: &str) -> bool {
    std::env::var("FP_SCANS").map_or(true, |w| w.split(',').any(|x| x == name))
}

/// A scan from ../shared/data, its texture not checked.
pub fn load(rel: &str) -> Mesh {
    let path = Path::new(DATA).join(rel);
    let options = LoadOptions {
        check_textures: false,
        ..Default::default()
    };
    io::load(&path, &options)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .0
}

/// The clean scan with the protocol's noise.
pub fn noisy(clean: &Mesh) -> Mesh {
    let options = NoiseOptions {
        sigma_factor: 0.2,
        seed: 1,
        ..NoiseOptions::default()
    };
    noisy_copy(clean, &options).0
}

/// Taubin λ|μ as the `smooth` step runs it (Table A.2: λ = 0.53, μ = −0.54, borders
/// fixed): `iterations` λ|μ pairs (`TaubinCount::Pairs`, what issue #26 calls Taubin) or
/// single passes (`TaubinCount::Passes`, the thesis' accounting).
pub fn taubin(mesh: &mut Mesh, iterations: u32, count: TaubinCount) {
    let params = SmoothParams {
        method: SmoothMethod::Taubin(TaubinParams {
            count,
            ..TaubinParams::default()
        }),
        iterations,
        ..SmoothParams::defaults(MethodName::Taubin)
    };
    smooth(mesh, &params);
}
