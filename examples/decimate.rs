//! Decimates one scan and prints the step's figures, the guarantee audit and the time;
//! `--meshopt` runs meshoptimizer's `simplify_with_attributes` on the same input instead.
//! Used for the speed and peak-memory measurements (`/usr/bin/time -v`) of issue #5:
//!
//! ```text
//! cargo run --release --example decimate -- ../shared/data/textured/facefuns_di3d_face/example.obj \
//!     --subdivide 2 --target 26000 [--method edge-collapse] [--meshopt] [--renumber] [--audit] [--quality] \
//!     [--seam-fix] [--texture IMG] [--params 'texture_weight = 1e-17'] [--out out.obj]
//! ```
//!
//! `--params 'halves = "off"'` (or `"on"`) compares one pass with the halves
//! (`ops::decimate::halves`; the default decides by size).

use clap::Parser;
use glam::{DVec2, DVec3};
use scanmill::mesh::io::load;
use scanmill::mesh::{LoadOptions, Mesh};
use scanmill::metrics::{MetricsOptions, distance, surface};
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
    #[arg(long, default_value = "edge-collapse")]
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
    /// The product's metrics against the input, and the texture-coordinate deviation.
    #[arg(long)]
    quality: bool,
    /// Run `seam_fix` after decimating.
    #[arg(long)]
    seam_fix: bool,
    /// Texture image when the mesh names none (pizza, facefuns): loaded as `scanmill process
    /// --texture` does, so the colour deviation is measured.
    #[arg(long)]
    texture: Option<PathBuf>,
    /// Renumber the input for locality first, as `scanmill process` does before a
    /// recipe that decimates (`Mesh::reorder_for_locality`).
    #[arg(long)]
    renumber: bool,
}

fn uv_at(mesh: &Mesh, t: u32, bary: DVec3) -> Option<DVec2> {
    let w = mesh.triangles[t as usize];
    Some(
        mesh.wedge_texcoord(w[0])? * bary.x
            + mesh.wedge_texcoord(w[1])? * bary.y
            + mesh.wedge_texcoord(w[2])? * bary.z,
    )
}

/// Whether each vertex is on a texture seam (two or more wedges with different texture
/// coordinates).
fn seam_vertices(mesh: &Mesh) -> Vec<bool> {
    let mut first: Vec<Option<DVec2>> = vec![None; mesh.positions.len()];
    let mut seam = vec![false; mesh.positions.len()];
    for w in &mesh.wedges {
        if let Some(uv) = w.texcoord.map(|t| mesh.texcoords[t as usize]) {
            match first[w.vertex as usize] {
                None => first[w.vertex as usize] = Some(uv),
                Some(f) if f != uv => seam[w.vertex as usize] = true,
                _ => {}
            }
        }
    }
    seam
}

/// The product's metrics of the result against the input (`metrics::compare`: distance both
/// ways, normals, texture colour deviation, topology), and beside them the texture-coordinate
/// deviation: at each of the metrics' samples of the result, its texture coordinate against
/// the input's at the closest input point (mean, RMS, the share above 0.05, typically across
/// a chart, and how many of those lie on triangles with a seam vertex).
fn quality(input: &Mesh, out: &Mesh) -> serde_json::Value {
    let options = MetricsOptions::default();
    let metrics = scanmill::metrics::compare(out, input, &options).expect("metrics");
    let samples = surface::sample_surface(out, options.samples, options.seed);
    let index = surface::SurfaceIndex::new(input, "input").expect("a measurable input");
    let closest = index.closest_all(&distance::positions(&samples));
    let seam = seam_vertices(out);
    let at_seam = |t: u32| {
        out.triangle_vertices(t as usize)
            .iter()
            .any(|&v| seam[v as usize])
    };
    let uv: Vec<(f64, bool)> = samples
        .iter()
        .zip(&closest)
        .filter_map(|(s, c)| {
            let d =
                uv_at(out, s.triangle, s.bary)?.distance(uv_at(input, c.on.triangle, c.on.bary)?);
            Some((d, at_seam(s.triangle)))
        })
        .collect();
    let n = uv.len().max(1) as f64;
    let far: Vec<bool> = uv
        .iter()
        .filter(|(d, _)| *d > 0.05)
        .map(|(_, s)| *s)
        .collect();
    serde_json::json!({
        "faces": out.triangles.len(),
        "metrics": metrics,
        "uv_mean": uv.iter().map(|(d, _)| d).sum::<f64>() / n,
        "uv_rms": (uv.iter().map(|(d, _)| d * d).sum::<f64>() / n).sqrt(),
        "uv_far": far.len() as f64 / n,
        "uv_far_at_seam": far.iter().filter(|s| **s).count() as f64 / far.len().max(1) as f64,
        "seam_share": samples.iter().filter(|s| at_seam(s.triangle)).count() as f64 / samples.len().max(1) as f64,
    })
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
        // meshoptimizer asserts on a target above the input (james has 12,228 faces).
        target.min(mesh.triangles.len()) * 3,
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
    // As the scanmill binary does, so that peak memory is measured as the product runs.
    scanmill::memory::configure();
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::from_default_env())
        .init();
    let args = Args::parse();
    let t0 = Instant::now();
    let options = LoadOptions {
        texture_override: args.texture.clone(),
        ..LoadOptions::default()
    };
    let (mut mesh, _) = load(&args.input, &options).expect("load");
    for _ in 0..args.subdivide {
        mesh = subdivide(&mesh);
    }
    mesh.triangle_origins.clear();
    if args.renumber {
        mesh.reorder_for_locality();
    }
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
    if args.seam_fix {
        if args.quality {
            // The same figures before the fix, so that one run gives both.
            println!(
                "{}",
                serde_json::json!({ "before_seam_fix": quality(&mesh, &out) })
            );
        }
        if args.meshopt {
            // meshoptimizer records no origins: take for each output triangle the input
            // triangle closest to its centroid.
            let index = surface::SurfaceIndex::new(&mesh, "input").expect("a measurable input");
            out.triangle_origins = (0..out.triangles.len())
                .map(|t| {
                    let p = out.triangle_positions(t);
                    index.closest((p[0] + p[1] + p[2]) / 3.0).on.triangle
                })
                .collect();
        }
        let r = scanmill::ops::seam_fix::seam_fix(&mut out, &mesh, &Default::default());
        println!("{}", serde_json::to_string(&r).unwrap());
    }
    if args.quality {
        println!("{}", quality(&mesh, &out));
    }
    if args.audit {
        let a = decimate::audit::audit(&mesh, &out);
        println!("{}", serde_json::to_string(&a).unwrap());
    }
    if let Some(path) = args.out {
        scanmill::mesh::io::save(&out, &path, &Default::default()).expect("save");
    }
}
