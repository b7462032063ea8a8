//! The noise protocol of issue #4, shared by the fairing probes (`fair_probe`,
//! `bilap_probe`): the four scans, their noisy copies (Gaussian along the vertex normals,
//! σ = 0.2 × mean edge length, seed 1) and the Taubin reference (spec/smoothing.md §5).

use glam::DVec3;
use scanmill::mesh::{LoadOptions, Mesh, Topology, io};
use scanmill::metrics::noise::{NoiseOptions, noisy_copy};
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

/// Umbrella operator `(L x)_v = mean of the neighbours − x_v`, every vertex with
/// neighbours.
pub fn umbrella(topo: &Topology, x: &[DVec3]) -> Vec<DVec3> {
    (0..x.len())
        .map(|v| {
            let nb = topo.vertex_neighbours(v as u32);
            if nb.is_empty() {
                return DVec3::ZERO;
            }
            nb.iter().map(|&j| x[j as usize]).sum::<DVec3>() / nb.len() as f64 - x[v]
        })
        .collect()
}

/// Taubin λ|μ: `passes` buffered umbrella passes, λ first (spec/smoothing.md §5 counts one
/// pass as one iteration; the `smooth` step and MeshLab count λ+μ pairs).
pub fn taubin(mesh: &mut Mesh, lambda: f64, mu: f64, passes: usize) {
    let topo = mesh.topology();
    for k in 0..passes {
        let f = if k % 2 == 0 { lambda } else { mu };
        let l = umbrella(&topo, &mesh.positions);
        for (p, d) in mesh.positions.iter_mut().zip(l) {
            *p += f * d;
        }
    }
}
