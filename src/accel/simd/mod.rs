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

    /// Closest-hit traversal (see `wide::closest`) on this kernel.
    #[inline]
    pub(crate) fn closest(
        self,
        nodes: &[WideNode],
        ray: &NodeRay,
        t_max: f64,
        stack: &mut impl Stack<StackEntry>,
        test: impl ClosestTest,
    ) -> f64 {
        match self {
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx2(k) => avx2::closest(k, nodes, ray, t_max, stack, test),
            Kernel::Sse2 => wide::closest(Sse2, nodes, ray, t_max, stack, test),
            Kernel::Scalar => wide::closest(Scalar, nodes, ray, t_max, stack, test),
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
        // A zero component would give 0·∞ = NaN on a slab through the
        // origin; a huge finite value of the same sign gives the right
        // answer (0 at the slab, ±∞ beyond it) in f32.
        let inv = |d: f64| {
            let i = (1.0 / d) as f32;
            if i.is_finite() {
                i
            } else {
                1e30f32.copysign(d as f32)
            }
        };
        let inv_dir = direction.to_array().map(inv);
        let near_row = [0, 1, 2].map(|a| {
            if inv_dir[a] >= 0.0 {
                MIN_X + a
            } else {
                MAX_X + a
            }
        });
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

/// One way of computing a node's eight entry distances: a lane mask of the
/// boxes the ray meets before `limit`, and the distances. Every
/// implementation computes, lane by lane, exactly [`Scalar`]'s operations.
pub(crate) trait Lanes: Copy {
    fn entries(self, node: &WideNode, ray: &NodeRay, limit: f32) -> (u32, [f32; WIDTH]);

    /// Asks the cache for a node that will be visited later (a hint only).
    #[inline(always)]
    fn prefetch(self, _node: &WideNode) {}
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
            let n = max(
                max(
                    max(t(ray.near_row[0], 0), t(ray.near_row[1], 1)),
                    t(ray.near_row[2], 2),
                ),
                0.0,
            );
            let f = min(
                min(t(ray.far_row[0], 0), t(ray.far_row[1], 1)),
                t(ray.far_row[2], 2),
            ) * SLACK;
            mask |= u32::from(n <= min(f, limit)) << lane;
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
                .max(t(ray.near_row[2], 2))
                .max(Vec4::ZERO);
            let f = t(ray.far_row[0], 0)
                .min(t(ray.far_row[1], 1))
                .min(t(ray.far_row[2], 2))
                * SLACK;
            (n.cmple(f.min(Vec4::splat(limit))).bitmask(), n)
        };
        let (lo_mask, lo) = half(0);
        let (hi_mask, hi) = half(1);
        let mut near = [0.0; WIDTH];
        lo.write_to_slice(&mut near[..4]);
        hi.write_to_slice(&mut near[4..]);
        ((lo_mask | hi_mask << 4) & node.valid, near)
    }
}
