//! The fuzz targets (fuzz/src/targets.rs) for the AFL harnesses in src/bin.
#[path = "targets.rs"]
mod targets;
pub use targets::{TARGETS, run};

/// With the `planted` feature, a bug for checking that instrumentation
/// and crash detection work: input that starts with `#PL`, compared byte
/// by byte. From the seed `#` two bytes are to be found, each rewarded with
/// new coverage; AFL++ finds it in about 2.5 minutes here, blind mutation
/// (1 in 65,536 per try at best) far later.
#[cfg(feature = "planted")]
pub fn planted(data: &[u8]) {
    use std::hint::black_box;
    // Nested, with a side effect at each level, so that each byte is its
    // own branch for the coverage map rather than one merged comparison.
    let b = data;
    if b.first() == Some(&b'#') {
        black_box(1);
        if b.get(1) == Some(&b'P') {
            black_box(2);
            if b.get(2) == Some(&b'L') {
                panic!("planted bug found");
            }
        }
    }
}
