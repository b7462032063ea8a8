//! Memory bounds of hostile inputs (issue #22, findings 1 and 5), measured on the real
//! binary: a gzip bomb, a PLY whose header lies about its size, an image header declaring
//! ten billion pixels. Kept apart from hostile_inputs.rs so that this test process stays
//! small (see hostile_support on how the child's peak is measured).

mod hostile_support;

use hostile_support::*;
use std::io::Write;

// ---------------------------------------------------------------------------------------
// Finding 1 and 5: memory

/// 1 GiB of newlines as gzip, about 1 MB: one compressed 64 MiB member, repeated (gzip
/// allows concatenated members, and the reader reads them all).
fn gzip_bomb() -> Vec<u8> {
    let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
    let chunk = vec![b'\n'; 1 << 20];
    for _ in 0..64 {
        enc.write_all(&chunk).unwrap();
    }
    let member = enc.finish().unwrap();
    member.repeat(16)
}

#[test]
fn gzip_bomb_stops_at_the_ratio_limit_with_bounded_memory() {
    let bomb = gzip_bomb();
    assert!(bomb.len() < 2 << 20, "{} bytes", bomb.len());
    let (_tmp, dir, out) = scan_dir(&[("bomb.obj.gz", &bomb)]);
    let input = dir.join("bomb.obj.gz");
    for r in [inspect(&input), process(&input, &out)] {
        assert_refused(
            &r,
            &out,
            &["bomb.obj.gz", "exceeds limits.max_gzip_ratio = 64"],
        );
        // Without the limit the whole gigabyte was read (1.1 GB peak).
        assert_peak_below(&r, 300 << 20);
    }
}

#[test]
fn ply_with_a_lying_vertex_count_fails_fast_and_small() {
    let header = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\n\
         property float y\nproperty float z\nelement face 1\n\
         property list uchar int vertex_indices\nend_header\n",
        1u64 << 31
    );
    let mut bytes = header.into_bytes();
    bytes.extend(std::iter::repeat_n(0u8, 1024));
    let (_tmp, dir, _out) = scan_dir(&[("lie.ply", &bytes)]);
    let r = inspect(&dir.join("lie.ply"));
    assert_eq!(r.code, Some(65), "{}", r.stderr);
    assert!(
        r.stderr
            .contains("truncated: expected 2147483648 vertex elements"),
        "{}",
        r.stderr
    );
    assert_peak_below(&r, 200 << 20);
}

/// A PNG whose header declares `w`×`h` pixels, followed by a little image data: the
/// decoder's allocation is what such a file costs.
fn png_header_only(w: u32, h: u32) -> Vec<u8> {
    fn crc(bytes: &[u8]) -> u32 {
        let mut c = 0xFFFF_FFFFu32;
        for &b in bytes {
            c ^= u32::from(b);
            for _ in 0..8 {
                c = if c & 1 != 0 {
                    0xEDB8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                };
            }
        }
        !c
    }
    fn chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
        out.extend((data.len() as u32).to_be_bytes());
        let mut body = kind.to_vec();
        body.extend(data);
        out.extend(&body);
        out.extend(crc(&body).to_be_bytes());
    }
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = Vec::new();
    ihdr.extend(w.to_be_bytes());
    ihdr.extend(h.to_be_bytes());
    ihdr.extend([8, 2, 0, 0, 0]);
    chunk(&mut out, b"IHDR", &ihdr);
    let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::best());
    z.write_all(&vec![0u8; 1 << 20]).unwrap();
    chunk(&mut out, b"IDAT", &z.finish().unwrap());
    chunk(&mut out, b"IEND", &[]);
    out
}

#[test]
fn texture_declaring_a_huge_size_is_refused_by_the_pixel_budget() {
    let mut files = obj_with_mtl("newmtl m\nmap_Kd big.png\n");
    files.push(("big.png", png_header_only(100_000, 100_000)));
    let (_tmp, dir, out) = scan_dir(&[]);
    write_all(&dir, &files);
    let r = process(&dir.join("scan.obj"), &out);
    assert_refused(
        &r,
        &out,
        &[
            "big.png",
            "(100000×100000)",
            "exceeds limits.max_texture_pixels = 268435456",
        ],
    );
    assert_peak_below(&r, 300 << 20);
}

#[test]
fn a_real_image_over_a_lowered_pixel_budget_is_refused() {
    use scanmill::mesh::{LoadOptions, load};
    let (_tmp, dir, _out) = scan_dir(&[]);
    let mut files = obj_with_mtl("newmtl m\nmap_Kd t.png\n");
    files.push(("t.png", png(64, 64, [1, 2, 3])));
    write_all(&dir, &files);
    let mut options = LoadOptions::default();
    load(&dir.join("scan.obj"), &options).unwrap();
    options.limits.max_texture_pixels = 64 * 64 - 1;
    let e = load(&dir.join("scan.obj"), &options).unwrap_err();
    assert!(
        e.to_string()
            .contains("exceeds limits.max_texture_pixels = 4095"),
        "{e}"
    );
}
