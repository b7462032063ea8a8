//! `remesh` with `method = "patches"` (issue #24): the remeshing thesis' experiments (its
//! §5.3–§5.4) on icospheres and cubes with and without noise, the one-non-manifold-edge
//! sphere, an open mesh, a torus, thread-count independence, and the closed real scans in
//! ../shared/data. Every output must be closed, manifold, of the input's topology, with no
//! patch facing against the input, and with volume and area in or above the thesis' bands.

mod common;

use glam::DVec3;
use scanmill::mesh::{Mesh, Topology};
use scanmill::metrics::distance::vertex_distances;
use scanmill::metrics::volume::volume;
use scanmill::ops::remesh::{Method, RemeshParams, remesh};
use std::collections::HashMap;
use std::time::Instant;

fn mesh_of(positions: Vec<DVec3>, triangles: Vec<[u32; 3]>) -> Mesh {
    let mut m = Mesh {
        positions,
        ..Mesh::default()
    };
    m.wedges = (0..m.positions.len() as u32)
        .map(|v| scanmill::mesh::Wedge {
            vertex: v,
            texcoord: None,
            normal: None,
        })
        .collect();
    m.triangles = triangles;
    m
}

/// The level-`k` icosphere on the unit sphere (10·4ᵏ + 2 vertices).
fn icosphere(level: usize) -> Mesh {
    let ico = scanmill::mesh::shapes::icosahedron();
    let mut p: Vec<DVec3> = ico.positions.iter().map(|v| v.normalize()).collect();
    let mut t: Vec<[u32; 3]> = (0..ico.triangles.len())
        .map(|i| ico.triangle_vertices(i))
        .collect();
    for _ in 0..level {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut next = Vec::new();
        for tri in &t {
            let mut m = [0u32; 3];
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                m[k] = *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    p.push(((p[a as usize] + p[b as usize]) * 0.5).normalize());
                    p.len() as u32 - 1
                });
            }
            next.push([tri[0], m[0], m[2]]);
            next.push([tri[1], m[1], m[0]]);
            next.push([tri[2], m[2], m[1]]);
            next.push(m);
        }
        t = next;
    }
    mesh_of(p, t)
}

/// The cube [-1,1]³ with an m×m grid of split quads per face (6m² + 2 vertices).
fn cube(m: usize) -> Mesh {
    let mut index: HashMap<[i64; 3], u32> = HashMap::new();
    let mut p = Vec::new();
    let mut t = Vec::new();
    let mut id = |q: DVec3, p: &mut Vec<DVec3>| -> u32 {
        let key = (q * m as f64).round().to_array().map(|x| x as i64);
        *index.entry(key).or_insert_with(|| {
            p.push(q);
            p.len() as u32 - 1
        })
    };
    for axis in 0..3 {
        for side in [-1.0, 1.0] {
            let n = DVec3::from_array(std::array::from_fn(|k| if k == axis { side } else { 0.0 }));
            let u = DVec3::from_array(std::array::from_fn(|k| {
                if k == (axis + 1) % 3 { 1.0 } else { 0.0 }
            }));
            let v = n.cross(u);
            let at = |i: usize, j: usize| {
                n + u * (2.0 * i as f64 / m as f64 - 1.0) + v * (2.0 * j as f64 / m as f64 - 1.0)
            };
            for i in 0..m {
                for j in 0..m {
                    let a = id(at(i, j), &mut p);
                    let b = id(at(i + 1, j), &mut p);
                    let c = id(at(i + 1, j + 1), &mut p);
                    let d = id(at(i, j + 1), &mut p);
                    t.push([a, b, c]);
                    t.push([a, c, d]);
                }
            }
        }
    }
    mesh_of(p, t)
}

/// Gaussian displacement of every vertex, σ in model units per axis (the thesis gives no noise model, §5.4), seeded.
fn noisy(mut m: Mesh, sigma: f64, seed: u64) -> Mesh {
    let mut s = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    let mut uniform = move || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((s >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    let mut gauss = move || {
        let (a, b) = (uniform(), uniform());
        (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
    };
    for q in &mut m.positions {
        *q += DVec3::new(gauss(), gauss(), gauss()) * sigma;
    }
    m
}

fn area(m: &Mesh) -> f64 {
    (0..m.triangles.len()).map(|t| m.triangle_area(t)).sum()
}

fn params(f: Option<f64>, n: usize) -> RemeshParams {
    RemeshParams {
        method: Method::Patches,
        f,
        patch_resolution: Some(n),
        ..RemeshParams::default()
    }
}

struct Figures {
    volume_ratio: f64,
    area_ratio: f64,
    faces: usize,
    seconds: f64,
    flipped: f64,
}

/// Remeshes and checks: closed, manifold, consistently oriented, same Euler
/// characteristic, finite, and the share of triangles facing against the input's nearest
/// triangle below `max_flipped`.
fn run_checked(input: &Mesh, p: &RemeshParams, max_flipped: f64) -> (Mesh, Figures) {
    p.validate().unwrap();
    let start = Instant::now();
    let (out, report) = remesh(input, p).unwrap();
    let seconds = start.elapsed().as_secs_f64();
    assert!(report.patches.is_some());
    out.check_invariants().unwrap();
    assert!(out.positions.iter().all(|q| q.is_finite()));
    let (ti, to) = (Topology::new(input), Topology::new(&out));
    assert_eq!(to.boundary_edges().count(), 0, "holes in the output");
    assert_eq!(to.non_manifold_edges().count(), 0, "non-manifold output");
    assert!(to.non_manifold_vertices().is_empty(), "non-manifold vertex");
    assert_eq!(
        (0..to.edge_count() as u32)
            .filter(|&e| to.is_inconsistent_edge(e))
            .count(),
        0
    );
    assert_eq!(to.euler_characteristic(), ti.euler_characteristic());
    assert_eq!(to.component_count(), ti.component_count());
    let against = common::faces_against(input, &out).len();
    let patches = report.patches.as_ref().unwrap();
    assert!(against <= patches.turned.left, "the report counts them");
    assert_eq!(
        patches.folded_chart_triangles, 0,
        "the harmonic charts fold over"
    );
    let flipped = against as f64 / out.triangles.len() as f64;
    assert!(
        flipped <= max_flipped,
        "{:.3} % of the triangles face against the input",
        100.0 * flipped
    );
    let (vi, vo) = (
        volume(input).value().unwrap(),
        volume(&out).value().unwrap(),
    );
    let figures = Figures {
        volume_ratio: vo / vi,
        area_ratio: area(&out) / area(input),
        faces: out.triangles.len(),
        seconds,
        flipped,
    };
    (out, figures)
}

/// The thesis' results (§5.3): about 92.5–97 % volume on the sphere, 92.5–95 % on the cube ("in or above").
fn in_bands(name: &str, g: &Figures, min_area: f64) {
    eprintln!(
        "{name}: {} triangles, V out/in {:.2} %, A out/in {:.2} %, {:.1} ms",
        g.faces,
        100.0 * g.volume_ratio,
        100.0 * g.area_ratio,
        1e3 * g.seconds
    );
    assert!(
        (0.925..=1.02).contains(&g.volume_ratio),
        "{name}: volume ratio {}",
        g.volume_ratio
    );
    assert!(
        (min_area..=1.02).contains(&g.area_ratio),
        "{name}: area ratio {}",
        g.area_ratio
    );
}

#[test]
fn icospheres_162_642_2562_are_remeshed_closed_within_the_bands() {
    for level in 2..=4 {
        let s = icosphere(level);
        assert_eq!(s.positions.len(), 10 * 4usize.pow(level as u32) + 2);
        let (_, g) = run_checked(&s, &params(None, 2), 0.0);
        in_bands(&format!("icosphere {}", s.positions.len()), &g, 0.93);
    }
}

#[test]
fn noisy_icospheres_are_remeshed_closed_within_the_bands() {
    for sigma in [0.02, 0.05] {
        let s = noisy(icosphere(2), sigma, 7);
        let (_, g) = run_checked(&s, &params(None, 2), 0.0);
        in_bands(&format!("icosphere 162 σ {sigma}"), &g, 0.85);
    }
}

#[test]
fn cubes_386_1538_6146_are_remeshed_closed_within_the_bands() {
    for m in [8, 16, 32] {
        let c = cube(m);
        assert_eq!(c.positions.len(), 6 * m * m + 2);
        let (_, g) = run_checked(&c, &params(None, 2), 0.0);
        in_bands(&format!("cube {}", c.positions.len()), &g, 0.85);
    }
}

#[test]
fn noisy_cubes_are_remeshed_closed_within_the_bands() {
    for sigma in [0.02, 0.05] {
        let c = noisy(cube(8), sigma, 11);
        let (_, g) = run_checked(&c, &params(None, 2), 0.0);
        in_bands(&format!("cube 386 σ {sigma}"), &g, 0.78);
    }
}

#[test]
fn a_torus_keeps_its_genus() {
    let t = scanmill::mesh::shapes::torus(2.0, 0.7, 48, 24);
    let (_, g) = run_checked(&t, &params(Some(0.06), 2), 0.0);
    eprintln!("torus: {} triangles, V {:.3}", g.faces, g.volume_ratio);
    assert!(g.volume_ratio > 0.9 && g.volume_ratio < 1.02);
}

#[test]
fn target_faces_chooses_the_spacing() {
    let s = icosphere(4);
    let p = RemeshParams {
        method: Method::Patches,
        target_faces: Some(20_000),
        patch_resolution: Some(2),
        ..RemeshParams::default()
    };
    let (_, g) = run_checked(&s, &p, 0.0);
    assert!(
        (10_000..=40_000).contains(&g.faces),
        "{} faces for 20,000",
        g.faces
    );
}

/// The thesis' §5.4 sphere with one non-manifold edge: 163 v / 322 t, a fin of two
/// triangles on one edge of the level-2 icosphere.
fn sphere_with_a_fin() -> Mesh {
    let mut s = icosphere(2);
    let [a, b, _] = s.triangle_vertices(0);
    let fin = (s.positions[a as usize] + s.positions[b as usize]) * 0.6;
    s.positions.push(fin);
    s.wedges.push(scanmill::mesh::Wedge {
        vertex: 162,
        texcoord: None,
        normal: None,
    });
    s.triangles.push([a, b, 162]);
    s.triangles.push([b, a, 162]);
    assert_eq!((s.positions.len(), s.triangles.len()), (163, 322));
    s
}

#[test]
fn the_sphere_with_one_non_manifold_edge_is_remeshed_as_the_clean_sphere() {
    // The thesis says its output was identical to the clean sphere's, and its own table
    // contradicts it (volume 2.689 against 4.047, digest pitfall 21): here it is identical.
    let (finned, clean) = (sphere_with_a_fin(), icosphere(2));
    assert_eq!(Topology::new(&finned).non_manifold_edges().count(), 1);
    let (out, report) = remesh(&finned, &params(None, 2)).unwrap();
    let defects = report.patches.as_ref().unwrap().defects;
    assert_eq!(
        (
            defects.non_manifold_edges,
            defects.sheets_dropped,
            defects.triangles_dropped
        ),
        (1, 1, 2)
    );
    let (_, g) = run_checked(&clean, &params(None, 2), 0.0);
    in_bands("icosphere 162 with a fin", &g, 0.93);
    let (expected, _) = remesh(&clean, &params(None, 2)).unwrap();
    assert_eq!(out.positions, expected.positions);
    assert_eq!(out.triangles, expected.triangles);
}

#[test]
fn a_fin_on_a_non_manifold_edge_of_a_torus_is_left_out_and_the_genus_kept() {
    // A flap of two triangles (a quad) hanging from one edge: a small open sheet, dropped.
    let mut t = scanmill::mesh::shapes::torus(2.0, 0.7, 48, 24);
    let [a, b, _] = t.triangle_vertices(10);
    let (pa, pb) = (t.positions[a as usize], t.positions[b as usize]);
    let out = (pa + pb) * 0.5 * 1.3;
    let n = t.positions.len() as u32;
    for p in [out, out + (pb - pa) * 0.5] {
        t.positions.push(p);
        t.wedges.push(scanmill::mesh::Wedge {
            vertex: t.positions.len() as u32 - 1,
            texcoord: None,
            normal: None,
        });
    }
    t.triangles.extend([[a, b, n], [n, b, n + 1]]);
    let topo = Topology::new(&t);
    assert_eq!(topo.non_manifold_edges().count(), 1);
    let (out, report) = remesh(&t, &params(Some(0.06), 2)).unwrap();
    let defects = report.patches.as_ref().unwrap().defects;
    assert_eq!((defects.sheets_dropped, defects.triangles_dropped), (1, 2));
    let to = Topology::new(&out);
    assert_eq!(to.boundary_edges().count(), 0);
    assert_eq!(to.non_manifold_edges().count(), 0);
    assert_eq!(to.euler_characteristic(), 0, "a torus stays a torus");
}

#[test]
fn two_spheres_sharing_an_edge_are_remeshed_as_two_spheres() {
    // Two equal spheres joined along one edge: neither is a defect, each is a closed
    // sheet once the edge's vertices are copied, and each is remeshed on its own.
    let s = icosphere(2);
    let mut m = s.clone();
    let [a, b, _] = s.triangle_vertices(0);
    // The mirror image of the sphere through the plane that holds the edge a-b and is
    // square to the radius through its middle, reusing a and b: the copy shares the edge.
    let n = s.positions.len() as u32;
    let normal = (s.positions[a as usize] + s.positions[b as usize]).normalize();
    let offset = |p: DVec3| p - normal * 2.0 * (p - s.positions[a as usize]).dot(normal);
    for v in 0..n {
        m.positions.push(offset(s.positions[v as usize]));
        m.wedges.push(scanmill::mesh::Wedge {
            vertex: n + v,
            texcoord: None,
            normal: None,
        });
    }
    let map = |v: u32| if v == a || v == b { v } else { n + v };
    for t in 0..s.triangles.len() {
        let [x, y, z] = s.triangle_vertices(t);
        m.triangles.push([map(x), map(z), map(y)]);
    }
    let topo = Topology::new(&m);
    assert_eq!(topo.non_manifold_edges().count(), 1);
    let (out, report) = remesh(&m, &params(None, 2)).unwrap();
    let defects = report.patches.as_ref().unwrap().defects;
    assert_eq!(defects.sheets_dropped, 0);
    let to = Topology::new(&out);
    assert_eq!(to.component_count(), 2);
    assert_eq!(to.non_manifold_edges().count(), 0);
    assert_eq!(to.boundary_edges().count(), 0);
}

#[test]
fn a_surface_touching_itself_gets_a_clear_error() {
    // The sphere pinched: its vertex 0 and the one opposite made one, a non-manifold
    // vertex inside one sheet, which no part left out can mend.
    let mut s = icosphere(2);
    let p0 = s.positions[0];
    let far = (0..s.positions.len() as u32)
        .max_by(|&a, &b| {
            let (da, db) = (
                s.positions[a as usize].distance(p0),
                s.positions[b as usize].distance(p0),
            );
            da.total_cmp(&db)
        })
        .unwrap();
    for t in &mut s.triangles {
        for w in t.iter_mut() {
            if *w == far {
                *w = 0;
            }
        }
    }
    assert_eq!(Topology::new(&s).non_manifold_vertices().len(), 1);
    let e = remesh(&s, &params(None, 2)).unwrap_err().to_string();
    assert!(
        e.contains("touches itself") && e.contains("isotropic"),
        "{e}"
    );
}

#[test]
fn an_open_mesh_is_pointed_to_isotropic() {
    let g = scanmill::mesh::shapes::grid(10, 10);
    let e = remesh(&g, &params(None, 2)).unwrap_err().to_string();
    assert!(e.contains("closed") && e.contains("isotropic"), "{e}");
}

#[test]
fn the_recipe_check_refuses_mixed_parameters() {
    let mut p = params(Some(0.1), 2);
    assert!(p.validate().is_ok());
    p.edge_fraction = Some(0.01);
    assert!(p.validate().is_err());
    let mut p = params(Some(0.1), 2);
    p.target_faces = Some(1000);
    assert!(p.validate().is_err());
    assert!(params(Some(0.0), 2).validate().is_err());
    assert!(params(Some(0.1), 0).validate().is_err());
    let mut p = params(Some(0.1), 2);
    p.on_surface = true;
    assert!(p.validate().is_err());
    let iso = RemeshParams {
        edge_fraction: Some(0.01),
        f: Some(0.1),
        ..RemeshParams::default()
    };
    assert!(iso.validate().is_err());
}

#[test]
fn the_output_does_not_depend_on_the_thread_count() {
    let c = noisy(cube(16), 0.02, 3);
    let p = params(Some(0.08), 3);
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| remesh(&c, &p).unwrap().0);
    let many = rayon::ThreadPoolBuilder::new()
        .num_threads(4)
        .build()
        .unwrap()
        .install(|| remesh(&c, &p).unwrap().0);
    assert_eq!(one, many);
}

/// The closed scans of ../shared/data (SOURCES.md), at 100k output triangles or the scan's
/// own count: closed, manifold, of the input's topology, fold-free charts, at most 0.03 % of
/// the triangles facing against the input (where a smooth patch bridges a crease narrower
/// than itself: eyelids, lips, ear folds; up to 0.13 % before the repair pass), near the input, volume kept within 2.5 %. The
/// figures go to docs/remeshing.md. A scan that is not closed and manifold must give the
/// clear error instead.
#[test]
fn closed_real_scans_are_remeshed_closed_and_manifold() {
    let scans = [
        "untextured/misc_scans/igea_cyberware_trilist_DERIVED.ply.gz",
        "untextured/misc_scans/stanford_lucy_100k.ply",
        "untextured/misc_scans/stanford_armadillo_libigl.obj.gz",
        "untextured/misc_scans/max_planck_decimated_libigl.obj",
        "untextured/misc_scans/nefertiti_hack_lowres.obj",
        "untextured/misc_scans/xyzrgb_dragon_20k.ply",
        "textured/spot_keenan_crane/spot_triangulated.obj",
        "textured/lee_perry_smith_head/LeePerrySmith_converted.obj",
    ];
    for rel in scans {
        let mesh = common::scan(rel);
        let p = RemeshParams {
            method: Method::Patches,
            // At least 100k: a region makes 384 triangles at n = 2, so fewer leaves a
            // small scan (spot, 5,856) with a dozen regions.
            target_faces: Some(mesh.triangles.len().max(100_000)),
            patch_resolution: Some(2),
            ..RemeshParams::default()
        };
        let topo = Topology::new(&mesh);
        let closed = topo.boundary_edges().count() == 0
            && topo.non_manifold_edges().count() == 0
            && topo.non_manifold_vertices().is_empty();
        if !closed {
            let e = remesh(&mesh, &p).unwrap_err().to_string();
            eprintln!("{rel}: not closed/manifold: {e}");
            assert!(e.contains("isotropic") || e.contains("orient"), "{e}");
            continue;
        }
        let (out, g) = run_checked(&mesh, &p, 0.0003);
        let d = vertex_distances(&out, &mesh).unwrap();
        let diag = mesh.bounding_box_diagonal();
        let mean = d.iter().sum::<f64>() / d.len() as f64;
        let max = d.iter().cloned().fold(0.0, f64::max);
        eprintln!(
            "{rel}: {} -> {} triangles in {:.2} s, volume {:+.2} %, area {:+.2} %, distance mean {:.4} % max {:.3} % of the diagonal, facing against the input {:.3} %",
            mesh.triangles.len(),
            g.faces,
            g.seconds,
            100.0 * (g.volume_ratio - 1.0),
            100.0 * (g.area_ratio - 1.0),
            100.0 * mean / diag,
            100.0 * max / diag,
            100.0 * g.flipped
        );
        assert!(
            (g.volume_ratio - 1.0).abs() < 0.025,
            "{rel}: volume ratio {}",
            g.volume_ratio
        );
        assert!(mean < 1e-3 * diag, "{rel}: mean distance {mean}");
    }
}
