//! Sample placement: stratified points in the unit square and directions
//! uniform over a cone.

use glam::{DVec2, DVec3};

use super::Frame;
use super::rng::PixelRng;

/// The cell of stratum `i` out of `n` in the unit square, as (corner, size).
///
/// The square is cut into `rows = ⌊√n⌋` rows of equal height; the first
/// `n mod rows` rows get one extra column, so there are exactly `n` cells of
/// nearly equal area (equal when `n` is a perfect square).
pub fn stratum(i: usize, n: usize) -> (DVec2, DVec2) {
    debug_assert!(i < n);
    let rows = (n as f64).sqrt().floor().max(1.0) as usize;
    let base = n / rows;
    let extra = n % rows;
    // Rows 0..extra hold base + 1 cells, the rest base cells.
    let (row, col, cols) = if i < extra * (base + 1) {
        (i / (base + 1), i % (base + 1), base + 1)
    } else {
        let j = i - extra * (base + 1);
        (extra + j / base, j % base, base)
    };
    let size = DVec2::new(1.0 / cols as f64, 1.0 / rows as f64);
    (DVec2::new(col as f64, row as f64) * size, size)
}

/// A jittered point in stratum `i` of `n` (see [`stratum`]).
#[inline]
pub fn stratified_point(i: usize, n: usize, rng: &mut PixelRng) -> DVec2 {
    let (corner, size) = stratum(i, n);
    corner + size * DVec2::new(rng.uniform(), rng.uniform())
}

/// A direction uniform over the cone of half-angle θmax around `frame.z`,
/// from a point `u` of the unit square: cos θ = 1 − u.x·(1 − cos θmax),
/// φ = 2π·u.y. Uniform in solid angle, so equal areas of the square map to
/// equal solid angles of the light.
#[inline]
pub fn uniform_cone(frame: &Frame, cos_theta_max: f64, u: DVec2) -> DVec3 {
    let cos_theta = 1.0 - u.x * (1.0 - cos_theta_max);
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let phi = std::f64::consts::TAU * u.y;
    frame.to_world(DVec3::new(
        sin_theta * phi.cos(),
        sin_theta * phi.sin(),
        cos_theta,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strata_tile_the_square_exactly() {
        for n in 1..=50 {
            let mut area = 0.0;
            for i in 0..n {
                let (c, s) = stratum(i, n);
                assert!(c.x >= 0.0 && c.y >= 0.0);
                assert!(c.x + s.x <= 1.0 + 1e-12 && c.y + s.y <= 1.0 + 1e-12);
                area += s.x * s.y;
                // No overlap with any other cell.
                for j in 0..i {
                    let (d, t) = stratum(j, n);
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
    fn perfect_squares_give_a_regular_grid() {
        let (c, s) = stratum(5, 9);
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
}
