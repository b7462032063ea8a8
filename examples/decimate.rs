//! Decimates one scan and prints the step's figures, the guarantee audit and the time;
//! `--meshopt` runs meshoptimizer's `simplify_with_attributes` on the same input instead.
//! Used for the speed and peak-memory measurements (`/usr/bin/time -v`) of issue #5:
//!
//! ```text
//! cargo run --release --example decimate -- ../shared/data/textured/facefuns_di3d_face/example.obj \
//!     --subdivide 2 --target 26000 [--method face-collapse] [--meshopt] [--audit] [--out out.obj]
//! ```

use clap::Parser;
use scanmill::mesh::io::load;
use scanmill::mesh::{LoadOptions, Mesh};
use scanmill::ops::decimate::{self, DecimateParams, Method};
use scanmill::ops::subdivide::subdivide;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Parser)]
struct Args {
    input: PathBuf,
    #[arg(long, default_value_t = 0)]
    subdivide: usize,
    #[arg(long, default_value_t = 26000)]
    target: usize,
    #[arg(long, default_value = "face-collapse")]
    method: String,
    /// Extra decimate parameters as TOML, e.g. 'texture_weight = 1.0'.
    #[arg(long, default_value = "")]
    params: String,
    #[arg(long)]
    meshopt: bool,
    /// meshopt's weight of the texture coordinates.
    #[arg(long, default_value_t = 1.0)]
    uv_weight: f32,
    #[arg(long)]
    audit: bool,
    #[arg(long)]
    out: Option<PathBuf>,
    #[arg(long, default_value_t = 1)]
    repeat: usize,
}

/// meshoptimizer on the wedge buffer (one vertex per wedge, texture coordinates as
/// attributes), mapped back to a wedge mesh.
fn run_meshopt(mesh: &Mesh, target: usize, uv_weight: f32) -> Mesh {
    let verts: Vec<[f32; 3]> = mesh
        .wedges
        .iter()
        .map(|w| mesh.positions[w.vertex as usize].as_vec3().to_array())
        .collect();
    let attrs: Vec<f32> = mesh
        .wedges
        .iter()
        .flat_map(|w| {
            let uv = w
                .texcoord
                .map(|t| mesh.texcoords[t as usize])
                .unwrap_or_default();
            [uv.x as f32, uv.y as f32]
        })
        .collect();
    let indices: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
    let bytes: &[u8] =
        unsafe { std::slice::from_raw_parts(verts.as_ptr().cast(), verts.len() * 12) };
    let adapter = meshopt::VertexDataAdapter::new(bytes, 12, 0).expect("adapter");
    let locks = vec![false; verts.len()];
    let out = meshopt::simplify_with_attributes_and_locks(
        &indices,
        &adapter,
        &attrs,
        &[uv_weight, uv_weight],
        8,
        &locks,
        target * 3,
        1.0,
        meshopt::SimplifyOptions::None,
        None,
    );
    let mut m = mesh.clone();
    m.triangles = out.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    m.triangle_materials.clear();
    m.triangle_origins.clear();
    m.compact();
    m
}

fn main() {
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::from_default_env())
        .init();
    let args = Args::parse();
    let t0 = Instant::now();
    let (mut mesh, _) = load(&args.input, &LoadOptions::default()).expect("load");
    for _ in 0..args.subdivide {
        mesh = subdivide(&mesh);
    }
    mesh.triangle_origins.clear();
    eprintln!(
        "loaded {} triangles, {} vertices, {} wedges in {:.2} s",
        mesh.triangles.len(),
        mesh.positions.len(),
        mesh.wedges.len(),
        t0.elapsed().as_secs_f64()
    );
    let mut out = Mesh::default();
    for _ in 0..args.repeat {
        let t = Instant::now();
        if args.meshopt {
            out = run_meshopt(&mesh, args.target, args.uv_weight);
            eprintln!(
                "meshopt: {} faces in {:.3} s",
                out.triangles.len(),
                t.elapsed().as_secs_f64()
            );
        } else {
            let text = format!(
                "method = \"{}\"\ntarget_faces = {}\n{}",
                args.method, args.target, args.params
            );
            let p: DecimateParams = toml::from_str(&text).expect("params");
            let (o, report) = decimate::decimate(&mesh, &p).expect("decimate");
            let secs = t.elapsed().as_secs_f64();
            println!("{}", serde_json::to_string(&report).unwrap());
            eprintln!(
                "{}: {} faces in {:.3} s",
                p.method.name(),
                o.triangles.len(),
                secs
            );
            out = o;
            let _ = Method::FaceCollapse;
        }
    }
    if args.audit {
        let a = decimate::audit::audit(&mesh, &out);
        println!("{}", serde_json::to_string(&a).unwrap());
    }
    if let Some(path) = args.out {
        scanmill::mesh::io::save(&out, &path, &Default::default()).expect("save");
    }
}
