//! The AVX2 node test, a prefetch hint, and a gate that compiles batch
//! loops for AVX2: the only `unsafe` code in the library. Each function
//! here is compiled for AVX2 and may run only where the CPU has it, which
//! an [`Avx2`] value proves.

#![allow(unsafe_code)]

use std::arch::x86_64::*;

use super::{Job, Lanes, NodePacket, NodeRay, PACKET, SLACK};
use crate::accel::packet::{self, PacketAnyTest, PacketClosestTest, PacketEntry};
use crate::accel::wide::{self, AnyTest, ClosestTest, Stack, StackEntry, WIDTH, WideNode};

/// A 64-byte-aligned slot whose address is taken, which makes the
/// compiler realign the stack frame of the function that holds it. The
/// single-ray and packet traversals keep vectors on the stack (spills of
/// a node's plane rows, the ray's broadcasts: hundreds of 32-byte
/// accesses in `any` and the packets' code); in a frame only 16-byte
/// aligned, where those slots fall depends on the caller's depth, and a
/// slot across two cache lines costs a split access at every node visit.
/// The same counting query from Python took 230–236 ms on the kept
/// one-thread pool against 173–176 ms through the global pool; realigned,
/// 174–177 and 178–179. (The streams, with few such slots, are left as
/// they were: realigned, their rows were 1–3 % slower.)
#[repr(C, align(64))]
struct FrameAlign([u8; 64]);

/// Realigns the calling frame (see [`FrameAlign`]); inlined, it costs the
/// realignment in the prologue and a 64-byte store, once per search.
#[inline(always)]
fn realign_frame() {
    let mut slot = FrameAlign([0; 64]);
    std::hint::black_box(&mut slot);
}

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

    /// Runs `job` in a function compiled for AVX2 (see
    /// `Kernel::vectorize_job`).
    #[inline]
    pub fn vectorize_job<J: Job>(self, job: J) -> J::Output {
        // SAFETY: `self` exists only where `detect` found AVX2.
        unsafe { job_with_avx2(job) }
    }
}

/// Asks the cache for the line holding `value` (a hint only).
#[inline(always)]
pub fn prefetch_line<T>(value: &T) {
    // SAFETY: SSE, which has the prefetch, is part of every x86-64 CPU; a
    // prefetch reads nothing the program sees and never faults.
    unsafe { _mm_prefetch::<_MM_HINT_T0>((value as *const T).cast::<i8>()) }
}

/// `job.run()`, with AVX2 enabled for its code, which `Job::run` inlines.
///
/// # Safety
/// The CPU must have AVX2.
#[target_feature(enable = "avx2")]
unsafe fn job_with_avx2<J: Job>(job: J) -> J::Output {
    job.run()
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
    fn ordered_entries(self, node: &WideNode, ray: &NodeRay, limit: f32) -> (usize, [u32; WIDTH]) {
        // SAFETY: `self` exists only where `detect` found AVX2.
        unsafe { ordered_entries(node, ray, limit) }
    }

    #[inline(always)]
    fn order(self, mask: u32, near: &[f32; WIDTH]) -> (usize, [u32; WIDTH]) {
        // SAFETY: `self` exists only where `detect` found AVX2; the load
        // reads the eight f32 of `near`.
        unsafe { ordered_keys(mask, _mm256_loadu_ps(near.as_ptr())) }
    }

    #[inline(always)]
    fn masked_max(self, values: &[f32; PACKET], mask: u32) -> f32 {
        // SAFETY: `self` exists only where `detect` found AVX2.
        unsafe { masked_max(values, mask) }
    }

    #[inline(always)]
    fn packet_entries(
        self,
        node: &WideNode,
        packet: &NodePacket,
        limit: f32,
    ) -> (u32, [f32; WIDTH]) {
        // SAFETY: `self` exists only where `detect` found AVX2.
        unsafe { packet_entries(node, packet, limit) }
    }

    #[inline(always)]
    fn ray_mask(
        self,
        node: &WideNode,
        slot: usize,
        packet: &NodePacket,
        limits: &[f32; PACKET],
    ) -> u32 {
        // SAFETY: `self` exists only where `detect` found AVX2.
        unsafe { ray_mask(node, slot, packet, limits) }
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

/// `Lanes::masked_max` without a branch per lane (those mispredicted on
/// every node visit and stack pop of a packet): absent lanes blended to
/// −∞, then the maximum by halves.
///
/// # Safety
/// The CPU must have AVX2.
#[inline(always)]
unsafe fn masked_max(values: &[f32; PACKET], mask: u32) -> f32 {
    // SAFETY: the caller guarantees AVX2; the load reads the eight f32 of
    // `values`, the rest are register operations.
    unsafe {
        let present = lane_mask(mask);
        let v = _mm256_blendv_ps(
            _mm256_set1_ps(f32::NEG_INFINITY),
            _mm256_loadu_ps(values.as_ptr()),
            _mm256_castsi256_ps(present),
        );
        let four = _mm_max_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps::<1>(v));
        let two = _mm_max_ps(four, _mm_movehl_ps(four, four));
        _mm_cvtss_f32(_mm_max_ss(two, _mm_shuffle_ps::<1>(two, two)))
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
    // SAFETY: the caller guarantees AVX2; the store writes eight f32 (32
    // bytes) into an array of that size.
    unsafe {
        let (mask, near) = node_test(node, ray, limit);
        let mut out = [0.0f32; WIDTH];
        _mm256_storeu_ps(out.as_mut_ptr(), near);
        (mask, out)
    }
}

/// `Lanes::ordered_entries` in registers: the keys (`wide::child_key`) of
/// the eight lanes, those not met made the greatest, put in order by a
/// sorting network, so that a node visit costs no branch per child met
/// (in cachegrind's simulated predictor those were a third of a scattered
/// ray's mispredictions).
///
/// # Safety
/// The CPU must have AVX2.
#[inline(always)]
unsafe fn ordered_entries(node: &WideNode, ray: &NodeRay, limit: f32) -> (usize, [u32; WIDTH]) {
    // SAFETY: the caller guarantees AVX2.
    unsafe {
        let (mask, near) = node_test(node, ray, limit);
        ordered_keys(mask, near)
    }
}

/// The node test of `entries` and `ordered_entries`: the mask of the
/// valid lanes met before `limit`, and the entry distances, in a register.
///
/// # Safety
/// The CPU must have AVX2.
#[inline(always)]
unsafe fn node_test(node: &WideNode, ray: &NodeRay, limit: f32) -> (u32, __m256) {
    // SAFETY: the caller guarantees AVX2; each load reads eight f32 (32
    // bytes) of a plane row of that size, and the unaligned form has no
    // alignment requirement.
    unsafe {
        let t = |row: usize, axis: usize| {
            let plane = _mm256_loadu_ps(node.planes[row].as_ptr());
            _mm256_mul_ps(
                _mm256_sub_ps(plane, _mm256_set1_ps(ray.origin[axis])),
                _mm256_set1_ps(ray.inv_dir[axis]),
            )
        };
        let (mask, near) = slab8(
            [
                t(ray.near_row[0], 0),
                t(ray.near_row[1], 1),
                t(ray.near_row[2], 2),
            ],
            [
                t(ray.far_row[0], 0),
                t(ray.far_row[1], 1),
                t(ray.far_row[2], 2),
            ],
            _mm256_set1_ps(limit),
        );
        (mask & node.valid, near)
    }
}

/// Lane i all ones where bit i of `mask` is set, else zero.
///
/// # Safety
/// The CPU must have AVX2.
#[inline(always)]
unsafe fn lane_mask(mask: u32) -> __m256i {
    // SAFETY: the caller guarantees AVX2; register operations only.
    unsafe {
        let lane_bits = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
        _mm256_cmpeq_epi32(
            _mm256_and_si256(_mm256_set1_epi32(mask as i32), lane_bits),
            lane_bits,
        )
    }
}

/// The keys (`wide::child_key`) of the lanes of `mask`, entry distances
/// `near`, nearest first (see `ordered_entries`).
///
/// # Safety
/// The CPU must have AVX2.
#[inline(always)]
unsafe fn ordered_keys(mask: u32, near: __m256) -> (usize, [u32; WIDTH]) {
    // SAFETY: the caller guarantees AVX2; the store writes eight u32 (32
    // bytes) into an array of that size.
    unsafe {
        let met = lane_mask(mask);
        let keys = _mm256_or_si256(
            _mm256_and_si256(_mm256_castps_si256(near), _mm256_set1_epi32(!7)),
            _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7),
        );
        // Lanes not met: all ones, after every key met.
        let keys = _mm256_or_si256(keys, _mm256_xor_si256(met, _mm256_set1_epi32(-1)));
        // One child or none (most visits): its key to the front, unsorted.
        let keys = if mask & mask.wrapping_sub(1) != 0 {
            sort8(keys)
        } else {
            _mm256_permutevar8x32_epi32(keys, _mm256_set1_epi32(mask.trailing_zeros() as i32))
        };
        let mut out = [0u32; WIDTH];
        _mm256_storeu_si256(out.as_mut_ptr().cast(), keys);
        (mask.count_ones() as usize, out)
    }
}

/// Eight u32 in ascending order: a bitonic sorting network, each step a
/// compare-exchange of every lane with its partner.
///
/// # Safety
/// The CPU must have AVX2.
#[inline(always)]
unsafe fn sort8(v: __m256i) -> __m256i {
    /// Each lane's min or max with `partner`'s lane: the max where bit
    /// `lane` of `TAKE_MAX` is set.
    #[inline(always)]
    unsafe fn exchange<const TAKE_MAX: i32>(v: __m256i, partner: __m256i) -> __m256i {
        // SAFETY: the caller guarantees AVX2; register operations only.
        unsafe {
            _mm256_blend_epi32::<TAKE_MAX>(
                _mm256_min_epu32(v, partner),
                _mm256_max_epu32(v, partner),
            )
        }
    }
    // SAFETY: the caller guarantees AVX2; register operations only.
    unsafe {
        // Partners one, two and four lanes over.
        let ones = |v: __m256i| _mm256_shuffle_epi32::<0b10_11_00_01>(v);
        let twos = |v: __m256i| _mm256_shuffle_epi32::<0b01_00_11_10>(v);
        let fours = |v: __m256i| _mm256_permute4x64_epi64::<0b01_00_11_10>(v);
        // Pairs ascending and descending by turns...
        let v = exchange::<0b0110_0110>(v, ones(v));
        // ...merged into fours ascending and descending by turns...
        let v = exchange::<0b0011_1100>(v, twos(v));
        let v = exchange::<0b0101_1010>(v, ones(v));
        // ...merged into eight ascending.
        let v = exchange::<0b1111_0000>(v, fours(v));
        let v = exchange::<0b1100_1100>(v, twos(v));
        exchange::<0b1010_1010>(v, ones(v))
    }
}

/// `super::slab` in eight lanes: the mask of the lanes whose box is met
/// before their limit, and the entry distances.
///
/// # Safety
/// The CPU must have AVX2.
#[inline(always)]
unsafe fn slab8(near: [__m256; 3], far: [__m256; 3], limit: __m256) -> (u32, __m256) {
    // SAFETY: the caller guarantees AVX2; register operations only.
    unsafe {
        let near = _mm256_max_ps(
            _mm256_max_ps(_mm256_max_ps(near[0], near[1]), near[2]),
            _mm256_setzero_ps(),
        );
        let far = _mm256_mul_ps(
            _mm256_min_ps(_mm256_min_ps(far[0], far[1]), far[2]),
            _mm256_set1_ps(SLACK),
        );
        let hit = _mm256_cmp_ps::<_CMP_LE_OQ>(near, _mm256_min_ps(far, limit));
        (_mm256_movemask_ps(hit) as u32, near)
    }
}

/// `super::packet_entries_scalar`, eight boxes at once: the same
/// operations lane by lane.
///
/// # Safety
/// The CPU must have AVX2.
#[inline(always)]
unsafe fn packet_entries(node: &WideNode, p: &NodePacket, limit: f32) -> (u32, [f32; WIDTH]) {
    // SAFETY (every block below): the caller guarantees AVX2; the loads
    // and the store read and write eight f32 of arrays of that size.
    unsafe {
        let (mask, near) = slab8(
            [
                interval_lo(node, p, p.near_row[0], 0),
                interval_lo(node, p, p.near_row[1], 1),
                interval_lo(node, p, p.near_row[2], 2),
            ],
            [
                interval_hi(node, p, p.far_row[0], 0),
                interval_hi(node, p, p.far_row[1], 1),
                interval_hi(node, p, p.far_row[2], 2),
            ],
            _mm256_set1_ps(limit),
        );
        let mut out = [0.0f32; WIDTH];
        _mm256_storeu_ps(out.as_mut_ptr(), near);
        (mask & node.valid, out)
    }
}

/// The four corner products of the packet's distances to plane row `row`
/// of each box (helpers are functions, not closures: a closure left out of
/// line would not be compiled for AVX2, and nor would the intrinsics in it).
///
/// # Safety
/// The CPU must have AVX2.
#[inline(always)]
unsafe fn interval_products(
    node: &WideNode,
    p: &NodePacket,
    row: usize,
    axis: usize,
) -> [__m256; 4] {
    // SAFETY: the caller guarantees AVX2; the load reads eight f32.
    unsafe {
        let plane = _mm256_loadu_ps(node.planes[row].as_ptr());
        let x0 = _mm256_sub_ps(plane, _mm256_set1_ps(p.origin_hi[axis]));
        let x1 = _mm256_sub_ps(plane, _mm256_set1_ps(p.origin_lo[axis]));
        let (i0, i1) = (
            _mm256_set1_ps(p.inv_lo[axis]),
            _mm256_set1_ps(p.inv_hi[axis]),
        );
        [
            _mm256_mul_ps(x0, i0),
            _mm256_mul_ps(x0, i1),
            _mm256_mul_ps(x1, i0),
            _mm256_mul_ps(x1, i1),
        ]
    }
}

/// The least of [`interval_products`].
///
/// # Safety
/// The CPU must have AVX2.
#[inline(always)]
unsafe fn interval_lo(node: &WideNode, p: &NodePacket, row: usize, axis: usize) -> __m256 {
    // SAFETY: the caller guarantees AVX2.
    unsafe {
        let [a, b, c, d] = interval_products(node, p, row, axis);
        _mm256_min_ps(_mm256_min_ps(a, b), _mm256_min_ps(c, d))
    }
}

/// The greatest of [`interval_products`].
///
/// # Safety
/// The CPU must have AVX2.
#[inline(always)]
unsafe fn interval_hi(node: &WideNode, p: &NodePacket, row: usize, axis: usize) -> __m256 {
    // SAFETY: the caller guarantees AVX2.
    unsafe {
        let [a, b, c, d] = interval_products(node, p, row, axis);
        _mm256_max_ps(_mm256_max_ps(a, b), _mm256_max_ps(c, d))
    }
}

/// `super::ray_mask_scalar`, eight rays at once: the same operations lane
/// by lane.
///
/// # Safety
/// The CPU must have AVX2.
#[inline(always)]
unsafe fn ray_mask(node: &WideNode, slot: usize, p: &NodePacket, limits: &[f32; PACKET]) -> u32 {
    // SAFETY (every block below): the caller guarantees AVX2; the loads
    // read eight f32 of arrays of that size.
    unsafe {
        let t = |row: usize, axis: usize| {
            _mm256_mul_ps(
                _mm256_sub_ps(
                    _mm256_set1_ps(node.planes[row][slot]),
                    _mm256_loadu_ps(p.origin[axis].as_ptr()),
                ),
                _mm256_loadu_ps(p.inv_dir[axis].as_ptr()),
            )
        };
        let (mask, _) = slab8(
            [
                t(p.near_row[0], 0),
                t(p.near_row[1], 1),
                t(p.near_row[2], 2),
            ],
            [t(p.far_row[0], 0), t(p.far_row[1], 1), t(p.far_row[2], 2)],
            _mm256_loadu_ps(limits.as_ptr()),
        );
        mask & p.present
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
        realign_frame();
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
        realign_frame();
        wide::any(proof, nodes, ray, t_max, stack, test)
    }
    // SAFETY: `proof` exists only where `detect` found AVX2.
    unsafe { run(proof, nodes, ray, t_max, stack, test) }
}

/// `wide::closest_stream` compiled for AVX2.
#[inline]
pub fn closest_stream<T: ClosestTest, const K: usize>(
    proof: Avx2,
    nodes: &[WideNode],
    rays: &[NodeRay; K],
    count: usize,
    t_max: &mut [f64; K],
    stacks: &mut [impl Stack<StackEntry>; K],
    tests: &mut [T; K],
) {
    #[target_feature(enable = "avx2")]
    fn run<T: ClosestTest, const K: usize>(
        proof: Avx2,
        nodes: &[WideNode],
        rays: &[NodeRay; K],
        count: usize,
        t_max: &mut [f64; K],
        stacks: &mut [impl Stack<StackEntry>; K],
        tests: &mut [T; K],
    ) {
        wide::closest_stream(proof, nodes, rays, count, t_max, stacks, tests)
    }
    // SAFETY: `proof` exists only where `detect` found AVX2.
    unsafe { run(proof, nodes, rays, count, t_max, stacks, tests) }
}

/// `wide::any_stream` compiled for AVX2.
#[inline]
pub fn any_stream<T: AnyTest, const K: usize>(
    proof: Avx2,
    nodes: &[WideNode],
    rays: &[NodeRay; K],
    count: usize,
    t_max: &[f64; K],
    stacks: &mut [impl Stack<StackEntry>; K],
    tests: &mut [T; K],
) -> u32 {
    #[target_feature(enable = "avx2")]
    fn run<T: AnyTest, const K: usize>(
        proof: Avx2,
        nodes: &[WideNode],
        rays: &[NodeRay; K],
        count: usize,
        t_max: &[f64; K],
        stacks: &mut [impl Stack<StackEntry>; K],
        tests: &mut [T; K],
    ) -> u32 {
        wide::any_stream(proof, nodes, rays, count, t_max, stacks, tests)
    }
    // SAFETY: `proof` exists only where `detect` found AVX2.
    unsafe { run(proof, nodes, rays, count, t_max, stacks, tests) }
}

/// `packet::span_reaches_leaf` compiled for AVX2.
#[inline]
pub fn span_reaches_leaf(
    proof: Avx2,
    nodes: &[WideNode],
    span: &NodePacket,
    limit: f32,
    budget: usize,
) -> bool {
    #[target_feature(enable = "avx2")]
    fn run(proof: Avx2, nodes: &[WideNode], span: &NodePacket, limit: f32, budget: usize) -> bool {
        realign_frame();
        packet::span_reaches_leaf(proof, nodes, span, limit, budget)
    }
    // SAFETY: `proof` exists only where `detect` found AVX2.
    unsafe { run(proof, nodes, span, limit, budget) }
}

/// `packet::closest` compiled for AVX2.
#[inline]
pub fn closest_packet(
    proof: Avx2,
    nodes: &[WideNode],
    rays: &NodePacket,
    t_max: &mut [f64; PACKET],
    stack: &mut impl Stack<PacketEntry>,
    test: impl PacketClosestTest,
) {
    #[target_feature(enable = "avx2")]
    fn run(
        proof: Avx2,
        nodes: &[WideNode],
        rays: &NodePacket,
        t_max: &mut [f64; PACKET],
        stack: &mut impl Stack<PacketEntry>,
        test: impl PacketClosestTest,
    ) {
        realign_frame();
        packet::closest(proof, nodes, rays, t_max, stack, test)
    }
    // SAFETY: `proof` exists only where `detect` found AVX2.
    unsafe { run(proof, nodes, rays, t_max, stack, test) }
}

/// `packet::any` compiled for AVX2.
#[inline]
pub fn any_packet(
    proof: Avx2,
    nodes: &[WideNode],
    rays: &NodePacket,
    t_max: &[f64; PACKET],
    stack: &mut impl Stack<(u32, u32)>,
    test: impl PacketAnyTest,
) -> u32 {
    #[target_feature(enable = "avx2")]
    fn run(
        proof: Avx2,
        nodes: &[WideNode],
        rays: &NodePacket,
        t_max: &[f64; PACKET],
        stack: &mut impl Stack<(u32, u32)>,
        test: impl PacketAnyTest,
    ) -> u32 {
        realign_frame();
        packet::any(proof, nodes, rays, t_max, stack, test)
    }
    // SAFETY: `proof` exists only where `detect` found AVX2.
    unsafe { run(proof, nodes, rays, t_max, stack, test) }
}
