//! Thumbnails of the previews for the job list: a preview is a few hundred kB, fifty of them
//! would make every list page megabytes. Scaled on the blocking pool, kept in a bounded
//! in-memory cache keyed by the job and the preview's content.

use std::collections::HashMap;
use std::hash::Hasher;
use std::sync::{Arc, Mutex};

/// Longest side of a thumbnail, in pixels: the list shows them 96 CSS pixels wide, and
/// screens of high density want three times that.
pub const THUMB_SIZE: u32 = 288;
/// Thumbnails kept (each a few kB to tens of kB); the cache is emptied when it is full.
const MAX_CACHED: usize = 1024;

/// (job id, hash of the preview's bytes).
type Key = (i64, u64);

#[derive(Default)]
pub struct Thumbs {
    cache: Mutex<HashMap<Key, Arc<Vec<u8>>>>,
}

fn content_key(bytes: &[u8]) -> u64 {
    let mut h = rustc_hash::FxHasher::default();
    h.write(bytes);
    h.finish()
}

/// `image` (PNG or JPEG) scaled to fit `THUMB_SIZE`, as PNG; `None` if it does not decode.
pub fn scale(image: &[u8]) -> Option<Vec<u8>> {
    let decoded = image::load_from_memory(image).ok()?;
    let small = decoded.thumbnail(THUMB_SIZE, THUMB_SIZE);
    let mut out = std::io::Cursor::new(Vec::new());
    small.write_to(&mut out, image::ImageFormat::Png).ok()?;
    Some(out.into_inner())
}

impl Thumbs {
    /// The thumbnail of job `id`'s preview `image`, from the cache when its content is the same.
    pub fn get(&self, id: i64, image: &[u8]) -> Option<Arc<Vec<u8>>> {
        let key = (id, content_key(image));
        if let Some(hit) = self
            .cache
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .get(&key)
        {
            return Some(hit.clone());
        }
        let thumb = Arc::new(scale(image)?);
        let mut cache = self.cache.lock().unwrap_or_else(|p| p.into_inner());
        if cache.len() >= MAX_CACHED {
            cache.clear();
        }
        cache.insert(key, thumb.clone());
        Some(thumb)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thumbnails_fit_the_box_keep_the_shape_and_are_cached() {
        let img = image::RgbImage::from_fn(1536, 512, |x, _| image::Rgb([(x % 256) as u8, 0, 0]));
        let mut png = std::io::Cursor::new(Vec::new());
        img.write_to(&mut png, image::ImageFormat::Png).unwrap();
        let png = png.into_inner();
        let thumbs = Thumbs::default();
        let t = thumbs.get(7, &png).unwrap();
        let small = image::load_from_memory(&t).unwrap();
        assert_eq!(
            (small.width(), small.height()),
            (THUMB_SIZE, THUMB_SIZE / 3)
        );
        assert!(Arc::ptr_eq(&t, &thumbs.get(7, &png).unwrap()), "cached");
        assert!(thumbs.get(8, b"not an image").is_none());
    }
}
