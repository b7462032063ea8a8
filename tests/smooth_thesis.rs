//! The smoothing thesis' comparison (its ch. 5 and App. B; docs/smoothing.md) reproduced on real scans: noise
//! σ = 0.2 × mean edge length along the vertex normals (seeded), then the four methods
//! with their Table A.2 parameters, measured against the clean scan with `compare`.
//!
//! The always-run test checks the volume ranking on one closed scan; the full four-scan
//! table (bunny, lucy, igea, facefuns) with the MeshLab reference figures is `#[ignore]`d
//! (about a minute on two cores): `cargo test --test smooth_thesis -- --ignored --nocapture`.

mod common;

use scanmill::compare::{CompareOptions, CompareTable, NamedRecipe, run_on_mesh};
use scanmill::mesh::Mesh;
use scanmill::metrics::MetricsOptions;
use scanmill::metrics::noise::NoiseOptions;
use scanmill::recipe::Recipe;
use std::path::Path;

use common::scan_untextured as load_scan;

fn recipe(name: &str, step: &str) -> NamedRecipe {
    NamedRecipe {
        name: name.to_string(),
        recipe: Recipe::from_toml(
            &format!("[[step]]\nkind = \"smooth\"\n{step}"),
            Path::new(name),
        )
        .unwrap(),
    }
}

/// The four methods with Table A.2 parameters (all defaults), and Taubin with the thesis'
/// pass counting (13 passes = 7 λ + 6 μ).
fn thesis_recipes() -> Vec<NamedRecipe> {
    vec![
        recipe("laplace λ0.08 ×22", "method = \"laplace\"\n"),
        recipe("hc α0.001 β0.5 ×8", "method = \"hc\"\n"),
        recipe("taubin 0.53/-0.54 ×13", "method = \"taubin\"\n"),
        recipe("bilateral ×3", "method = \"bilateral\"\n"),
        recipe(
            "taubin ×13 passes",
            "method = \"taubin\"\ncount = \"passes\"\n",
        ),
        recipe(
            "taubin ×13 free border",
            "method = \"taubin\"\nboundary = \"free\"\n",
        ),
    ]
}

fn compare(clean: &Mesh, name: &str, recipes: &[NamedRecipe], samples: usize) -> CompareTable {
    let options = CompareOptions {
        noise: Some(NoiseOptions::default()),
        metrics: MetricsOptions {
            samples,
            ..Default::default()
        },
    };
    run_on_mesh(clean, name, recipes, &options).unwrap()
}

fn volume(t: &CompareTable, row: usize) -> f64 {
    t.rows[row]
        .volume_change_percent
        .unwrap_or_else(|| panic!("{}: no volume", t.rows[row].name))
}

fn abs_volumes(t: &CompareTable) -> Vec<f64> {
    (1..t.rows.len()).map(|r| volume(t, r).abs()).collect()
}

/// The thesis' cube (Table A.1, its size derived from the counts): edge 1.8, each face a 32 × 32 grid of squares
/// cut into two triangles: 6146 vertices, 12288 triangles, closed, outward.
fn thesis_cube() -> Mesh {
    use scanmill::mesh::Wedge;
    use std::collections::BTreeMap;
    const N: i32 = 32;
    let mut mesh = Mesh::default();
    let mut index: BTreeMap<[i32; 3], u32> = BTreeMap::new();
    let mut vertex = |mesh: &mut Mesh, l: [i32; 3]| {
        *index.entry(l).or_insert_with(|| {
            let p = l.map(|c| 1.8 * c as f64 / N as f64 - 0.9);
            mesh.positions.push(glam::DVec3::from_array(p));
            (mesh.positions.len() - 1) as u32
        })
    };
    for axis in 0..3 {
        for side in [0, N] {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            for i in 0..N {
                for j in 0..N {
                    let at = |di: i32, dj: i32| {
                        let mut l = [0; 3];
                        l[axis] = side;
                        l[u] = i + di;
                        l[v] = j + dj;
                        l
                    };
                    let q = [at(0, 0), at(1, 0), at(1, 1), at(0, 1)].map(|l| vertex(&mut mesh, l));
                    // e_u × e_v = e_axis: counter-clockwise in (u, v) faces +axis.
                    let tris = if side == N {
                        [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]
                    } else {
                        [[q[0], q[2], q[1]], [q[0], q[3], q[2]]]
                    };
                    mesh.triangles.extend(tris);
                }
            }
        }
    }
    mesh.wedges = (0..mesh.positions.len() as u32)
        .map(|v| Wedge {
            vertex: v,
            texcoord: None,
            normal: None,
        })
        .collect();
    mesh
}

/// Volume kept on the thesis' own cube with its solids' parameters (Table A.2: BMDS
/// σ_c = 0.2, σ_s = 0.01 absolute, 4 iterations; Taubin counted in passes as the thesis
/// does): HC best, then Taubin, bilateral, Laplace, as in Table B (cube: 99.96, 99.79,
/// 99.57, 99.31 %) and the thesis' average ranking (§5.5). The bilateral filter keeps
/// its default 3 rings: ρ = 0.4 would span about 6, and with the whole ball it rounds the
/// cube's faces (angle 0.18 rad against the thesis' 0.085; docs/smoothing.md).
#[test]
fn cube_volume_ranking_as_in_the_thesis() {
    let cube = thesis_cube();
    assert_eq!((cube.positions.len(), cube.triangles.len()), (6146, 12288));
    let recipes = [
        recipe("laplace", "method = \"laplace\"\n"),
        recipe("hc", "method = \"hc\"\n"),
        recipe(
            "taubin ×13 passes",
            "method = \"taubin\"\ncount = \"passes\"\n",
        ),
        recipe(
            "bilateral 0.2/0.01 ×4",
            "method = \"bilateral\"\nunits = \"absolute\"\nsigma_c = 0.2\nsigma_s = 0.01\niterations = 4\n",
        ),
    ];
    let t = compare(&cube, "thesis cube", &recipes, 20_000);
    println!("{}", t.to_text());
    let v = abs_volumes(&t);
    let (laplace, hc, taubin, bilateral) = (v[0], v[1], v[2], v[3]);
    assert!(
        hc < taubin && taubin < bilateral && bilateral < laplace,
        "{v:?}\n{}",
        t.to_text()
    );
    // ... and, as in the thesis, the bilateral filter gives the best face normals on the
    // cube (sharp edges kept): Table B cube 0.085 rad against 0.105–0.114.
    let angle = |r: usize| t.rows[r].angular_mean.unwrap();
    assert!((1..4).all(|r| angle(4) < angle(r)), "{}", t.to_text());
}

/// On a real scan (lucy, closed): HC keeps the volume best, Taubin (thesis counting) next,
/// both far better than Laplace; HC, Taubin and Laplace all bring the surface closer to the
/// clean one. The bilateral filter with the thesis' bunny parameters shrinks this scan more
/// than Laplace, as it shrank the thesis' bunny and sphere more than Laplace did (Table B:
/// 99.54 vs 99.68 %, 98.70 vs 99.36 %); it wins on average only thanks to the flat-faced
/// solids (see the cube test).
#[test]
fn lucy_volume_ranking_and_denoising() {
    let clean = load_scan("untextured/misc_scans/stanford_lucy_100k.ply");
    let recipes = thesis_recipes();
    let t = compare(&clean, "lucy", &recipes[..5], 50_000);
    println!("{}", t.to_text());
    // Rows: 0 noisy input, 1 laplace, 2 hc, 3 taubin (pairs), 4 bilateral, 5 taubin passes.
    let v = abs_volumes(&t);
    let (laplace, hc, taubin_pairs, bilateral, taubin) = (v[0], v[1], v[2], v[3], v[4]);
    assert!(
        hc < taubin && taubin < laplace && taubin < bilateral,
        "{v:?}\n{}",
        t.to_text()
    );
    assert!(taubin_pairs < laplace / 10.0, "{v:?}");
    let noisy = t.rows[0].to_clean_mean_percent.unwrap();
    for row in [1, 2, 3, 5] {
        let d = t.rows[row].to_clean_mean_percent.unwrap();
        assert!(d < noisy, "{}: {d} vs noisy {noisy}", t.rows[row].name);
    }
}

/// MeshLab on the same protocol (mean distance from the result to the clean surface, % of
/// the bounding-box diagonal): noisy → Taubin 0.53/−0.54 ×13.
const MESHLAB: [(&str, &str, f64, f64); 4] = [
    (
        "bunny",
        "untextured/stanford_bunny/bun_zipper.ply",
        0.057,
        0.032,
    ),
    (
        "lucy",
        "untextured/misc_scans/stanford_lucy_100k.ply",
        0.044,
        0.026,
    ),
    (
        "igea",
        "untextured/misc_scans/igea_cyberware_trilist_DERIVED.ply.gz",
        0.033,
        0.017,
    ),
    (
        "facefuns",
        "textured/facefuns_di3d_face/example.obj",
        0.052,
        0.028,
    ),
];

#[test]
#[ignore = "the full four-scan table, about a minute: run with --ignored --nocapture"]
fn thesis_table_on_four_scans() {
    let mut recipes = thesis_recipes();
    // Bilateral with σ_s near the noise level instead of the thesis' bunny values.
    recipes.push(recipe(
        "bilateral 1/0.2 ×3",
        "method = \"bilateral\"\nsigma_c = 1.0\nsigma_s = 0.2\n",
    ));
    recipes.push(recipe(
        "bilateral 1/0.2 ×3 1-ring",
        "method = \"bilateral\"\nsigma_c = 1.0\nsigma_s = 0.2\nrings = 1\n",
    ));
    let mut summary = String::from(
        "mean distance, % of the diagonal: result → clean (clean → result), MeshLab, ratios\n",
    );
    for (name, path, meshlab_noisy, meshlab_taubin) in MESHLAB {
        let clean = load_scan(path);
        let t = compare(&clean, name, &recipes, 100_000);
        println!("{}", t.to_text());
        for (label, r, meshlab) in [("noisy", 0, meshlab_noisy), ("taubin", 3, meshlab_taubin)] {
            let to = t.rows[r].to_clean_mean_percent.unwrap();
            let from = t.rows[r].from_clean_mean_percent.unwrap();
            summary.push_str(&format!(
                "{name:<9} {label:<7} {to:>8.4} ({from:.4})  {meshlab:>31.3}  {:.2} ({:.2})\n",
                to / meshlab,
                from / meshlab
            ));
            // docs/smoothing.md ("Against MeshLab"): Taubin within 10 % of MeshLab's on all
            // four scans, the noisy input within 16 % (result → clean) and 6 % (clean →
            // result); the bands leave a little room for another sampling seed.
            let band = if r == 0 { 0.8..1.2 } else { 0.85..1.15 };
            assert!(
                band.contains(&(from / meshlab)) || band.contains(&(to / meshlab)),
                "{name} {label}: {to} ({from}) against MeshLab's {meshlab}"
            );
        }
        let (noisy, taubin) = (
            t.rows[0].to_clean_mean_percent,
            t.rows[3].to_clean_mean_percent,
        );
        assert!(
            taubin < noisy,
            "{name}: Taubin {taubin:?} not below the noisy {noisy:?}"
        );
    }
    println!("{summary}");
}
