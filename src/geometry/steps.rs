//! The steps of the notes' tests, as the tests take them: each formula
//! function that a lecture works by hand (`plane_hit`, `crossing_count`,
//! `sphere_roots`, the watertight triangle test, `reflect`, `refract`) has
//! a `_steps` form that tells a [`Steps`] every intermediate value, and its
//! plain form is that function with `()`, which hears nothing: every
//! method is empty and inlined, so the renderer's code is the same
//! operations in the same order, and `render::explain` calls the same
//! function with a recorder. One implementation, two listeners.

use glam::{DVec2, DVec3};

/// An edge of a projected polygon, as the notes sort it (the hit point
/// translated to the origin, the test ray along the positive x axis of the
/// 2D plane, z across it; z = 0 counts as negative, so an outline through
/// a vertex on the axis crosses once).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum EdgeCase {
    /// Both ends have z > 0: no crossing.
    BothZPositive,
    /// Both ends have z ≤ 0: no crossing.
    BothZNegative,
    /// The ends straddle the axis but both have x < 0: no crossing.
    BothXNegative,
    /// Otherwise x_int = x₁ − z₁(x₂ − x₁)/(z₂ − z₁) is computed; the edge
    /// crosses when x_int > 0.
    Intersects {
        /// Where the edge meets the axis.
        x_int: f64,
    },
}

/// Hears the steps of an intersection test or a secondary ray's
/// construction. Every method does nothing by default; `()` hears nothing
/// and, every call being empty and inlined, costs nothing.
pub trait Steps {
    /// The plane test: n·d, and t = (d − n·O)/(n·d) unless the ray runs
    /// parallel (|n·d| below `PARALLEL_COSINE`).
    #[inline(always)]
    fn plane(&mut self, n_dot_d: f64, t: Option<f64>) {
        let _ = (n_dot_d, t);
    }
    /// The polygon's principal axis (0, 1, 2: x, y, z), the plane hit
    /// P = O + tD and P projected along the axis.
    #[inline(always)]
    fn projection(&mut self, principal_axis: usize, point: DVec3, projected: DVec2) {
        let _ = (principal_axis, point, projected);
    }
    /// One edge of the polygon translated so the projected hit is the
    /// origin, and its case.
    #[inline(always)]
    fn edge(&mut self, from: DVec2, to: DVec2, case: EdgeCase) {
        let _ = (from, to, case);
    }
    /// The count of edges crossing the positive x axis.
    #[inline(always)]
    fn crossings(&mut self, count: usize) {
        let _ = count;
    }
    /// The sphere's quadratic a·t² + 2b′·t + c = 0 (a = D·D, b′ = (O − C)·D,
    /// c = |O − C|² − r²) and its reduced discriminant Δ′ = b′² − a·c,
    /// computed as a·(r² − |f − (b′/a)D|²).
    #[inline(always)]
    fn quadratic(&mut self, a: f64, half_b: f64, c: f64, discriminant: f64) {
        let _ = (a, half_b, c, discriminant);
    }
    /// The roots t₀ ≤ t₁ (none: Δ′ < 0).
    #[inline(always)]
    fn roots(&mut self, roots: Option<(f64, f64)>) {
        let _ = roots;
    }
    /// The root kept: the nearest in (t_min, t_max).
    #[inline(always)]
    fn root_taken(&mut self, t: Option<f64>) {
        let _ = t;
    }
    /// The watertight triangle test: the axes (kx, ky, kz; kz the ray
    /// direction's largest component), the 2D edge functions U, V, W of
    /// the sheared vertices, their sum (the determinant; not computed when
    /// the signs are mixed) and t (when computed).
    #[inline(always)]
    fn triangle(
        &mut self,
        axes: [usize; 3],
        edge_functions: DVec3,
        det: Option<f64>,
        t: Option<f64>,
    ) {
        let _ = (axes, edge_functions, det, t);
    }
    /// Reflection: I·N and R = I − 2N(I·N).
    #[inline(always)]
    fn reflection(&mut self, i_dot_n: f64, r: DVec3) {
        let _ = (i_dot_n, r);
    }
    /// Refraction by Snell's law: cos θi = −I·N, the radicand
    /// 1 − η²(1 − cos² θi) (= cos² θt; negative: total internal
    /// reflection) and T where there is one.
    #[inline(always)]
    fn refraction(&mut self, cos_i: f64, radicand: f64, t: Option<DVec3>) {
        let _ = (cos_i, radicand, t);
    }
}

/// Hears nothing.
impl Steps for () {}
