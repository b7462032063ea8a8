//! Helpers shared by the unit tests of several modules.

/// `f` run in a rayon pool of its own with `threads` threads, for tests that a result does
/// not depend on the thread count.
pub fn on_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

/// Knuth's MMIX linear congruential generator: deterministic pseudo-random numbers for unit
/// tests, with no RNG crate. Each call advances the state once.
pub struct Lcg(pub u64);

impl Lcg {
    /// The next state.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        self.0
    }

    /// Uniform in [0, 1), from the state's top 53 bits.
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [−1, 1).
    pub fn signed(&mut self) -> f64 {
        self.unit() * 2.0 - 1.0
    }
}

/// A horizontal ramp written as `ramp.png` in `dir`: red = column (0..=255), green =
/// 255 − column, blue = 17; for tests of the texture metric and the bake.
pub fn ramp_png(dir: &std::path::Path) -> std::path::PathBuf {
    let img = image::RgbImage::from_fn(256, 64, |x, _| image::Rgb([x as u8, 255 - x as u8, 17]));
    let path = dir.join("ramp.png");
    img.save(&path).unwrap();
    path
}

/// A material whose diffuse texture is the image at `path` (not checked).
pub fn ramp_material(path: &std::path::Path) -> crate::mesh::Material {
    crate::mesh::Material {
        name: "skin".into(),
        diffuse_texture: Some(crate::mesh::Texture {
            name: "ramp.png".into(),
            path: path.to_path_buf(),
            size: None,
            embedded: None,
        }),
        other_statements: vec![],
        map_files: vec![],
    }
}

/// The texture deviation of `result` against `reference`, from 4,000 samples of `result`.
pub fn texture_deviation(
    result: &crate::mesh::Mesh,
    reference: &crate::mesh::Mesh,
) -> crate::metrics::texture::TextureDeviation {
    use crate::metrics::surface::{SurfaceIndex, sample_surface};
    let index = SurfaceIndex::new(reference, "reference").unwrap();
    let samples = sample_surface(result, 4000, 11);
    let points: Vec<glam::DVec3> = samples.iter().map(|s| s.point).collect();
    let closest = index.closest_all(&points);
    crate::metrics::texture::deviation_with(
        result,
        reference,
        &samples,
        &closest,
        &mut crate::metrics::texture::TextureCache::new(),
    )
}
