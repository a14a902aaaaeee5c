//! Per-pixel random streams.
//!
//! Every pixel owns a PCG stream seeded from (scene seed, x, y), so the
//! samples a pixel draws do not depend on which thread renders it or in
//! which order: the image is bit-identical for any thread count, and any
//! region of it can be rendered alone.

/// The random stream of one pixel: PCG's 128-bit multiplicative generator
/// with the XSL RR output (`pcg64_fast`), the stream of `rand_pcg`'s
/// `Pcg64Mcg` to the bit (a test compares them). Written out here because
/// a batch of draws needs the state: draw k of a batch is state · Mᵏ, so
/// the draws of a batch are independent multiplies rather than a chain of
/// them (see [`fill_uniform`](Self::fill_uniform)).
pub struct PixelRng {
    state: u128,
}

/// The generator's multiplier M.
const MULTIPLIER: u128 = 0x2360_ED05_1FC6_5DA4_4385_DF64_9FCC_F645;

/// Most draws [`PixelRng::fill_uniform`] makes at once.
pub const FILL_MAX: usize = 32;

/// M¹ … M^FILL_MAX (mod 2¹²⁸).
const POWERS: [u128; FILL_MAX] = {
    let mut powers = [MULTIPLIER; FILL_MAX];
    let mut k = 1;
    while k < FILL_MAX {
        powers[k] = powers[k - 1].wrapping_mul(MULTIPLIER);
        k += 1;
    }
    powers
};

/// PCG's XSL RR output of a state: xor of the halves, rotated by the top
/// six bits.
#[inline(always)]
fn output(state: u128) -> u64 {
    let rotate = (state >> 122) as u32;
    (((state >> 64) as u64) ^ (state as u64)).rotate_right(rotate)
}

/// 53 random bits as a uniform number in [0, 1).
#[inline(always)]
fn to_unit(bits: u64) -> f64 {
    // Through i64, whose conversion is one instruction (u64's is a
    // sequence); below 2⁵³ both give the same number.
    (bits >> 11) as i64 as f64 * (1.0 / (1u64 << 53) as f64)
}

/// SplitMix64 finaliser: spreads nearby inputs over the whole 64-bit range.
#[inline]
pub fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl PixelRng {
    /// The stream for pixel (x, y) of a render with `seed`.
    pub fn new(seed: u64, x: u32, y: u32) -> Self {
        let key = splitmix64(splitmix64(seed) ^ ((u64::from(y) << 32) | u64::from(x)));
        let hi = splitmix64(key);
        let state = (u128::from(hi) << 64) | u128::from(splitmix64(hi ^ key));
        // The generator needs an odd state (as `Pcg64Mcg::from_seed` sets).
        PixelRng { state: state | 1 }
    }

    /// A uniform number in [0, 1) with 53 random bits.
    #[inline]
    pub fn uniform(&mut self) -> f64 {
        self.state = self.state.wrapping_mul(MULTIPLIER);
        to_unit(output(self.state))
    }

    /// Fills `out` (at most [`FILL_MAX`] long) with the next `out.len()`
    /// values of [`uniform`](Self::uniform), in order, leaving the stream
    /// where those calls would: the same numbers, from multiplies that do
    /// not wait for one another.
    #[inline]
    pub fn fill_uniform(&mut self, out: &mut [f64]) {
        let Some(last) = out.len().checked_sub(1) else {
            return;
        };
        assert!(out.len() <= FILL_MAX, "at most {FILL_MAX} draws at once");
        let state = self.state;
        for (value, power) in out.iter_mut().zip(&POWERS) {
            *value = to_unit(output(state.wrapping_mul(*power)));
        }
        self.state = state.wrapping_mul(POWERS[last]);
    }

    /// Moves the stream on past `n` draws, where `n` calls of
    /// [`uniform`](Self::uniform) would leave it, without making them.
    #[inline]
    pub fn skip(&mut self, mut n: usize) {
        while n > 0 {
            let step = n.min(FILL_MAX);
            self.state = self.state.wrapping_mul(POWERS[step - 1]);
            n -= step;
        }
    }

    /// An index in 0..n (n > 0).
    #[inline]
    pub fn below(&mut self, n: usize) -> usize {
        ((self.uniform() * n as f64) as usize).min(n - 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn skipping_draws_leaves_the_stream_where_drawing_them_would() {
        for n in 0..100 {
            let (mut drawn, mut skipped) =
                (PixelRng::new(7, n as u32, 1), PixelRng::new(7, n as u32, 1));
            for _ in 0..n {
                drawn.uniform();
            }
            skipped.skip(n);
            assert_eq!(drawn.uniform(), skipped.uniform(), "{n}");
        }
    }

    #[test]
    fn streams_are_reproducible_and_distinct() {
        let a: Vec<f64> = (0..4).map(|_| 0.0).collect();
        let mut r1 = PixelRng::new(1, 3, 4);
        let mut r2 = PixelRng::new(1, 3, 4);
        let mut r3 = PixelRng::new(1, 4, 3);
        let s1: Vec<f64> = a.iter().map(|_| r1.uniform()).collect();
        let s2: Vec<f64> = a.iter().map(|_| r2.uniform()).collect();
        let s3: Vec<f64> = a.iter().map(|_| r3.uniform()).collect();
        assert_eq!(s1, s2);
        assert_ne!(s1, s3);
    }

    /// The stream is `rand_pcg`'s `Pcg64Mcg` seeded with the same state,
    /// draw for draw, and a batch is the draws one by one.
    #[test]
    fn the_stream_is_pcg64_fast_and_a_batch_is_its_draws() {
        use rand_core::{RngCore, SeedableRng};
        for (seed, x, y) in [(0, 0, 0), (1, 3, 4), (u64::MAX, 639, 479), (42, 7, 0)] {
            let mut ours = PixelRng::new(seed, x, y);
            let key = splitmix64(splitmix64(seed) ^ ((u64::from(y) << 32) | u64::from(x)));
            let hi = splitmix64(key);
            let state = (u128::from(hi) << 64) | u128::from(splitmix64(hi ^ key));
            let mut reference = rand_pcg::Pcg64Mcg::from_seed(state.to_le_bytes());
            for _ in 0..10_000 {
                let expected = (reference.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
                assert_eq!(ours.uniform(), expected);
            }
            // Batches of every length, then one by one: the same stream.
            let mut batched = PixelRng::new(seed, x, y);
            let mut single = PixelRng::new(seed, x, y);
            for len in 0..=FILL_MAX {
                let mut out = [f64::NAN; FILL_MAX];
                batched.fill_uniform(&mut out[..len]);
                for (k, &value) in out[..len].iter().enumerate() {
                    assert_eq!(value, single.uniform(), "batch of {len}, draw {k}");
                }
                assert_eq!(
                    batched.uniform(),
                    single.uniform(),
                    "after a batch of {len}"
                );
            }
        }
    }

    #[test]
    fn uniform_has_the_right_mean_and_range() {
        let mut r = PixelRng::new(0, 0, 0);
        let n = 100_000;
        let mut sum = 0.0;
        for _ in 0..n {
            let u = r.uniform();
            assert!((0.0..1.0).contains(&u));
            sum += u;
        }
        assert!((sum / n as f64 - 0.5).abs() < 0.005);
    }
}
