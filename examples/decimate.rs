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
use scanmill::geom::closest_on_triangle;
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
    /// Sampled distance and texture-coordinate deviation against the input (a stand-in
    /// until `metrics::compare` lands on main).
    #[arg(long)]
    quality: bool,
    /// Run `seam_fix` after decimating.
    #[arg(long)]
    seam_fix: bool,
    /// Texture image for the colour deviation when the mesh names none (pizza, facefuns).
    #[arg(long)]
    texture: Option<PathBuf>,
    /// Renumber the input for locality first, as `scanmill process` does before a
    /// recipe that decimates (`Mesh::reorder_for_locality`).
    #[arg(long)]
    renumber: bool,
}

/// An RGB image for bilinear lookups at OBJ texture coordinates (origin bottom left,
/// coordinates wrap), as the metrics module defines texture deviation.
struct Image(image::RgbImage);

impl Image {
    fn at(&self, uv: DVec2) -> [f64; 3] {
        let (w, h) = (self.0.width() as f64, self.0.height() as f64);
        let x = uv.x.rem_euclid(1.0) * w - 0.5;
        let y = (1.0 - uv.y.rem_euclid(1.0)) * h - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let px = |i: f64, j: f64| {
            let i = (i as i64).rem_euclid(self.0.width() as i64) as u32;
            let j = (j as i64).clamp(0, self.0.height() as i64 - 1) as u32;
            self.0.get_pixel(i, j).0.map(f64::from)
        };
        let (a, b, c, d) = (
            px(x0, y0),
            px(x0 + 1.0, y0),
            px(x0, y0 + 1.0),
            px(x0 + 1.0, y0 + 1.0),
        );
        std::array::from_fn(|k| {
            (a[k] * (1.0 - fx) + b[k] * fx) * (1.0 - fy) + (c[k] * (1.0 - fx) + d[k] * fx) * fy
        })
    }
}

/// Uniform grid over the input's triangles for closest-point queries.
struct Grid<'a> {
    mesh: &'a Mesh,
    lo: DVec3,
    cell: f64,
    n: [i64; 3],
    cells: std::collections::HashMap<[i64; 3], Vec<u32>>,
}

impl<'a> Grid<'a> {
    fn new(mesh: &'a Mesh) -> Self {
        let (lo, hi) = mesh.bounding_box().unwrap();
        let cell = mesh.mean_edge_length() * 2.0;
        let n = ((hi - lo) / cell)
            .ceil()
            .as_i64vec3()
            .to_array()
            .map(|x| x.max(1));
        let mut cells: std::collections::HashMap<[i64; 3], Vec<u32>> = Default::default();
        for t in 0..mesh.triangles.len() {
            let p = mesh.triangle_positions(t);
            let a = ((p[0].min(p[1]).min(p[2]) - lo) / cell)
                .floor()
                .as_i64vec3();
            let b = ((p[0].max(p[1]).max(p[2]) - lo) / cell)
                .floor()
                .as_i64vec3();
            for i in a.x..=b.x {
                for j in a.y..=b.y {
                    for k in a.z..=b.z {
                        cells.entry([i, j, k]).or_default().push(t as u32);
                    }
                }
            }
        }
        Grid {
            mesh,
            lo,
            cell,
            n,
            cells,
        }
    }

    /// (distance, triangle, barycentric) of the closest input point.
    fn closest(&self, p: DVec3) -> (f64, usize, DVec3) {
        let c = ((p - self.lo) / self.cell).floor().as_i64vec3();
        let mut best = (f64::INFINITY, 0usize, DVec3::ZERO);
        let max_r = self.n.iter().copied().max().unwrap_or(1) + 1;
        for r in 0..=max_r {
            for i in c.x - r..=c.x + r {
                for j in c.y - r..=c.y + r {
                    for k in c.z - r..=c.z + r {
                        let on_shell =
                            (i - c.x).abs() == r || (j - c.y).abs() == r || (k - c.z).abs() == r;
                        if !on_shell {
                            continue;
                        }
                        if let Some(list) = self.cells.get(&[i, j, k]) {
                            for &t in list {
                                let q = self.mesh.triangle_positions(t as usize);
                                let (x, bary) = closest_on_triangle(p, q[0], q[1], q[2]);
                                let d = x.distance(p);
                                if d < best.0 {
                                    best = (d, t as usize, bary);
                                }
                            }
                        }
                    }
                }
            }
            if best.0 <= r as f64 * self.cell {
                break;
            }
        }
        best
    }
}

fn uv_at(mesh: &Mesh, t: usize, bary: DVec3) -> Option<DVec2> {
    let w = mesh.triangles[t];
    Some(
        mesh.wedge_texcoord(w[0])? * bary.x
            + mesh.wedge_texcoord(w[1])? * bary.y
            + mesh.wedge_texcoord(w[2])? * bary.z,
    )
}

/// Mean / RMS / max one-sided distance (result → input) in % of the box diagonal, and
/// mean / RMS texture-coordinate deviation (result's texture coordinate at a sample against
/// the input's at the closest input point), from 100,000 area-weighted samples.
fn quality(input: &Mesh, out: &Mesh, image: Option<&Image>) -> serde_json::Value {
    use rayon::prelude::*;
    let grid = Grid::new(input);
    let areas: Vec<f64> = (0..out.triangles.len())
        .map(|t| out.triangle_area(t))
        .collect();
    let total: f64 = areas.iter().sum();
    let samples = 100_000usize;
    let mut pts = Vec::with_capacity(samples);
    let mut seed = 0x9E3779B97F4A7C15u64;
    let mut rnd = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut acc = 0.0;
    let mut t = 0;
    for i in 0..samples {
        let target = (i as f64 + rnd()) / samples as f64 * total;
        while t + 1 < areas.len() && acc + areas[t] < target {
            acc += areas[t];
            t += 1;
        }
        let (mut u, mut v) = (rnd(), rnd());
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        pts.push((t, DVec3::new(1.0 - u - v, u, v)));
    }
    let res: Vec<(f64, Option<f64>, Option<f64>)> = pts
        .par_iter()
        .map(|&(t, b)| {
            let q = out.triangle_positions(t);
            let p = q[0] * b.x + q[1] * b.y + q[2] * b.z;
            let (d, ti, bi) = grid.closest(p);
            let (ua, ub) = (uv_at(out, t, b), uv_at(input, ti, bi));
            let uv = match (ua, ub) {
                (Some(a), Some(c)) => Some(a.distance(c)),
                _ => None,
            };
            let colour = match (ua, ub, image) {
                (Some(a), Some(c), Some(img)) => {
                    let (x, y) = (img.at(a), img.at(c));
                    Some(((0..3).map(|k| (x[k] - y[k]).powi(2)).sum::<f64>() / 3.0).sqrt())
                }
                _ => None,
            };
            (d, uv, colour)
        })
        .collect();
    let diag = input.bounding_box_diagonal();
    let n = res.len() as f64;
    let mean = res.iter().map(|r| r.0).sum::<f64>() / n;
    let rms = (res.iter().map(|r| r.0 * r.0).sum::<f64>() / n).sqrt();
    let max = res.iter().map(|r| r.0).fold(0.0, f64::max);
    let uv: Vec<f64> = res.iter().filter_map(|r| r.1).collect();
    let uv_mean = uv.iter().sum::<f64>() / uv.len().max(1) as f64;
    let uv_rms = (uv.iter().map(|x| x * x).sum::<f64>() / uv.len().max(1) as f64).sqrt();
    // Share of samples whose texture coordinate is far off (across a chart, typically),
    // and how many of those lie on triangles with a seam vertex (two or more wedges).
    let uv_far = uv.iter().filter(|&&x| x > 0.05).count() as f64 / uv.len().max(1) as f64;
    let seam_vertex = {
        let mut first: Vec<Option<DVec2>> = vec![None; out.positions.len()];
        let mut seam = vec![false; out.positions.len()];
        for w in &out.wedges {
            let uv = w.texcoord.map(|t| out.texcoords[t as usize]);
            if let Some(uv) = uv {
                match first[w.vertex as usize] {
                    None => first[w.vertex as usize] = Some(uv),
                    Some(f) if f != uv => seam[w.vertex as usize] = true,
                    _ => {}
                }
            }
        }
        seam
    };
    let far_at_seam = pts
        .iter()
        .zip(&res)
        .filter(|(_, r)| r.1.is_some_and(|x| x > 0.05))
        .filter(|((t, _), _)| {
            out.triangle_vertices(*t)
                .iter()
                .any(|&v| seam_vertex[v as usize])
        })
        .count() as f64
        / res
            .iter()
            .filter(|r| r.1.is_some_and(|x| x > 0.05))
            .count()
            .max(1) as f64;
    let seam_share = pts
        .iter()
        .filter(|(t, _)| {
            out.triangle_vertices(*t)
                .iter()
                .any(|&v| seam_vertex[v as usize])
        })
        .count() as f64
        / pts.len() as f64;
    let col: Vec<f64> = res.iter().filter_map(|r| r.2).collect();
    let col_mean = col.iter().sum::<f64>() / col.len().max(1) as f64;
    let col_rms = (col.iter().map(|x| x * x).sum::<f64>() / col.len().max(1) as f64).sqrt();
    serde_json::json!({
        "faces": out.triangles.len(),
        "colour_mean": col_mean,
        "colour_rms": col_rms,
        "mean_pct": 100.0 * mean / diag,
        "rms_pct": 100.0 * rms / diag,
        "max_pct": 100.0 * max / diag,
        "uv_mean": uv_mean,
        "uv_rms": uv_rms,
        "uv_far": uv_far,
        "uv_far_at_seam": far_at_seam,
        "seam_share": seam_share,
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
    let (mut mesh, _) = load(&args.input, &LoadOptions::default()).expect("load");
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
    let image = args
        .quality
        .then(|| {
            args.texture.clone().or_else(|| {
                mesh.materials
                    .iter()
                    .find_map(|m| m.diffuse_texture.as_ref().map(|t| t.path.clone()))
            })
        })
        .flatten()
        .and_then(|p| image::open(p).ok())
        .map(|i| Image(i.to_rgb8()));
    if args.seam_fix {
        if args.quality {
            // The same figures before the fix, so that one run gives both.
            println!(
                "{}",
                serde_json::json!({ "before_seam_fix": quality(&mesh, &out, image.as_ref()) })
            );
        }
        if args.meshopt {
            // meshoptimizer records no origins: take for each output triangle the input
            // triangle closest to its centroid.
            let grid = Grid::new(&mesh);
            out.triangle_origins = (0..out.triangles.len())
                .map(|t| {
                    let p = out.triangle_positions(t);
                    grid.closest((p[0] + p[1] + p[2]) / 3.0).1 as u32
                })
                .collect();
        }
        let r = scanmill::ops::seam_fix::seam_fix(&mut out, &mesh, &Default::default());
        println!("{}", serde_json::to_string(&r).unwrap());
    }
    if args.quality {
        println!("{}", quality(&mesh, &out, image.as_ref()));
    }
    if args.audit {
        let a = decimate::audit::audit(&mesh, &out);
        println!("{}", serde_json::to_string(&a).unwrap());
    }
    if let Some(path) = args.out {
        scanmill::mesh::io::save(&out, &path, &Default::default()).expect("save");
    }
}
