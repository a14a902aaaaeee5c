//! Sample placement: stratified points in the unit square, points uniform
//! over the unit disk and directions uniform over a cone.

use glam::{DVec2, DVec3};

use super::Frame;
use super::rng::PixelRng;
use super::transcendental;

/// A cut of the unit square into `n` strata of nearly equal area.
///
/// The square is cut into `rows = ⌊√n⌋` rows of equal height; the first
/// `n mod rows` rows get one extra column, so there are exactly `n` cells of
/// nearly equal area (equal when `n` is a perfect square).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Strata {
    n: usize,
    rows: usize,
    /// Columns of the short rows.
    base: usize,
    /// Rows with one more column.
    extra: usize,
    /// 1/rows, 1/base and 1/(base + 1): the cell sizes, divided out once
    /// rather than per point (the same bits).
    row_height: f64,
    base_width: f64,
    wide_width: f64,
}

impl Strata {
    /// `n` strata (n ≥ 1).
    pub fn new(n: usize) -> Self {
        let n = n.max(1);
        let rows = (n as f64).sqrt().floor().max(1.0) as usize;
        let base = n / rows;
        Strata {
            n,
            rows,
            base,
            extra: n % rows,
            row_height: 1.0 / rows as f64,
            base_width: 1.0 / base as f64,
            wide_width: 1.0 / (base + 1) as f64,
        }
    }

    /// How many strata.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Never: there is at least one stratum.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Stratum `i` as (corner, size).
    pub fn cell(&self, i: usize) -> (DVec2, DVec2) {
        debug_assert!(i < self.n);
        let wide = self.base + 1;
        // Rows 0..extra hold base + 1 cells, the rest base cells.
        let (row, col, width) = if i < self.extra * wide {
            let (row, col) = divide(i, wide, self.wide_width);
            (row, col, self.wide_width)
        } else {
            let (row, col) = divide(i - self.extra * wide, self.base, self.base_width);
            (self.extra + row, col, self.base_width)
        };
        let size = DVec2::new(width, self.row_height);
        // Through i64, whose conversion is one instruction (usize's is a
        // sequence); the values are small, so the same numbers.
        (
            DVec2::new(col as i64 as f64, row as i64 as f64) * size,
            size,
        )
    }

    /// A jittered point in stratum `i`.
    #[inline]
    pub fn point(&self, i: usize, rng: &mut PixelRng) -> DVec2 {
        self.point_at(i, DVec2::new(rng.uniform(), rng.uniform()))
    }

    /// The point of stratum `i` at `jitter` (in [0, 1)²) across the cell.
    #[inline]
    pub fn point_at(&self, i: usize, jitter: DVec2) -> DVec2 {
        let (corner, size) = self.cell(i);
        corner + size * jitter
    }
}

/// (i / d, i mod d) for d ≥ 1 given `inverse` = 1/d (rounded), by a
/// multiply instead of an integer division (a tenth of drawing a camera
/// sample was waiting on one). (i + ½)/d lies at least ½/d from every
/// integer, and the float product misses it by at most (i + ½)/d · 2⁻⁵²,
/// less than that while i < 2⁵⁰: its truncation is the quotient. Beyond
/// (never, for sample counts) the division itself.
#[inline(always)]
fn divide(i: usize, d: usize, inverse: f64) -> (usize, usize) {
    if i < 1 << 50 {
        // Through i64: a float to usize takes several instructions
        // without AVX-512, to i64 one (q < 2⁵⁰ either way).
        let q = ((i as i64 as f64 + 0.5) * inverse) as i64 as usize;
        (q, i - q * d)
    } else {
        (i / d, i % d)
    }
}

/// A direction uniform over the cone of half-angle θmax around `frame.z`,
/// from a point `u` of the unit square: cos θ = 1 − u.x·(1 − cos θmax),
/// φ = 2π·u.y. Uniform in solid angle, so equal areas of the square map to
/// equal solid angles of the light.
#[inline]
pub fn uniform_cone(frame: &Frame, cos_theta_max: f64, u: DVec2) -> DVec3 {
    let (sin_theta, cos_theta) = cone_polar(cos_theta_max, u.x);
    let (sin_phi, cos_phi) = transcendental::sin_cos_turns(u.y);
    cone_direction(frame, sin_theta, cos_theta, sin_phi, cos_phi)
}

/// The polar angle θ of [`uniform_cone`] from `u_x`: (sin θ, cos θ).
#[inline(always)]
pub fn cone_polar(cos_theta_max: f64, u_x: f64) -> (f64, f64) {
    let cos_theta = 1.0 - u_x * (1.0 - cos_theta_max);
    ((1.0 - cos_theta * cos_theta).max(0.0).sqrt(), cos_theta)
}

/// The direction of [`uniform_cone`] from its polar and azimuthal angles.
#[inline(always)]
pub fn cone_direction(
    frame: &Frame,
    sin_theta: f64,
    cos_theta: f64,
    sin_phi: f64,
    cos_phi: f64,
) -> DVec3 {
    frame.to_world(DVec3::new(
        sin_theta * cos_phi,
        sin_theta * sin_phi,
        cos_theta,
    ))
}

/// A point uniform over the unit disk from a point `u` of the unit square,
/// by Shirley and Chiu's concentric map (1997): each square around the
/// centre goes to the circle of the same rank, so the map keeps areas in
/// proportion (π/4 per unit of the square's area) and neighbouring strata
/// stay neighbours, which the polar map (r = √u.x) does not.
///
/// Without a branch (the centre, where both quotients are 0/0, is a
/// select at the end), so that a batch of lanes compiles to vector code.
#[inline(always)]
pub fn concentric_disk(u: DVec2) -> DVec2 {
    let a = 2.0 * u - DVec2::ONE;
    let centre = a.x == 0.0 && a.y == 0.0;
    // The angle in turns (1 turn = 2π): within ±1/8 of the axis of the
    // larger coordinate. Both quotients are formed and one chosen: the
    // choice is a coin toss a branch would mispredict half the time.
    let x_major = a.x.abs() > a.y.abs();
    let (near_x, near_y) = (0.125 * (a.y / a.x), 0.25 - 0.125 * (a.x / a.y));
    let r = if x_major { a.x } else { a.y };
    let turns = if x_major { near_x } else { near_y };
    let (sin, cos) = transcendental::sin_cos_turns(turns);
    let (x, y) = (r * cos, r * sin);
    DVec2::new(if centre { 0.0 } else { x }, if centre { 0.0 } else { y })
}

#[cfg(test)]
#[allow(clippy::disallowed_methods)] // references computed with the platform's functions
mod tests {
    use super::*;

    #[test]
    fn strata_tile_the_square_exactly() {
        for n in 1..=50 {
            let strata = Strata::new(n);
            assert_eq!(strata.len(), n);
            let mut area = 0.0;
            for i in 0..n {
                let (c, s) = strata.cell(i);
                assert!(c.x >= 0.0 && c.y >= 0.0);
                assert!(c.x + s.x <= 1.0 + 1e-12 && c.y + s.y <= 1.0 + 1e-12);
                area += s.x * s.y;
                // No overlap with any other cell.
                for j in 0..i {
                    let (d, t) = strata.cell(j);
                    let ox = (c.x + s.x).min(d.x + t.x) - c.x.max(d.x);
                    let oy = (c.y + s.y).min(d.y + t.y) - c.y.max(d.y);
                    assert!(
                        ox <= 1e-12 || oy <= 1e-12,
                        "cells {i} and {j} of {n} overlap"
                    );
                }
            }
            assert!((area - 1.0).abs() < 1e-12, "n = {n}: area {area}");
        }
    }

    #[test]
    fn division_by_the_inverse_is_exact() {
        for d in 1..=300usize {
            let inverse = 1.0 / d as f64;
            for i in (0..3000).chain([(1 << 40) + 7, (1 << 50) - 1, 1 << 50, usize::MAX]) {
                assert_eq!(divide(i, d, inverse), (i / d, i % d), "{i} / {d}");
            }
        }
    }

    #[test]
    fn perfect_squares_give_a_regular_grid() {
        let (c, s) = Strata::new(9).cell(5);
        assert_eq!(s, DVec2::splat(1.0 / 3.0));
        assert!((c - DVec2::new(2.0 / 3.0, 1.0 / 3.0)).length() < 1e-15);
    }

    #[test]
    fn cone_directions_stay_inside_and_are_uniform_in_solid_angle() {
        let axis = DVec3::new(1.0, 2.0, -0.5).normalize();
        let frame = Frame::from_z(axis);
        let cos_max = 0.8f64;
        let mut rng = PixelRng::new(3, 1, 1);
        let n = 40_000;
        let mut inner = 0usize;
        // The cap with cos θ > c has solid angle 2π(1 − c); with c halfway
        // in solid angle the expected fraction is exactly 1/2.
        let c_half = 1.0 - 0.5 * (1.0 - cos_max);
        for _ in 0..n {
            let d = uniform_cone(&frame, cos_max, DVec2::new(rng.uniform(), rng.uniform()));
            assert!((d.length() - 1.0).abs() < 1e-12);
            let c = d.dot(axis);
            assert!(c >= cos_max - 1e-12);
            if c > c_half {
                inner += 1;
            }
        }
        let frac = inner as f64 / n as f64;
        assert!((frac - 0.5).abs() < 0.01, "fraction {frac}");
    }

    #[test]
    fn the_concentric_map_fills_the_disk_uniformly() {
        // Corners, edge midpoints and the centre land where the map says.
        assert_eq!(concentric_disk(DVec2::splat(0.5)), DVec2::ZERO);
        let right = concentric_disk(DVec2::new(1.0, 0.5));
        assert!((right - DVec2::X).length() < 1e-15, "{right}");
        let top = concentric_disk(DVec2::new(0.5, 1.0));
        assert!((top - DVec2::Y).length() < 1e-15, "{top}");
        let corner = concentric_disk(DVec2::ONE);
        assert!((corner - DVec2::splat(0.5f64.sqrt())).length() < 1e-15);
        // Uniform in area: r² and the angle are uniform; every point is in.
        let mut rng = PixelRng::new(5, 8, 13);
        let n = 200_000;
        let (mut rings, mut sectors) = ([0usize; 4], [0usize; 8]);
        for _ in 0..n {
            let p = concentric_disk(DVec2::new(rng.uniform(), rng.uniform()));
            let r2 = p.length_squared();
            assert!(r2 <= 1.0 + 1e-15);
            rings[((r2 * 4.0) as usize).min(3)] += 1;
            let turn = p.y.atan2(p.x) / std::f64::consts::TAU + 0.5;
            sectors[((turn * 8.0) as usize).min(7)] += 1;
        }
        // Each share within 1 % of the expected (σ ≈ 0.2 %).
        for c in rings {
            assert!((c as f64 / n as f64 - 0.25).abs() < 0.01, "{rings:?}");
        }
        for c in sectors {
            assert!((c as f64 / n as f64 - 0.125).abs() < 0.01, "{sectors:?}");
        }
        // Area-preserving everywhere: the Jacobian determinant is π (the
        // disk's area over the square's), by central differences.
        let h = 1e-6;
        for _ in 0..1000 {
            let u = DVec2::new(rng.uniform(), rng.uniform()) * 0.98 + 0.01;
            let dx =
                (concentric_disk(u + DVec2::X * h) - concentric_disk(u - DVec2::X * h)) / (2.0 * h);
            let dy =
                (concentric_disk(u + DVec2::Y * h) - concentric_disk(u - DVec2::Y * h)) / (2.0 * h);
            let det = dx.x * dy.y - dx.y * dy.x;
            assert!((det - std::f64::consts::PI).abs() < 1e-4, "{u}: {det}");
        }
    }
}
