//! Input limits: how much one scan may make scanmill read, decompress and decode.
//!
//! A scan is untrusted input. Every reader takes its limits from
//! [`LoadOptions::limits`](super::LoadOptions), so one [`InputLimits`] value bounds a whole
//! load: the mesh file, its `.gz` layer, its MTLs and its texture images. `scanmill process`
//! and `inspect` use [`InputLimits::default`]; the daemon reads them from the `[limits]` table
//! of its configuration.
//!
//! The defaults leave a wide margin over real scans (the largest file in ../shared/data is
//! 11 MB decompressed, a 400k-triangle OBJ is about 40 MB, real gzip ratios are 2-4, real
//! textures are at most 8192²) while keeping what a hostile file can cost in memory to a
//! small multiple of its size on disk.

use serde::{Deserialize, Serialize};

/// One limit, by its configuration key (for errors that name the key to raise).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Limit {
    FileBytes,
    MtlBytes,
    DecompressedBytes,
    GzipRatio,
    TexturePixels,
}

impl Limit {
    /// The key as written in the configuration, e.g. `limits.max_file_bytes`.
    pub fn key(self) -> &'static str {
        match self {
            Limit::FileBytes => "limits.max_file_bytes",
            Limit::MtlBytes => "limits.max_mtl_bytes",
            Limit::DecompressedBytes => "limits.max_decompressed_bytes",
            Limit::GzipRatio => "limits.max_gzip_ratio",
            Limit::TexturePixels => "limits.max_texture_pixels",
        }
    }

    /// The limit's value in `limits`.
    pub fn value(self, limits: &InputLimits) -> u64 {
        match self {
            Limit::FileBytes => limits.max_file_bytes,
            Limit::MtlBytes => limits.max_mtl_bytes,
            Limit::DecompressedBytes => limits.max_decompressed_bytes,
            Limit::GzipRatio => limits.max_gzip_ratio,
            Limit::TexturePixels => limits.max_texture_pixels,
        }
    }
}

impl std::fmt::Display for Limit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.key())
    }
}

/// The `[limits]` table. Every key is optional; a missing key takes its default.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct InputLimits {
    /// Largest file read whole, checked from its size before reading and again while
    /// reading (a file can grow): the mesh file as stored (compressed or not) and each
    /// texture image. Default 2 GiB: a mesh of some twenty million triangles as OBJ text,
    /// fifty times a 400k-triangle scan.
    pub max_file_bytes: u64,
    /// Largest MTL file. Default 16 MiB: an MTL of thousands of materials is a few hundred
    /// KB; a bigger one is not a material library.
    pub max_mtl_bytes: u64,
    /// Largest decompressed content of a `.gz` mesh. Default 2 GiB, the same as a plain
    /// file may be.
    pub max_decompressed_bytes: u64,
    /// Largest ratio of decompressed to compressed size of a `.gz` mesh. Default 64: mesh
    /// files compress 2-4 times (the gzipped scans in ../shared/data), while gzip can reach
    /// about 1000 (a file of one repeated byte); this stops a 1 MB file that expands to 1 GiB
    /// at 64 MB instead of reading the gigabyte.
    pub max_gzip_ratio: u64,
    /// Decoded texture pixels per job, over every distinct image (each is decoded once).
    /// Checked from the image headers before any decoding. Default 2^28 (268 million): one
    /// 16384² texture or four 8192² ones, about 1 GiB as RGBA.
    pub max_texture_pixels: u64,
}

impl Default for InputLimits {
    fn default() -> Self {
        InputLimits {
            max_file_bytes: 2 << 30,
            max_mtl_bytes: 16 << 20,
            max_decompressed_bytes: 2 << 30,
            max_gzip_ratio: 64,
            max_texture_pixels: 1 << 28,
        }
    }
}

/// Highest value a byte limit may be set to: 1 TiB (a mesh above that cannot be held in
/// memory anyway, and products of sizes then stay far from overflowing).
const MAX_BYTES: u64 = 1 << 40;

impl InputLimits {
    /// Range checks, one message per problem, naming the key.
    pub fn validate(&self) -> Vec<String> {
        let mut problems = Vec::new();
        let mut range = |limit: Limit, min: u64, max: u64| {
            let v = limit.value(self);
            if !(min..=max).contains(&v) {
                problems.push(format!("{limit} must be {min}..={max}, not {v}"));
            }
        };
        range(Limit::FileBytes, 1 << 10, MAX_BYTES);
        range(Limit::MtlBytes, 1 << 10, MAX_BYTES);
        range(Limit::DecompressedBytes, 1 << 10, MAX_BYTES);
        range(Limit::GzipRatio, 2, 1 << 20);
        range(Limit::TexturePixels, 1, 1 << 40);
        problems
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_missing_keys_take_them() {
        assert!(InputLimits::default().validate().is_empty());
        let parsed: InputLimits = toml::from_str("max_gzip_ratio = 10\n").unwrap();
        assert_eq!(parsed.max_gzip_ratio, 10);
        assert_eq!(parsed.max_file_bytes, InputLimits::default().max_file_bytes);
    }

    #[test]
    fn unknown_keys_and_bad_ranges_are_refused() {
        assert!(toml::from_str::<InputLimits>("max_bytes = 1\n").is_err());
        let limits = InputLimits {
            max_gzip_ratio: 0,
            max_texture_pixels: 0,
            ..InputLimits::default()
        };
        let problems = limits.validate().join("\n");
        assert!(
            problems.contains("limits.max_gzip_ratio must be"),
            "{problems}"
        );
        assert!(problems.contains("limits.max_texture_pixels"), "{problems}");
    }
}
