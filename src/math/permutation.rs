//! Pseudo-random permutations of 0..n without storing them, for pairing
//! the strata of one sample dimension with another's at random.

/// Element `i` of the permutation of 0..`len` that `key` chooses
/// (Kensler, "Correlated Multi-Jittered Sampling", 2013; pbrt-v4's
/// `PermutationElement`). Every step of the hash is a bijection of the
/// integers below the next power of two, so walking its cycle until it
/// falls below `len` (fewer than two steps on average) gives a
/// permutation of 0..len for any length and key.
pub fn permutation_element(i: u32, len: u32, key: u32) -> u32 {
    Permutation::new(len, key).element(i)
}

/// The permutation of [`permutation_element`] for one length and key,
/// with what does not depend on the element worked out once: a pixel asks
/// its permutation for every one of its samples.
#[derive(Clone, Copy, Debug)]
pub struct Permutation {
    len: u32,
    key: u32,
    /// The mask of the next power of two at or above `len`, less one.
    mask: u32,
    /// key mod len: the final shift (i + key) mod len without a division,
    /// as i < len.
    key_mod: u32,
}

impl Permutation {
    /// The permutation of 0..`len` (len ≥ 1) that `key` chooses.
    pub fn new(len: u32, key: u32) -> Self {
        debug_assert!(len > 0);
        let mut w = len.wrapping_sub(1);
        w |= w >> 1;
        w |= w >> 2;
        w |= w >> 4;
        w |= w >> 8;
        w |= w >> 16;
        Permutation {
            len,
            key,
            mask: w,
            key_mod: key % len.max(1),
        }
    }

    /// Element `i` (i < len).
    #[inline]
    pub fn element(&self, i: u32) -> u32 {
        debug_assert!(i < self.len);
        let (p, w, len) = (self.key, self.mask, self.len);
        let mut i = i;
        loop {
            i ^= p;
            i = i.wrapping_mul(0xe170_893d);
            i ^= p >> 16;
            i ^= (i & w) >> 4;
            i ^= p >> 8;
            i = i.wrapping_mul(0x0929_eb3f);
            i ^= p >> 23;
            i ^= (i & w) >> 1;
            i = i.wrapping_mul(1 | p >> 27);
            i = i.wrapping_mul(0x6935_fa69);
            i ^= (i & w) >> 11;
            i = i.wrapping_mul(0x74dc_b303);
            i ^= (i & w) >> 2;
            i = i.wrapping_mul(0x9e50_1cc3);
            i ^= (i & w) >> 2;
            i = i.wrapping_mul(0xc860_a3df);
            i &= w;
            i ^= i >> 5;
            if i < len {
                break;
            }
        }
        // (i + key) mod len, as pbrt's: i + key mod len < 2·len.
        let shifted = u64::from(i) + u64::from(self.key_mod);
        if shifted >= u64::from(len) {
            (shifted - u64::from(len)) as u32
        } else {
            shifted as u32
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_length_and_key_gives_a_permutation() {
        for len in (1..=70).chain([255, 256, 257, 1000, 4096]) {
            for key in [0, 1, 0x9e37_79b9, u32::MAX, 12_345] {
                let mut seen = vec![false; len as usize];
                for i in 0..len {
                    let j = permutation_element(i, len, key) as usize;
                    assert!(!seen[j], "len {len}, key {key}: {j} twice");
                    seen[j] = true;
                }
            }
        }
    }

    #[test]
    fn the_shift_without_a_division_is_the_modulo() {
        // The element before the shift, walked as `element` walks it, then
        // shifted by the division pbrt writes.
        let reference = |i: u32, len: u32, key: u32| {
            let unshifted = Permutation {
                key_mod: 0,
                ..Permutation::new(len, key)
            }
            .element(i);
            ((u64::from(unshifted) + u64::from(key)) % u64::from(len)) as u32
        };
        for len in [1, 2, 3, 7, 16, 17, 100, 1024, 65_537] {
            for key in [0, 1, len - 1, len, 0x9e37_79b9, u32::MAX, u32::MAX - 1] {
                let p = Permutation::new(len, key);
                for i in (0..len).step_by((len as usize / 50).max(1)) {
                    assert_eq!(p.element(i), reference(i, len, key), "{i} {len} {key}");
                }
            }
        }
    }

    #[test]
    fn keys_give_different_orders() {
        // Keys as a render draws them: 32 random bits.
        let order = |k: u32| {
            let key = k.wrapping_mul(0x9e37_79b9);
            (0..16)
                .map(|i| permutation_element(i, 16, key))
                .collect::<Vec<_>>()
        };
        let orders: Vec<_> = (0..20).map(order).collect();
        let distinct = (0..20)
            .filter(|&a| (0..a).all(|b| orders[a] != orders[b]))
            .count();
        assert_eq!(distinct, 20);
        // Each element lands in each place about equally often over keys.
        let mut first = [0u32; 16];
        for key in 0..16_000u32 {
            first[permutation_element(0, 16, key.wrapping_mul(0x9e37_79b9)) as usize] += 1;
        }
        assert!(first.iter().all(|&c| (700..1300).contains(&c)), "{first:?}");
    }
}
