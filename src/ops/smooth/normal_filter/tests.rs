use super::super::tests::{noise, noisy_grid, noisy_sphere, signed_volume};
use super::super::{Border, MethodName, SmoothMethod, SmoothParams, SmoothParamsFile, smooth};
use super::NormalVariant;
use crate::mesh::Mesh;
use crate::mesh::shapes::uv_sphere;
use crate::testing::on_threads;

fn params(f: impl FnOnce(&mut SmoothParamsFile)) -> SmoothParams {
    let mut file = SmoothParamsFile {
        method: Some(MethodName::NormalFilter),
        ..Default::default()
    };
    f(&mut file);
    SmoothParams::try_from(file).unwrap()
}

fn parse(text: &str) -> Result<SmoothParams, String> {
    toml::from_str::<SmoothParams>(text).map_err(|e| e.to_string())
}

/// Distance of every vertex from the unit sphere, RMS.
fn radius_error(m: &Mesh) -> f64 {
    let sum: f64 = m.positions.iter().map(|p| (p.length() - 1.0).powi(2)).sum();
    (sum / m.positions.len() as f64).sqrt()
}

/// A sphere of 16k triangles (four parallel chunks) with radial noise of 1 %.
fn big_noisy_sphere() -> Mesh {
    let mut m = uv_sphere(1.0, 64, 128);
    let r = noise(5, m.positions.len());
    for (p, dr) in m.positions.iter_mut().zip(r) {
        *p *= 1.0 + 0.01 * dr;
    }
    m
}

/// Triangles whose normal in `after` points against (or across) the one in `before`.
fn flipped(before: &Mesh, after: &Mesh) -> usize {
    (0..before.triangle_count())
        .filter(|&t| {
            let reference = before.triangle_cross(t);
            reference.length() > 0.0 && after.triangle_cross(t).dot(reference) <= 0.0
        })
        .count()
}

#[test]
fn defaults_and_strength() {
    let p = SmoothParams::defaults(MethodName::NormalFilter);
    assert_eq!(p.iterations, 4);
    assert_eq!(p.boundary, Border::Fixed);
    let SmoothMethod::NormalFilter(n) = p.method else {
        panic!("{p:?}")
    };
    assert_eq!(n.variant, NormalVariant::Bilateral);
    assert_eq!((n.normal_passes, n.vertex_passes), (1, 3));
    assert_eq!((n.sigma_c, n.sigma_r), (1.0, 1.2));
    assert_eq!(params(|f| f.strength = Some(2.0)).iterations, 8);
    assert_eq!(params(|f| f.strength = Some(0.5)).iterations, 2);
    assert_eq!(params(|f| f.strength = Some(0.01)).iterations, 1);
    let guided = parse("method = \"normal-filter\"\nvariant = \"guided\"\n").unwrap();
    assert!(
        matches!(guided.method, SmoothMethod::NormalFilter(n) if n.variant == NormalVariant::Guided)
    );
    // The resolved form reads back to the same parameters.
    let text = toml::to_string(&guided).unwrap();
    assert_eq!(parse(&text).unwrap(), guided);
}

#[test]
fn parsing_rejects_what_does_not_belong() {
    let err = |text: &str| parse(&format!("method = \"normal-filter\"\n{text}")).unwrap_err();
    assert!(err("strength = 2.0\niterations = 3").contains("not both"));
    assert!(err("strength = 0.0").contains("strength"));
    assert!(err("strength = 11.0").contains("strength"));
    assert!(err("sigma_r = -1.0").contains("sigma_r"));
    assert!(err("sigma_c = 0.0").contains("sigma_c"));
    assert!(err("vertex_passes = 0").contains("vertex_passes"));
    assert!(err("lambda = 0.5").contains("does not apply"));
    assert!(err("update = \"in-place\"").contains("buffered"));
    assert!(err("variant = \"median\"").contains("variant"));
    // ... and the other methods do not take its parameters.
    let other = parse("method = \"taubin\"\nstrength = 1.0\n").unwrap_err();
    assert!(other.contains("does not apply"), "{other}");
}

/// Rayon pools of 1 and 3 threads give the same bits, for both variants.
#[test]
fn deterministic_whatever_the_thread_count() {
    for variant in [NormalVariant::Bilateral, NormalVariant::Guided] {
        let p = params(|f| f.variant = Some(variant));
        let run = |threads| {
            let mut m = big_noisy_sphere();
            let report = on_threads(threads, || smooth(&mut m, &p));
            (m.positions, report.undone_updates)
        };
        let (one, three) = (run(1), run(3));
        assert!(
            one == three,
            "{variant:?}: results differ between 1 and 3 threads"
        );
    }
}

/// On a closed sphere with 1 % radial noise: the radius error drops to well under half,
/// the volume stays within 0.1 %, no triangle flips; the guided variant too.
#[test]
fn denoises_a_sphere_and_keeps_its_volume() {
    for variant in [NormalVariant::Bilateral, NormalVariant::Guided] {
        let noisy = noisy_sphere();
        let mut m = noisy.clone();
        let report = smooth(&mut m, &params(|f| f.variant = Some(variant)));
        let (before, after) = (radius_error(&noisy), radius_error(&m));
        assert!(after < 0.4 * before, "{variant:?}: {before} → {after}");
        let change = signed_volume(&m) / signed_volume(&noisy) - 1.0;
        assert!(change.abs() < 1e-3, "{variant:?}: volume {change}");
        assert_eq!(flipped(&noisy, &m), 0);
        assert_eq!(report.method, "normal-filter");
        assert_eq!(report.passes, 4 * (1 + 3));
    }
}

/// `boundary = "fixed"` holds the border where it is; `"free"` lets it move (along its
/// normal, like every other vertex); the interior is denoised either way.
#[test]
fn borders_as_the_other_methods() {
    let noisy = {
        let mut m = noisy_grid();
        // Noise on the border too, so that a free border has something to remove.
        let z = noise(3, m.positions.len());
        for (p, dz) in m.positions.iter_mut().zip(z) {
            p.z += 0.05 * dz;
        }
        m
    };
    let on_border = |p: &glam::DVec3| p.x < 0.5 || p.x > 19.5 || p.y < 0.5 || p.y > 19.5;
    for boundary in [Border::Fixed, Border::Curve] {
        let mut m = noisy.clone();
        let report = smooth(&mut m, &params(|f| f.boundary = Some(boundary)));
        let moved_border = noisy
            .positions
            .iter()
            .zip(&m.positions)
            .filter(|(a, b)| on_border(a) && a != b)
            .count();
        match boundary {
            Border::Fixed => {
                assert_eq!(moved_border, 0);
                assert_eq!(report.fixed_boundary_vertices, 80);
            }
            Border::Curve => assert!(moved_border > 40, "{moved_border}"),
            other => unreachable!("{other:?} is not a smooth mode"),
        }
        let rms = |m: &Mesh| {
            let inner: Vec<f64> = m
                .positions
                .iter()
                .filter(|p| !on_border(p))
                .map(|p| p.z * p.z)
                .collect();
            (inner.iter().sum::<f64>() / inner.len() as f64).sqrt()
        };
        assert!(rms(&m) < 0.5 * rms(&noisy), "{boundary:?}");
    }
}

/// Noise as large as the edges folds many triangles of the input; whatever the filter
/// asks, no triangle ends up flipped against the input, and the guard had work to do.
#[test]
fn no_triangle_flips_against_the_input() {
    let mut noisy = uv_sphere(1.0, 30, 60);
    let d = noise(9, 3 * noisy.positions.len());
    for (i, p) in noisy.positions.iter_mut().enumerate() {
        *p += glam::DVec3::new(d[3 * i], d[3 * i + 1], d[3 * i + 2]) * 0.06;
    }
    let mut m = noisy.clone();
    let report = smooth(&mut m, &params(|f| f.strength = Some(3.0)));
    assert_eq!(flipped(&noisy, &m), 0);
    assert!(report.undone_updates > 0, "the guard never acted");
}

/// Only positions move: wedges (texture coordinates, normals) and triangles are untouched.
#[test]
fn only_positions_change() {
    let noisy = noisy_sphere();
    let mut m = noisy.clone();
    smooth(&mut m, &SmoothParams::defaults(MethodName::NormalFilter));
    assert_ne!(m.positions, noisy.positions);
    assert_eq!(m.wedges, noisy.wedges);
    assert_eq!(m.triangles, noisy.triangles);
    assert_eq!(m.texcoords, noisy.texcoords);
}
