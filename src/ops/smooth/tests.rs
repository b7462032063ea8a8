use super::*;
use crate::mesh::shapes::{grid, uv_sphere};
use crate::mesh::{Index, Wedge};
use crate::testing::on_threads;
use glam::DVec2;

const ALL: [MethodName; 4] = [
    MethodName::Laplace,
    MethodName::Hc,
    MethodName::Taubin,
    MethodName::Bilateral,
];

fn parse(text: &str) -> Result<SmoothParams, String> {
    toml::from_str::<SmoothParams>(text).map_err(|e| e.to_string())
}

fn with(method: MethodName, f: impl FnOnce(&mut SmoothParamsFile)) -> SmoothParams {
    let mut file = SmoothParamsFile {
        method: Some(method),
        ..Default::default()
    };
    f(&mut file);
    SmoothParams::try_from(file).unwrap()
}

/// Deterministic pseudo-random numbers in [-1, 1] (no RNG crate needed for unit tests).
pub(super) fn noise(seed: u64, count: usize) -> Vec<f64> {
    let mut lcg = crate::testing::Lcg(seed);
    lcg.next_u64();
    (0..count).map(|_| lcg.signed()).collect()
}

pub(super) fn signed_volume(m: &Mesh) -> f64 {
    (0..m.triangle_count())
        .map(|t| {
            let [a, b, c] = m.triangle_positions(t);
            a.dot(b.cross(c))
        })
        .sum::<f64>()
        / 6.0
}

fn rms_z(m: &Mesh) -> f64 {
    (m.positions.iter().map(|p| p.z * p.z).sum::<f64>() / m.positions.len() as f64).sqrt()
}

/// A 20×20 grid with z noise of amplitude 0.1 on the interior vertices.
pub(super) fn noisy_grid() -> Mesh {
    let mut m = grid(20, 20);
    let z = noise(7, m.positions.len());
    for (p, dz) in m.positions.iter_mut().zip(z) {
        let interior = p.x > 0.5 && p.x < 19.5 && p.y > 0.5 && p.y < 19.5;
        if interior {
            p.z = 0.1 * dz;
        }
    }
    m
}

pub(super) fn noisy_sphere() -> Mesh {
    let mut m = uv_sphere(1.0, 40, 80);
    let r = noise(11, m.positions.len());
    for (p, dr) in m.positions.iter_mut().zip(r) {
        *p *= 1.0 + 0.01 * dr;
    }
    m
}

#[test]
fn defaults_are_table_a2() {
    let l = SmoothParams::defaults(MethodName::Laplace);
    assert_eq!(l.iterations, 22);
    assert_eq!(
        l.method,
        SmoothMethod::Laplace(LaplaceParams {
            lambda: 0.08,
            anchor: LaplaceAnchor::Current,
            weights: Weights::Uniform
        })
    );
    let h = SmoothParams::defaults(MethodName::Hc);
    assert_eq!(h.iterations, 8);
    assert!(
        matches!(h.method, SmoothMethod::Hc(p) if p.lambda == 1.0 && p.alpha == 0.001 && p.beta == 0.5)
    );
    let t = SmoothParams::defaults(MethodName::Taubin);
    assert_eq!(t.iterations, 13);
    assert!(
        matches!(t.method, SmoothMethod::Taubin(p) if p.lambda == 0.53 && p.mu == -0.54 && p.count == TaubinCount::Pairs)
    );
    let b = SmoothParams::defaults(MethodName::Bilateral);
    assert_eq!(b.iterations, 3);
    assert_eq!(b.update, Update::Buffered);
    assert_eq!(b.boundary, Border::Fixed);
    let abs = parse("method = \"bilateral\"\nunits = \"absolute\"\n").unwrap();
    assert!(
        matches!(abs.method, SmoothMethod::Bilateral(p) if p.sigma_c == 0.02 && p.sigma_s == 0.01)
    );
}

#[test]
fn parsing_rejects_what_does_not_belong() {
    for (text, says) in [
        (
            "method = \"laplace\"\nsigma_c = 1.0\n",
            &["sigma_c", "lambda"][..],
        ),
        ("method = \"taubin\"\nlambda = 0.5\nmu = -0.4\n", &["mu"]),
        ("method = \"hc\"\nupdate = \"in-place\"\n", &["buffered"]),
        ("method = \"laplace\"\nlamda = 0.5\n", &["lamda"]),
        ("method = \"gauss\"\n", &["taubin"]),
        ("method = \"laplace\"\niterations = 0\n", &["iterations"]),
        ("iterations = 3\n", &["method"]),
    ] {
        let e = parse(text).unwrap_err();
        assert!(says.iter().all(|s| e.contains(s)), "{text}: {e}");
    }
    assert!(parse("method = \"laplace\"\nlambda = 1.0\n").is_ok());
    assert!(parse("method = \"laplace\"\nlambda = 1.5\n").is_err());
}

#[test]
fn resolved_form_round_trips() {
    for m in ALL {
        let p = SmoothParams::defaults(m);
        let text = toml::to_string(&p).unwrap();
        assert_eq!(parse(&text).unwrap(), p, "{text}");
        assert!(p.validate().is_ok());
    }
}

#[test]
fn recipe_step_parses() {
    let recipe = crate::recipe::Recipe::from_toml(
        "[[step]]\nkind = \"smooth\"\nmethod = \"taubin\"\niterations = 5\n",
        std::path::Path::new("r.toml"),
    )
    .unwrap();
    assert_eq!(recipe.steps[0].kind(), "smooth");
    let e = crate::recipe::Recipe::from_toml(
        "[[step]]\nkind = \"smooth\"\nmethod = \"taubin\"\nsigma_s = 5\n",
        std::path::Path::new("r.toml"),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("sigma_s") && e.contains("line"), "{e}");
}

#[test]
fn plane_stays_a_plane() {
    for method in ALL {
        for boundary in [Border::Fixed, Border::Curve] {
            for weights in [Weights::Uniform, Weights::Cotangent] {
                if method == MethodName::Bilateral && weights == Weights::Cotangent {
                    continue;
                }
                let mut m = grid(12, 9);
                // Shear in-plane so the umbrella really moves vertices.
                for p in &mut m.positions {
                    p.x += 0.3 * (p.y * 1.7).sin();
                }
                let params = with(method, |f| {
                    f.boundary = Some(boundary);
                    if method != MethodName::Bilateral {
                        f.weights = Some(weights);
                    }
                });
                let report = smooth(&mut m, &params);
                assert!(
                    m.positions.iter().all(|p| p.z.abs() < 1e-12),
                    "{method:?} {boundary:?} {weights:?}"
                );
                assert!(m.positions.iter().all(|p| p.is_finite()));
                assert!(report.passes > 0);
            }
        }
    }
}

#[test]
fn noisy_plane_gets_flatter() {
    for method in ALL {
        let mut m = noisy_grid();
        let before = rms_z(&m);
        smooth(&mut m, &SmoothParams::defaults(method));
        let after = rms_z(&m);
        assert!(after < 0.7 * before, "{method:?}: {before} → {after}");
    }
}

#[test]
fn laplace_shrinks_a_sphere_taubin_and_hc_nearly_do_not() {
    let clean = signed_volume(&uv_sphere(1.0, 40, 80));
    let change = |method: MethodName, iterations: u32| {
        let mut m = noisy_sphere();
        let p = with(method, |f| f.iterations = Some(iterations));
        smooth(&mut m, &p);
        signed_volume(&m) / clean - 1.0
    };
    // λ = 1 (Eq. 3.4) for a clear shrink; Taubin and HC at their Table A.2 settings.
    let mut laplace = noisy_sphere();
    let p = with(MethodName::Laplace, |f| {
        f.lambda = Some(1.0);
        f.iterations = Some(20)
    });
    smooth(&mut laplace, &p);
    let laplace = signed_volume(&laplace) / clean - 1.0;
    let taubin = change(MethodName::Taubin, 10);
    let hc = change(MethodName::Hc, 10);
    assert!(laplace < -0.05, "laplace {laplace}");
    assert!(taubin.abs() < 0.01, "taubin {taubin}");
    assert!(hc.abs() < 0.01, "hc {hc}");
    assert!(taubin.abs() < laplace.abs() / 5.0 && hc.abs() < laplace.abs() / 5.0);
}

#[test]
fn laplace_eq_3_4_is_eq_3_3_with_lambda_one() {
    // Plain neighbour averaging by hand against the λ = 1 run (Eq. 3.4 is Eq. 3.3 with λ = 1).
    let mut m = noisy_sphere();
    let topo = m.topology();
    let expected: Vec<DVec3> = (0..m.positions.len() as u32)
        .map(|v| {
            let ring = topo.vertex_neighbours(v);
            ring.iter().map(|&j| m.positions[j as usize]).sum::<DVec3>() * (1.0 / ring.len() as f64)
        })
        .collect();
    smooth(
        &mut m,
        &with(MethodName::Laplace, |f| {
            f.lambda = Some(1.0);
            f.iterations = Some(1)
        }),
    );
    for (a, b) in m.positions.iter().zip(&expected) {
        assert!(a.distance(*b) < 1e-15);
    }
}

#[test]
fn anchored_laplace_stays_near_the_original() {
    let original = noisy_sphere();
    let run = |anchor| {
        let mut m = original.clone();
        smooth(
            &mut m,
            &with(MethodName::Laplace, |f| {
                f.lambda = Some(0.72);
                f.anchor = Some(anchor);
                f.iterations = Some(30)
            }),
        );
        signed_volume(&m)
    };
    let v0 = signed_volume(&original);
    let current = run(LaplaceAnchor::Current) / v0 - 1.0;
    let anchored = run(LaplaceAnchor::Original) / v0 - 1.0;
    assert!(
        anchored.abs() < current.abs() / 3.0,
        "{anchored} vs {current}"
    );
}

#[test]
fn taubin_pass_counting() {
    let run = |count, iterations| {
        let mut m = noisy_sphere();
        let r = smooth(
            &mut m,
            &with(MethodName::Taubin, |f| {
                f.count = Some(count);
                f.iterations = Some(iterations)
            }),
        );
        (m, r.passes)
    };
    let (pairs, passes_a) = run(TaubinCount::Pairs, 3);
    let (passes, passes_b) = run(TaubinCount::Passes, 6);
    assert_eq!((passes_a, passes_b), (6, 6));
    assert_eq!(pairs.positions, passes.positions);
    let (_, thirteen) = run(TaubinCount::Passes, 13);
    assert_eq!(thirteen, 13);
}

#[test]
fn buffered_is_deterministic_across_thread_counts() {
    for method in ALL {
        let run = |threads| {
            let mut m = noisy_sphere();
            on_threads(threads, || smooth(&mut m, &SmoothParams::defaults(method)));
            m.positions
        };
        assert_eq!(run(1), run(3), "{method:?}");
    }
}

#[test]
fn in_place_smooths_and_differs_from_buffered() {
    for method in [MethodName::Laplace, MethodName::Taubin] {
        let mut buffered = noisy_grid();
        let mut in_place = noisy_grid();
        smooth(&mut buffered, &SmoothParams::defaults(method));
        smooth(
            &mut in_place,
            &with(method, |f| f.update = Some(Update::InPlace)),
        );
        assert_ne!(buffered.positions, in_place.positions);
        assert!(rms_z(&in_place) < 0.7 * rms_z(&noisy_grid()));
    }
}

#[test]
fn fixed_border_does_not_move_free_border_is_not_pulled_in() {
    let original = noisy_grid();
    for method in ALL {
        for boundary in [Border::Fixed, Border::Curve] {
            let mut m = original.clone();
            let r = smooth(&mut m, &with(method, |f| f.boundary = Some(boundary)));
            let border = |p: DVec3| p.x < 0.5 || p.x > 19.5 || p.y < 0.5 || p.y > 19.5;
            for (a, b) in original.positions.iter().zip(&m.positions) {
                if !border(*a) {
                    continue;
                }
                match boundary {
                    Border::Fixed => assert_eq!(a, b),
                    // Curve border vertices average only their border neighbours, which lie
                    // in z = 0 (the noise is on the interior): they stay in the plane, not
                    // pulled towards the noisy interior. (The bilateral filter moves them
                    // along their normal instead.)
                    Border::Curve if method == MethodName::Bilateral => {}
                    Border::Curve => assert!(b.z.abs() < 1e-12, "{method:?}: {a} → {b}"),
                    other => unreachable!("{other:?} is not a smooth mode"),
                }
            }
            let expected_fixed = if boundary == Border::Fixed { 80 } else { 0 };
            assert_eq!(r.fixed_boundary_vertices, expected_fixed);
        }
    }
}

#[test]
fn only_positions_move_seams_untouched() {
    // Split the grid's wedges on the right half: a texture seam along x = 10.
    let mut m = noisy_grid();
    let base = m.texcoords.len() as Index;
    m.texcoords.extend(
        m.texcoords
            .clone()
            .iter()
            .map(|t| *t + DVec2::new(5.0, 0.0)),
    );
    let mut extra = Vec::new();
    for t in 0..m.triangles.len() {
        if m.triangle_positions(t).iter().all(|p| p.x >= 10.0) {
            for c in 0..3 {
                let w = m.wedges[m.triangles[t][c] as usize];
                extra.push(Wedge {
                    vertex: w.vertex,
                    texcoord: w.texcoord.map(|i| i + base),
                    normal: None,
                });
                m.triangles[t][c] = (m.wedges.len() + extra.len() - 1) as Index;
            }
        }
    }
    m.wedges.extend(extra);
    m.check_invariants().unwrap();
    assert!(m.topology().counts().texture_seam_edges > 0);
    for method in ALL {
        let mut s = m.clone();
        smooth(&mut s, &SmoothParams::defaults(method));
        assert_ne!(s.positions, m.positions);
        let mut same = s.clone();
        same.positions = m.positions.clone();
        assert_eq!(same, m, "{method:?} changed more than positions");
    }
}

#[test]
fn degenerate_input_does_not_panic() {
    // Isolated vertex, a single triangle, zero-length edges.
    let mut m = grid(1, 1);
    m.positions.push(DVec3::new(5.0, 5.0, 5.0));
    for method in ALL {
        for boundary in [Border::Fixed, Border::Curve] {
            let mut s = m.clone();
            let r = smooth(&mut s, &with(method, |f| f.boundary = Some(boundary)));
            assert_eq!(r.isolated_vertices, 1);
            assert!(s.positions.iter().all(|p| p.is_finite()));
        }
    }
    let mut collapsed = uv_sphere(1.0, 4, 6);
    for p in &mut collapsed.positions {
        *p = DVec3::ZERO;
    }
    for method in ALL {
        let mut s = collapsed.clone();
        let p = with(method, |f| {
            if method != MethodName::Bilateral {
                f.weights = Some(Weights::Cotangent)
            }
        });
        smooth(&mut s, &p);
        assert!(s.positions.iter().all(|p| *p == DVec3::ZERO), "{method:?}");
    }
    let mut empty = Mesh::default();
    for method in ALL {
        smooth(&mut empty, &SmoothParams::defaults(method));
    }
}

#[test]
fn bilateral_keeps_a_sharp_edge_sharper_than_laplace() {
    // A folded grid (a 90° ridge along x = 10) with noise: the bilateral filter's signal
    // weight keeps the ridge; Laplace rounds it.
    let mut fold = grid(20, 20);
    for p in &mut fold.positions {
        p.z = 10.0 - (p.x - 10.0).abs();
    }
    let mut noisy = fold.clone();
    let r = noise(3, noisy.positions.len());
    for (p, d) in noisy.positions.iter_mut().zip(r) {
        p.z += 0.05 * d;
    }
    let ridge_error = |m: &Mesh| {
        m.positions
            .iter()
            .zip(&fold.positions)
            .filter(|(_, c)| (c.x - 10.0).abs() < 0.5 && c.y > 1.0 && c.y < 19.0)
            .map(|(p, c)| p.distance(*c))
            .sum::<f64>()
    };
    let mut bilateral = noisy.clone();
    smooth(
        &mut bilateral,
        &with(MethodName::Bilateral, |f| {
            f.sigma_c = Some(1.0);
            f.sigma_s = Some(0.1);
            f.iterations = Some(3)
        }),
    );
    let mut laplace = noisy.clone();
    smooth(
        &mut laplace,
        &with(MethodName::Laplace, |f| {
            f.lambda = Some(0.5);
            f.iterations = Some(6)
        }),
    );
    assert!(
        ridge_error(&bilateral) < 0.5 * ridge_error(&laplace),
        "{} vs {}",
        ridge_error(&bilateral),
        ridge_error(&laplace)
    );
}
