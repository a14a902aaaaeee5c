//! Which instruction set tests a wide node's eight boxes, chosen once at
//! run time: AVX2 where the CPU has it (one 8-lane instruction per step),
//! else four-lane vectors (SSE2 on every x86-64, through glam; two per
//! step), or a plain scalar loop. `PRISM_SIMD=avx2|sse2|scalar` forces one,
//! so that tests and CI can compare their images byte for byte.
//!
//! Why the bits cannot change with the path: every path does the same f32
//! operations lane by lane (subtract, multiply, compare-and-select minima
//! and maxima; no fused multiply-add), so they agree on every box; and even
//! where they did not, a box test only decides what is tested and in which
//! order — the hit is decided by the exact f64 test and the (t, index)
//! tie-break, and every box test is conservative.

#[cfg(target_arch = "x86_64")]
mod avx2;

use std::sync::OnceLock;

use glam::{DVec3, Vec4};

use super::packet::{self, PacketAnyTest, PacketClosestTest, PacketEntry};
use super::wide::{self, AnyTest, ClosestTest, MAX_X, MIN_X, Stack, StackEntry, WIDTH, WideNode};

/// An instruction set for the wide node test.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SimdPath {
    /// 8 lanes of AVX2.
    Avx2,
    /// Two 4-lane halves (SSE2 on x86-64, NEON on ARM, scalar with the
    /// `scalar-math` feature).
    Sse2,
    /// One lane at a time.
    Scalar,
}

impl SimdPath {
    /// Every path, widest first.
    pub const ALL: [SimdPath; 3] = [SimdPath::Avx2, SimdPath::Sse2, SimdPath::Scalar];

    /// The name `PRISM_SIMD` takes.
    pub fn name(self) -> &'static str {
        match self {
            SimdPath::Avx2 => "avx2",
            SimdPath::Sse2 => "sse2",
            SimdPath::Scalar => "scalar",
        }
    }

    /// The kernel of the path, if this CPU can run it.
    pub(crate) fn kernel(self) -> Option<Kernel> {
        match self {
            #[cfg(target_arch = "x86_64")]
            SimdPath::Avx2 => avx2::Avx2::detect().map(Kernel::Avx2),
            #[cfg(not(target_arch = "x86_64"))]
            SimdPath::Avx2 => None,
            SimdPath::Sse2 => Some(Kernel::Sse2),
            SimdPath::Scalar => Some(Kernel::Scalar),
        }
    }
}

/// The path traversals use: `PRISM_SIMD` when it names one this CPU can
/// run, else the widest available.
pub fn simd_path() -> SimdPath {
    kernel().path()
}

/// The kernel every traversal uses, chosen once per process.
#[inline]
pub(crate) fn kernel() -> Kernel {
    static KERNEL: OnceLock<Kernel> = OnceLock::new();
    *KERNEL.get_or_init(|| {
        let forced = std::env::var("PRISM_SIMD").ok();
        SimdPath::ALL
            .iter()
            .find(|p| forced.as_deref() == Some(p.name()))
            .and_then(|p| p.kernel())
            .or_else(|| SimdPath::ALL.iter().find_map(|p| p.kernel()))
            .unwrap_or(Kernel::Scalar)
    })
}

/// A path ready to run: holding an AVX2 kernel proves the CPU has AVX2.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Kernel {
    #[cfg(target_arch = "x86_64")]
    Avx2(avx2::Avx2),
    Sse2,
    Scalar,
}

impl Kernel {
    fn path(self) -> SimdPath {
        match self {
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx2(_) => SimdPath::Avx2,
            Kernel::Sse2 => SimdPath::Sse2,
            Kernel::Scalar => SimdPath::Scalar,
        }
    }

    /// Runs `f`, on the AVX2 path compiled for AVX2, so that its loops
    /// over batches become 256-bit vector code rather than baseline SSE2.
    /// A vector operation is the scalar one lane by lane (and FMA stays
    /// off), so `f` computes the same bits on every path.
    #[inline]
    pub(crate) fn vectorize<R>(self, f: impl FnOnce() -> R) -> R {
        match self {
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx2(k) => k.vectorize(f),
            Kernel::Sse2 | Kernel::Scalar => f(),
        }
    }

    /// Runs `job` as [`vectorize`](Self::vectorize) runs a closure, with
    /// its body certain to be compiled into the AVX2 function: a closure's
    /// body is inlined there only while it stays small enough, and one that
    /// grew (a callee inlined into it) silently fell back to baseline SSE2
    /// (`bench/mesh-soft.toml` 12 % slower).
    #[inline]
    pub(crate) fn vectorize_job<J: Job>(self, job: J) -> J::Output {
        match self {
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx2(k) => k.vectorize_job(job),
            Kernel::Sse2 | Kernel::Scalar => job.run(),
        }
    }

    /// Closest-hit traversal (see `wide::closest`) on this kernel, of a
    /// tree whose traversal stack needs `need` entries at most
    /// (`wide::stack_need`).
    #[inline]
    pub(crate) fn closest(
        self,
        nodes: &[WideNode],
        need: usize,
        ray: &NodeRay,
        t_max: f64,
        test: impl ClosestTest,
    ) -> f64 {
        match self {
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx2(k) => avx2::closest(k, nodes, need, ray, t_max, test),
            Kernel::Sse2 => wide::closest_sized(Sse2, nodes, need, ray, t_max, test),
            Kernel::Scalar => wide::closest_sized(Scalar, nodes, need, ray, t_max, test),
        }
    }

    /// Closest-hit traversal of up to K rays in turns (see
    /// `wide::closest_stream`) on this kernel.
    #[inline]
    pub(crate) fn closest_stream<T: ClosestTest, const K: usize>(
        self,
        nodes: &[WideNode],
        rays: &[NodeRay; K],
        count: usize,
        t_max: &mut [f64; K],
        stacks: &mut [impl Stack<StackEntry>; K],
        tests: &mut [T; K],
    ) {
        match self {
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx2(k) => avx2::closest_stream(k, nodes, rays, count, t_max, stacks, tests),
            Kernel::Sse2 => wide::closest_stream(Sse2, nodes, rays, count, t_max, stacks, tests),
            Kernel::Scalar => {
                wide::closest_stream(Scalar, nodes, rays, count, t_max, stacks, tests)
            }
        }
    }

    /// Any-hit traversal of up to K rays in turns (see `wide::any_stream`)
    /// on this kernel: the mask of the rays blocked.
    #[inline]
    pub(crate) fn any_stream<T: AnyTest, const K: usize>(
        self,
        nodes: &[WideNode],
        rays: &[NodeRay; K],
        count: usize,
        t_max: &[f64; K],
        stacks: &mut [impl Stack<StackEntry>; K],
        tests: &mut [T; K],
    ) -> u32 {
        match self {
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx2(k) => avx2::any_stream(k, nodes, rays, count, t_max, stacks, tests),
            Kernel::Sse2 => wide::any_stream(Sse2, nodes, rays, count, t_max, stacks, tests),
            Kernel::Scalar => wide::any_stream(Scalar, nodes, rays, count, t_max, stacks, tests),
        }
    }

    /// Any-hit traversal (see `wide::any`) on this kernel.
    #[inline]
    pub(crate) fn any(
        self,
        nodes: &[WideNode],
        ray: &NodeRay,
        t_max: f64,
        stack: &mut impl Stack<u32>,
        test: impl AnyTest,
    ) -> bool {
        match self {
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx2(k) => avx2::any(k, nodes, ray, t_max, stack, test),
            Kernel::Sse2 => wide::any(Sse2, nodes, ray, t_max, stack, test),
            Kernel::Scalar => wide::any(Scalar, nodes, ray, t_max, stack, test),
        }
    }
}

impl Kernel {
    /// Closest-hit traversal of a packet (see `packet::closest`).
    #[inline]
    pub(crate) fn closest_packet(
        self,
        nodes: &[WideNode],
        rays: &NodePacket,
        t_max: &mut [f64; PACKET],
        stack: &mut impl Stack<PacketEntry>,
        test: impl PacketClosestTest,
    ) {
        match self {
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx2(k) => avx2::closest_packet(k, nodes, rays, t_max, stack, test),
            Kernel::Sse2 => packet::closest(Sse2, nodes, rays, t_max, stack, test),
            Kernel::Scalar => packet::closest(Scalar, nodes, rays, t_max, stack, test),
        }
    }

    /// Whether the rays of a span may reach a leaf (see
    /// `packet::span_reaches_leaf`) on this kernel.
    #[inline]
    pub(crate) fn span_reaches_leaf(
        self,
        nodes: &[WideNode],
        span: &NodePacket,
        limit: f32,
        budget: usize,
    ) -> bool {
        match self {
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx2(k) => avx2::span_reaches_leaf(k, nodes, span, limit, budget),
            Kernel::Sse2 => packet::span_reaches_leaf(Sse2, nodes, span, limit, budget),
            Kernel::Scalar => packet::span_reaches_leaf(Scalar, nodes, span, limit, budget),
        }
    }

    /// Any-hit traversal of a packet (see `packet::any`): the blocked rays.
    #[inline]
    pub(crate) fn any_packet(
        self,
        nodes: &[WideNode],
        rays: &NodePacket,
        t_max: &[f64; PACKET],
        stack: &mut impl Stack<(u32, u32)>,
        test: impl PacketAnyTest,
    ) -> u32 {
        match self {
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx2(k) => avx2::any_packet(k, nodes, rays, t_max, stack, test),
            Kernel::Sse2 => packet::any(Sse2, nodes, rays, t_max, stack, test),
            Kernel::Scalar => packet::any(Scalar, nodes, rays, t_max, stack, test),
        }
    }
}

/// Asks the cache for the line holding `value`: a hint only, which cannot
/// change a result (nothing where the CPU has no such instruction).
#[inline(always)]
pub(crate) fn prefetch<T>(value: &T) {
    #[cfg(target_arch = "x86_64")]
    avx2::prefetch_line(value);
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}

/// Work for [`Kernel::vectorize_job`]: a trait rather than a closure, so
/// that an implementation can insist (`#[inline(always)]` on `run`) on
/// being compiled into its caller.
pub(crate) trait Job {
    /// What the work gives.
    type Output;
    /// Does the work.
    fn run(self) -> Self::Output;
}

/// A ray prepared for wide node tests, in f32.
#[derive(Clone, Copy, Debug)]
pub struct NodeRay {
    origin: [f32; 3],
    inv_dir: [f32; 3],
    /// Per axis, the plane row (of `WideNode::planes`) the ray enters
    /// through: the minimum for a positive direction, else the maximum.
    near_row: [usize; 3],
    /// The plane row it leaves through.
    far_row: [usize; 3],
}

/// Slack on the exit distance and on t_max: a few f32 roundings of the
/// distances (the box padding covers the roundings of its corners and of
/// the origin's coordinates).
const SLACK: f32 = 1.0 + 8.0 * f32::EPSILON;

impl NodeRay {
    /// Prepares `origin + t·direction`.
    #[inline]
    pub fn new(origin: DVec3, direction: DVec3) -> Self {
        let inv_dir = direction.to_array().map(inverse);
        let near_row = [
            near_row(inv_dir[0], 0),
            near_row(inv_dir[1], 1),
            near_row(inv_dir[2], 2),
        ];
        NodeRay {
            origin: origin.as_vec3().to_array(),
            inv_dir,
            near_row,
            far_row: near_row.map(|r| (r + 3) % 6),
        }
    }

    /// The f32 bound boxes are culled against for hits before `t_max`:
    /// rounded up, with the same slack as the exit distance.
    #[inline]
    pub fn box_limit(t_max: f64) -> f32 {
        let f = t_max as f32;
        let up = if f64::from(f) < t_max { f.next_up() } else { f };
        up * SLACK
    }
}

/// Rays in a packet: one per lane of the per-ray box test.
pub const PACKET: usize = 8;

/// Up to [`PACKET`] rays prepared for wide node tests together: per axis,
/// the interval of their f32 origins and inverse directions (one test of a
/// node's eight boxes then answers for the whole packet), and the rays one
/// by one, lane k holding ray k (one test of a single box then answers for
/// each ray).
#[derive(Clone, Copy, Debug)]
pub struct NodePacket {
    origin_lo: [f32; 3],
    origin_hi: [f32; 3],
    inv_lo: [f32; 3],
    inv_hi: [f32; 3],
    /// Shared by every ray of the packet.
    near_row: [usize; 3],
    far_row: [usize; 3],
    /// `origin[axis][k]` of ray k; lanes past the last ray repeat ray 0.
    origin: [[f32; PACKET]; 3],
    inv_dir: [[f32; PACKET]; 3],
    /// Bit k set when lane k holds a ray.
    present: u32,
}

impl NodePacket {
    /// The packet of `rays` (origin, direction), or `None` when they
    /// cannot share one: none or more than [`PACKET`] rays, rays entering
    /// boxes through different planes on some axis (directions of unlike
    /// sign), or values that could make an interval product NaN (an origin
    /// beyond 10³⁰, an inverse direction of 0). Each ray's lane holds what
    /// [`NodeRay::new`] makes of it.
    #[inline(always)]
    pub fn new(rays: &[(DVec3, DVec3)]) -> Option<Self> {
        let &(first_origin, first_direction) = rays.first()?;
        if rays.len() > PACKET {
            return None;
        }
        // Lanes past the last ray repeat ray 0, which changes no interval.
        let mut o64 = [[0.0; PACKET]; 3];
        let mut d64 = [[0.0; PACKET]; 3];
        for k in 0..PACKET {
            let (o, d) = if k < rays.len() {
                rays[k]
            } else {
                (first_origin, first_direction)
            };
            for (axis, (o, d)) in o.to_array().into_iter().zip(d.to_array()).enumerate() {
                o64[axis][k] = o;
                d64[axis][k] = d;
            }
        }
        // Loops rather than `map`, which stays a call and is not vectorised.
        let mut origin = [[0.0; PACKET]; 3];
        let mut inv_dir = [[0.0; PACKET]; 3];
        for axis in 0..3 {
            for k in 0..PACKET {
                origin[axis][k] = o64[axis][k] as f32;
                inv_dir[axis][k] = inverse(d64[axis][k]);
            }
        }
        let near_row = [
            near_row(inv_dir[0][0], 0),
            near_row(inv_dir[1][0], 1),
            near_row(inv_dir[2][0], 2),
        ];
        let mut fits = true;
        for axis in 0..3 {
            let positive = inv_dir[axis][0] >= 0.0;
            for k in 0..PACKET {
                let i = inv_dir[axis][k];
                fits &= ((i >= 0.0) == positive)
                    & (origin[axis][k].abs() < 1e30)
                    & (i.abs() > 0.0)
                    & (i.abs() <= f32::MAX);
            }
        }
        if !fits {
            return None;
        }
        let (mut origin_lo, mut origin_hi) = ([0.0; 3], [0.0; 3]);
        let (mut inv_lo, mut inv_hi) = ([0.0; 3], [0.0; 3]);
        for axis in 0..3 {
            let (o, i) = (&origin[axis], &inv_dir[axis]);
            (origin_lo[axis], origin_hi[axis]) = (o[0], o[0]);
            (inv_lo[axis], inv_hi[axis]) = (i[0], i[0]);
            for k in 1..PACKET {
                origin_lo[axis] = min(origin_lo[axis], o[k]);
                origin_hi[axis] = max(origin_hi[axis], o[k]);
                inv_lo[axis] = min(inv_lo[axis], i[k]);
                inv_hi[axis] = max(inv_hi[axis], i[k]);
            }
        }
        Some(NodePacket {
            origin_lo,
            origin_hi,
            inv_lo,
            inv_hi,
            near_row,
            far_row: [0, 1, 2].map(|a| (near_row[a] + 3) % 6),
            origin,
            inv_dir,
            present: (1 << rays.len()) - 1,
        })
    }

    /// A packet for the node test alone (`packet_entries`) that stands for
    /// every ray whose origin lies in `origin_lo..=origin_hi` and direction
    /// in `direction_lo..=direction_hi`, axis by axis (any number of
    /// rays). Each such ray's f32 origin and inverse direction, as
    /// [`NodeRay::new`] makes them, lie in its intervals: `as f32` is
    /// monotone, and so is 1/d rounded to f32 on each side of zero while
    /// |d| stays within [10⁻³⁰, 10³⁰] (no ±∞ replaced, no zero). `None`
    /// where a direction component changes sign or leaves that range, or
    /// an origin is beyond 10³⁰. Its lanes hold no rays (`present` is 0):
    /// it is not for `ray_mask`, `ray` or a traversal.
    pub fn spanning(
        origin_lo: DVec3,
        origin_hi: DVec3,
        direction_lo: DVec3,
        direction_hi: DVec3,
    ) -> Option<Self> {
        let mut origin_bounds = ([0.0f32; 3], [0.0f32; 3]);
        let mut inv_bounds = ([0.0f32; 3], [0.0f32; 3]);
        let mut near_row = [0; 3];
        for axis in 0..3 {
            let (lo, hi) = (direction_lo[axis], direction_hi[axis]);
            let magnitudes = 1e-30..=1e30;
            let one_sign = (lo > 0.0 || hi < 0.0) && lo <= hi;
            if !(one_sign
                && magnitudes.contains(&lo.abs())
                && magnitudes.contains(&hi.abs())
                && origin_lo[axis].abs() < 1e30
                && origin_hi[axis].abs() < 1e30)
            {
                return None;
            }
            // 1/d falls as d grows on either side of zero.
            inv_bounds.0[axis] = inverse(hi);
            inv_bounds.1[axis] = inverse(lo);
            origin_bounds.0[axis] = origin_lo[axis] as f32;
            origin_bounds.1[axis] = origin_hi[axis] as f32;
            near_row[axis] = self::near_row(inv_bounds.0[axis], axis);
        }
        Some(NodePacket {
            origin_lo: origin_bounds.0,
            origin_hi: origin_bounds.1,
            inv_lo: inv_bounds.0,
            inv_hi: inv_bounds.1,
            near_row,
            far_row: [0, 1, 2].map(|a| (near_row[a] + 3) % 6),
            origin: [[0.0; PACKET]; 3],
            inv_dir: [[0.0; PACKET]; 3],
            present: 0,
        })
    }

    /// Bit k set when lane k holds a ray.
    pub fn present(&self) -> u32 {
        self.present
    }

    /// Whether every ray starts at the same point.
    #[inline(always)]
    pub fn shares_origin(&self) -> bool {
        self.origin_lo == self.origin_hi
    }

    /// Ray `k` alone, as [`NodeRay::new`] makes it.
    #[inline(always)]
    pub fn ray(&self, k: usize) -> NodeRay {
        NodeRay {
            origin: [self.origin[0][k], self.origin[1][k], self.origin[2][k]],
            inv_dir: [self.inv_dir[0][k], self.inv_dir[1][k], self.inv_dir[2][k]],
            near_row: self.near_row,
            far_row: self.far_row,
        }
    }
}

/// The packet test of one node, one lane at a time: the reference the
/// vector forms match. Per box, a lower bound of every ray's entry and an
/// upper bound of every ray's exit, by interval arithmetic: a ray's
/// distance to a plane, fl(fl(plane − o)·inv), is bilinear in o and inv
/// before rounding, so it is bounded by the products at the interval's
/// corners, and rounding is monotone. So a box a ray's own test lets
/// through (with its limit, at most `limit`) is let through here too.
#[inline(always)]
pub(crate) fn packet_entries_scalar(
    node: &WideNode,
    p: &NodePacket,
    limit: f32,
) -> (u32, [f32; WIDTH]) {
    let mut near = [0.0; WIDTH];
    let mut mask = 0;
    for (lane, near) in near.iter_mut().enumerate() {
        let products = |row: usize, axis: usize| {
            let plane = node.planes[row][lane];
            let (x0, x1) = (plane - p.origin_hi[axis], plane - p.origin_lo[axis]);
            let (i0, i1) = (p.inv_lo[axis], p.inv_hi[axis]);
            [x0 * i0, x0 * i1, x1 * i0, x1 * i1]
        };
        let lo = |row: usize, axis: usize| {
            let [a, b, c, d] = products(row, axis);
            min(min(a, b), min(c, d))
        };
        let hi = |row: usize, axis: usize| {
            let [a, b, c, d] = products(row, axis);
            max(max(a, b), max(c, d))
        };
        let (hit, n) = slab_rows(p.near_row, p.far_row, lo, hi, limit);
        mask |= u32::from(hit) << lane;
        *near = n;
    }
    (mask & node.valid, near)
}

/// Which rays of the packet meet slot `slot` of `node` before their own
/// limit: for each ray, exactly [`Scalar`]'s test of that box.
#[inline(always)]
pub(crate) fn ray_mask_scalar(
    node: &WideNode,
    slot: usize,
    p: &NodePacket,
    limits: &[f32; PACKET],
) -> u32 {
    let mut mask = 0;
    for (k, &limit) in limits.iter().enumerate() {
        let t = |row: usize, axis: usize| {
            (node.planes[row][slot] - p.origin[axis][k]) * p.inv_dir[axis][k]
        };
        let (hit, _) = slab_rows(p.near_row, p.far_row, t, t, limit);
        mask |= u32::from(hit) << k;
    }
    mask & p.present
}

/// 1/d in f32, as node tests use it. A zero component would give
/// 0·∞ = NaN on a slab through the origin; a huge finite value of the same
/// sign gives the right answer (0 at the slab, ±∞ beyond it) in f32.
#[inline(always)]
fn inverse(d: f64) -> f32 {
    let i = (1.0 / d) as f32;
    if i.is_finite() {
        i
    } else {
        1e30f32.copysign(d as f32)
    }
}

/// The plane row of axis `axis` a ray with inverse direction `inv`
/// enters boxes through: the minimum for a positive direction, else the
/// maximum.
#[inline(always)]
fn near_row(inv: f32, axis: usize) -> usize {
    if inv >= 0.0 {
        MIN_X + axis
    } else {
        MAX_X + axis
    }
}

/// One way of computing a node's eight entry distances: a lane mask of the
/// boxes the ray meets before `limit`, and the distances. Every
/// implementation computes, lane by lane, exactly [`Scalar`]'s operations.
pub(crate) trait Lanes: Copy {
    fn entries(self, node: &WideNode, ray: &NodeRay, limit: f32) -> (u32, [f32; WIDTH]);

    /// The node test's children met in order: how many, and their keys
    /// (`wide::child_key`) nearest first (past that many: unspecified).
    #[inline(always)]
    fn ordered_entries(self, node: &WideNode, ray: &NodeRay, limit: f32) -> (usize, [u32; WIDTH]) {
        let (mask, near) = self.entries(node, ray, limit);
        self.order(mask, &near)
    }

    /// The lanes of `mask`, of entry distances `near` (non-negative), in
    /// order: how many, and their keys (`wide::child_key`) nearest first.
    #[inline(always)]
    fn order(self, mask: u32, near: &[f32; WIDTH]) -> (usize, [u32; WIDTH]) {
        let mut keys = [u32::MAX; WIDTH];
        let mut met = 0;
        let mut scan = mask;
        while scan != 0 {
            let lane = scan.trailing_zeros() as usize;
            scan &= scan - 1;
            keys[met] = wide::child_key(near[lane], lane);
            met += 1;
        }
        keys[..met].sort_unstable();
        (met, keys)
    }

    /// Asks the cache for a node that will be visited later (a hint only).
    #[inline(always)]
    fn prefetch(self, _node: &WideNode) {}

    /// The packet's test of a node: a lane mask of the boxes some ray of
    /// `packet` may meet before `limit`, and a lower bound of their entry
    /// distances (see [`packet_entries_scalar`], which every form matches).
    #[inline(always)]
    fn packet_entries(
        self,
        node: &WideNode,
        packet: &NodePacket,
        limit: f32,
    ) -> (u32, [f32; WIDTH]) {
        packet_entries_scalar(node, packet, limit)
    }

    /// The greatest of `values` in the lanes of `mask` (−∞ for none): a
    /// packet's limit over its present rays. Forms may differ only in the
    /// sign of a zero, which no comparison of the limit tells apart.
    #[inline(always)]
    fn masked_max(self, values: &[f32; PACKET], mask: u32) -> f32 {
        let mut greatest = f32::NEG_INFINITY;
        for (k, &v) in values.iter().enumerate() {
            if mask & (1 << k) != 0 && v > greatest {
                greatest = v;
            }
        }
        greatest
    }

    /// The rays of `packet` whose own test lets slot `slot` of `node`
    /// through (see [`ray_mask_scalar`], which every form matches).
    #[inline(always)]
    fn ray_mask(
        self,
        node: &WideNode,
        slot: usize,
        packet: &NodePacket,
        limits: &[f32; PACKET],
    ) -> u32 {
        ray_mask_scalar(node, slot, packet, limits)
    }
}

/// `a > b ? a : b` and `a < b ? a : b`: the SSE and AVX max and min, to the
/// bit (f32::max may differ on ±0).
#[inline(always)]
fn max(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}
#[inline(always)]
fn min(a: f32, b: f32) -> f32 {
    if a < b { a } else { b }
}

/// The slab test of one box from its distances to the planes a ray enters
/// (`near`, by axis) and leaves (`far`) through: whether the ray meets it
/// before `limit`, and where it enters (0 for an origin inside). Every
/// node test, scalar or vector, ends in these operations in this order
/// (AVX2's closest-hit search in their exact complements: which lanes
/// fail, NaN included).
#[inline(always)]
fn slab(near: [f32; 3], far: [f32; 3], limit: f32) -> (bool, f32) {
    // Paired so that the vector forms wait on fewer steps in a row (the
    // next node's address waits on them).
    let n = max(max(near[0], near[1]), max(near[2], 0.0));
    let f = min(min(far[0], far[1]), far[2]) * SLACK;
    ((n <= f) & (n <= limit), n)
}

/// [`slab`] of a box whose distance to the plane of row `row` on axis
/// `axis` is `near(row, axis)` for the rows a ray enters through
/// (`near_row`, by axis) and `far(row, axis)` for those it leaves through
/// (`far_row`): the scalar node tests, per ray and per packet.
#[inline(always)]
fn slab_rows(
    near_row: [usize; 3],
    far_row: [usize; 3],
    near: impl Fn(usize, usize) -> f32,
    far: impl Fn(usize, usize) -> f32,
    limit: f32,
) -> (bool, f32) {
    slab(
        [
            near(near_row[0], 0),
            near(near_row[1], 1),
            near(near_row[2], 2),
        ],
        [far(far_row[0], 0), far(far_row[1], 1), far(far_row[2], 2)],
        limit,
    )
}

/// One lane at a time: the reference the others match.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Scalar;

impl Lanes for Scalar {
    #[inline(always)]
    fn entries(self, node: &WideNode, ray: &NodeRay, limit: f32) -> (u32, [f32; WIDTH]) {
        let mut near = [0.0; WIDTH];
        let mut mask = 0;
        for (lane, near) in near.iter_mut().enumerate() {
            let t = |row: usize, axis: usize| {
                (node.planes[row][lane] - ray.origin[axis]) * ray.inv_dir[axis]
            };
            let (hit, n) = slab_rows(ray.near_row, ray.far_row, t, t, limit);
            mask |= u32::from(hit) << lane;
            *near = n;
        }
        (mask & node.valid, near)
    }
}

/// Two halves of four lanes.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Sse2;

impl Lanes for Sse2 {
    #[inline(always)]
    fn entries(self, node: &WideNode, ray: &NodeRay, limit: f32) -> (u32, [f32; WIDTH]) {
        let half = |h: usize| {
            let t = |row: usize, axis: usize| {
                let plane = Vec4::from_slice(&node.planes[row][4 * h..4 * h + 4]);
                (plane - Vec4::splat(ray.origin[axis])) * Vec4::splat(ray.inv_dir[axis])
            };
            let n = t(ray.near_row[0], 0)
                .max(t(ray.near_row[1], 1))
                .max(t(ray.near_row[2], 2).max(Vec4::ZERO));
            let f = t(ray.far_row[0], 0)
                .min(t(ray.far_row[1], 1))
                .min(t(ray.far_row[2], 2))
                * SLACK;
            ((n.cmple(f) & n.cmple(Vec4::splat(limit))).bitmask(), n)
        };
        let (lo_mask, lo) = half(0);
        let (hi_mask, hi) = half(1);
        let mut near = [0.0; WIDTH];
        lo.write_to_slice(&mut near[..4]);
        hi.write_to_slice(&mut near[4..]);
        ((lo_mask | hi_mask << 4) & node.valid, near)
    }
}
