//! Seeds: small hand-made inputs generated in code (every layout the readers know, and the
//! hostile cases of issue #22), and the real files under ../shared/data.

use std::io::Write;
use std::path::{Path, PathBuf};

use super::oracle::Target;

/// A named seed input.
pub struct Seed {
    pub name: String,
    pub bytes: Vec<u8>,
}

fn seed(name: &str, bytes: impl Into<Vec<u8>>) -> Seed {
    Seed {
        name: name.to_string(),
        bytes: bytes.into(),
    }
}

/// The hand-made seeds of a target.
pub fn hand_made(target: Target) -> Vec<Seed> {
    match target {
        Target::Obj => obj_seeds(),
        Target::Mtl => mtl_seeds(),
        Target::PlyAscii => ply_seeds(PlyForm::Ascii),
        Target::PlyBinary => {
            let mut s = ply_seeds(PlyForm::Little);
            s.extend(ply_seeds(PlyForm::Big));
            s
        }
        Target::Gzip => gzip_seeds(),
        Target::Recipe => recipe_seeds(),
        Target::Config => config_seeds(),
        Target::Stl => stl_seeds(),
        Target::Gltf => gltf_seeds(),
        Target::Glb => glb_seeds(),
        Target::SelfTest => Vec::new(),
    }
}

const OBJ_TEXTURED: &str = "# hand-made seed\nmtllib scan.mtl\no thing\n\
v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 0.5 1 0.2 0.3 0.4\n\
vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nvn 0 1 0\n\
usemtl m0\nf 1/1/1 2/2/1 3/3/1\nf 1/1 3/3 4/4\n\
usemtl m1\ns 1\nf -5//1 -4//1 -1//2\ng side\nf 2 3 5\nf 3 4 5 1\n";

fn obj_grid(n: usize) -> String {
    let mut s = String::from("mtllib scan.mtl\nusemtl m0\n");
    for j in 0..=n {
        for i in 0..=n {
            s += &format!(
                "v {i} {j} {}\nvt {} {}\n",
                (i * j) % 3,
                i as f64 / n as f64,
                j as f64 / n as f64
            );
        }
    }
    let at = |i: usize, j: usize| j * (n + 1) + i + 1;
    for j in 0..n {
        for i in 0..n {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            s += &format!("f {a}/{a} {b}/{b} {c}/{c} {d}/{d}\n");
        }
    }
    s
}

fn obj_seeds() -> Vec<Seed> {
    vec![
        seed("textured", OBJ_TEXTURED),
        seed("grid", obj_grid(12)),
        seed("plain", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"),
        seed(
            "continuation",
            "v 0 0 \\\n 0\nv 1 0 0\nv 0 1 0\nf 1 \\\n2 3\n",
        ),
        seed(
            "polygon",
            "v 0 0 0\nv 1 0 0\nv 2 1 0\nv 1 2 0\nv 0 2 0\nv -1 1 0\nf 1 2 3 4 5 6\nf 6 5 4\n",
        ),
        seed("no-faces", "v 0 0 0\nv 1 0 0\n"),
        seed(
            "mtllib-escape",
            "mtllib ../outside.mtl\nusemtl m0\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1\n",
        ),
        seed(
            "mtllib-absolute",
            "mtllib /etc/passwd\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        ),
        seed(
            "mtllib-fifo",
            "mtllib fifo.png\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        ),
        seed(
            "mtllib-dev-zero",
            "mtllib /dev/zero\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        ),
        seed(
            "huge-index",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4294967296\nf -9223372036854775808 1 2\n",
        ),
        seed("non-finite", "v nan 0 0\nv inf 0 0\nv 1e309 0 0\nf 1 2 3\n"),
    ]
}

fn mtl_seeds() -> Vec<Seed> {
    let escape =
        |name: &str, statement: &str| seed(name, format!("newmtl m0\nKd 1 1 1\n{statement}\n"));
    vec![
        seed(
            "companion",
            "newmtl m0\nKd 1 1 1\nmap_Kd tex.png\nnewmtl m1\nmap_Kd -s 1 1 1 -o 0 0 0 tex.jpg\n\
             map_Bump sub/inner.png\nbump -bm 1 sub/inner.png\ndisp tex.png\nmap_Ks tex.jpg\n",
        ),
        seed("empty", ""),
        seed("no-name", "newmtl\nmap_Kd tex.png\n"),
        seed("continuation", "newmtl m0\nmap_Kd \\\ntex.png\n"),
        escape("parent", "map_Kd ../secret.png"),
        escape("absolute", "map_Kd /etc/passwd"),
        escape("symlink", "map_Kd link.png"),
        escape("backslash-bump", "map_Bump ..\\secret.png"),
        escape("backslash-kd", "map_Kd ..\\secret.png"),
        escape("fifo", "map_Kd fifo.png"),
        escape("fifo-bump", "map_Bump fifo.png"),
        escape("dev-zero", "map_Kd /dev/zero"),
        escape("not-an-image", "map_Kd bad.png"),
        escape("nul", "map_Kd tex\0.png"),
        escape("dot-dot-inside", "map_Kd sub/../tex.png"),
        // A map line repeated 100k times (2.3 MB): resolving each and looking each up on
        // output took minutes before they were done once per name (campaign seed 2026).
        seed(
            "many-map-lines",
            format!("newmtl m0\n{}", "map_Bump sub/inner.png\n".repeat(100_000)),
        ),
    ]
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum PlyForm {
    Ascii,
    Little,
    Big,
}

/// Typed values of one PLY element row.
#[derive(Clone, Copy)]
enum V {
    F(f32),
    D(f64),
    U8(u8),
    I32(i32),
    U32(u32),
}

/// A PLY file from a header (without `ply`/`format`/`end_header`) and rows of values.
fn ply(form: PlyForm, header: &str, rows: &[Vec<V>]) -> Vec<u8> {
    let format = match form {
        PlyForm::Ascii => "ascii",
        PlyForm::Little => "binary_little_endian",
        PlyForm::Big => "binary_big_endian",
    };
    let mut out = format!("ply\nformat {format} 1.0\n{header}end_header\n").into_bytes();
    for row in rows {
        if form == PlyForm::Ascii {
            let words: Vec<String> = row
                .iter()
                .map(|v| match *v {
                    V::F(x) => x.to_string(),
                    V::D(x) => x.to_string(),
                    V::U8(x) => x.to_string(),
                    V::I32(x) => x.to_string(),
                    V::U32(x) => x.to_string(),
                })
                .collect();
            out.extend_from_slice(words.join(" ").as_bytes());
            out.push(b'\n');
            continue;
        }
        for v in row {
            let little = form == PlyForm::Little;
            macro_rules! put {
                ($x:expr) => {
                    if little {
                        out.extend_from_slice(&$x.to_le_bytes())
                    } else {
                        out.extend_from_slice(&$x.to_be_bytes())
                    }
                };
            }
            match *v {
                V::F(x) => put!(x),
                V::D(x) => put!(x),
                V::U8(x) => out.push(x),
                V::I32(x) => put!(x),
                V::U32(x) => put!(x),
            }
        }
    }
    out
}

fn ply_seeds(form: PlyForm) -> Vec<Seed> {
    let tag = match form {
        PlyForm::Ascii => "ascii",
        PlyForm::Little => "le",
        PlyForm::Big => "be",
    };
    let corners = [
        (0.0f32, 0.0f32, 0.0f32),
        (1.0, 0.0, 0.0),
        (1.0, 1.0, 0.0),
        (0.0, 1.0, 0.5),
    ];
    let xyz: Vec<Vec<V>> = corners
        .iter()
        .map(|&(x, y, z)| vec![V::F(x), V::F(y), V::F(z)])
        .collect();
    let tri = |a: i32, b: i32, c: i32| vec![V::U8(3), V::I32(a), V::I32(b), V::I32(c)];
    let faces = vec![tri(0, 1, 2), tri(0, 2, 3)];
    let mut seeds = Vec::new();
    let mut add = |name: &str, bytes: Vec<u8>| seeds.push(seed(&format!("{tag}-{name}"), bytes));

    let vertex_xyz = "element vertex 4\nproperty float x\nproperty float y\nproperty float z\n";
    let face_list = "element face 2\nproperty list uchar int vertex_indices\n";
    add(
        "plain",
        ply(
            form,
            &format!("{vertex_xyz}{face_list}"),
            &[xyz.clone(), faces.clone()].concat(),
        ),
    );

    // Per-vertex u v, colours, normals, doubles; TextureFile.
    let rich_rows: Vec<Vec<V>> = corners
        .iter()
        .map(|&(x, y, z)| {
            vec![
                V::D(x as f64),
                V::D(y as f64),
                V::D(z as f64),
                V::F(0.0),
                V::F(0.0),
                V::F(1.0),
                V::U8(200),
                V::U8(100),
                V::U8(50),
                V::F(x),
                V::F(y),
            ]
        })
        .collect();
    add(
        "rich",
        ply(
            form,
            &format!(
                "comment TextureFile tex.png\nelement vertex 4\nproperty double x\nproperty double y\n\
                 property double z\nproperty float nx\nproperty float ny\nproperty float nz\n\
                 property uchar red\nproperty uchar green\nproperty uchar blue\nproperty float u\n\
                 property float v\n{face_list}"
            ),
            &[rich_rows, faces.clone()].concat(),
        ),
    );

    // Per-face texcoord lists (MeshLab, OpenMVS), with a texnumber.
    let tex_face = |a: i32, b: i32, c: i32| {
        vec![
            V::U8(3),
            V::I32(a),
            V::I32(b),
            V::I32(c),
            V::U8(6),
            V::F(0.0),
            V::F(0.0),
            V::F(1.0),
            V::F(0.0),
            V::F(1.0),
            V::F(1.0),
            V::I32(0),
        ]
    };
    for (name, texture) in [
        ("texcoord", "tex.png"),
        ("texcoord-escape", "../secret.png"),
        ("texcoord-symlink", "link.png"),
        ("texcoord-absolute", "/etc/passwd"),
        ("texcoord-fifo", "fifo.png"),
        ("texcoord-backslash", "..\\secret.png"),
    ] {
        add(
            name,
            ply(
                form,
                &format!(
                    "comment TextureFile {texture}\n{vertex_xyz}element face 2\n\
                     property list uchar int vertex_indices\nproperty list uchar float texcoord\n\
                     property int texnumber\n"
                ),
                &[xyz.clone(), vec![tex_face(0, 1, 2), tex_face(0, 2, 3)]].concat(),
            ),
        );
    }

    // Triangle strips (-1 restarts a strip).
    add(
        "tristrips",
        ply(
            form,
            &format!("{vertex_xyz}element tristrips 1\nproperty list int int vertex_indices\n"),
            &[
                xyz.clone(),
                vec![vec![
                    V::I32(6),
                    V::I32(0),
                    V::I32(1),
                    V::I32(3),
                    V::I32(2),
                    V::I32(-1),
                    V::I32(0),
                ]],
            ]
            .concat(),
        ),
    );
    // Unsigned indices, uint list count, an extra element to skip.
    add(
        "uint-lists",
        ply(
            form,
            &format!(
                "{vertex_xyz}element face 1\nproperty list uint uint vertex_indices\n\
                 element extra 2\nproperty uchar flag\n"
            ),
            &[
                xyz.clone(),
                vec![vec![V::U32(4), V::U32(0), V::U32(1), V::U32(2), V::U32(3)]],
                vec![vec![V::U8(1)], vec![V::U8(2)]],
            ]
            .concat(),
        ),
    );
    // Hostile headers: counts far beyond the body.
    add(
        "huge-vertex-count",
        ply(
            form,
            &format!(
                "element vertex 4294967295\nproperty float x\nproperty float y\nproperty float z\n{face_list}"
            ),
            &[xyz.clone(), faces.clone()].concat(),
        ),
    );
    add(
        "huge-face-count",
        ply(
            form,
            &format!(
                "{vertex_xyz}element face 2147483648\nproperty list uchar int vertex_indices\n"
            ),
            &[xyz.clone(), faces.clone()].concat(),
        ),
    );
    add(
        "huge-list",
        ply(
            form,
            &format!("{vertex_xyz}element face 1\nproperty list uint int vertex_indices\n"),
            &[
                xyz.clone(),
                vec![vec![V::U32(u32::MAX), V::I32(0), V::I32(1), V::I32(2)]],
            ]
            .concat(),
        ),
    );
    add(
        "huge-strip-count",
        ply(
            form,
            &format!(
                "{vertex_xyz}element tristrips 1000000000\nproperty list uchar uchar vertex_indices\n"
            ),
            &[xyz, vec![vec![V::U8(255), V::U8(0), V::U8(1), V::U8(2)]]].concat(),
        ),
    );
    seeds
}

fn gzip(body: &[u8]) -> Vec<u8> {
    let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    enc.write_all(body).expect("gzip to memory");
    enc.finish().expect("gzip to memory")
}

fn gzip_seeds() -> Vec<Seed> {
    let mut seeds = vec![
        seed("obj", gzip(OBJ_TEXTURED.as_bytes())),
        seed("grid", gzip(obj_grid(8).as_bytes())),
        seed("truncated", {
            let mut g = gzip(OBJ_TEXTURED.as_bytes());
            g.truncate(g.len() / 2);
            g
        }),
        seed(
            "two-members",
            [gzip(b"v 0 0 0\nv 1 0 0\n"), gzip(b"v 0 1 0\nf 1 2 3\n")].concat(),
        ),
        seed("garbage", b"\x1f\x8b\x08\x00garbage".to_vec()),
        // A bomb: 64 MiB of newlines in about 64 KiB (bigger ones are made by the mutator).
        seed("bomb-64mib", bomb(b"", b"\n", 64 << 20)),
        // 1.2 GiB of newlines in 1.2 MB (finding 1 of #22 was a 1 MB one).
        seed("bomb-1200mib", bomb(b"", b"\n", 1200 << 20)),
        // 400 MiB of vertices at a gzip ratio just under 64, about 7.5 MB.
        seed("ratio-bomb-400mib", ratio_bomb((400 << 20) / 12)),
    ];
    for s in ply_seeds(PlyForm::Little).into_iter().take(3) {
        seeds.push(seed(&format!("ply-{}", s.name), gzip(&s.bytes)));
    }
    seeds
}

/// A gzip file that decompresses to `head` followed by `total` bytes of `pattern`: members of
/// 1 MiB of the pattern repeated, so that building a GiB costs a MiB of compression.
pub fn bomb(head: &[u8], pattern: &[u8], total: usize) -> Vec<u8> {
    const MEMBER: usize = 1 << 20;
    let block: Vec<u8> = pattern.iter().copied().cycle().take(MEMBER).collect();
    bomb_of_blocks(head, &block, total)
}

/// A binary PLY of `n` vertices (float x y z, no faces) whose body compresses about 55 times:
/// just under a gzip ratio limit of 64, it makes the most of whatever decompressed size the
/// limits allow. The body is zeros with a pseudo-random low mantissa byte every 140 bytes
/// (tiny finite floats, so the reader does not stop at a non-finite value).
pub fn ratio_bomb(n: usize) -> Vec<u8> {
    const MEMBER: usize = 12 << 16;
    let mut block = vec![0u8; MEMBER];
    let mut state: u32 = 0x2545_f491;
    for i in (0..MEMBER).step_by(140) {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        block[i] = state as u8;
    }
    let head = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {n}\nproperty float x\n\
         property float y\nproperty float z\nend_header\n"
    );
    bomb_of_blocks(head.as_bytes(), &block, n * 12)
}

fn bomb_of_blocks(head: &[u8], block: &[u8], total: usize) -> Vec<u8> {
    let member = {
        let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
        enc.write_all(block).expect("gzip to memory");
        enc.finish().expect("gzip to memory")
    };
    let mut out = gzip(head);
    let whole = total / block.len();
    for _ in 0..whole {
        out.extend_from_slice(&member);
    }
    let rest = total - whole * block.len();
    if rest > 0 {
        out.extend_from_slice(&gzip(&block[..rest]));
    }
    out
}

fn toml_step(step: &scanmill::recipe::Step) -> String {
    format!("[[step]]\n{}\n", toml::to_string(step).unwrap_or_default())
}

fn recipe_seeds() -> Vec<Seed> {
    use scanmill::ops;
    use scanmill::ops::smooth::{MethodName, SmoothParams, SmoothParamsFile};
    use scanmill::recipe::Step;
    let smooth = |method| {
        SmoothParams::try_from(SmoothParamsFile {
            method: Some(method),
            ..Default::default()
        })
        .ok()
        .map(Step::Smooth)
    };
    let mut steps = vec![
        Step::Crop(ops::crop::CropParams {
            min: Some([-1.0, -1.0, -1.0]),
            max: Some([5.0, 5.0, 1.0]),
            ..Default::default()
        }),
        Step::Relax(ops::fair::RelaxParams::default()),
        Step::Fair(ops::fair::FairParams::default()),
        Step::Decimate(ops::decimate::DecimateParams {
            target_faces: Some(40),
            ..Default::default()
        }),
        Step::SeamFix(ops::seam_fix::SeamFixParams::default()),
        Step::Normals(ops::normals::NormalsParams::default()),
    ];
    steps.extend(
        [
            MethodName::Laplace,
            MethodName::Hc,
            MethodName::Taubin,
            MethodName::Bilateral,
        ]
        .into_iter()
        .filter_map(smooth),
    );
    let mut seeds = Vec::new();
    let tables = "[output]\nformat = \"ply\"\nply_encoding = \"ascii\"\n\n[input]\nweld_tolerance = 0.0\n\n\
                  [metrics]\nenabled = true\nsamples = 2000\nseed = 7\ncrack_distance_factor = 2.0\n\n\
                  [preview]\nenabled = false\n\n";
    let mut all = tables.to_string();
    for step in &steps {
        let text = toml_step(step);
        seeds.push(seed(
            &step.kind(),
            format!("[metrics]\nenabled = false\n\n{text}"),
        ));
        all += &text;
    }
    seeds.push(seed("every-step", all));
    for file in ["face-scan.toml", "normals-only.toml"] {
        let path = repo_dir().join("config/recipes").join(file);
        if let Ok(bytes) = std::fs::read(&path) {
            seeds.push(seed(file, bytes));
        }
    }
    seeds.push(seed("weld-nan", "[input]\nweld_tolerance = nan\n"));
    seeds.push(seed(
        "iterations-huge",
        "[[step]]\nkind = \"smooth\"\niterations = 4294967295\n",
    ));
    seeds
}

fn config_seeds() -> Vec<Seed> {
    let watch = "[[watch]]\npath = \"inbox\"\noutput = \"outbox\"\nrecipe = \"recipe.toml\"\n\
                 quiet_period_secs = 2.0\npoll_secs = 0.0\ninclude = [\"*.obj\", \"**/*.ply\"]\n\
                 exclude = [\"tmp/**\"]\nmarker = \"{stem}.done\"\n";
    let mut seeds = vec![
        seed(
            "full",
            format!(
                "state_dir = \"state\"\nworkers = 2\ncreate_missing_dirs = true\nmax_attempts = 3\n\
                 retry_base_secs = 30\nretry_max_secs = 3600\njob_timeout_secs = 1800\n\
                 drain_timeout_secs = 60\nrescan_secs = 300\nincomplete_report_secs = 600\n\
                 max_input_bytes = 2147483648\nmin_free_disk_mb = 1024\n\n{watch}"
            ),
        ),
        seed(
            "minimal",
            "create_missing_dirs = true\n[[watch]]\npath = \"in\"\noutput = \"out\"\n",
        ),
        seed(
            "timeout-1e300",
            "create_missing_dirs = true\njob_timeout_secs = 1e300\n[[watch]]\npath = \"in\"\noutput = \"out\"\n",
        ),
        seed(
            "rescan-1e19",
            "create_missing_dirs = true\nrescan_secs = 1e19\n[[watch]]\npath = \"in\"\noutput = \"out\"\n",
        ),
        seed(
            "recipe-dev-zero",
            "create_missing_dirs = true\n[[watch]]\npath = \"in\"\noutput = \"out\"\nrecipe = \"/dev/zero\"\n",
        ),
        seed(
            "recipe-fifo",
            "create_missing_dirs = true\n[[watch]]\npath = \"in\"\noutput = \"out\"\nrecipe = \"scan/fifo.png\"\n",
        ),
        seed(
            "output-inside",
            "create_missing_dirs = true\n[[watch]]\npath = \"in\"\noutput = \"in/out\"\n",
        ),
        seed("bad-syntax", "workers = [\n"),
    ];
    if let Ok(bytes) = std::fs::read(repo_dir().join("config/scanmill.toml")) {
        seeds.push(seed("shipped", bytes));
    }
    seeds
}

/// The repository (for its shipped recipes and configuration).
pub fn repo_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The real scans beside the checkout.
pub fn data_dir() -> PathBuf {
    repo_dir().join("../shared/data")
}

/// Files under `dir` (recursively) that belong to `target`, sorted by path.
pub fn data_files(target: Target, dir: &Path) -> Vec<PathBuf> {
    let mut files = Vec::new();
    walk(dir, &mut files);
    files.sort();
    files.retain(|p| belongs(target, p));
    files
}

fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let path = e.path();
        match e.file_type() {
            Ok(t) if t.is_dir() => walk(&path, out),
            Ok(t) if t.is_file() => out.push(path),
            _ => {}
        }
    }
}

fn belongs(target: Target, path: &Path) -> bool {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let ply_format = || {
        let mut head = [0u8; 64];
        let n = std::fs::File::open(path)
            .and_then(|mut f| std::io::Read::read(&mut f, &mut head))
            .unwrap_or(0);
        String::from_utf8_lossy(&head[..n]).contains("format ascii")
    };
    match target {
        Target::Obj => name.ends_with(".obj"),
        Target::Mtl => name.ends_with(".mtl"),
        Target::PlyAscii => name.ends_with(".ply") && ply_format(),
        Target::PlyBinary => name.ends_with(".ply") && !ply_format(),
        Target::Gzip => name.ends_with(".obj.gz") || name.ends_with(".ply.gz"),
        Target::Stl => name.ends_with(".stl"),
        Target::Gltf => name.ends_with(".gltf"),
        Target::Glb => name.ends_with(".glb"),
        Target::Recipe | Target::Config | Target::SelfTest => false,
    }
}

/// A real file adapted to the scratch folder, so that it loads as far as its content allows:
/// an OBJ names the scratch's `scan.mtl` and its materials `m0`/`m1`; an MTL's maps name the
/// scratch's `tex.png`. (The hostile names come from the hand-made seeds and the mutators.)
pub fn adapt(target: Target, bytes: Vec<u8>) -> Vec<u8> {
    match target {
        Target::Obj => adapt_obj(&bytes),
        Target::Mtl => adapt_mtl(&bytes),
        Target::Gzip => {
            let mut body = Vec::new();
            let whole = std::io::Read::read_to_end(
                &mut flate2::read::MultiGzDecoder::new(&bytes[..]),
                &mut body,
            );
            if whole.is_err() || body.starts_with(b"ply") {
                bytes
            } else {
                gzip(&adapt_obj(&body))
            }
        }
        _ => bytes,
    }
}

fn adapt_obj(bytes: &[u8]) -> Vec<u8> {
    let mut names: Vec<Vec<u8>> = Vec::new();
    let mut out = Vec::with_capacity(bytes.len());
    for line in bytes.split_inclusive(|&b| b == b'\n') {
        if line.starts_with(b"mtllib") {
            out.extend_from_slice(b"mtllib scan.mtl\n");
        } else if let Some(name) = line.strip_prefix(b"usemtl ") {
            let name = name.trim_ascii().to_vec();
            let index = names.iter().position(|n| *n == name).unwrap_or_else(|| {
                names.push(name);
                names.len() - 1
            });
            out.extend_from_slice(format!("usemtl m{}\n", index % 2).as_bytes());
        } else {
            out.extend_from_slice(line);
        }
    }
    out
}

fn adapt_mtl(bytes: &[u8]) -> Vec<u8> {
    let text = String::from_utf8_lossy(bytes);
    let mut out = String::new();
    for line in text.lines() {
        let keyword = line.split_whitespace().next().unwrap_or("");
        let is_map = keyword.to_ascii_lowercase().starts_with("map_")
            || matches!(keyword, "bump" | "disp" | "decal" | "refl" | "norm");
        if is_map {
            out += &format!("{keyword} tex.png\n");
        } else {
            out += line;
            out.push('\n');
        }
    }
    out.into_bytes()
}

const STL_ASCII: &str = "solid t\nfacet normal 0 0 -1\nouter loop\nvertex 0 0 0\nvertex 0 1 0\nvertex 1 0 0\nendloop\nendfacet\n\
facet normal 0 -1 0\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 0 1\nendloop\nendfacet\n\
facet normal 1 1 1\nouter loop\nvertex 1 0 0\nvertex 0 1 0\nvertex 0 0 1\nendloop\nendfacet\nendsolid t\n";

fn binary_stl(header: &[u8], facets: &[[f32; 9]], attribute: u16) -> Vec<u8> {
    let mut out = header.to_vec();
    out.resize(80, b' ');
    out.extend_from_slice(&(facets.len() as u32).to_le_bytes());
    for f in facets {
        out.extend_from_slice(&[0u8; 12]);
        f.iter()
            .for_each(|v| out.extend_from_slice(&v.to_le_bytes()));
        out.extend_from_slice(&attribute.to_le_bytes());
    }
    out
}

fn stl_seeds() -> Vec<Seed> {
    let facets = [
        [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0],
        [1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0],
        [0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
    ];
    let mut lying = binary_stl(b"x", &facets, 0);
    lying[80..84].copy_from_slice(&u32::MAX.to_le_bytes());
    vec![
        seed("ascii", STL_ASCII),
        seed("binary", binary_stl(b"binary", &facets, 0)),
        seed(
            "binary-says-solid",
            binary_stl(b"solid colour", &facets, 0x801f),
        ),
        seed("lying-count", lying),
        seed("two-solids", format!("{STL_ASCII}{STL_ASCII}")),
    ]
}

/// A one-triangle glTF document: positions, texture coordinates and indices in buffer 0
/// (`uri`, or the GLB's BIN chunk when `None`), and a material whose image is `image`.
fn gltf_doc(uri: Option<&str>, image: serde_json::Value) -> (Vec<u8>, Vec<u8>) {
    let mut bin: Vec<u8> = [0f32, 0., 0., 1., 0., 0., 0., 1., 0.]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    bin.extend(
        [0f32, 0., 1., 0., 0., 1.]
            .iter()
            .flat_map(|v| v.to_le_bytes()),
    );
    bin.extend([0u16, 1, 2, 0].iter().flat_map(|i| i.to_le_bytes()));
    let mut buffer = serde_json::json!({ "byteLength": bin.len() });
    if let Some(uri) = uri {
        buffer["uri"] = serde_json::json!(uri);
    }
    let doc = serde_json::json!({
        "asset": { "version": "2.0" },
        "scene": 0, "scenes": [{ "nodes": [0] }],
        "nodes": [{ "children": [1], "scale": [2, 2, 2] }, { "mesh": 0, "translation": [1, 0, 0] }],
        "meshes": [{ "primitives": [{
            "attributes": { "POSITION": 0, "TEXCOORD_0": 1 }, "indices": 2, "material": 0 }] }],
        "materials": [{ "pbrMetallicRoughness": { "baseColorTexture": { "index": 0 } } }],
        "textures": [{ "source": 0 }],
        "images": [image],
        "accessors": [
            { "bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
              "min": [0, 0, 0], "max": [1, 1, 0] },
            { "bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2" },
            { "bufferView": 2, "componentType": 5123, "count": 3, "type": "SCALAR" },
        ],
        "bufferViews": [
            { "buffer": 0, "byteOffset": 0, "byteLength": 36 },
            { "buffer": 0, "byteOffset": 36, "byteLength": 24 },
            { "buffer": 0, "byteOffset": 60, "byteLength": 6 },
        ],
        "buffers": [buffer],
    });
    (serde_json::to_vec_pretty(&doc).unwrap(), bin)
}

fn data_uri(bytes: &[u8]) -> String {
    use base64::Engine;
    let b64 = base64::engine::general_purpose::STANDARD.encode(bytes);
    format!("data:application/octet-stream;base64,{b64}")
}

/// A tiny PNG (2×2).
fn tiny_png() -> Vec<u8> {
    let img = image::RgbImage::from_pixel(2, 2, image::Rgb([9, 8, 7]));
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

fn gltf_seeds() -> Vec<Seed> {
    let (_, bin) = gltf_doc(None, serde_json::json!({}));
    let inline = data_uri(&bin);
    let png = format!("data:image/png;base64,{}", &data_uri(&tiny_png())[37..]);
    let doc = |uri: &str, image: serde_json::Value| gltf_doc(Some(uri), image).0;
    vec![
        seed(
            "file-image",
            doc(&inline, serde_json::json!({ "uri": "tex.png" })),
        ),
        seed(
            "data-image",
            doc(&inline, serde_json::json!({ "uri": png })),
        ),
        seed(
            "escape-image",
            doc(&inline, serde_json::json!({ "uri": "../secret.png" })),
        ),
        seed(
            "symlink-image",
            doc(&inline, serde_json::json!({ "uri": "link.png" })),
        ),
        seed(
            "fifo-buffer",
            doc("fifo.png", serde_json::json!({ "uri": "tex.png" })),
        ),
        seed(
            "escape-buffer",
            doc("..%2Fsecret.png", serde_json::json!({ "uri": "tex.png" })),
        ),
    ]
}

fn glb(json: &[u8], bin: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    scanmill::mesh::gltf::glb::write(&mut out, json, bin).unwrap();
    out
}

fn glb_seeds() -> Vec<Seed> {
    let (json, mut bin) = gltf_doc(None, serde_json::json!({}));
    let image_at = bin.len();
    let png = tiny_png();
    bin.extend_from_slice(&png);
    let mut doc: serde_json::Value = serde_json::from_slice(&json).unwrap();
    doc["bufferViews"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({ "buffer": 0, "byteOffset": image_at, "byteLength": png.len() }));
    doc["images"] = serde_json::json!([{ "bufferView": 3, "mimeType": "image/png" }]);
    doc["buffers"][0]["byteLength"] = serde_json::json!(bin.len());
    let embedded = serde_json::to_vec(&doc).unwrap();
    let (file_image, plain_bin) = gltf_doc(None, serde_json::json!({ "uri": "tex.png" }));
    vec![
        seed("embedded-image", glb(&embedded, &bin)),
        seed("file-image", glb(&file_image, &plain_bin)),
        seed("no-bin", glb(&file_image, &[])),
    ]
}
