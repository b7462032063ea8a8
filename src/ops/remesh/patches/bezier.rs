//! Biquadratic Bézier patches from Doo–Sabin points (remeshing thesis §4.5).
//!
//! Every sub-quad of the refined quad mesh is one patch, centred on its Doo–Sabin point
//! C₁₁. With the thesis' stencil rule (the b₂₀ typo fixed: C₂₀, not C₂₂, reading P4) the
//! control net is: the centre b₁₁ = C₁₁; each side's middle control point the mean of the
//! two Doo–Sabin points across that side; each corner the mean of the Doo–Sabin points of
//! all sub-quads around that vertex. At a vertex of valence 4 that is the thesis'
//! ¼(C₀₀+C₁₀+C₀₁+C₁₁); at a region corner of any valence it is the thesis' corner
//! averaging (§4.5, "the average of the element-0 points of all regions sharing the
//! corner"). Neighbours share their side control points exactly, so the patches meet (G0)
//! by construction, without per-region orientation transforms (reading P6).

use super::quads::FineQuads;
use glam::DVec3;
use std::collections::HashMap;

/// Control points shared between patches: one per vertex, one per side (keyed by its
/// ends, lower first).
pub struct Nets {
    pub corner: Vec<DVec3>,
    pub side: HashMap<(u32, u32), DVec3>,
}

/// Corner and side control points of all patches. Fails when a side is not shared by
/// exactly two sub-quads (the layout check makes that impossible; kept as a guard).
pub fn nets(q: &FineQuads) -> Result<Nets, String> {
    let mut sum = vec![DVec3::ZERO; q.vertex_count];
    let mut count = vec![0u32; q.vertex_count];
    let mut sides: HashMap<(u32, u32), (DVec3, u32)> = HashMap::with_capacity(2 * q.faces.len());
    for (f, face) in q.faces.iter().enumerate() {
        let d = q.points[f];
        for k in 0..4 {
            let v = face[k] as usize;
            sum[v] += d;
            count[v] += 1;
            let (a, b) = (face[k], face[(k + 1) % 4]);
            let e = sides
                .entry((a.min(b), a.max(b)))
                .or_insert((DVec3::ZERO, 0));
            e.0 += d;
            e.1 += 1;
        }
    }
    if let Some(((a, b), _)) = sides.iter().find(|(_, s)| s.1 != 2) {
        return Err(format!(
            "internal: patch side {a}-{b} is not shared by exactly two patches"
        ));
    }
    Ok(Nets {
        corner: sum
            .iter()
            .zip(&count)
            .map(|(&s, &c)| if c > 0 { s / c as f64 } else { s })
            .collect(),
        side: sides.into_iter().map(|(k, (s, _))| (k, s * 0.5)).collect(),
    })
}

/// The 3×3 control net `b[x][y]` of sub-quad `f` with corners c₀ (0,0), c₁ (1,0), c₂ (1,1),
/// c₃ (0,1) (thesis §4.5).
pub fn control_net(q: &FineQuads, nets: &Nets, f: usize) -> [[DVec3; 3]; 3] {
    let c = q.faces[f];
    let side = |a: u32, b: u32| nets.side[&(a.min(b), a.max(b))];
    let v = |a: u32| nets.corner[a as usize];
    [
        [v(c[0]), side(c[0], c[3]), v(c[3])],
        [side(c[0], c[1]), q.points[f], side(c[3], c[2])],
        [v(c[1]), side(c[1], c[2]), v(c[2])],
    ]
}

/// The quadratic Bernstein weights (1−t)², 2t(1−t), t².
fn bernstein(t: f64) -> [f64; 3] {
    [(1.0 - t) * (1.0 - t), 2.0 * t * (1.0 - t), t * t]
}

/// A quadratic Bézier curve (thesis §4.7, de Casteljau's result in closed form).
pub fn curve(p: [DVec3; 3], t: f64) -> DVec3 {
    let w = bernstein(t);
    p[0] * w[0] + p[1] * w[1] + p[2] * w[2]
}

/// S(u, v) = Σ b_xy B_x(u) B_y(v) (thesis §4.7).
pub fn surface(b: &[[DVec3; 3]; 3], u: f64, v: f64) -> DVec3 {
    let (wu, wv) = (bernstein(u), bernstein(v));
    let mut s = DVec3::ZERO;
    for x in 0..3 {
        for y in 0..3 {
            s += b[x][y] * (wu[x] * wv[y]);
        }
    }
    s
}
