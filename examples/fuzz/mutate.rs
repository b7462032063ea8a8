//! The mutation engine. Input `i` of a campaign is a pure function of (seed, target, i) and the
//! corpus: the same seed and corpus give the same inputs in the same order on any machine,
//! with any number of jobs.
//!
//! The first inputs are the corpus entries themselves, unmutated. After that, each input is a
//! corpus entry (large ones cut to a window of lines or of body bytes), mutated one to sixteen
//! times by mutators chosen for the target: byte and bit edits, inserts, deletes, chunk
//! duplication and splicing between entries, interesting numbers in place of numbers,
//! line edits (cut, duplicate, repeat thousands of times, swap), dictionary tokens and lines
//! (hostile paths, huge counts, keywords), binary PLY header fields and body words, and for the
//! gzip target re-compression, damage to the gzip framing, extra members, and gzip bombs.

use std::io::{Read, Write};

use super::oracle::Target;

/// No generated input is longer (a bomb's compressed form is far below it).
pub const MAX_INPUT: usize = 8 << 20;
/// Corpus entries longer than this are usually cut to a window of at most this many bytes.
const WINDOW: usize = 64 << 10;
/// Gzip bodies kept in memory for mutation are cut to this length.
const MAX_BODY: usize = 64 << 20;

/// SplitMix64: small, fast, and fixed forever (a campaign's inputs must not change when a
/// dependency does).
pub struct Rng(u64);

impl Rng {
    /// The generator of input `iteration` of `target` in the campaign `seed`.
    pub fn for_input(seed: u64, target: Target, iteration: u64) -> Rng {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for b in target.name().bytes() {
            h = (h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
        }
        let mut r = Rng(seed ^ h.rotate_left(17) ^ iteration.wrapping_mul(0x9e37_79b9_7f4a_7c15));
        r.next_u64();
        r
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in `0..n` (`n > 0`).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    /// True with probability `num / den`.
    pub fn chance(&mut self, num: usize, den: usize) -> bool {
        self.below(den) < num
    }

    pub fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }

    /// Small numbers far more often than large ones: `0..max`, log-uniform-ish.
    pub fn small(&mut self, max: usize) -> usize {
        let bits = self.below(usize::BITS as usize - max.leading_zeros() as usize + 1);
        self.below((1usize << bits).min(max).max(1))
    }
}

/// A corpus entry: its bytes and, for the gzip target, its decompressed body.
pub struct Entry {
    pub bytes: Vec<u8>,
    pub body: Option<Vec<u8>>,
}

impl Entry {
    pub fn new(target: Target, bytes: Vec<u8>) -> Entry {
        let body = (target == Target::Gzip)
            .then(|| gunzip_prefix(&bytes))
            .flatten();
        Entry { bytes, body }
    }
}

/// The body of a gzip file, if it decompresses completely within [`MAX_BODY`].
fn gunzip_prefix(compressed: &[u8]) -> Option<Vec<u8>> {
    let mut body = Vec::new();
    flate2::read::MultiGzDecoder::new(compressed)
        .take(MAX_BODY as u64 + 1)
        .read_to_end(&mut body)
        .ok()?;
    (body.len() <= MAX_BODY).then_some(body)
}

pub fn gzip(body: &[u8], level: u32) -> Vec<u8> {
    let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::new(level));
    enc.write_all(body).expect("gzip to memory");
    enc.finish().expect("gzip to memory")
}

/// Everything input generation needs for one target.
pub struct Generator {
    pub target: Target,
    pub seed: u64,
    pub corpus: Vec<Entry>,
    /// Prebuilt gzip bombs (gzip target only).
    bombs: Vec<Vec<u8>>,
    /// Tokens and lines for the target's format.
    words: Vec<Vec<u8>>,
    lines: Vec<Vec<u8>>,
}

/// Numbers that break parsers: limits of every integer width, float extremes, non-numbers.
const NUMBERS: &[&str] = &[
    "0",
    "-0",
    "1",
    "-1",
    "2",
    "3",
    "255",
    "256",
    "65535",
    "65536",
    "2147483647",
    "2147483648",
    "-2147483648",
    "-2147483649",
    "4294967295",
    "4294967296",
    "9223372036854775807",
    "9223372036854775808",
    "-9223372036854775808",
    "18446744073709551615",
    "18446744073709551616",
    "99999999999999999999999999",
    "1e308",
    "1e309",
    "-1e308",
    "1e-320",
    "4.9e-324",
    "3.4028236e38",
    "1.7976931348623157e308",
    "nan",
    "NaN",
    "-nan",
    "inf",
    "-inf",
    "infinity",
    "0.0",
    "1.5",
    "-0.5",
    "0x10",
    "1_000",
    "+1",
    "1e",
    "1e+",
    ".",
    "-",
    "1.2.3",
    "00000000000000000000000000000001",
];

/// Paths a scan might name: inside, outside, links, special files, odd spellings.
const PATHS: &[&str] = &[
    "tex.png",
    "tex.jpg",
    "sub/inner.png",
    "bad.png",
    "link.png",
    "fifo.png",
    "../secret.png",
    "..\\secret.png",
    "..\\..\\..\\etc\\passwd",
    "/etc/passwd",
    "/dev/zero",
    "/dev/null",
    "/proc/self/mem",
    "../outside.mtl",
    "scan.mtl",
    "sub/../tex.png",
    "./tex.png",
    "sub/",
    "C:\\textures\\tex.png",
    "tex.png\0",
    "",
    ".",
    "..",
    "/",
    "scan.obj",
    "scan.scanmill.json",
    "scan.preview.png",
    "tex%2e%2e.png",
    "\u{202e}gnp.xet",
];

const OBJ_LINES: &[&str] = &[
    "v 0 0 0",
    "v 1e308 -1e308 1e308",
    "v nan 0 0",
    "v 1 2 3 0.5 0.5 0.5",
    "v 1 2",
    "vt 0.5 0.5",
    "vt 0 0 0",
    "vt nan",
    "vn 0 0 1",
    "vn 0 0 0",
    "f 1 2 3",
    "f 1/1/1 2/2/2 3/3/3",
    "f 1//1 2//1 3//1",
    "f -1 -2 -3",
    "f 0 0 0",
    "f 1 1 1",
    "f 1 2",
    "f 1 2 3 4 5 6 7 8 9 10",
    "f 1/2147483648 2/1 3/1",
    "f 1 2 4294967297",
    "f -4294967297 1 2",
    "f 1/ 2/ 3/",
    "f a b c",
    "l 1 2",
    "p 1",
    "usemtl m0",
    "usemtl m1",
    "usemtl nothere",
    "usemtl",
    "mtllib",
    "mtllib scan.mtl",
    "mtllib scan.mtl scan.mtl",
    "mtllib ../outside.mtl",
    "mtllib /etc/passwd",
    "mtllib fifo.png",
    "mtllib /dev/zero",
    "mtllib sub/../scan.mtl",
    "mtllib ..\\outside.mtl",
    "o",
    "g a b",
    "s off",
    "s 1",
    "#",
    "\\",
    "vp 0 0",
    "curv 0 1 1 2",
    "cstype bezier",
];

const MTL_LINES: &[&str] = &[
    "newmtl m0",
    "newmtl m1",
    "newmtl",
    "newmtl  ",
    "Kd 1 1 1",
    "Ka nan",
    "illum 2",
    "d 0.5",
    "map_Kd tex.png",
    "map_Kd",
    "map_Kd -s 1 1 1 tex.png",
    "map_Kd -o",
    "map_Kd -clamp on tex.jpg",
    "map_Kd ../secret.png",
    "map_Kd /etc/passwd",
    "map_Kd link.png",
    "map_Kd ..\\secret.png",
    "map_Kd fifo.png",
    "map_Kd /dev/zero",
    "map_Kd bad.png",
    "map_Kd sub/inner.png",
    "map_Bump ..\\secret.png",
    "map_Bump ../secret.png",
    "map_Bump link.png",
    "map_Bump fifo.png",
    "bump -bm 1 ../secret.png",
    "disp /etc/passwd",
    "map_d link.png",
    "map_Ks /dev/zero",
    "refl -type sphere ../secret.png",
    "norm ..\\secret.png",
    "map_Kd scan.scanmill.json",
    "map_Kd scan.preview.png",
    "map_Kd tex.png tex.jpg",
    "#",
];

const PLY_LINES: &[&str] = &[
    "element vertex 4294967295",
    "element vertex 2147483648",
    "element vertex 0",
    "element face 4294967295",
    "element face 1000000000",
    "element face 0",
    "element vertex -1",
    "element tristrips 1",
    "element multi_texture_vertex 3",
    "element multi_texture_face 1",
    "element extra 1",
    "property float x",
    "property float y",
    "property float z",
    "property double x",
    "property uchar red",
    "property float u",
    "property float v",
    "property float nx",
    "property list uchar int vertex_indices",
    "property list uint uint vertex_indices",
    "property list int int vertex_indices",
    "property list uchar uchar vertex_indices",
    "property list uint float texcoord",
    "property list uchar float texcoord",
    "property int texnumber",
    "property int tx",
    "property int tn",
    "property list uchar int texture_vertex_indices",
    "property list",
    "property",
    "comment TextureFile ../secret.png",
    "comment TextureFile link.png",
    "comment TextureFile /etc/passwd",
    "comment TextureFile fifo.png",
    "comment TextureFile /dev/zero",
    "comment TextureFile ..\\secret.png",
    "comment TextureFile tex.png",
    "comment TextureFile",
    "format ascii 1.0",
    "format binary_little_endian 1.0",
    "format binary_big_endian 1.0",
    "format ascii 2.0",
    "obj_info x",
    "end_header",
    "ply",
];

const PLY_TYPES: &[&str] = &[
    "char", "uchar", "short", "ushort", "int", "uint", "float", "double", "int8", "uint8", "int16",
    "uint16", "int32", "uint32", "float32", "float64", "list", "int64", "bogus",
];

const TOML_LINES: &[&str] = &[
    "[[step]]",
    "[output]",
    "[input]",
    "[metrics]",
    "[preview]",
    "[[watch]]",
    "[limits]",
    "kind = \"decimate\"",
    "kind = \"smooth\"",
    "kind = \"fair\"",
    "kind = \"relax\"",
    "kind = \"crop\"",
    "kind = \"seam_fix\"",
    "kind = \"normals\"",
    "kind = \"sharpen\"",
    "metrics = true",
    "enabled = true",
    "path = \"/dev/zero\"",
    "recipe = \"/dev/zero\"",
    "recipe = \"scan/fifo.png\"",
    "recipe = \"/etc/passwd\"",
    "recipe = \"recipe.toml\"",
    "recipe = \"\"",
    "output = \"/\"",
    "path = \"..\"",
    "state_dir = \"/proc\"",
    "x = 1",
    "a.b.c = 1",
    "step = 1",
    "watch = []",
    "step = [{ kind = \"normals\" }]",
    "include = [\"[\"]",
    "marker = \"/\"",
    "marker = \"\"",
    "\"\\u0000\" = 1",
    "'''",
    "\"\"\"",
];

const TOML_WORDS: &[&str] = &[
    "= nan",
    "= -nan",
    "= inf",
    "= -inf",
    "= 1e300",
    "= 1e19",
    "= -1",
    "= 0",
    "= 0.0",
    "= 18446744073709551615",
    "= 9223372036854775807",
    "= -9223372036854775808",
    "= 4294967295",
    "= 4294967296",
    "= \"\"",
    "= []",
    "= {}",
    "= true",
    "= [1, 2]",
    "= [nan, inf, -inf]",
    "= [1e308, 1e308, 1e308]",
    "= \"scan/fifo.png\"",
    "=",
    "[",
    "]",
    "{",
    "}",
    ",",
    "#",
    "\\",
    "\"",
    "'",
];

/// Lines spliced into STL inputs.
const STL_LINES: &[&str] = &[
    "solid x",
    "endsolid x",
    "facet normal 0 0 1",
    "outer loop",
    "vertex 0 0 0",
    "vertex nan 0 0",
    "vertex 1e39 0 0",
    "vertex 1 2",
    "endloop",
    "endfacet",
];

/// Tokens spliced into glTF JSON (and the JSON chunk of a GLB): keys, the values that
/// matter, and URIs that leave the folder or name special files.
const GLTF_WORDS: &[&str] = &[
    "\"count\": 4294967295",
    "\"count\": 0",
    "\"byteOffset\": 18446744073709551615",
    "\"byteStride\": 4",
    "\"byteLength\": 9999999999",
    "\"componentType\": 5121",
    "\"componentType\": 5125",
    "\"type\": \"VEC2\"",
    "\"mode\": 0",
    "\"mode\": 5",
    "\"normalized\": true",
    "\"sparse\": {}",
    "\"extensionsRequired\": [\"KHR_draco_mesh_compression\"]",
    "\"uri\": \"../../../etc/passwd\"",
    "\"uri\": \"/etc/passwd\"",
    "\"uri\": \"scan%2F..%2F..%2Fsecret\"",
    "\"uri\": \"fifo.png\"",
    "\"uri\": \"tex.png\"",
    "\"uri\": \"data:application/octet-stream;base64,AAAA\"",
    "\"uri\": \"data:,x\"",
    "\"bufferView\": 0",
    "\"source\": 0",
    "\"material\": 0",
    "\"matrix\": [0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0]",
    "\"scale\": [-1, 1, 1]",
    "\"children\": [0]",
];

impl Generator {
    pub fn new(target: Target, seed: u64, corpus: Vec<Entry>) -> Generator {
        let (mut lines, mut words): (Vec<&str>, Vec<&str>) = match target {
            Target::Obj => (OBJ_LINES.to_vec(), PATHS.to_vec()),
            Target::Mtl => (MTL_LINES.to_vec(), PATHS.to_vec()),
            Target::PlyAscii | Target::PlyBinary => (PLY_LINES.to_vec(), PLY_TYPES.to_vec()),
            Target::Gzip => {
                let mut l = OBJ_LINES.to_vec();
                l.extend(PLY_LINES);
                (l, PLY_TYPES.to_vec())
            }
            Target::Recipe | Target::Config => (TOML_LINES.to_vec(), TOML_WORDS.to_vec()),
            Target::Stl => (STL_LINES.to_vec(), Vec::new()),
            Target::Gltf | Target::Glb => (GLTF_WORDS.to_vec(), GLTF_WORDS.to_vec()),
            Target::SelfTest => (Vec::new(), Vec::new()),
        };
        words.extend(NUMBERS);
        if target == Target::PlyAscii || target == Target::PlyBinary {
            words.extend(PATHS);
        }
        lines.sort_unstable();
        lines.dedup();
        let mut words: Vec<Vec<u8>> = words.iter().map(|w| w.as_bytes().to_vec()).collect();
        let mut lines: Vec<Vec<u8>> = lines.iter().map(|w| w.as_bytes().to_vec()).collect();
        if matches!(target, Target::Recipe | Target::Config) {
            // Every key the seeds use, with hostile values.
            for key in toml_keys(&corpus) {
                for value in [
                    "nan",
                    "inf",
                    "-1",
                    "0",
                    "1e300",
                    "18446744073709551615",
                    "\"\"",
                ] {
                    lines.push(format!("{key} = {value}").into_bytes());
                }
                words.push(key.into_bytes());
            }
        }
        let bombs = if target == Target::Gzip {
            make_bombs()
        } else {
            Vec::new()
        };
        Generator {
            target,
            seed,
            corpus,
            bombs,
            words,
            lines,
        }
    }

    /// Input `iteration` of the campaign.
    pub fn input(&self, iteration: u64) -> Vec<u8> {
        if let Some(entry) = self.corpus.get(iteration as usize) {
            return entry.bytes.clone();
        }
        let mut rng = Rng::for_input(self.seed, self.target, iteration);
        if self.target == Target::Gzip {
            return self.gzip_input(&mut rng);
        }
        let entry = rng.pick(&self.corpus);
        let mut data = self.window(&entry.bytes, &mut rng);
        let binary = self.target == Target::PlyBinary;
        self.mutate(&mut data, binary, &mut rng);
        data.truncate(MAX_INPUT);
        data
    }

    fn gzip_input(&self, rng: &mut Rng) -> Vec<u8> {
        if rng.chance(1, 40) {
            return rng.pick(&self.bombs).clone();
        }
        let entry = rng.pick(&self.corpus);
        let mut out = match (&entry.body, rng.chance(3, 4)) {
            (Some(body), true) => {
                let mut data = self.window(body, rng);
                let binary = data.starts_with(b"ply") && !head_says_ascii(&data);
                self.mutate(&mut data, binary, rng);
                data.truncate(MAX_BODY);
                gzip(&data, rng.below(10) as u32)
            }
            _ => entry.bytes.clone(),
        };
        if rng.chance(2, 5) {
            self.damage_gzip(&mut out, rng);
        }
        out.truncate(MAX_INPUT);
        out
    }

    /// Edits to the gzip framing: header flags and fields, the CRC and size trailer, the
    /// compressed stream, extra members, garbage after the end.
    fn damage_gzip(&self, gz: &mut Vec<u8>, rng: &mut Rng) {
        let n = gz.len();
        match rng.below(8) {
            0 if n > 10 => gz[rng.below(10)] ^= 1 << rng.below(8),
            1 if n > 8 => {
                let at = n - 1 - rng.below(8);
                gz[at] = rng.next_u64() as u8;
            }
            2 if n > 0 => {
                let at = rng.below(n);
                gz[at] ^= 1 << rng.below(8);
            }
            3 => gz.truncate(rng.below(n + 1)),
            4 => {
                let other = rng.pick(&self.corpus);
                let chunk = &other.bytes[..other.bytes.len().min(WINDOW)];
                gz.extend_from_slice(chunk);
            }
            5 => gz.extend_from_slice(&gzip(rng.pick(&self.lines).as_slice(), 6)),
            6 if n > 3 => {
                // FLG: FTEXT, FHCRC, FEXTRA, FNAME, FCOMMENT, reserved bits.
                gz[3] = rng.next_u64() as u8;
            }
            _ => {
                let count = 1 + rng.small(64);
                for _ in 0..count {
                    gz.push(rng.next_u64() as u8);
                }
            }
        }
    }

    /// A large entry is cut to a window (of lines for text, of body bytes after the header
    /// for binary PLY) most of the time; the whole entry is kept now and then.
    fn window(&self, bytes: &[u8], rng: &mut Rng) -> Vec<u8> {
        if bytes.len() <= WINDOW || rng.chance(1, 12) {
            return bytes.to_vec();
        }
        let header_end = find(bytes, b"end_header\n").map(|i| i + b"end_header\n".len());
        let len = 1 + rng.below(WINDOW);
        match header_end {
            Some(h) if bytes.starts_with(b"ply") => {
                let body = &bytes[h..];
                let start = if rng.chance(1, 2) {
                    0
                } else {
                    rng.below(body.len().max(1))
                };
                let end = (start + len).min(body.len());
                [&bytes[..h], &body[start..end]].concat()
            }
            _ => {
                let start = if rng.chance(1, 2) {
                    0
                } else {
                    line_start(bytes, rng.below(bytes.len()))
                };
                let end = line_end(bytes, (start + len).min(bytes.len()));
                bytes[start..end].to_vec()
            }
        }
    }

    /// One to sixteen mutations in place.
    fn mutate(&self, data: &mut Vec<u8>, binary: bool, rng: &mut Rng) {
        let rounds = if rng.chance(1, 4) {
            1 + rng.below(16)
        } else {
            1 + rng.below(3)
        };
        for _ in 0..rounds {
            if binary && rng.chance(1, 2) {
                self.mutate_binary_ply(data, rng);
            } else {
                self.mutate_generic(data, rng);
            }
            if data.len() > MAX_INPUT {
                data.truncate(MAX_INPUT);
            }
        }
    }

    fn mutate_generic(&self, data: &mut Vec<u8>, rng: &mut Rng) {
        let n = data.len();
        match rng.below(16) {
            0 if n > 0 => {
                let at = rng.below(n);
                data[at] ^= 1 << rng.below(8);
            }
            1 if n > 0 => {
                const BYTES: &[u8] = b"\0\xff\n\r \t\\/#-.e+\x80\xc0\xef\"'=[]{}";
                let at = rng.below(n);
                data[at] = *rng.pick(BYTES);
            }
            2 => {
                let word = rng.pick(&self.words).clone();
                let at = rng.below(n + 1);
                data.splice(at..at, word);
            }
            3 if n > 0 => {
                let at = rng.below(n);
                let len = 1 + rng.small(256);
                data.drain(at..(at + len).min(n));
            }
            4 if n > 0 => {
                // Duplicate a chunk somewhere else.
                let from = rng.below(n);
                let len = 1 + rng.small(4096);
                let chunk = data[from..(from + len).min(n)].to_vec();
                let at = rng.below(n + 1);
                data.splice(at..at, chunk);
            }
            5 => self.splice_other(data, rng),
            6 | 7 => replace_number(data, rng),
            8 => {
                let line = rng.pick(&self.lines).clone();
                let at = line_start(data, rng.below(n + 1));
                data.splice(at..at, line.into_iter().chain([b'\n']));
            }
            9 if n > 0 => {
                // Cut a line.
                let start = line_start(data, rng.below(n));
                let end = (line_end(data, start) + 1).min(n);
                data.drain(start..end);
            }
            10 if n > 0 => {
                // Repeat a line: a few times, or thousands.
                let start = line_start(data, rng.below(n));
                let end = (line_end(data, start) + 1).min(n);
                let line = data[start..end].to_vec();
                let times = if rng.chance(1, 8) {
                    1 + rng.below(100_000)
                } else {
                    1 + rng.below(4)
                };
                let times = times.min(MAX_INPUT / line.len().max(1));
                let repeated: Vec<u8> = line
                    .iter()
                    .copied()
                    .cycle()
                    .take(line.len() * times)
                    .collect();
                data.splice(end..end, repeated);
            }
            11 if n > 0 => {
                // Swap two lines.
                let a = line_start(data, rng.below(n));
                let a_end = (line_end(data, a) + 1).min(n);
                let b = line_start(data, rng.below(n));
                let b_end = (line_end(data, b) + 1).min(n);
                if a_end <= b {
                    let second = data[b..b_end].to_vec();
                    let first = data[a..a_end].to_vec();
                    data.splice(b..b_end, first);
                    data.splice(a..a_end, second);
                }
            }
            12 => replace_token(data, rng.pick(&self.words).as_slice(), rng),
            13 => data.truncate(rng.below(n + 1)),
            14 if n > 0 => {
                // Line endings: CRLF, lone CR, none.
                let at = line_end(data, rng.below(n));
                if at < n {
                    match rng.below(3) {
                        0 => data.insert(at, b'\r'),
                        1 => data[at] = b'\r',
                        _ => {
                            data.remove(at);
                        }
                    }
                }
            }
            _ => {
                let word = rng.pick(&self.words).clone();
                let at = rng.below(n + 1);
                data.splice(at..at, word.into_iter().chain([b' ']));
            }
        }
    }

    /// Replace a stretch of `data` with a stretch of another corpus entry.
    fn splice_other(&self, data: &mut Vec<u8>, rng: &mut Rng) {
        let other = rng.pick(&self.corpus);
        let source = other.body.as_ref().unwrap_or(&other.bytes);
        if source.is_empty() {
            return;
        }
        let from = rng.below(source.len());
        let len = 1 + rng.small(8192);
        let chunk = &source[from..(from + len).min(source.len())];
        let at = rng.below(data.len() + 1);
        let cut = (at + rng.small(8192)).min(data.len());
        data.splice(at..cut, chunk.iter().copied());
    }

    /// Edits that keep a binary PLY's structure: header counts and types, the format line, and
    /// words of the body overwritten with extreme values.
    fn mutate_binary_ply(&self, data: &mut Vec<u8>, rng: &mut Rng) {
        let Some(h) = find(data, b"end_header\n") else {
            return self.mutate_generic(data, rng);
        };
        let body = h + b"end_header\n".len();
        match rng.below(6) {
            0 => {
                // A header number (element count) replaced.
                let mut header = data[..body].to_vec();
                replace_number(&mut header, rng);
                data.splice(..body, header);
            }
            1 => {
                // A property type replaced.
                let mut header = data[..body].to_vec();
                let types: Vec<Vec<u8>> = PLY_TYPES.iter().map(|t| t.as_bytes().to_vec()).collect();
                replace_token(&mut header, rng.pick(&types).as_slice(), rng);
                data.splice(..body, header);
            }
            2 => {
                let formats: [&[u8]; 3] = [b"ascii", b"binary_little_endian", b"binary_big_endian"];
                for f in formats {
                    if let Some(at) = find(&data[..body], f) {
                        let new = rng.pick(&formats).to_vec();
                        data.splice(at..at + f.len(), new);
                        break;
                    }
                }
            }
            _ if data.len() > body => {
                // A word of the body: list counts and indices live in 1, 2 and 4 bytes.
                const WORDS: &[u32] = &[
                    0,
                    1,
                    3,
                    0xff,
                    0xffff,
                    0x7fff_ffff,
                    0x8000_0000,
                    0xffff_ffff,
                    0x7f80_0000,
                    0x7fc0_0000,
                    0xff80_0000,
                ];
                let at = body + rng.below(data.len() - body);
                let word = rng.pick(WORDS).to_le_bytes();
                let width = *rng.pick(&[1usize, 2, 4]);
                for (i, b) in word.iter().take(width).enumerate() {
                    if let Some(slot) = data.get_mut(at + i) {
                        *slot = if rng.chance(1, 2) {
                            *b
                        } else {
                            word[width - 1 - i]
                        };
                    }
                }
            }
            _ => self.mutate_generic(data, rng),
        }
    }
}

/// The keys (`key = ...`) the TOML entries of a corpus use.
fn toml_keys(corpus: &[Entry]) -> Vec<String> {
    let mut keys: Vec<String> = corpus
        .iter()
        .flat_map(|e| {
            String::from_utf8_lossy(&e.bytes)
                .lines()
                .filter_map(|l| {
                    let (k, _) = l.split_once('=')?;
                    let k = k.trim();
                    (!k.is_empty() && !k.starts_with('#') && !k.contains(' '))
                        .then(|| k.to_string())
                })
                .collect::<Vec<_>>()
        })
        .collect();
    keys.sort();
    keys.dedup();
    keys
}

fn head_says_ascii(data: &[u8]) -> bool {
    let head = &data[..data.len().min(128)];
    find(head, b"format ascii").is_some()
}

/// Gzip bombs: small files that decompress to far more than any limit should allow, in the
/// shapes that hurt most (newlines, vertex lines, a binary PLY whose header matches the body).
fn make_bombs() -> Vec<Vec<u8>> {
    use super::seeds::bomb;
    let ply_head = |n: u64| {
        format!(
            "ply\nformat binary_little_endian 1.0\nelement vertex {n}\nproperty float x\n\
             property float y\nproperty float z\nelement face 0\n\
             property list uchar int vertex_indices\nend_header\n"
        )
        .into_bytes()
    };
    vec![
        bomb(b"", b"\n", 256 << 20),
        bomb(b"", b"\n", 1536 << 20),
        bomb(b"", b"v 1 2 3\n", 768 << 20),
        bomb(b"v 0 0 0\nv 1 0 0\nv 0 1 0\n", b"f 1 2 3\n", 512 << 20),
        bomb(&ply_head(100_000_000), &[0], 1200 << 20),
        bomb(b"", b"\0", 4 << 30),
        super::seeds::ratio_bomb((600 << 20) / 12),
    ]
}

pub fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    memchr::memmem::find(haystack, needle)
}

fn line_start(data: &[u8], at: usize) -> usize {
    let at = at.min(data.len());
    memchr::memrchr(b'\n', &data[..at]).map_or(0, |i| i + 1)
}

fn line_end(data: &[u8], at: usize) -> usize {
    let at = at.min(data.len());
    memchr::memchr(b'\n', &data[at..]).map_or(data.len(), |i| at + i)
}

fn is_number_byte(b: u8) -> bool {
    b.is_ascii_digit() || matches!(b, b'-' | b'+' | b'.' | b'e' | b'E')
}

/// Replaces one number (a digit run with its sign, point and exponent) near a random place
/// with an interesting number.
fn replace_number(data: &mut Vec<u8>, rng: &mut Rng) {
    if data.is_empty() {
        return;
    }
    let from = rng.below(data.len());
    let Some(digit) = data[from..]
        .iter()
        .position(u8::is_ascii_digit)
        .map(|i| from + i)
    else {
        return;
    };
    let mut start = digit;
    while start > 0 && is_number_byte(data[start - 1]) {
        start -= 1;
    }
    let mut end = digit;
    while end < data.len() && is_number_byte(data[end]) {
        end += 1;
    }
    let number = rng.pick(NUMBERS).as_bytes().to_vec();
    data.splice(start..end, number);
}

/// Replaces one whitespace-separated token near a random place with `word`.
fn replace_token(data: &mut Vec<u8>, word: &[u8], rng: &mut Rng) {
    if data.is_empty() {
        return;
    }
    let space = |b: &u8| b.is_ascii_whitespace();
    let from = rng.below(data.len());
    let Some(start) = data[from..]
        .iter()
        .position(|b| !space(b))
        .map(|i| from + i)
    else {
        return;
    };
    let start = data[..start].iter().rposition(space).map_or(0, |i| i + 1);
    let end = data[start..]
        .iter()
        .position(space)
        .map_or(data.len(), |i| start + i);
    data.splice(start..end, word.iter().copied());
}
