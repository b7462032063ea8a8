//! Hoppe's attribute-extended quadric (thesis §2.3.2, eqs.
//! 2.8–2.12) in compact form, and the wedge-aware vertex quadric of dimension 3 + k·m
//! (§3.2, eqs. 3.4–3.6) minimised through its Schur complement (§2.3.3).
//!
//! Storage per quadric is the thesis' "11 + 4m" numbers (§2.3.2): the weighted symmetric
//! 3×3 position block `p`, the weighted linear term `beta`, the weighted constant `c`, and
//! for the attribute block the *unweighted* area sums `g_j = Σ a·g_j`, `delta_j = Σ a·d_j`
//! and `alpha = Σ a`. The attribute block of the full matrix is then `−w_j·g_j` (coupling),
//! `w_j·alpha` (diagonal) and `−w_j·delta_j` (linear term), so nothing is lost by keeping
//! those parts unweighted, and the optimal attributes `s_j = (g_j·p + delta_j)/alpha` do not
//! depend on the weights at all (our derivation from §2.3.3).
//!
//! Readings applied (docs/decimation.md): the plane offset is `d = −n·p1` (reading R1, the thesis prints
//! `d = n·p1`); the attribute block of (2.11) is `g gᵀ`, not `n nᵀ` (reading R2); the attribute
//! term is squared (reading R3); the extended quadric is area-weighted as a whole (reading R4).

/// Per-quadric weights: `geom` multiplies the plane term, `attr[j]` attribute `j`'s term.
/// These are the *w* of §2.3.2 (the caller decides whether they are λ or λ²).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Weights<const M: usize> {
    pub geom: f64,
    pub attr: [f64; M],
}

/// The compact attribute-extended quadric over (position, m attributes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quadric<const M: usize> {
    /// The position part, weighted: the symmetric 3×3 block `p` (as `m`: xx, xy, xz, yy, yz,
    /// zz), the linear term `beta` (as `r`) and the constant `c`. Its type is that of the
    /// reduced system, which is this part once the attribute blocks are eliminated.
    pub pos: Reduced,
    /// The attribute block, unweighted (its `alpha` is the area the quadric was summed over).
    pub attr: AttrPart<M>,
}

impl<const M: usize> Default for Quadric<M> {
    fn default() -> Self {
        Quadric {
            pos: Reduced::default(),
            attr: AttrPart::default(),
        }
    }
}

#[inline]
pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline]
pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
#[inline]
pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
#[inline]
fn scale(a: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}
#[inline]
fn sym_outer_add(m: &mut [f64; 6], v: [f64; 3], s: f64) {
    m[0] += s * v[0] * v[0];
    m[1] += s * v[0] * v[1];
    m[2] += s * v[0] * v[2];
    m[3] += s * v[1] * v[1];
    m[4] += s * v[1] * v[2];
    m[5] += s * v[2] * v[2];
}
#[inline]
pub(crate) fn sym_mul(m: &[f64; 6], v: [f64; 3]) -> [f64; 3] {
    [
        m[0] * v[0] + m[1] * v[1] + m[2] * v[2],
        m[1] * v[0] + m[3] * v[1] + m[4] * v[2],
        m[2] * v[0] + m[4] * v[1] + m[5] * v[2],
    ]
}

/// The linear attribute field of one triangle (eq. 2.10): `s_j(p) = g_j·p + d_j` with
/// `g_j` in the triangle's plane. Solved in closed form with the dual basis of the edge
/// vectors instead of the 4×4 system (same solution: the last row of (2.10) only says
/// `g_j ⊥ n`). `None` for a degenerate triangle (the system is singular; our note on §2.3.2).
pub fn attribute_gradients<const M: usize>(
    p: [[f64; 3]; 3],
    s: [[f64; M]; 3],
) -> Option<([[f64; 3]; M], [f64; M])> {
    let e1 = sub(p[1], p[0]);
    let e2 = sub(p[2], p[0]);
    let n = cross(e1, e2);
    let nn = dot(n, n);
    if !(nn > 0.0) || !nn.is_finite() {
        return None;
    }
    let b1 = scale(cross(e2, n), 1.0 / nn);
    let b2 = scale(cross(n, e1), 1.0 / nn);
    let mut g = [[0.0; 3]; M];
    let mut d = [0.0; M];
    for j in 0..M {
        let (ds1, ds2) = (s[1][j] - s[0][j], s[2][j] - s[0][j]);
        g[j] = [
            ds1 * b1[0] + ds2 * b2[0],
            ds1 * b1[1] + ds2 * b2[1],
            ds1 * b1[2] + ds2 * b2[2],
        ];
        d[j] = s[0][j] - dot(g[j], p[0]);
    }
    Some((g, d))
}

impl<const M: usize> Quadric<M> {
    /// The area-weighted quadric of one triangle (eqs. 2.9–2.12 with the weights of §2.3.2
    /// and the errata in the module comment). `None` for a zero-area triangle.
    pub fn from_triangle(p: [[f64; 3]; 3], s: [[f64; M]; 3], w: &Weights<M>) -> Option<Self> {
        let nvec = cross(sub(p[1], p[0]), sub(p[2], p[0]));
        let len = dot(nvec, nvec).sqrt();
        if !(len > 0.0) || !len.is_finite() {
            return None;
        }
        let n = scale(nvec, 1.0 / len);
        let area = 0.5 * len;
        // reading R1: d = −n·p1 so that n·v + d is the signed distance of v from the plane.
        let d = -dot(n, p[0]);
        let (g, dj) = attribute_gradients(p, s)?;
        let mut q = Quadric::<M>::default();
        q.attr.alpha = area;
        sym_outer_add(&mut q.pos.m, n, area * w.geom);
        q.pos.r = scale(n, area * w.geom * d);
        q.pos.c = area * w.geom * d * d;
        for j in 0..M {
            let wj = area * w.attr[j];
            sym_outer_add(&mut q.pos.m, g[j], wj);
            for k in 0..3 {
                q.pos.r[k] += wj * dj[j] * g[j][k];
            }
            q.pos.c += wj * dj[j] * dj[j];
            q.attr.g[j] = scale(g[j], area);
            q.attr.delta[j] = area * dj[j];
        }
        Some(q)
    }

    /// A pure plane quadric (no attribute part, zero area): used for the boundary planes of
    /// `boundary = "weighted"`. `weight` multiplies the squared distance from the plane
    /// through `point` with unit normal `n`.
    pub fn plane(n: [f64; 3], point: [f64; 3], weight: f64) -> Self {
        let d = -dot(n, point);
        let mut q = Quadric::<M>::default();
        sym_outer_add(&mut q.pos.m, n, weight);
        q.pos.r = scale(n, weight * d);
        q.pos.c = weight * d * d;
        q
    }

    #[inline]
    pub fn add(&mut self, o: &Self) {
        self.pos.add(&o.pos);
        self.attr.add(&o.attr);
    }

    /// The optimal attributes at position `p`: see [`AttrPart::attributes_at`].
    #[inline]
    pub fn attributes_at(&self, p: [f64; 3]) -> Option<[f64; M]> {
        self.attr.attributes_at(p)
    }

    /// Q(p, s) = xᵀAx + 2bᵀx + c for x = (p; s) (eq. 2.12 evaluation), compact form.
    pub fn eval(&self, p: [f64; 3], s: &[f64; M], w: &Weights<M>) -> f64 {
        let pos = &self.pos;
        let mut q = dot(p, sym_mul(&pos.m, p)) + 2.0 * dot(pos.r, p) + pos.c;
        let a = &self.attr;
        for j in 0..M {
            q += w.attr[j]
                * (a.alpha * s[j] * s[j] - 2.0 * s[j] * dot(a.g[j], p) - 2.0 * a.delta[j] * s[j]);
        }
        q
    }
}

/// The attribute part of a wedge quadric, `(Σ a·g_j, Σ a·d_j, Σ a)`: what the wedge-aware
/// quadric keeps per wedge. The position part (`p`, `beta`, `c`) is additive over the wedges
/// of a vertex, so the decimators keep it per vertex, already reduced (see [`Reduced`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AttrPart<const M: usize> {
    pub g: [[f64; 3]; M],
    pub delta: [f64; M],
    pub alpha: f64,
}

impl<const M: usize> Default for AttrPart<M> {
    fn default() -> Self {
        AttrPart {
            g: [[0.0; 3]; M],
            delta: [0.0; M],
            alpha: 0.0,
        }
    }
}

impl<const M: usize> AttrPart<M> {
    #[inline]
    pub fn add(&mut self, o: &Self) {
        for j in 0..M {
            for k in 0..3 {
                self.g[j][k] += o.g[j][k];
            }
            self.delta[j] += o.delta[j];
        }
        self.alpha += o.alpha;
    }

    /// The optimal attributes at position `p` (our derivation from §2.3.3): the
    /// area-weighted mean of the summed faces' linear predictions, independent of the
    /// weights. `None` without area.
    #[inline]
    pub fn attributes_at(&self, p: [f64; 3]) -> Option<[f64; M]> {
        if !(self.alpha > 0.0) {
            return None;
        }
        let mut s = [0.0; M];
        for j in 0..M {
            s[j] = (dot(self.g[j], p) + self.delta[j]) / self.alpha;
        }
        Some(s)
    }

    /// How much attributes `s` cost above the optimum at `p`: for fixed `p` the quadric is
    /// `Σ_j w_j·α·(s_j − s*_j)²` plus its minimum.
    #[inline]
    pub fn excess(&self, p: [f64; 3], s: &[f64; M], w: &Weights<M>) -> f64 {
        let Some(opt) = self.attributes_at(p) else {
            return 0.0;
        };
        (0..M)
            .map(|j| w.attr[j] * self.alpha * (s[j] - opt[j]).powi(2))
            .sum()
    }
}

/// The attribute parts of all wedges, stored compactly (issue #5, peak memory): the
/// texture-coordinate part in f64, the normal part (the last three attributes when the mesh
/// has normals) in f32. Normals only ever come out of the quadric as directions that are
/// renormalised (reading R9) and written as f32, and with the default normal weight (§2.3.2,
/// 1e-17) their Schur terms are far below the f64 resolution of the position system, so
/// f32 sums lose nothing that reaches the output; the texture part feeds the position
/// system with real weight and stays f64. For a mesh with texture coordinates and normals
/// this is 120 instead of 168 bytes per wedge.
#[derive(Debug, Clone, Default)]
pub struct WedgeQuadrics<const M: usize> {
    /// Attributes `0..wide` are f64, `wide..M` f32.
    wide: usize,
    f64s: Vec<f64>,
    f32s: Vec<f32>,
}

impl<const M: usize> WedgeQuadrics<M> {
    /// `count` zero quadrics; `normals`: the last three attributes are normals.
    pub fn new(count: usize, normals: bool) -> Self {
        let wide = if normals && M >= 3 { M - 3 } else { M };
        WedgeQuadrics {
            wide,
            f64s: vec![0.0; count * (4 * wide + 1)],
            f32s: vec![0.0; count * 4 * (M - wide)],
        }
    }

    #[inline]
    fn strides(&self) -> (usize, usize) {
        (4 * self.wide + 1, 4 * (M - self.wide))
    }

    #[inline]
    pub fn get(&self, w: usize) -> AttrPart<M> {
        let (s64, s32) = self.strides();
        let a = &self.f64s[w * s64..(w + 1) * s64];
        let b = &self.f32s[w * s32..(w + 1) * s32];
        let wide = self.wide;
        let mut q = AttrPart::<M>::default();
        // One loop over the constant M (unrolled), no copies of run-time length.
        for j in 0..M {
            if j < wide {
                q.g[j] = [a[4 * j], a[4 * j + 1], a[4 * j + 2]];
                q.delta[j] = a[4 * j + 3];
            } else {
                let i = 4 * (j - wide);
                q.g[j] = [b[i] as f64, b[i + 1] as f64, b[i + 2] as f64];
                q.delta[j] = b[i + 3] as f64;
            }
        }
        q.alpha = a[4 * wide];
        q
    }

    /// Asks the memory for wedge `w`'s quadric ([`super::prefetch`]).
    #[inline]
    pub fn prefetch(&self, w: usize) {
        let (s64, s32) = self.strides();
        super::prefetch::prefetch_span(&self.f64s, w * s64, s64);
        super::prefetch::prefetch_span(&self.f32s, w * s32, s32);
    }

    #[inline]
    pub fn set(&mut self, w: usize, q: &AttrPart<M>) {
        let (s64, s32) = self.strides();
        let wide = self.wide;
        let a = &mut self.f64s[w * s64..(w + 1) * s64];
        let b = &mut self.f32s[w * s32..(w + 1) * s32];
        for j in 0..wide {
            a[4 * j..4 * j + 3].copy_from_slice(&q.g[j]);
            a[4 * j + 3] = q.delta[j];
        }
        for j in wide..M {
            let i = 4 * (j - wide);
            for k in 0..3 {
                b[i + k] = q.g[j][k] as f32;
            }
            b[i + 3] = q.delta[j] as f32;
        }
        a[4 * wide] = q.alpha;
    }

    /// A writer for parallel tasks that fill disjoint wedges (see [`RawWedgeWriter::set`]).
    pub fn raw_writer(&mut self) -> RawWedgeWriter<M> {
        RawWedgeWriter {
            wide: self.wide,
            count: self.f64s.len() / (4 * self.wide + 1),
            f64s: self.f64s.as_mut_ptr(),
            f32s: self.f32s.as_mut_ptr(),
        }
    }
}

/// Raw access to a [`WedgeQuadrics`] for parallel set-up.
pub struct RawWedgeWriter<const M: usize> {
    wide: usize,
    count: usize,
    f64s: *mut f64,
    f32s: *mut f32,
}

// SAFETY: the writer only writes through `set`, whose contract makes the writes of
// different threads disjoint.
unsafe impl<const M: usize> Sync for RawWedgeWriter<M> {}

impl<const M: usize> RawWedgeWriter<M> {
    /// Stores `q` as wedge `w`'s quadric.
    ///
    /// # Safety
    /// The [`WedgeQuadrics`] this writer came from must be alive and not otherwise accessed
    /// while writers are in use, and no two threads may call this with the same `w`.
    #[inline]
    pub unsafe fn set(&self, w: usize, q: &AttrPart<M>) {
        assert!(w < self.count, "wedge {w} out of range");
        let (s64, s32) = (4 * self.wide + 1, 4 * (M - self.wide));
        // SAFETY: `w < count`, so both ranges are inside the arrays; the caller guarantees
        // that no other thread touches wedge `w`.
        let (a, b) = unsafe {
            (
                std::slice::from_raw_parts_mut(self.f64s.add(w * s64), s64),
                std::slice::from_raw_parts_mut(self.f32s.add(w * s32), s32),
            )
        };
        for j in 0..self.wide {
            a[4 * j..4 * j + 3].copy_from_slice(&q.g[j]);
            a[4 * j + 3] = q.delta[j];
        }
        for j in self.wide..M {
            let i = 4 * (j - self.wide);
            for k in 0..3 {
                b[i + k] = q.g[j][k] as f32;
            }
            b[i + 3] = q.delta[j] as f32;
        }
        a[4 * self.wide] = q.alpha;
    }
}

/// The attribute values of all wedges, with the same split as [`WedgeQuadrics`]: texture
/// coordinates in f64, normals (directions, renormalised on output) in f32.
#[derive(Debug, Clone, Default)]
pub struct WedgeAttrs<const M: usize> {
    wide: usize,
    f64s: Vec<f64>,
    f32s: Vec<f32>,
}

impl<const M: usize> WedgeAttrs<M> {
    pub fn new(values: impl ExactSizeIterator<Item = [f64; M]>, normals: bool) -> Self {
        let wide = if normals && M >= 3 { M - 3 } else { M };
        let n = values.len();
        let mut out = WedgeAttrs {
            wide,
            f64s: Vec::with_capacity(n * wide),
            f32s: Vec::with_capacity(n * (M - wide)),
        };
        for v in values {
            out.f64s.extend_from_slice(&v[..wide]);
            out.f32s.extend(v[wide..].iter().map(|&x| x as f32));
        }
        out
    }

    #[inline]
    pub fn get(&self, w: usize) -> [f64; M] {
        let (wide, narrow) = (self.wide, M - self.wide);
        let (a, b) = (
            &self.f64s[w * wide..(w + 1) * wide],
            &self.f32s[w * narrow..(w + 1) * narrow],
        );
        // A loop over the constant M (unrolled) rather than a copy of run-time length
        // (a `memcpy` call per wedge in the collapse loop).
        std::array::from_fn(|j| if j < wide { a[j] } else { b[j - wide] as f64 })
    }

    /// Asks the memory for wedge `w`'s record ([`super::prefetch`]).
    #[inline]
    pub fn prefetch(&self, w: usize) {
        let (wide, narrow) = (self.wide, M - self.wide);
        super::prefetch::prefetch_span(&self.f64s, w * wide, wide);
        super::prefetch::prefetch_span(&self.f32s, w * narrow, narrow);
    }

    /// The first two attributes (texture coordinates when the mesh has them).
    #[inline]
    pub fn uv(&self, w: usize) -> [f64; 2] {
        // Read in place: a copy of the whole record through `get` has a run-time length
        // (`wide`), which costs a `memcpy` call in the collapse loop's hot checks.
        let wide = self.wide;
        let at = |j: usize| {
            if j < wide {
                self.f64s[w * wide + j]
            } else if j < M {
                self.f32s[w * (M - wide) + j - wide] as f64
            } else {
                0.0
            }
        };
        [at(0), at(1)]
    }

    #[inline]
    pub fn set(&mut self, w: usize, a: &[f64; M]) {
        let (wide, narrow) = (self.wide, M - self.wide);
        self.f64s[w * wide..(w + 1) * wide].copy_from_slice(&a[..wide]);
        for (x, &y) in self.f32s[w * narrow..(w + 1) * narrow]
            .iter_mut()
            .zip(&a[wide..])
        {
            *x = y as f32;
        }
    }
}

impl<const M: usize> Quadric<M> {
    /// Splits into the (unreduced) position part and the attribute part.
    pub fn split(&self) -> (Reduced, AttrPart<M>) {
        (self.pos, self.attr)
    }
}

/// The wedge-aware vertex quadric (§3.2, eqs. 3.4–3.6) reduced to position by the Schur
/// complement (§2.3.3): after the k wedge blocks are eliminated,
/// `Q_red(p) = pᵀ M p + 2 rᵀ p + c_red` with
/// `M = Σ_w P_w − Σ_w Σ_j w_j G_wj G_wjᵀ / α_w`, `r = Σ_w β_w − Σ_w Σ_j w_j δ_wj G_wj / α_w`,
/// and each wedge's optimal attributes are `s_wj = (G_wj·p + δ_wj)/α_w`. Only a 3×3 system
/// is ever solved, in O(k·m).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Reduced {
    pub m: [f64; 6],
    pub r: [f64; 3],
    pub c: f64,
}

impl Reduced {
    /// Adds one wedge block (one (3+m) quadric) to the system.
    pub fn add_wedge<const M: usize>(&mut self, q: &Quadric<M>, w: &Weights<M>) {
        let (geo, attr) = q.split();
        self.add(&geo);
        self.schur(&attr, w, -1.0);
    }

    #[inline]
    pub fn add(&mut self, o: &Reduced) {
        for k in 0..6 {
            self.m[k] += o.m[k];
        }
        for k in 0..3 {
            self.r[k] += o.r[k];
        }
        self.c += o.c;
    }

    /// Adds `sign` times the Schur term of one wedge block: `sign = −1` eliminates the
    /// block's attributes, `+1` undoes that (when two blocks merge into one).
    #[inline]
    pub fn schur<const M: usize>(&mut self, a: &AttrPart<M>, w: &Weights<M>, sign: f64) {
        if !(a.alpha > 0.0) {
            return;
        }
        for j in 0..M {
            let f = sign * w.attr[j] / a.alpha;
            if f == 0.0 {
                continue;
            }
            sym_outer_add(&mut self.m, a.g[j], f);
            for k in 0..3 {
                self.r[k] += f * a.delta[j] * a.g[j][k];
            }
            self.c += f * a.delta[j] * a.delta[j];
        }
    }

    /// Adds a plane-only quadric (no wedge block).
    pub fn add_plane<const M: usize>(&mut self, q: &Quadric<M>) {
        self.add(&q.pos);
    }

    /// Q_red at `p` (attributes optimal for `p`), clamped at 0 against round-off.
    #[inline]
    pub fn eval(&self, p: [f64; 3]) -> f64 {
        (dot(p, sym_mul(&self.m, p)) + 2.0 * dot(self.r, p) + self.c).max(0.0)
    }

    /// The minimiser of Q_red on the segment `a + t(b − a)`, `t ∈ [0, 1]`; returns `t`.
    pub fn minimise_on_segment(&self, a: [f64; 3], b: [f64; 3]) -> f64 {
        let d = sub(b, a);
        let curv = dot(d, sym_mul(&self.m, d));
        let slope = dot(d, sym_mul(&self.m, a)) + dot(d, self.r);
        if curv > 0.0 && curv.is_finite() {
            (-slope / curv).clamp(0.0, 1.0)
        } else if self.eval(b) < self.eval(a) {
            1.0
        } else {
            0.0
        }
    }

    /// Minimises Q_red. When the reduced matrix's condition number exceeds `max_cond` the
    /// system is ill-conditioned (§2.3.4); then the position is `fallback` (the mean of the
    /// merged vertices, thesis §3.1.2) in the directions the quadric does not determine:
    /// with `regularise`, `(M + μI)p = −r + μ·fallback` with `μ = λ_max / max_cond`, which is
    /// exactly the mean when the quadric is fully degenerate and never has a larger error
    /// than the mean; without, the plain mean (thesis-literal). Returns the position and
    /// whether the fallback was used.
    pub fn minimise(
        &self,
        fallback: [f64; 3],
        max_cond: f64,
        regularise: bool,
    ) -> ([f64; 3], bool) {
        self.minimise_with(|| fallback, max_cond, regularise)
    }

    /// [`Reduced::minimise`] with the fallback position computed only when it is needed.
    #[inline]
    pub fn minimise_with(
        &self,
        fallback: impl FnOnce() -> [f64; 3],
        max_cond: f64,
        regularise: bool,
    ) -> ([f64; 3], bool) {
        // Cheap sufficient test first: for a positive definite 3×3 matrix
        // λ_max/λ_min ≤ λ_max³/det ≤ trace³/det, so trace³ ≤ max_cond·det proves it well
        // conditioned without the eigenvalues; only the doubtful cases pay for them.
        let m = &self.m;
        let trace = m[0] + m[3] + m[5];
        let det = m[0] * (m[3] * m[5] - m[4] * m[4]) - m[1] * (m[1] * m[5] - m[4] * m[2])
            + m[2] * (m[1] * m[4] - m[3] * m[2]);
        let (lmin, lmax) = if det > 0.0 && trace > 0.0 && trace * trace * trace <= max_cond * det {
            (det, det)
        } else {
            sym3_eigen_range(&self.m)
        };
        let ok = lmax > 0.0 && lmin > 0.0 && lmax <= max_cond * lmin;
        if ok && let Some(p) = solve_sym3(&self.m, scale(self.r, -1.0)) {
            return (p, false);
        }
        let fallback = fallback();
        if !regularise || !(lmax > 0.0) || !lmax.is_finite() {
            return (fallback, true);
        }
        let mu = lmax / max_cond.max(1.0);
        let mut m = self.m;
        m[0] += mu;
        m[3] += mu;
        m[5] += mu;
        let rhs = [
            -self.r[0] + mu * fallback[0],
            -self.r[1] + mu * fallback[1],
            -self.r[2] + mu * fallback[2],
        ];
        (solve_sym3(&m, rhs).unwrap_or(fallback), true)
    }
}

/// Smallest and largest eigenvalue of a symmetric 3×3 matrix (analytic, trigonometric
/// form). Accurate to about ε·λ_max in absolute terms, plenty for a threshold of 1e8.
pub fn sym3_eigen_range(m: &[f64; 6]) -> (f64, f64) {
    let (a00, a01, a02, a11, a12, a22) = (m[0], m[1], m[2], m[3], m[4], m[5]);
    let p1 = a01 * a01 + a02 * a02 + a12 * a12;
    let q = (a00 + a11 + a22) / 3.0;
    let p2 = (a00 - q).powi(2) + (a11 - q).powi(2) + (a22 - q).powi(2) + 2.0 * p1;
    if !(p2 > 0.0) {
        return (q, q);
    }
    let p = (p2 / 6.0).sqrt();
    let (b00, b11, b22) = ((a00 - q) / p, (a11 - q) / p, (a22 - q) / p);
    let (b01, b02, b12) = (a01 / p, a02 / p, a12 / p);
    let det = b00 * (b11 * b22 - b12 * b12) - b01 * (b01 * b22 - b12 * b02)
        + b02 * (b01 * b12 - b11 * b02);
    let r = (det / 2.0).clamp(-1.0, 1.0);
    let phi = r.acos() / 3.0;
    let e1 = q + 2.0 * p * phi.cos();
    let e3 = q + 2.0 * p * (phi + 2.0 * std::f64::consts::PI / 3.0).cos();
    (e3.min(e1), e1.max(e3))
}

/// Solves the symmetric 3×3 system by the adjugate; `None` if singular or not finite.
pub fn solve_sym3(m: &[f64; 6], b: [f64; 3]) -> Option<[f64; 3]> {
    let (a, bb, c, d, e, f) = (m[0], m[1], m[2], m[3], m[4], m[5]);
    let c00 = d * f - e * e;
    let c01 = c * e - bb * f;
    let c02 = bb * e - c * d;
    let det = a * c00 + bb * c01 + c * c02;
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let c11 = a * f - c * c;
    let c12 = bb * c - a * e;
    let c22 = a * d - bb * bb;
    let inv = 1.0 / det;
    let x = [
        (c00 * b[0] + c01 * b[1] + c02 * b[2]) * inv,
        (c01 * b[0] + c11 * b[1] + c12 * b[2]) * inv,
        (c02 * b[0] + c12 * b[1] + c22 * b[2]) * inv,
    ];
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// The dense (3 + k·m) matrix A and vector b of the wedge-aware quadric (eqs. 3.4–3.6),
/// for the thesis-literal conditioning test and as a test oracle.
pub fn dense_wedge_system<const M: usize>(
    wedges: &[Quadric<M>],
    w: &Weights<M>,
) -> (Vec<Vec<f64>>, Vec<f64>, f64) {
    let n = 3 + wedges.len() * M;
    let mut a = vec![vec![0.0; n]; n];
    let mut b = vec![0.0; n];
    let mut c = 0.0;
    let idx = [[0, 1, 2], [1, 3, 4], [2, 4, 5]];
    for (k, q) in wedges.iter().enumerate() {
        for r in 0..3 {
            for s in 0..3 {
                a[r][s] += q.pos.m[idx[r][s]];
            }
            b[r] += q.pos.r[r];
        }
        c += q.pos.c;
        for j in 0..M {
            let col = 3 + k * M + j;
            for r in 0..3 {
                a[r][col] = -w.attr[j] * q.attr.g[j][r];
                a[col][r] = -w.attr[j] * q.attr.g[j][r];
            }
            a[col][col] = w.attr[j] * q.attr.alpha;
            b[col] = -w.attr[j] * q.attr.delta[j];
        }
    }
    (a, b, c)
}

/// Eigenvalues of a dense symmetric matrix by cyclic Jacobi rotations (small matrices only:
/// the thesis-literal condition number of the full wedge quadric, and tests).
pub fn dense_sym_eigenvalues(mut a: Vec<Vec<f64>>) -> Vec<f64> {
    let n = a.len();
    for _sweep in 0..60 {
        let off: f64 = (0..n)
            .flat_map(|i| (0..n).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| a[i][j] * a[i][j])
            .sum();
        let diag: f64 = (0..n).map(|i| a[i][i] * a[i][i]).sum();
        if off <= 1e-30 * diag.max(f64::MIN_POSITIVE) {
            break;
        }
        for p in 0..n {
            for q in p + 1..n {
                if a[p][q] == 0.0 {
                    continue;
                }
                let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let cs = 1.0 / (t * t + 1.0).sqrt();
                let sn = t * cs;
                for k in 0..n {
                    let (akp, akq) = (a[k][p], a[k][q]);
                    a[k][p] = cs * akp - sn * akq;
                    a[k][q] = sn * akp + cs * akq;
                }
                for k in 0..n {
                    let (apk, aqk) = (a[p][k], a[q][k]);
                    a[p][k] = cs * apk - sn * aqk;
                    a[q][k] = sn * apk + cs * aqk;
                }
            }
        }
    }
    (0..n).map(|i| a[i][i]).collect()
}

/// Thesis-literal condition number of the full (3 + k·m) matrix (§2.3.4; see reading R7 for why
/// it flags every quadric with the recommended weights).
pub fn dense_condition_number<const M: usize>(wedges: &[Quadric<M>], w: &Weights<M>) -> f64 {
    let (a, _, _) = dense_wedge_system(wedges, w);
    let ev = dense_sym_eigenvalues(a);
    let max = ev.iter().fold(0.0f64, |m, &v| m.max(v.abs()));
    let min = ev.iter().fold(f64::INFINITY, |m, &v| m.min(v.abs()));
    if min > 0.0 { max / min } else { f64::INFINITY }
}

#[cfg(test)]
mod tests {
    use super::*;

    const W2: Weights<2> = Weights {
        geom: 1.0,
        attr: [0.5, 0.25],
    };

    fn tri() -> ([[f64; 3]; 3], [[f64; 2]; 3]) {
        (
            [[0.1, 0.2, 0.3], [0.9, 0.25, 0.1], [0.3, 0.8, 0.6]],
            [[0.1, 0.7], [0.5, 0.2], [0.9, 0.9]],
        )
    }

    #[test]
    fn gradients_reproduce_corner_attributes() {
        let (p, s) = tri();
        let (g, d) = attribute_gradients(p, s).unwrap();
        let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
        for j in 0..2 {
            assert!(dot(g[j], n).abs() < 1e-12, "gradient not in plane");
            for i in 0..3 {
                let v = dot(g[j], p[i]) + d[j];
                assert!((v - s[i][j]).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn face_quadric_is_zero_on_the_face_with_interpolated_attributes() {
        let (p, s) = tri();
        let q = Quadric::from_triangle(p, s, &W2).unwrap();
        for (b0, b1) in [(0.2, 0.3), (1.0, 0.0), (0.0, 0.0), (0.5, 0.5)] {
            let b2 = 1.0 - b0 - b1;
            let x = [0, 1, 2].map(|k| b0 * p[0][k] + b1 * p[1][k] + b2 * p[2][k]);
            let sv = [0, 1].map(|j| b0 * s[0][j] + b1 * s[1][j] + b2 * s[2][j]);
            assert!(q.eval(x, &sv, &W2).abs() < 1e-12);
        }
        // Off the plane by h: area·h² (geometry weight 1).
        let n = {
            let c = cross(sub(p[1], p[0]), sub(p[2], p[0]));
            scale(c, 1.0 / dot(c, c).sqrt())
        };
        let x = [0, 1, 2].map(|k| p[0][k] + 0.1 * n[k]);
        let sv = q.attributes_at(x).unwrap();
        assert!((sv[0] - s[0][0]).abs() < 1e-12 && (sv[1] - s[0][1]).abs() < 1e-12);
        assert!((q.eval(x, &sv, &W2) - q.attr.alpha * 0.01).abs() < 1e-12);
    }

    #[test]
    fn schur_solution_matches_dense_solve() {
        // Two wedges on a curved patch: the reduced 3×3 solve must equal the dense one.
        let pts = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.2],
            [0.0, 1.0, 0.1],
            [1.0, 1.0, 0.5],
            [-1.0, 0.3, 0.4],
            [0.2, -1.0, 0.3],
        ];
        let faces = [[0, 1, 2], [1, 3, 2], [0, 2, 4], [0, 5, 1]];
        let attr = |v: usize, w: usize| [v as f64 * 0.1 + w as f64, (v * v) as f64 * 0.05];
        let mut wq = [Quadric::<2>::default(); 2];
        for (fi, f) in faces.iter().enumerate() {
            let wedge = fi % 2;
            let q =
                Quadric::from_triangle(f.map(|v| pts[v]), f.map(|v| attr(v, wedge)), &W2).unwrap();
            wq[wedge].add(&q);
        }
        let mut red = Reduced::default();
        for q in &wq {
            red.add_wedge(q, &W2);
        }
        let (p, fell_back) = red.minimise([0.0; 3], 1e12, true);
        assert!(!fell_back);
        let (a, b, c) = dense_wedge_system(&wq, &W2);
        // Dense solve by Gaussian elimination.
        let n = a.len();
        let mut m: Vec<Vec<f64>> = a
            .iter()
            .zip(&b)
            .map(|(row, bi)| row.iter().copied().chain([-bi]).collect())
            .collect();
        for i in 0..n {
            let piv = (i..n)
                .max_by(|&x, &y| m[x][i].abs().total_cmp(&m[y][i].abs()))
                .unwrap();
            m.swap(i, piv);
            for r in 0..n {
                if r != i {
                    let f = m[r][i] / m[i][i];
                    for k in i..=n {
                        m[r][k] -= f * m[i][k];
                    }
                }
            }
        }
        let x: Vec<f64> = (0..n).map(|i| m[i][n] / m[i][i]).collect();
        for k in 0..3 {
            assert!((x[k] - p[k]).abs() < 1e-9, "{x:?} vs {p:?}");
        }
        for (wi, q) in wq.iter().enumerate() {
            let s = q.attributes_at(p).unwrap();
            for j in 0..2 {
                assert!((x[3 + wi * 2 + j] - s[j]).abs() < 1e-9);
            }
        }
        // The minimum value agrees too.
        let qmin: f64 = wq
            .iter()
            .map(|q| q.eval(p, &q.attributes_at(p).unwrap(), &W2))
            .sum();
        let dense_min = c + b.iter().zip(&x).map(|(bi, xi)| bi * xi).sum::<f64>();
        assert!((qmin - dense_min).abs() < 1e-9 && (red.eval(p) - qmin).abs() < 1e-9);
    }

    #[test]
    fn thesis_literal_condition_number_rejects_tiny_weights() {
        // reading R7: with λ = 1e-17 the full matrix has cond ≳ w_p / (3 w_j) ≫ 1e8, while the
        // reduced 3×3 matrix of a curved vertex is well conditioned.
        let w = Weights::<2> {
            geom: 1.0,
            attr: [1e-34, 1e-34],
        };
        let pts = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.3],
            [0.0, 1.0, 0.3],
            [-1.0, -1.0, 0.5],
        ];
        let mut q = Quadric::<2>::default();
        for f in [[0, 1, 2], [0, 2, 3], [0, 3, 1]] {
            q.add(
                &Quadric::from_triangle(
                    f.map(|v| pts[v]),
                    [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]],
                    &w,
                )
                .unwrap(),
            );
        }
        assert!(dense_condition_number(&[q], &w) > 1e20);
        let mut red = Reduced::default();
        red.add_wedge(&q, &w);
        let (lo, hi) = sym3_eigen_range(&red.m);
        assert!(hi / lo < 1e3, "{lo} {hi}");
    }

    #[test]
    fn flat_patch_falls_back_to_the_mean_in_plane() {
        let w = Weights::<0> {
            geom: 1.0,
            attr: [],
        };
        let pts = [[0.0, 0.0, 0.5], [1.0, 0.0, 0.5], [0.0, 1.0, 0.5]];
        let q = Quadric::<0>::from_triangle(pts, [[]; 3], &w).unwrap();
        let mut red = Reduced::default();
        red.add_wedge(&q, &w);
        let mean = [0.3, 0.4, 0.9];
        let (p, fell_back) = red.minimise(mean, 1e8, true);
        assert!(fell_back);
        // In-plane: the mean; normal direction: onto the plane.
        assert!((p[0] - 0.3).abs() < 1e-6 && (p[1] - 0.4).abs() < 1e-6);
        assert!((p[2] - 0.5).abs() < 1e-6, "{p:?}");
        let (p2, _) = red.minimise(mean, 1e8, false);
        assert_eq!(p2, mean);
    }

    #[test]
    fn eigen_range_matches_jacobi() {
        let m = [2.0, 0.3, -0.1, 1.5, 0.2, 0.7];
        let (lo, hi) = sym3_eigen_range(&m);
        let dense = vec![
            vec![2.0, 0.3, -0.1],
            vec![0.3, 1.5, 0.2],
            vec![-0.1, 0.2, 0.7],
        ];
        let mut ev = dense_sym_eigenvalues(dense);
        ev.sort_by(f64::total_cmp);
        assert!((lo - ev[0]).abs() < 1e-12 && (hi - ev[2]).abs() < 1e-12);
    }

    #[test]
    fn segment_minimiser_is_clamped() {
        let w = Weights::<0> {
            geom: 1.0,
            attr: [],
        };
        let q = Quadric::<0>::plane([1.0, 0.0, 0.0], [0.25, 0.0, 0.0], w.geom);
        let mut red = Reduced::default();
        red.add_plane(&q);
        let t = red.minimise_on_segment([0.0, 0.0, 0.0], [1.0, 0.0, 0.0]);
        assert!((t - 0.25).abs() < 1e-12);
        let t = red.minimise_on_segment([0.5, 0.0, 0.0], [1.0, 0.0, 0.0]);
        assert_eq!(t, 0.0);
    }
}
