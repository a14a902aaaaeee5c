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

/// x to the power y.
#[inline]
pub fn pow(x: f64, y: f64) -> f64 {
    libm::pow(x, y)
}

/// x to a whole power n, by repeated squaring: about log₂ n multiplies
/// instead of libm's pow (a fifth of the Whitted benchmark scene with a
/// 64-feeler light was pow for the Phong highlight, whose exponent is
/// usually whole). Plain multiplies in a
/// fixed order, so every CPU gets the same bits; each of the at most
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
    if (0.0..=4096.0).contains(&y) && y == f64::from(y as u32) {
        powi(x, y as u32)
    } else {
        pow(x, y)
    }
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
