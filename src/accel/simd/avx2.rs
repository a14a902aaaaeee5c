//! The AVX2 node test, a prefetch hint, and a gate that compiles batch
//! loops for AVX2: the only `unsafe` code in the library. Each function
//! here is compiled for AVX2 and may run only where the CPU has it, which
//! an [`Avx2`] value proves.

#![allow(unsafe_code)]

use std::arch::x86_64::*;

use super::{Lanes, NodeRay, SLACK};
use crate::accel::wide::{self, AnyTest, ClosestTest, Stack, StackEntry, WIDTH, WideNode};

/// Proof that this CPU runs AVX2: made only by [`Avx2::detect`].
#[derive(Clone, Copy, Debug)]
pub struct Avx2 {
    _proof: (),
}

impl Avx2 {
    /// The proof, where the CPU has AVX2.
    pub fn detect() -> Option<Self> {
        is_x86_feature_detected!("avx2").then_some(Avx2 { _proof: () })
    }

    /// Runs `f` inlined into a function compiled for AVX2.
    #[inline]
    pub fn vectorize<R>(self, f: impl FnOnce() -> R) -> R {
        // SAFETY: `self` exists only where `detect` found AVX2.
        unsafe { with_avx2(f) }
    }
}

/// `f()`, with AVX2 enabled for the code of `f` inlined here.
///
/// # Safety
/// The CPU must have AVX2.
#[target_feature(enable = "avx2")]
unsafe fn with_avx2<R>(f: impl FnOnce() -> R) -> R {
    f()
}

impl Lanes for Avx2 {
    #[inline(always)]
    fn entries(self, node: &WideNode, ray: &NodeRay, limit: f32) -> (u32, [f32; WIDTH]) {
        // SAFETY: `self` exists only where `detect` found AVX2.
        unsafe { entries(node, ray, limit) }
    }

    #[inline(always)]
    fn prefetch(self, node: &WideNode) {
        // The plane rows, the first three of the node's four cache lines.
        let p = node.planes.as_ptr().cast::<i8>();
        // SAFETY: SSE is part of AVX2, which `self` proves; a prefetch
        // reads nothing (the addresses lie inside `node` anyway).
        unsafe {
            _mm_prefetch::<_MM_HINT_T0>(p);
            _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64));
            _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(128));
        }
    }
}

/// The eight entry distances in one pass: per step the same operation as
/// `Scalar::entries` on each lane (`_mm256_max_ps` is `a > b ? a : b`).
///
/// Not itself marked for AVX2 (that would stop it being inlined): it is
/// inlined into the `run` functions below, which are.
///
/// # Safety
/// The CPU must have AVX2.
#[inline(always)]
unsafe fn entries(node: &WideNode, ray: &NodeRay, limit: f32) -> (u32, [f32; WIDTH]) {
    // SAFETY (every block below): the caller guarantees AVX2; the loads
    // and the store read and write eight f32 (32 bytes) of arrays of that
    // size, and the unaligned forms have no alignment requirement.
    unsafe {
        let t = |row: usize, axis: usize| {
            let plane = _mm256_loadu_ps(node.planes[row].as_ptr());
            _mm256_mul_ps(
                _mm256_sub_ps(plane, _mm256_set1_ps(ray.origin[axis])),
                _mm256_set1_ps(ray.inv_dir[axis]),
            )
        };
        let near = _mm256_max_ps(
            _mm256_max_ps(
                _mm256_max_ps(t(ray.near_row[0], 0), t(ray.near_row[1], 1)),
                t(ray.near_row[2], 2),
            ),
            _mm256_setzero_ps(),
        );
        let far = _mm256_mul_ps(
            _mm256_min_ps(
                _mm256_min_ps(t(ray.far_row[0], 0), t(ray.far_row[1], 1)),
                t(ray.far_row[2], 2),
            ),
            _mm256_set1_ps(SLACK),
        );
        let hit = _mm256_cmp_ps::<_CMP_LE_OQ>(near, _mm256_min_ps(far, _mm256_set1_ps(limit)));
        let mask = _mm256_movemask_ps(hit) as u32 & node.valid;
        let mut out = [0.0f32; WIDTH];
        _mm256_storeu_ps(out.as_mut_ptr(), near);
        (mask, out)
    }
}

/// `wide::closest` compiled for AVX2.
#[inline]
pub fn closest(
    proof: Avx2,
    nodes: &[WideNode],
    ray: &NodeRay,
    t_max: f64,
    stack: &mut impl Stack<StackEntry>,
    test: impl ClosestTest,
) -> f64 {
    #[target_feature(enable = "avx2")]
    fn run(
        proof: Avx2,
        nodes: &[WideNode],
        ray: &NodeRay,
        t_max: f64,
        stack: &mut impl Stack<StackEntry>,
        test: impl ClosestTest,
    ) -> f64 {
        wide::closest(proof, nodes, ray, t_max, stack, test)
    }
    // SAFETY: `proof` exists only where `detect` found AVX2.
    unsafe { run(proof, nodes, ray, t_max, stack, test) }
}

/// `wide::any` compiled for AVX2.
#[inline]
pub fn any(
    proof: Avx2,
    nodes: &[WideNode],
    ray: &NodeRay,
    t_max: f64,
    stack: &mut impl Stack<u32>,
    test: impl AnyTest,
) -> bool {
    #[target_feature(enable = "avx2")]
    fn run(
        proof: Avx2,
        nodes: &[WideNode],
        ray: &NodeRay,
        t_max: f64,
        stack: &mut impl Stack<u32>,
        test: impl AnyTest,
    ) -> bool {
        wide::any(proof, nodes, ray, t_max, stack, test)
    }
    // SAFETY: `proof` exists only where `detect` found AVX2.
    unsafe { run(proof, nodes, ray, t_max, stack, test) }
}
