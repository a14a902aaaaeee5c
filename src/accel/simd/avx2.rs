//! The AVX2 node test, a prefetch hint, and a gate that compiles batch
//! loops for AVX2: the only `unsafe` code in the library. Each function
//! here is compiled for AVX2 and may run only where the CPU has it, which
//! an [`Avx2`] value proves.

#![allow(unsafe_code)]

use std::arch::x86_64::*;
use std::mem::MaybeUninit;

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

/// Proof that this CPU runs AVX2 (and POPCNT, BMI1, BMI2 and LZCNT): made
/// only by [`Avx2::detect`].
#[derive(Clone, Copy, Debug)]
pub struct Avx2 {
    _proof: (),
}

impl Avx2 {
    /// The proof, where the CPU has AVX2 and the bit instructions every
    /// AVX2 CPU has beside it (a population count and a trailing-zero
    /// count in one instruction each, where x86-64's base set takes eight
    /// for the first, at every node visit).
    pub fn detect() -> Option<Self> {
        let bits = is_x86_feature_detected!("popcnt")
            && is_x86_feature_detected!("bmi1")
            && is_x86_feature_detected!("bmi2")
            && is_x86_feature_detected!("lzcnt");
        (is_x86_feature_detected!("avx2") && bits).then_some(Avx2 { _proof: () })
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
#[target_feature(enable = "avx2,popcnt,bmi1,bmi2,lzcnt")]
unsafe fn job_with_avx2<J: Job>(job: J) -> J::Output {
    job.run()
}

/// `f()`, with AVX2 enabled for the code of `f` inlined here.
///
/// # Safety
/// The CPU must have AVX2.
#[target_feature(enable = "avx2,popcnt,bmi1,bmi2,lzcnt")]
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
    // SAFETY: the caller guarantees AVX2.
    unsafe {
        let (hit, near) = node_slab(node, ray, limit);
        (_mm256_movemask_ps(hit) as u32 & node.valid, near)
    }
}

/// [`slab8`] of the ray against a node's eight boxes (valid or not).
///
/// # Safety
/// The CPU must have AVX2.
#[inline(always)]
unsafe fn node_slab(node: &WideNode, ray: &NodeRay, limit: f32) -> (__m256, __m256) {
    // SAFETY: the caller guarantees AVX2.
    unsafe {
        let (near, far) = node_entry_exit(node, ray);
        let hit = _mm256_and_ps(
            _mm256_cmp_ps::<_CMP_LE_OQ>(near, far),
            _mm256_cmp_ps::<_CMP_LE_OQ>(near, _mm256_set1_ps(limit)),
        );
        (hit, near)
    }
}

/// [`entry_exit8`] of the ray against a node's eight boxes.
///
/// # Safety
/// The CPU must have AVX2.
#[inline(always)]
unsafe fn node_entry_exit(node: &WideNode, ray: &NodeRay) -> (__m256, __m256) {
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
        entry_exit8(
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
        )
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
        let keys = lane_keys(mask, near);
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

/// Each lane's key (`wide::child_key`) where `mask` has its bit, else all
/// ones (after every key met).
///
/// # Safety
/// The CPU must have AVX2.
#[inline(always)]
unsafe fn lane_keys(mask: u32, near: __m256) -> __m256i {
    // SAFETY: the caller guarantees AVX2; register operations only.
    unsafe {
        _mm256_or_si256(
            entry_keys(near),
            _mm256_xor_si256(lane_mask(mask), _mm256_set1_epi32(-1)),
        )
    }
}

/// Each lane's key (`wide::child_key`) from its entry distance.
///
/// # Safety
/// The CPU must have AVX2.
#[inline(always)]
unsafe fn entry_keys(near: __m256) -> __m256i {
    // SAFETY: the caller guarantees AVX2; register operations only.
    unsafe {
        _mm256_or_si256(
            _mm256_and_si256(_mm256_castps_si256(near), _mm256_set1_epi32(!7)),
            _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7),
        )
    }
}

/// The least of eight keys, in every lane: three steps of a minimum with
/// a shuffled copy.
///
/// # Safety
/// The CPU must have AVX2.
#[inline(always)]
unsafe fn min_keys(keys: __m256i) -> __m256i {
    // SAFETY: the caller guarantees AVX2; register operations only.
    unsafe {
        let m = _mm256_min_epu32(keys, _mm256_shuffle_epi32::<0b10_11_00_01>(keys));
        let m = _mm256_min_epu32(m, _mm256_shuffle_epi32::<0b01_00_11_10>(m));
        _mm256_min_epu32(m, _mm256_permute4x64_epi64::<0b01_00_11_10>(m))
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

/// `super::slab` in eight lanes: all ones in the lanes whose box is met
/// before their limit, and the entry distances.
///
/// # Safety
/// The CPU must have AVX2.
#[inline(always)]
unsafe fn slab8(near: [__m256; 3], far: [__m256; 3], limit: __m256) -> (__m256, __m256) {
    // SAFETY: the caller guarantees AVX2; register operations only.
    unsafe {
        let (near, far) = entry_exit8(near, far);
        let hit = _mm256_and_ps(
            _mm256_cmp_ps::<_CMP_LE_OQ>(near, far),
            _mm256_cmp_ps::<_CMP_LE_OQ>(near, limit),
        );
        (hit, near)
    }
}

/// The entry and the exit distances (with the slack) of `super::slab`,
/// in eight lanes.
///
/// # Safety
/// The CPU must have AVX2.
#[inline(always)]
unsafe fn entry_exit8(near: [__m256; 3], far: [__m256; 3]) -> (__m256, __m256) {
    // SAFETY: the caller guarantees AVX2; register operations only.
    unsafe {
        let near = _mm256_max_ps(
            _mm256_max_ps(near[0], near[1]),
            _mm256_max_ps(near[2], _mm256_setzero_ps()),
        );
        let far = _mm256_mul_ps(
            _mm256_min_ps(_mm256_min_ps(far[0], far[1]), far[2]),
            _mm256_set1_ps(SLACK),
        );
        (near, far)
    }
}

/// [`slab8`]'s lanes as bits.
///
/// # Safety
/// The CPU must have AVX2.
#[inline(always)]
unsafe fn slab8_mask(near: [__m256; 3], far: [__m256; 3], limit: __m256) -> (u32, __m256) {
    // SAFETY: the caller guarantees AVX2; register operations only.
    unsafe {
        let (hit, near) = slab8(near, far, limit);
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
        let (mask, near) = slab8_mask(
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
        let (mask, _) = slab8_mask(
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

/// `wide::closest` for AVX2, its stack in rows (see [`closest_in_rows`]):
/// on the call stack where the tree's stack `need` (`wide::stack_need`)
/// allows, else on the heap.
#[inline]
pub fn closest(
    proof: Avx2,
    nodes: &[WideNode],
    need: usize,
    ray: &NodeRay,
    t_max: f64,
    test: impl ClosestTest,
) -> f64 {
    #[target_feature(enable = "avx2,popcnt,bmi1,bmi2,lzcnt")]
    fn run(
        _proof: Avx2,
        nodes: &[WideNode],
        rows: &mut [MaybeUninit<u32>],
        ray: &NodeRay,
        t_max: f64,
        test: impl ClosestTest,
    ) -> f64 {
        realign_frame();
        // SAFETY: AVX2 is enabled in this function.
        unsafe { closest_in_rows(nodes, StackRows::new(rows), ray, t_max, test) }
    }
    if need <= wide::STACK {
        // Left unwritten: entries are read only once pushed.
        let mut rows = [MaybeUninit::uninit(); 3 * (wide::STACK + WIDTH)];
        // SAFETY: `proof` exists only where `detect` found AVX2.
        unsafe { run(proof, nodes, &mut rows, ray, t_max, test) }
    } else {
        let mut rows = vec![MaybeUninit::uninit(); 3 * (need + WIDTH)];
        // SAFETY: as above.
        unsafe { run(proof, nodes, &mut rows, ray, t_max, test) }
    }
}

/// The closest-hit stack of [`closest_in_rows`]: entry distances (as
/// [`wide::key_entry`] keeps them), children and item counts in three
/// rows, so that a node visit pushes the children it met with three
/// vector stores. Each row has room for eight entries past any depth the
/// tree reaches, since the stores write eight.
struct StackRows<'a> {
    rows: &'a mut [MaybeUninit<u32>],
    /// Entries per row.
    len: usize,
}

impl<'a> StackRows<'a> {
    fn new(rows: &'a mut [MaybeUninit<u32>]) -> Self {
        let len = rows.len() / 3;
        StackRows { rows, len }
    }

    /// Writes eight entries from `at` (the stack keeps those its length
    /// covers).
    ///
    /// # Safety
    /// The CPU must have AVX2.
    #[inline(always)]
    unsafe fn store(&mut self, at: usize, entry: __m256i, index: __m256i, count: __m256i) {
        // Checked: a tree deeper than its measured need panics here
        // rather than writing past the rows.
        assert!(at + WIDTH <= self.len, "traversal stack overflow");
        let first = self.rows.as_mut_ptr().wrapping_add(at);
        // SAFETY: the caller guarantees AVX2; each store writes eight u32
        // inside its row (checked above).
        unsafe {
            _mm256_storeu_si256(first.cast(), entry);
            _mm256_storeu_si256(first.add(self.len).cast(), index);
            _mm256_storeu_si256(first.add(2 * self.len).cast(), count);
        }
    }

    /// Entry `at`, as (entry distance, child, count).
    ///
    /// # Safety
    /// Entry `at` must have been stored (so it lies inside the rows).
    #[inline(always)]
    unsafe fn get(&self, at: usize) -> (f32, usize, usize) {
        // SAFETY: the caller guarantees the entry was stored.
        unsafe {
            let row = |r: usize| self.rows.get_unchecked(r * self.len + at).assume_init();
            (f32::from_bits(row(0)), row(1) as usize, row(2) as usize)
        }
    }
}

/// `wide::closest` with a shorter wait between one node and the next. A
/// scattered ray's search is a chain of dependent steps (a node's planes
/// loaded and tested, the nearest child chosen, its index found, the next
/// node loaded), so each step taken off it is time saved at every visit:
/// the keys (`wide::child_key`) come straight from the test's lanes, the
/// nearest child from a minimum over them and a permute of the node's
/// children. The others are pushed without a branch per child or on how
/// many there are: the keys always sorted, reversed and stored far to
/// near, eight lanes at once, of which the stack keeps as many as were
/// met. The same nodes are visited and the same items tested, in the same
/// order, as `wide::closest` does. On the 3,674-triangle bunny's scattered
/// rays the query took 10 % less time (docs/performance.md, "Shorter waits
/// per node visit").
///
/// # Safety
/// The CPU must have AVX2.
#[inline(always)]
unsafe fn closest_in_rows(
    nodes: &[WideNode],
    mut stack: StackRows,
    ray: &NodeRay,
    mut t_max: f64,
    mut leaf: impl ClosestTest,
) -> f64 {
    if nodes.is_empty() {
        return t_max;
    }
    // SAFETY: the caller guarantees AVX2; the loads read a node's eight
    // children and eight counts; entries are read only below `top`, where
    // they were stored.
    unsafe {
        let lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
        let mut top = 0usize;
        let mut limit = NodeRay::box_limit(t_max);
        let mut current = 0usize;
        loop {
            let node = &nodes[current];
            // The keys straight from the test's lanes: the mask's round
            // trip through a general register, and a load of the nearest
            // child by its lane, would lie on the way to the next node.
            // A lane missed is one whose test fails (the exact complement,
            // NaN included), or an empty slot.
            let (near, far) = node_entry_exit(node, ray);
            let missed = _mm256_or_si256(
                _mm256_or_si256(
                    _mm256_castps_si256(_mm256_cmp_ps::<_CMP_NLE_UQ>(near, _mm256_set1_ps(limit))),
                    _mm256_xor_si256(lane_mask(node.valid), _mm256_set1_epi32(-1)),
                ),
                _mm256_castps_si256(_mm256_cmp_ps::<_CMP_NLE_UQ>(near, far)),
            );
            let mask = !(_mm256_movemask_ps(_mm256_castsi256_ps(missed)) as u32) & 0xff;
            if mask != 0 {
                let keys = _mm256_or_si256(entry_keys(near), missed);
                let children = _mm256_loadu_si256(node.child.as_ptr().cast());
                let counts = _mm256_cvtepu16_epi32(_mm_loadu_si128(node.count.as_ptr().cast()));
                let nearest = min_keys(keys);
                let child = _mm256_cvtsi256_si32(_mm256_permutevar8x32_epi32(children, nearest));
                let count = _mm256_cvtsi256_si32(_mm256_permutevar8x32_epi32(counts, nearest));
                let met = mask.count_ones() as usize;
                // Sorted keys met-1, met-2, ..., 1 in lanes 0, 1, ...:
                // far to near, so that they pop nearest first.
                let far_to_near = _mm256_permutevar8x32_epi32(
                    sort8(keys),
                    _mm256_sub_epi32(_mm256_set1_epi32(met as i32 - 1), lanes),
                );
                let slot = _mm256_and_si256(far_to_near, _mm256_set1_epi32(7));
                stack.store(
                    top,
                    _mm256_and_si256(far_to_near, _mm256_set1_epi32(!7)),
                    _mm256_permutevar8x32_epi32(children, slot),
                    _mm256_permutevar8x32_epi32(counts, slot),
                );
                top += met - 1;
                let (child, count) = (child as u32 as usize, count as usize);
                if count == 0 {
                    current = child;
                    continue;
                }
                wide::test_leaf(&mut leaf, child, count, &mut t_max, &mut limit);
            }
            // Pop until an interior node to visit; leaves are tested on
            // the way.
            loop {
                if top == 0 {
                    return t_max;
                }
                top -= 1;
                let (entry, index, count) = stack.get(top);
                if entry > limit {
                    continue;
                }
                if count == 0 {
                    current = index;
                    break;
                }
                wide::test_leaf(&mut leaf, index, count, &mut t_max, &mut limit);
            }
        }
    }
}

/// `wide::any` for AVX2 (see [`any_direct`]).
#[inline]
pub fn any(
    proof: Avx2,
    nodes: &[WideNode],
    ray: &NodeRay,
    t_max: f64,
    stack: &mut impl Stack<u32>,
    test: impl AnyTest,
) -> bool {
    #[target_feature(enable = "avx2,popcnt,bmi1,bmi2,lzcnt")]
    fn run(
        _proof: Avx2,
        nodes: &[WideNode],
        ray: &NodeRay,
        t_max: f64,
        stack: &mut impl Stack<u32>,
        test: impl AnyTest,
    ) -> bool {
        realign_frame();
        // SAFETY: AVX2 is enabled in this function.
        unsafe { any_direct(nodes, ray, t_max, stack, test) }
    }
    // SAFETY: `proof` exists only where `detect` found AVX2.
    unsafe { run(proof, nodes, ray, t_max, stack, test) }
}

/// `wide::any` with the next node found without the stack: of the
/// children a node visit meets, the leaves are tested in lane order, the
/// interior ones but the last pushed in lane order, and the last (the one
/// `wide::any` would pop next) visited at once. The same nodes are visited
/// and the same items tested, in the same order, as `wide::any` does; the
/// next node's address waits on a bit scan and one load instead of a loop
/// over the lanes, a push and a pop.
///
/// # Safety
/// The CPU must have AVX2.
#[inline(always)]
unsafe fn any_direct(
    nodes: &[WideNode],
    ray: &NodeRay,
    t_max: f64,
    stack: &mut impl Stack<u32>,
    mut leaf: impl AnyTest,
) -> bool {
    if nodes.is_empty() {
        return false;
    }
    // SAFETY: the caller guarantees AVX2; the load reads a node's eight
    // counts.
    unsafe {
        let limit = NodeRay::box_limit(t_max);
        let mut current = 0usize;
        loop {
            let node = &nodes[current];
            let (mask, _) = node_test(node, ray, limit);
            let counts = _mm256_cvtepu16_epi32(_mm_loadu_si128(node.count.as_ptr().cast()));
            let interior_lanes = _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpeq_epi32(
                counts,
                _mm256_setzero_si256(),
            ))) as u32;
            let interior = mask & interior_lanes;
            let mut leaves = mask & !interior_lanes;
            while leaves != 0 {
                let lane = leaves.trailing_zeros() as usize;
                leaves &= leaves - 1;
                let start = node.child[lane] as usize;
                if (start..start + usize::from(node.count[lane])).any(|p| leaf.test(p)) {
                    return true;
                }
            }
            if interior != 0 {
                let last = 31 - interior.leading_zeros();
                let mut rest = interior & !(1 << last);
                while rest != 0 {
                    let lane = rest.trailing_zeros() as usize;
                    rest &= rest - 1;
                    stack.push(node.child[lane]);
                }
                current = node.child[last as usize] as usize;
                continue;
            }
            match stack.pop() {
                Some(next) => current = next as usize,
                None => return false,
            }
        }
    }
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
    #[target_feature(enable = "avx2,popcnt,bmi1,bmi2,lzcnt")]
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
    #[target_feature(enable = "avx2,popcnt,bmi1,bmi2,lzcnt")]
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
    #[target_feature(enable = "avx2,popcnt,bmi1,bmi2,lzcnt")]
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
    #[target_feature(enable = "avx2,popcnt,bmi1,bmi2,lzcnt")]
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
    #[target_feature(enable = "avx2,popcnt,bmi1,bmi2,lzcnt")]
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
