//! Big arrays that traversals read at random (a mesh's triangles and
//! vertices, its tree's nodes) in memory the kernel is asked to back with
//! huge pages: on a million-triangle mesh the arrays span tens of
//! megabytes, and with 4 KiB pages nearly every node or vertex load of an
//! incoherent ray also misses the TLB. Where the system leaves huge pages
//! to the program (Linux's `transparent_hugepage=madvise`, the usual
//! default), only a program that asks gets them.
//!
//! The same request serves a query's big answers ([`zeros`]): memory fresh
//! from the system is faulted in by its first write, a 4 KiB page at a
//! time, up to 16 Ki faults for a million rays' nearest hits (64 MB); a
//! fresh Python process's first such queries took 5.5–10 Ki, and
//! 1.5–1.9 Ki advised.
//!
//! The request is a hint: it changes no value, and where it is refused or
//! not supported the arrays are ordinary ones.

// The `madvise` call below is the one exception to the crate's
// `deny(unsafe_code)` besides the AVX2 intrinsics.
#![allow(unsafe_code)]

/// Arrays smaller than this are not worth a request: few 2 MiB pages fit.
const FROM_BYTES: usize = 4 << 20;

/// An empty vector with room for `capacity` items, its memory advised for
/// huge pages before anything is written to it (the kernel picks the page
/// size at the first write of each page).
pub fn with_capacity<T>(capacity: usize) -> Vec<T> {
    let v = Vec::with_capacity(capacity);
    advise(v.as_ptr() as usize, capacity.saturating_mul(size_of::<T>()));
    v
}

/// The vector of `items`, in memory advised as by [`with_capacity`].
pub fn collect<T>(items: impl ExactSizeIterator<Item = T>) -> Vec<T> {
    let mut v = with_capacity(items.len());
    v.extend(items);
    v
}

/// `n` copies of `zero`, a zero (all bits 0), as `vec![zero; n]` makes
/// them: memory the allocator takes from the system as it is, with no
/// pass over it here. That memory is advised as by [`with_capacity`], so
/// whoever writes it first (a query's workers, each its own chunks) faults
/// it in a huge page at a time rather than 4 KiB at a time.
pub fn zeros<T: Clone>(zero: T, n: usize) -> Vec<T> {
    let v = vec![zero; n];
    advise(v.as_ptr() as usize, n.saturating_mul(size_of::<T>()));
    v
}

#[cfg(target_os = "linux")]
fn advise(start: usize, bytes: usize) {
    const PAGE: usize = 4096;
    if bytes < FROM_BYTES {
        return;
    }
    // The whole pages inside the allocation.
    let begin = start.next_multiple_of(PAGE);
    let end = (start + bytes) / PAGE * PAGE;
    if end <= begin {
        return;
    }
    // SAFETY: the range lies inside an allocation this vector owns, and
    // MADV_HUGEPAGE changes neither its contents nor its validity, only
    // the size of the pages backing it. The result is ignored: a refusal
    // (no THP in this kernel, a page size other than 4 KiB) leaves
    // ordinary pages.
    unsafe {
        libc::madvise(begin as *mut libc::c_void, end - begin, libc::MADV_HUGEPAGE);
    }
}

#[cfg(not(target_os = "linux"))]
fn advise(_start: usize, _bytes: usize) {}

#[cfg(test)]
mod tests {
    #[test]
    fn the_arrays_hold_what_they_are_given() {
        let small: Vec<u64> = super::collect((0..10u32).map(u64::from));
        assert_eq!(small, (0..10).collect::<Vec<u64>>());
        // Big enough to be advised.
        let n = (super::FROM_BYTES / 8) * 3 + 5;
        let big: Vec<u64> = super::collect((0..n).map(|i| i as u64 * 3));
        assert_eq!(big.len(), n);
        assert!(big.iter().enumerate().all(|(i, &v)| v == i as u64 * 3));
        let zeros = super::zeros(0.0f64, n);
        assert!(zeros.len() == n && zeros.iter().all(|&z| z == 0.0));
        let mut grown: Vec<u32> = super::with_capacity(super::FROM_BYTES);
        grown.extend(0..super::FROM_BYTES as u32 * 2);
        assert_eq!(
            grown[super::FROM_BYTES * 2 - 1],
            super::FROM_BYTES as u32 * 2 - 1
        );
    }
}
