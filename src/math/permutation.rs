//! Pseudo-random permutations of 0..n without storing them, for pairing
//! the strata of one sample dimension with another's at random.

/// Element `i` of the permutation of 0..`len` that `key` chooses
/// (Kensler, "Correlated Multi-Jittered Sampling", 2013; pbrt-v4's
/// `PermutationElement`). Every step of the hash is a bijection of the
/// integers below the next power of two, so walking its cycle until it
/// falls below `len` (fewer than two steps on average) gives a
/// permutation of 0..len for any length and key.
pub fn permutation_element(i: u32, len: u32, key: u32) -> u32 {
    debug_assert!(i < len);
    let mut w = len.wrapping_sub(1);
    w |= w >> 1;
    w |= w >> 2;
    w |= w >> 4;
    w |= w >> 8;
    w |= w >> 16;
    let p = key;
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
    ((u64::from(i) + u64::from(p)) % u64::from(len)) as u32
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
