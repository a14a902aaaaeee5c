//! The transcendental functions that feed pixels, from one implementation:
//! the `libm` crate (a Rust port of musl's libm). The platform's libm may
//! pick a different code path per CPU at run time (glibc has FMA and AVX2
//! variants of `sin`, `pow`, …) and round the last bit differently, so
//! nodes of a render farm with different CPUs would disagree on a pixel.
//! Pure Rust compiled for baseline x86-64 computes the same bits everywhere.
//!
//! `clippy.toml` forbids the `f64` methods these replace outside tests.

/// sin x and cos x.
#[inline]
pub fn sin_cos(x: f64) -> (f64, f64) {
    libm::sincos(x)
}

/// sin 2πt and cos 2πt for t in [0, 1] turns (an azimuth drawn from the
/// unit interval), without libm's argument reduction and without a branch,
/// so that a batch of them compiles to vector code:
/// - the nearest quarter turn k comes from 4t by the round-to-nearest of
///   adding 1.5·2⁵² (exact), and 4t − k is exact too;
/// - the angle left, x = (4t − k)·π/2 with |x| ≤ π/4, goes through the
///   Taylor series to x¹⁷ and x¹⁸ (truncation below 10⁻¹⁹) by Horner's
///   rule;
/// - turning by k quarter turns swaps sine and cosine and changes signs,
///   all exact, by selects.
///
/// Plain multiplies and adds in a fixed order: the same bits on every CPU,
/// within a few units in the last place of sin and cos.
#[inline(always)]
pub fn sin_cos_turns(t: f64) -> (f64, f64) {
    const ROUND: f64 = 6_755_399_441_055_744.0; // 1.5·2⁵²
    let quarters = 4.0 * t;
    let shifted = quarters + ROUND;
    // The low bits of the shifted value's mantissa are k.
    let k = shifted.to_bits();
    let x = (quarters - (shifted - ROUND)) * std::f64::consts::FRAC_PI_2;
    let x2 = x * x;
    let sin = x
        * (1.0
            + x2 * (-1.0 / 6.0
                + x2 * (1.0 / 120.0
                    + x2 * (-1.0 / 5_040.0
                        + x2 * (1.0 / 362_880.0
                            + x2 * (-1.0 / 39_916_800.0
                                + x2 * (1.0 / 6_227_020_800.0
                                    + x2 * (-1.0 / 1_307_674_368_000.0
                                        + x2 * (1.0 / 355_687_428_096_000.0)))))))));
    let cos = 1.0
        + x2 * (-0.5
            + x2 * (1.0 / 24.0
                + x2 * (-1.0 / 720.0
                    + x2 * (1.0 / 40_320.0
                        + x2 * (-1.0 / 3_628_800.0
                            + x2 * (1.0 / 479_001_600.0
                                + x2 * (-1.0 / 87_178_291_200.0
                                    + x2 * (1.0 / 20_922_789_888_000.0
                                        + x2 * (-1.0 / 6_402_373_705_728_000.0)))))))));
    // Quarter turn k: (sin, cos) → (cos, −sin) → (−sin, −cos) → (−cos, sin).
    let odd = k & 1 == 1;
    let (s, c) = if odd { (cos, sin) } else { (sin, cos) };
    let sin_sign = if k & 2 == 0 { 1.0 } else { -1.0 };
    let cos_sign = if k.wrapping_add(1) & 2 == 0 {
        1.0
    } else {
        -1.0
    };
    (sin_sign * s, cos_sign * c)
}

/// x to the power y.
#[inline]
pub fn pow(x: f64, y: f64) -> f64 {
    libm::pow(x, y)
}

/// x to a whole power n, by repeated squaring: about log₂ n multiplies
/// instead of libm's pow (a fifth of the Whitted benchmark scene with a
/// 64-feeler light was pow for the Phong highlight, whose exponent is
/// usually whole). Plain multiplies in a fixed order, so every CPU gets
/// the same bits; each of the at most
/// 2·log₂ n roundings adds one relative error of 2⁻⁵³ (doubled by each
/// squaring after it), so the result is within about 2n units in the last
/// place of xⁿ: 240 for n = 120, 3·10⁻¹⁴ relative.
#[inline]
pub fn powi(x: f64, n: u32) -> f64 {
    let mut result = 1.0;
    let mut base = x;
    let mut n = n;
    while n > 0 {
        if n & 1 == 1 {
            result *= base;
        }
        n >>= 1;
        if n > 0 {
            base *= base;
        }
    }
    result
}

/// x to the power y ≥ 0: [`powi`] where y is a whole number up to 4096,
/// else [`pow`].
#[inline]
pub fn pow_whole_fast(x: f64, y: f64) -> f64 {
    match whole_exponent(y) {
        Some(n) => powi(x, n),
        None => pow(x, y),
    }
}

/// `y` as the whole exponent [`pow_whole_fast`] takes by squaring: a whole
/// number in 0..=4096, else `None` (libm's pow).
#[inline]
pub fn whole_exponent(y: f64) -> Option<u32> {
    ((0.0..=4096.0).contains(&y) && y == f64::from(y as u32)).then_some(y as u32)
}

/// tan x.
#[inline]
pub fn tan(x: f64) -> f64 {
    libm::tan(x)
}

/// The angle of (x, y) from the +x axis, in (−π, π].
#[inline]
pub fn atan2(y: f64, x: f64) -> f64 {
    libm::atan2(y, x)
}

/// arcsin x, in [−π/2, π/2].
#[inline]
pub fn asin(x: f64) -> f64 {
    libm::asin(x)
}

#[cfg(test)]
#[allow(clippy::disallowed_methods)] // hand-worked values use the platform's functions
mod tests {
    use super::*;

    /// Against the platform's functions: both are accurate to about one
    /// unit in the last place, so they agree to a few.
    #[test]
    fn agrees_with_the_platform_to_a_few_ulp() {
        let close = |a: f64, b: f64| (a - b).abs() <= 4.0 * f64::EPSILON * a.abs().max(1e-300);
        let mut rng = super::super::rng::PixelRng::new(99, 0, 0);
        for _ in 0..10_000 {
            let x = (rng.uniform() - 0.5) * 20.0;
            let y = rng.uniform() * 3.0;
            let (s, c) = sin_cos(x);
            assert!(close(s, x.sin()) && close(c, x.cos()), "{x}");
            assert!(close(pow(y, x), y.powf(x)), "{y}^{x}");
            assert!(close(atan2(x, y - 1.5), x.atan2(y - 1.5)));
            assert!(close(asin(x / 10.0), (x / 10.0).asin()));
            assert!(close(tan(x / 8.0), (x / 8.0).tan()));
        }
        // Hand-worked values.
        assert_eq!(pow(2.0, 10.0), 1024.0);
        assert_eq!(powi(2.0, 10), 1024.0);
        assert_eq!(powi(-3.0, 3), -27.0);
        assert_eq!(powi(0.5, 0), 1.0);
        assert_eq!(powi(0.0, 5), 0.0);
        assert_eq!(pow_whole_fast(1.5, 2.5), pow(1.5, 2.5));
        assert_eq!(sin_cos(0.0), (0.0, 1.0));
        assert_eq!(atan2(1.0, 0.0), std::f64::consts::FRAC_PI_2);
    }

    /// The azimuth's sine and cosine against libm's on the angle 2πt:
    /// within a few ulps everywhere, right at the quadrant seams and their
    /// midpoints (where the reduction changes sides) too.
    #[test]
    fn sin_cos_turns_matches_sin_cos() {
        assert_eq!(sin_cos_turns(0.0), (0.0, 1.0));
        assert_eq!(sin_cos_turns(0.25), (1.0, 0.0));
        assert_eq!(sin_cos_turns(0.5), (0.0, -1.0));
        assert_eq!(sin_cos_turns(0.75), (-1.0, 0.0));
        assert_eq!(sin_cos_turns(1.0), (0.0, 1.0));
        let mut rng = super::super::rng::PixelRng::new(8, 0, 0);
        let seams = (0..=8).map(|k| k as f64 / 8.0);
        let near = (0..=8).flat_map(|k| {
            let t = k as f64 / 8.0;
            [t - 1e-12, t - f64::EPSILON, t + f64::EPSILON, t + 1e-12]
        });
        let random = (0..100_000).map(|_| rng.uniform());
        for t in seams
            .chain(near)
            .chain(random)
            .filter(|t| (0.0..=1.0).contains(t))
        {
            let (s, c) = sin_cos_turns(t);
            let (ls, lc) = sin_cos(std::f64::consts::TAU * t);
            // 2πt is itself rounded: up to an ulp of 2πt in angle.
            let tol = 4.0 * f64::EPSILON + std::f64::consts::TAU * t * f64::EPSILON;
            assert!(
                (s - ls).abs() <= tol && (c - lc).abs() <= tol,
                "{t}: {s} {c} against {ls} {lc}"
            );
            assert!((s * s + c * c - 1.0).abs() <= 4.0 * f64::EPSILON, "{t}");
        }
    }

    /// Whole powers by squaring against libm's pow: within 2n ulps, for
    /// every exponent of a Phong highlight and bases over (0, 1].
    #[test]
    fn powi_is_within_its_bound_of_pow() {
        let mut rng = super::super::rng::PixelRng::new(7, 0, 0);
        for n in 0..=300u32 {
            for _ in 0..200 {
                let x = rng.uniform().max(1e-3);
                let (fast, exact) = (powi(x, n), pow(x, f64::from(n)));
                let bound = (2.0 * f64::from(n) + 1.0) * f64::EPSILON * exact;
                assert!(
                    (fast - exact).abs() <= bound,
                    "{x}^{n}: {fast} against {exact}"
                );
                assert_eq!(pow_whole_fast(x, f64::from(n)), fast);
            }
        }
    }
}
