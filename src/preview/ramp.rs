//! The colour ramp of the distance panel: viridis (van der Walt and Smith, matplotlib),
//! perceptually uniform and readable with the common colour-vision deficiencies. Nine
//! samples of the published table, interpolated linearly in sRGB, are within a few levels
//! of the full 256-entry table, which is plenty for a preview.

const VIRIDIS: [[f64; 3]; 9] = [
    [68.0, 1.0, 84.0],
    [71.0, 44.0, 122.0],
    [59.0, 81.0, 139.0],
    [44.0, 113.0, 142.0],
    [33.0, 144.0, 141.0],
    [39.0, 173.0, 129.0],
    [92.0, 200.0, 99.0],
    [170.0, 220.0, 50.0],
    [253.0, 231.0, 37.0],
];

/// The ramp's colour at `t` in [0, 1] (clamped; NaN reads 0), as 0..255 floats.
pub fn viridis(t: f64) -> [f64; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (VIRIDIS.len() - 1) as f64;
    let i = (x.floor() as usize).min(VIRIDIS.len() - 2);
    let f = x - i as f64;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    [0, 1, 2].map(|k| a[k] + (b[k] - a[k]) * f)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ends_middle_and_clamping() {
        assert_eq!(viridis(0.0), VIRIDIS[0]);
        assert_eq!(viridis(1.0), VIRIDIS[8]);
        assert_eq!(viridis(0.5), VIRIDIS[4]);
        assert_eq!(viridis(-3.0), VIRIDIS[0]);
        assert_eq!(viridis(7.0), VIRIDIS[8]);
        assert_eq!(viridis(f64::NAN), VIRIDIS[0]);
        // Lightness grows along the ramp (sum of channels as a rough proxy).
        let sum = |c: [f64; 3]| c.iter().sum::<f64>();
        assert!(sum(viridis(0.2)) < sum(viridis(0.6)) && sum(viridis(0.6)) < sum(viridis(1.0)));
    }
}
