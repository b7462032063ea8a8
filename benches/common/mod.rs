//! What several benches share: the 400,000-triangle face scan (facefuns subdivided to scanner
//! density, with scanner-like noise), the size the face-scan recipe is measured at.

use scanmill::mesh::{LoadOptions, Mesh, load};
use scanmill::metrics::noise::{NoiseOptions, add_noise};
use scanmill::ops::subdivide::scanner_sized;
use std::path::{Path, PathBuf};

pub const FACE: &str = "../shared/data/textured/facefuns_di3d_face/example.obj";
const TEXTURE: &str = "../shared/data/textured/facefuns_di3d_face/example.png";
pub const FACES: usize = 400_000;

/// The face400k scan, or `None` when ../shared/data is not beside the checkout.
pub fn face400k() -> Option<Mesh> {
    let options = LoadOptions {
        texture_override: Some(PathBuf::from(TEXTURE)),
        ..LoadOptions::default()
    };
    let (mesh, _) = load(Path::new(FACE), &options).ok()?;
    let mut mesh = scanner_sized(&mesh, FACES);
    add_noise(
        &mut mesh,
        &NoiseOptions {
            sigma_factor: 0.1,
            ..NoiseOptions::default()
        },
    );
    Some(mesh)
}
