//! Bounding volume hierarchy: binned SAH build (parallel for large inputs)
//! into a flat depth-first node array, ordered closest-hit traversal and
//! early-exit any-hit traversal. Generic over what the leaves hold: the
//! caller supplies the leaf test.

use arrayvec::ArrayVec;
use glam::{DVec3, Vec3};

use super::packet::{PacketAnyTest, PacketClosestTest};
use super::simd::{self, Kernel, NodePacket, NodeRay, PACKET};
use super::wide::{self, WideNode};
pub use super::wide::{AnyTest, ClosestTest, Fetch};
use crate::geometry::Aabb;

/// Items per leaf at most; fewer if the SAH says a split pays.
const MAX_LEAF: usize = 4;
/// Bins along the split axis.
const BINS: usize = 16;
/// Cost of visiting a node relative to one primitive test.
const TRAVERSAL_COST: f64 = 1.0;
/// Depth past which the build splits at the median instead of by SAH.
const MEDIAN_DEPTH: usize = 48;
/// Subtrees with more items than this are built on separate threads.
const PARALLEL_THRESHOLD: usize = 16 * 1024;

/// One node of the flattened tree, 32 bytes: two nodes per cache line.
/// Interior: children at `index + 1` and `offset`; leaf: items
/// `offset .. offset + count` of the item order. The box is stored in f32,
/// rounded outwards, so it always contains the exact f64 box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BvhNode {
    min: [f32; 3],
    max: [f32; 3],
    offset: u32,
    count: u16,
    axis: u8,
}

impl BvhNode {
    /// Fills room not yet written.
    const UNSET: BvhNode = BvhNode {
        min: [0.0; 3],
        max: [0.0; 3],
        offset: 0,
        count: 0,
        axis: 0,
    };

    fn new(bounds: &Aabb, offset: u32, count: u16, axis: u8) -> Self {
        // Round outwards by a relative margin well above f32 rounding of
        // both the box and the ray origin, so no hit is ever culled.
        let pad = (bounds.max - bounds.min).abs().max_element() * 1e-6;
        let lo = |v: f64| {
            let f = (v - pad - v.abs() * 1e-6) as f32;
            if (f as f64) > v { f.next_down() } else { f }
        };
        let hi = |v: f64| {
            let f = (v + pad + v.abs() * 1e-6) as f32;
            if (f as f64) < v { f.next_up() } else { f }
        };
        BvhNode {
            min: bounds.min.to_array().map(lo),
            max: bounds.max.to_array().map(hi),
            offset,
            count,
            axis,
        }
    }

    /// Leaf: first item position; interior: index of the second child.
    pub(crate) fn offset(&self) -> u32 {
        self.offset
    }

    /// Leaf: number of items; interior: 0.
    pub(crate) fn count(&self) -> u16 {
        self.count
    }

    /// The stored f32 box as (min, max).
    pub(crate) fn raw_bounds(&self) -> ([f32; 3], [f32; 3]) {
        (self.min, self.max)
    }

    /// The stored (outward-rounded) box.
    pub fn bounds(&self) -> Aabb {
        Aabb {
            min: DVec3::from_array(self.min.map(f64::from)),
            max: DVec3::from_array(self.max.map(f64::from)),
        }
    }
}

/// A BVH over items numbered 0..n.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Bvh {
    /// The binary tree as built, collapsed to 8-wide nodes.
    wide: Vec<WideNode>,
    /// Traversal stack entries the wide tree can need.
    stack_need: usize,
    /// Exact bounds of everything.
    bounds: Aabb,
    /// Item numbers in leaf order.
    order: Vec<u32>,
}

/// One item while the tree is built: 28 bytes, its box in f32 rounded
/// outwards (half the size of an f64 box, at the build's peak). The SAH
/// decides on these boxes; each node box is their union, so it still
/// contains the exact boxes below it.
struct BuildItem {
    min: Vec3,
    max: Vec3,
    index: u32,
}

impl BuildItem {
    fn new(bounds: &Aabb, index: u32) -> Self {
        let down = |v: f64| {
            let f = v as f32;
            if f64::from(f) > v { f.next_down() } else { f }
        };
        let up = |v: f64| {
            let f = v as f32;
            if f64::from(f) < v { f.next_up() } else { f }
        };
        BuildItem {
            min: Vec3::from_array(bounds.min.to_array().map(down)),
            max: Vec3::from_array(bounds.max.to_array().map(up)),
            index,
        }
    }

    #[inline]
    fn bounds(&self) -> Aabb {
        Aabb {
            min: self.min.as_dvec3(),
            max: self.max.as_dvec3(),
        }
    }

    #[inline]
    fn centroid(&self) -> DVec3 {
        (self.min.as_dvec3() + self.max.as_dvec3()) * 0.5
    }
}

impl Bvh {
    /// Builds a tree over items with the given bounds (item i is the i-th
    /// box). Takes an iterator so that callers need not hold a copy of the
    /// boxes besides the builder's own.
    pub fn build(bounds: impl IntoIterator<Item = Aabb>) -> Self {
        let mut exact = Aabb::EMPTY;
        let mut items: Vec<BuildItem> = bounds
            .into_iter()
            .enumerate()
            .map(|(i, b)| {
                exact = exact.union(&b);
                BuildItem::new(&b, i as u32)
            })
            .collect();
        if items.is_empty() {
            return Bvh::default();
        }
        // One array with room for the most nodes n items can make (2n - 1),
        // written in place and then cut to size: no node is copied from
        // one buffer to another, and the cut returns the rest.
        let mut nodes = vec![BvhNode::UNSET; 2 * items.len() - 1];
        let len = build_into(&mut items, 0, &mut nodes, 0, 0);
        nodes.truncate(len);
        nodes.shrink_to_fit();
        // Each transient goes as soon as it is used up: the items before
        // the 8-wide copy is made, the binary nodes after.
        let order = items.iter().map(|i| i.index).collect();
        drop(items);
        let wide = wide::collapse(&nodes);
        drop(nodes);
        Bvh {
            bounds: exact,
            stack_need: wide::stack_need(&wide),
            wide,
            order,
        }
    }

    /// Item numbers in leaf order: leaves refer to ranges of this.
    pub fn order(&self) -> &[u32] {
        &self.order
    }

    /// Number of (8-wide) nodes.
    pub fn node_count(&self) -> usize {
        self.wide.len()
    }

    /// Heap memory of the nodes and the item order, in bytes.
    pub fn memory_bytes(&self) -> usize {
        self.wide.len() * std::mem::size_of::<WideNode>() + self.order.len() * 4
    }

    /// Bounds of everything in the tree.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// Closest-hit traversal: visits leaves front to back and calls
    /// `test(position, t_max)` for every item position in them (an index
    /// into [`order`](Self::order)); `test` returns the distance of a
    /// hit at or before `t_max` that it keeps, which then becomes `t_max`.
    /// Returns the final `t_max`.
    ///
    /// Runs on the 8-wide form: one SIMD test decides a node's eight
    /// children; those hit are taken nearest first, and any whose entry lies
    /// beyond a closer hit found meanwhile is dropped untested. Every box
    /// that may hold a hit at or before `t_max` is visited, so `test` sees
    /// ties too.
    #[inline]
    pub fn closest(&self, ray: &NodeRay, t_max: f64, test: impl ClosestTest) -> f64 {
        self.closest_on(simd::kernel(), ray, t_max, test)
    }

    /// [`closest`](Self::closest) on a given kernel.
    #[inline]
    pub(crate) fn closest_on(
        &self,
        kernel: Kernel,
        ray: &NodeRay,
        t_max: f64,
        test: impl ClosestTest,
    ) -> f64 {
        kernel.closest(&self.wide, self.stack_need, ray, t_max, test)
    }

    /// [`closest`](Self::closest) for the first `count` of K rays, in turns
    /// (see `wide::closest_stream`): `tests[k]` and `t_max[k]` are ray k's.
    /// Each ray's final limit and the items it is tested against are what
    /// `closest` gives it alone.
    #[inline]
    pub(crate) fn closest_stream_on<T: ClosestTest, const K: usize>(
        &self,
        kernel: Kernel,
        rays: &[NodeRay; K],
        count: usize,
        t_max: &mut [f64; K],
        tests: &mut [T; K],
    ) {
        if self.stack_need <= wide::STACK {
            let mut stacks: [ArrayVec<_, { wide::STACK }>; K] =
                std::array::from_fn(|_| ArrayVec::new());
            kernel.closest_stream(&self.wide, rays, count, t_max, &mut stacks, tests);
        } else {
            let mut stacks: [Vec<_>; K] =
                std::array::from_fn(|_| Vec::with_capacity(self.stack_need));
            kernel.closest_stream(&self.wide, rays, count, t_max, &mut stacks, tests);
        }
    }

    /// [`any`](Self::any) for the first `count` of K rays, in turns (see
    /// `wide::any_stream`): bit k of the answer is set when ray k is
    /// blocked, as `any` answers it alone.
    #[inline]
    pub(crate) fn any_stream_on<T: AnyTest, const K: usize>(
        &self,
        kernel: Kernel,
        rays: &[NodeRay; K],
        count: usize,
        t_max: &[f64; K],
        tests: &mut [T; K],
    ) -> u32 {
        if self.stack_need <= wide::STACK {
            let mut stacks: [ArrayVec<_, { wide::STACK }>; K] =
                std::array::from_fn(|_| ArrayVec::new());
            kernel.any_stream(&self.wide, rays, count, t_max, &mut stacks, tests)
        } else {
            let mut stacks: [Vec<_>; K] =
                std::array::from_fn(|_| Vec::with_capacity(self.stack_need));
            kernel.any_stream(&self.wide, rays, count, t_max, &mut stacks, tests)
        }
    }

    /// Visits the item positions of the leaves that may hold an item within
    /// `reach`, nearest box first (see `wide::nearest_items`): for nearest
    /// point queries. Returns the final reach.
    pub fn nearest_items(
        &self,
        stack: &mut Vec<(f64, u32, u16)>,
        reach: f64,
        lower: impl Fn(&Aabb) -> f64,
        test: impl FnMut(usize, f64) -> f64,
    ) -> f64 {
        wide::nearest_items(&self.wide, stack, reach, lower, test)
    }

    /// Visits the item positions in every leaf whose box passes `keep`,
    /// descending only into boxes that pass it; stops and returns false as
    /// soon as `visit` does.
    pub fn visit(&self, keep: impl Fn(&Aabb) -> bool, visit: impl FnMut(usize) -> bool) -> bool {
        if self.stack_need <= wide::STACK {
            let mut stack = ArrayVec::<_, { wide::STACK }>::new();
            wide::visit(&self.wide, &mut stack, keep, visit)
        } else {
            let mut stack = Vec::with_capacity(self.stack_need);
            wide::visit(&self.wide, &mut stack, keep, visit)
        }
    }

    /// Any-hit traversal: true as soon as `test(position)` is true for an
    /// item in a leaf the ray meets within `t_max`.
    #[inline]
    pub fn any(&self, ray: &NodeRay, t_max: f64, test: impl AnyTest) -> bool {
        self.any_on(simd::kernel(), ray, t_max, test)
    }

    /// [`any`](Self::any) on a given kernel.
    #[inline]
    pub(crate) fn any_on(
        &self,
        kernel: Kernel,
        ray: &NodeRay,
        t_max: f64,
        test: impl AnyTest,
    ) -> bool {
        if self.stack_need <= wide::STACK {
            let mut stack = ArrayVec::<_, { wide::STACK }>::new();
            kernel.any(&self.wide, ray, t_max, &mut stack, test)
        } else {
            let mut stack = Vec::with_capacity(self.stack_need);
            kernel.any(&self.wide, ray, t_max, &mut stack, test)
        }
    }
}

/// Node tests a span of rays is given to show that it meets no leaf
/// ([`Bvh::span_may_meet`]).
const SPAN_BUDGET: usize = 8;

impl Bvh {
    /// Whether some ray `span` stands for (see [`NodePacket::spanning`])
    /// may meet an item before `t_max`: false only where the packet's node
    /// test, which lets through every box a ray's own test does, lets no
    /// leaf through within [`SPAN_BUDGET`] node tests from the root
    /// (`packet::span_reaches_leaf`), so that every such ray's traversal
    /// ends with nothing found.
    pub(crate) fn span_may_meet(&self, span: &NodePacket, t_max: f64) -> bool {
        simd::kernel().span_reaches_leaf(&self.wide, span, NodeRay::box_limit(t_max), SPAN_BUDGET)
    }

    /// Closest-hit traversal of a packet of rays: what
    /// [`closest`](Self::closest) does for each ray, with `test(ray,
    /// position, t_max)` in place of `test(position, t_max)`; `t_max[k]`
    /// ends as ray k's final limit.
    #[inline]
    pub(crate) fn closest_packet_on(
        &self,
        kernel: Kernel,
        rays: &NodePacket,
        t_max: &mut [f64; PACKET],
        test: impl PacketClosestTest,
    ) {
        if self.stack_need <= wide::STACK {
            let mut stack = ArrayVec::<_, { wide::STACK }>::new();
            kernel.closest_packet(&self.wide, rays, t_max, &mut stack, test);
        } else {
            let mut stack = Vec::with_capacity(self.stack_need);
            kernel.closest_packet(&self.wide, rays, t_max, &mut stack, test);
        }
    }

    /// Any-hit traversal of a packet of rays: the mask of the rays some
    /// item blocks within their `t_max`.
    #[inline]
    pub(crate) fn any_packet_on(
        &self,
        kernel: Kernel,
        rays: &NodePacket,
        t_max: &[f64; PACKET],
        test: impl PacketAnyTest,
    ) -> u32 {
        if self.stack_need <= wide::STACK {
            let mut stack = ArrayVec::<_, { wide::STACK }>::new();
            kernel.any_packet(&self.wide, rays, t_max, &mut stack, test)
        } else {
            let mut stack = Vec::with_capacity(self.stack_need);
            kernel.any_packet(&self.wide, rays, t_max, &mut stack, test)
        }
    }
}

/// How to divide a subtree's items.
enum Plan {
    Leaf,
    /// Items `..mid` (as reordered) go left.
    Split {
        mid: usize,
        axis: usize,
    },
}

/// Writes the subtree over `items` (reordered in place) depth first to the
/// start of `out`, which has room for its 2n - 1 nodes at most, and
/// returns how many it wrote. Its root will sit at `node_base` in the
/// whole array and its first item at `item_base`. Halves of more than
/// `PARALLEL_THRESHOLD` items are built at once, each in its own part of
/// `out`; the right one then moves down behind the left.
fn build_into(
    items: &mut [BuildItem],
    depth: usize,
    out: &mut [BvhNode],
    node_base: u32,
    item_base: u32,
) -> usize {
    let n = items.len();
    if n <= PARALLEL_THRESHOLD {
        let mut nodes = Nodes {
            out,
            len: 0,
            base: node_base,
        };
        build_serial(items, depth, item_base, &mut nodes);
        return nodes.len;
    }
    let (bounds, plan) = plan(items, depth);
    let Plan::Split { mid, axis } = plan else {
        // Only coinciding centroids of at most MAX_LEAF items make a leaf,
        // far below the threshold.
        unreachable!("a leaf of {n} items");
    };
    let (left_items, right_items) = items.split_at_mut(mid);
    let (parent, rest) = out.split_first_mut().expect("room for the parent");
    let (left_out, right_out) = rest.split_at_mut(2 * mid - 1);
    // The right half is built as if it started where its part does.
    let right_at = 1 + left_out.len();
    let (left_len, right_len) = rayon::join(
        || build_into(left_items, depth + 1, left_out, node_base + 1, item_base),
        || {
            build_into(
                right_items,
                depth + 1,
                right_out,
                node_base + right_at as u32,
                item_base + mid as u32,
            )
        },
    );
    let right_start = 1 + left_len;
    *parent = BvhNode::new(&bounds, node_base + right_start as u32, 0, axis as u8);
    out.copy_within(right_at..right_at + right_len, right_start);
    let shift = (right_at - right_start) as u32;
    for node in &mut out[right_start..right_start + right_len] {
        if node.count == 0 {
            node.offset -= shift;
        }
    }
    right_start + right_len
}

/// A node array being written front to back into a slice, its first node
/// at `base` in the whole array.
struct Nodes<'a> {
    out: &'a mut [BvhNode],
    len: usize,
    base: u32,
}

impl Nodes<'_> {
    fn push(&mut self, node: BvhNode) -> usize {
        self.out[self.len] = node;
        self.len += 1;
        self.len - 1
    }
}

/// Writes the subtree over `items` (reordered in place) depth first: a
/// parent, its left subtree, its right subtree. Item offsets are counted
/// from `item_base`.
fn build_serial(items: &mut [BuildItem], depth: usize, item_base: u32, nodes: &mut Nodes) {
    let (bounds, plan) = plan(items, depth);
    match plan {
        Plan::Leaf => {
            nodes.push(BvhNode::new(&bounds, item_base, items.len() as u16, 0));
        }
        Plan::Split { mid, axis } => {
            let at = nodes.push(BvhNode::new(&bounds, 0, 0, axis as u8));
            let (left, right) = items.split_at_mut(mid);
            build_serial(left, depth + 1, item_base, nodes);
            nodes.out[at].offset = nodes.base + nodes.len as u32;
            build_serial(right, depth + 1, item_base + mid as u32, nodes);
        }
    }
}

/// The bounds of `items` and how to divide them (partitioning them if
/// they are split).
fn plan(items: &mut [BuildItem], depth: usize) -> (Aabb, Plan) {
    let bounds = items.iter().fold(Aabb::EMPTY, |b, i| b.union(&i.bounds()));
    let n = items.len();
    if n == 1 {
        return (bounds, Plan::Leaf);
    }
    let centroids = items.iter().fold(Aabb::EMPTY, |b, i| Aabb {
        min: b.min.min(i.centroid()),
        max: b.max.max(i.centroid()),
    });
    let extent = centroids.max - centroids.min;
    let widest = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    if extent[widest] <= 0.0 {
        // All centroids coincide: no split separates them.
        if n <= MAX_LEAF {
            return (bounds, Plan::Leaf);
        }
        return (
            bounds,
            Plan::Split {
                mid: n / 2,
                axis: widest,
            },
        );
    }
    // Past MEDIAN_DEPTH only median splits: pathological inputs (say,
    // exponentially spaced boxes) cannot make the tree, and the recursions
    // over it, deeper than MEDIAN_DEPTH + log2(n).
    let sah = if depth < MEDIAN_DEPTH {
        sah_split(items, &centroids, bounds.surface_area())
    } else {
        None
    };
    let plan = match sah {
        Some((mid, axis)) => Plan::Split { mid, axis },
        None if n <= MAX_LEAF => Plan::Leaf,
        None => {
            // The SAH prefers a leaf but it would be too big: median.
            items.select_nth_unstable_by(n / 2, |a, b| {
                a.centroid()[widest].total_cmp(&b.centroid()[widest])
            });
            Plan::Split {
                mid: n / 2,
                axis: widest,
            }
        }
    };
    (bounds, plan)
}

/// The binned SAH split of `items`: the cheapest bin boundary over the
/// three axes. Partitions the items and returns (split position, axis), or
/// `None` when a leaf is cheaper.
fn sah_split(items: &mut [BuildItem], centroids: &Aabb, area: f64) -> Option<(usize, usize)> {
    let extent = centroids.max - centroids.min;
    let bin_of = |axis: usize, c: f64| {
        let scale = BINS as f64 / extent[axis];
        (((c - centroids.min[axis]) * scale) as usize).min(BINS - 1)
    };
    let (mut best_cost, mut best_bin, mut best_axis) = (f64::INFINITY, 0, 0);
    for axis in (0..3).filter(|&a| extent[a] > 0.0) {
        let mut bin_bounds = [Aabb::EMPTY; BINS];
        let mut bin_counts = [0usize; BINS];
        for item in items.iter() {
            let b = bin_of(axis, item.centroid()[axis]);
            bin_counts[b] += 1;
            bin_bounds[b] = bin_bounds[b].union(&item.bounds());
        }
        // Sweep from the right to get the cost of each right side.
        let mut right_area = [0.0; BINS];
        let mut right_count = [0usize; BINS];
        let (mut acc, mut count) = (Aabb::EMPTY, 0);
        for b in (1..BINS).rev() {
            acc = acc.union(&bin_bounds[b]);
            count += bin_counts[b];
            right_area[b] = acc.surface_area();
            right_count[b] = count;
        }
        let (mut acc, mut count) = (Aabb::EMPTY, 0);
        for b in 1..BINS {
            acc = acc.union(&bin_bounds[b - 1]);
            count += bin_counts[b - 1];
            if count == 0 || right_count[b] == 0 {
                continue;
            }
            let cost = acc.surface_area() * count as f64 + right_area[b] * right_count[b] as f64;
            if cost < best_cost {
                (best_cost, best_bin, best_axis) = (cost, b, axis);
            }
        }
    }
    let n = items.len();
    let split_cost = TRAVERSAL_COST + best_cost / area.max(f64::MIN_POSITIVE);
    if best_bin == 0 || (n <= MAX_LEAF && split_cost >= n as f64) {
        return None;
    }
    // Partition: items in bins below best_bin first.
    let mut mid = 0;
    for i in 0..n {
        if bin_of(best_axis, items[i].centroid()[best_axis]) < best_bin {
            items.swap(i, mid);
            mid += 1;
        }
    }
    Some((mid, best_axis))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::PixelRng;

    fn random_boxes(n: usize, seed: u64) -> Vec<Aabb> {
        let mut rng = PixelRng::new(seed, 0, 0);
        (0..n)
            .map(|_| {
                let c = DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 100.0;
                let h = DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 2.0;
                Aabb {
                    min: c - h,
                    max: c + h,
                }
            })
            .collect()
    }

    /// Exact slab test as a reference.
    fn box_entry(b: &Aabb, o: DVec3, d: DVec3) -> Option<f64> {
        let (mut near, mut far) = (0.0f64, f64::INFINITY);
        for a in 0..3 {
            if d[a] == 0.0 {
                if o[a] < b.min[a] || o[a] > b.max[a] {
                    return None;
                }
                continue;
            }
            let (t0, t1) = ((b.min[a] - o[a]) / d[a], (b.max[a] - o[a]) / d[a]);
            near = near.max(t0.min(t1));
            far = far.min(t0.max(t1));
        }
        (near <= far).then_some(near)
    }

    #[test]
    fn every_item_sits_in_exactly_one_leaf_inside_its_ancestors() {
        for n in [1, 2, 3, 5, 17, 1000, 40_000] {
            let boxes = random_boxes(n, n as u64);
            let bvh = Bvh::build(boxes.iter().copied());
            let mut seen = vec![0; n];
            for &i in bvh.order() {
                seen[i as usize] += 1;
            }
            assert!(seen.iter().all(|&c| c == 1), "n = {n}");
            // Every slot's box contains what is below it, and every item
            // position is reached from exactly one leaf slot.
            let mut reached = vec![0; n];
            for node in &bvh.wide {
                for (bounds, child, count) in node.slots() {
                    if count == 0 {
                        for (inner, _, _) in bvh.wide[child as usize].slots() {
                            assert_eq!(bounds.union(&inner), bounds);
                        }
                    } else {
                        for p in child as usize..child as usize + count as usize {
                            reached[p] += 1;
                            let b = boxes[bvh.order()[p] as usize];
                            assert_eq!(bounds.union(&b), bounds);
                        }
                    }
                }
            }
            assert!(reached.iter().all(|&c| c == 1), "n = {n}");
        }
    }

    #[test]
    fn wide_nodes_with_free_slots_hold_only_the_binary_trees_leaves() {
        // A node with a free slot has split every leaf it could (a merged
        // binary subtree), so each of its leaves is one of the binary
        // tree's: testing the smaller leaves costs no extra node visit.
        let (mut merged, mut checked) = (0, 0);
        for n in [5, 17, 300, 5000] {
            let boxes = random_boxes(n, 7 + n as u64);
            let mut items: Vec<BuildItem> = boxes
                .iter()
                .enumerate()
                .map(|(i, b)| BuildItem::new(b, i as u32))
                .collect();
            let mut binary = vec![BvhNode::UNSET; 2 * n - 1];
            let len = build_into(&mut items, 0, &mut binary, 0, 0);
            binary.truncate(len);
            let binary_leaves: std::collections::HashSet<(u32, u16)> = binary
                .iter()
                .filter(|b| b.count() > 0)
                .map(|b| (b.offset(), b.count()))
                .collect();
            for node in wide::collapse(&binary) {
                let slots: Vec<_> = node.slots().collect();
                for &(_, child, count) in &slots {
                    let is_binary_leaf = count == 0 || binary_leaves.contains(&(child, count));
                    merged += usize::from(!is_binary_leaf);
                    if slots.len() < wide::WIDTH {
                        checked += 1;
                        assert!(
                            is_binary_leaf,
                            "n = {n}: leaf ({child}, {count}) left merged"
                        );
                    }
                }
            }
        }
        // The invariant is not vacuous: nodes with free slots exist, and
        // full ones still hold merged leaves.
        assert!(
            checked > 0 && merged > 0,
            "{checked} checked, {merged} merged"
        );
    }

    /// Every kernel this CPU runs.
    fn kernels() -> Vec<Kernel> {
        let all: Vec<Kernel> = simd::SimdPath::ALL
            .iter()
            .filter_map(|p| p.kernel())
            .collect();
        assert!(all.len() >= 2, "at least the four-lane and scalar paths");
        all
    }

    #[test]
    fn every_kernel_orders_the_children_met_nearest_first() {
        use crate::accel::simd::{Lanes, Scalar};
        let bvh = Bvh::build(random_boxes(600, 29));
        let mut rng = PixelRng::new(31, 0, 0);
        let mut sorted = 0;
        for i in 0..1000 {
            let o = DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 140.0 - 20.0;
            let mut d = DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 2.0 - DVec3::ONE;
            if i % 7 == 0 {
                d.x = 0.0; // the zero-component path
            }
            let ray = NodeRay::new(o, d);
            let limit = NodeRay::box_limit([f64::INFINITY, 60.0, 3.0][i % 3]);
            for node in &bvh.wide {
                // The reference: each lane met keyed by its own entry
                // distance, sorted as numbers.
                let (mask, near) = Scalar.entries(node, &ray, limit);
                let mut expected: Vec<u32> = (0..wide::WIDTH)
                    .filter(|&lane| mask & (1 << lane) != 0)
                    .map(|lane| wide::child_key(near[lane], lane))
                    .collect();
                expected.sort_unstable();
                sorted += usize::from(expected.len() > 2);
                for kernel in kernels() {
                    let (met, keys) = match kernel {
                        #[cfg(target_arch = "x86_64")]
                        Kernel::Avx2(k) => k.ordered_entries(node, &ray, limit),
                        Kernel::Sse2 => simd::Sse2.ordered_entries(node, &ray, limit),
                        Kernel::Scalar => Scalar.ordered_entries(node, &ray, limit),
                    };
                    assert_eq!(keys[..met], expected[..], "ray {i}, {kernel:?}");
                    // The packet traversal's form, from distances given.
                    let (given, given_keys) = match kernel {
                        #[cfg(target_arch = "x86_64")]
                        Kernel::Avx2(k) => k.order(mask, &near),
                        Kernel::Sse2 => simd::Sse2.order(mask, &near),
                        Kernel::Scalar => Scalar.order(mask, &near),
                    };
                    assert_eq!(given_keys[..given], expected[..], "ray {i}, {kernel:?}");
                    for &key in &keys[..met] {
                        let lane = wide::key_lane(key);
                        assert!(wide::key_entry(key) <= near[lane], "ray {i}");
                    }
                }
            }
        }
        assert!(
            sorted > 60,
            "only {sorted} nodes with three children met or more"
        );
    }

    #[test]
    fn the_packet_test_lets_through_every_box_a_ray_of_it_does() {
        use crate::accel::simd::{
            Lanes, NodePacket, PACKET, Scalar, packet_entries_scalar, ray_mask_scalar,
        };
        let bvh = Bvh::build(random_boxes(600, 17));
        let mut rng = PixelRng::new(23, 0, 0);
        let mut through = 0;
        for i in 0..400 {
            let base = DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 120.0 - 10.0;
            let aim = DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 100.0;
            let spread = [0.0, 0.01, 1.0, 20.0][i % 4];
            let rays: Vec<(DVec3, DVec3)> = (0..PACKET)
                .map(|_| {
                    let o = base
                        + if i % 2 == 0 {
                            DVec3::ZERO
                        } else {
                            DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * spread
                        };
                    let mut d =
                        aim + DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * spread - o;
                    if i % 5 == 0 {
                        d.y = 0.0; // the zero-component path
                    }
                    (o, d)
                })
                .collect();
            let Some(packet) = NodePacket::new(&rays) else {
                continue;
            };
            let t_max: [f64; PACKET] =
                std::array::from_fn(|k| [f64::INFINITY, 50.0, 5.0][(i + k) % 3]);
            let limits = t_max.map(NodeRay::box_limit);
            let limit = limits.iter().copied().fold(f32::NEG_INFINITY, f32::max);
            for node in &bvh.wide {
                let (mask, near) = packet_entries_scalar(node, &packet, limit);
                for kernel in kernels() {
                    let vector = match kernel {
                        #[cfg(target_arch = "x86_64")]
                        Kernel::Avx2(k) => k.packet_entries(node, &packet, limit),
                        Kernel::Sse2 => simd::Sse2.packet_entries(node, &packet, limit),
                        Kernel::Scalar => Scalar.packet_entries(node, &packet, limit),
                    };
                    assert_eq!(vector.0, mask);
                    assert_eq!(vector.1.map(f32::to_bits), near.map(f32::to_bits));
                }
                for (k, &(o, d)) in rays.iter().enumerate() {
                    let (own, own_near) = Scalar.entries(node, &NodeRay::new(o, d), limits[k]);
                    assert_eq!(own & !mask, 0, "packet {i}, ray {k}");
                    for slot in 0..wide::WIDTH {
                        if own & (1 << slot) != 0 {
                            assert!(near[slot] <= own_near[slot]);
                            through += 1;
                        }
                        let rays_through = ray_mask_scalar(node, slot, &packet, &limits);
                        assert_eq!(
                            rays_through >> k & 1,
                            own >> slot & 1,
                            "packet {i}, ray {k}"
                        );
                        for kernel in kernels() {
                            #[cfg(target_arch = "x86_64")]
                            if let Kernel::Avx2(p) = kernel {
                                assert_eq!(p.ray_mask(node, slot, &packet, &limits), rays_through);
                            }
                        }
                    }
                }
            }
        }
        assert!(through > 10_000, "{through}");
    }

    /// Every kernel's `masked_max` is the scalar one for every mask, up to
    /// the sign of a zero (values include ±0, ±∞ and ties).
    #[test]
    fn masked_maxima_agree_on_every_kernel() {
        use crate::accel::simd::{Lanes, PACKET, Scalar};
        let mut rng = PixelRng::new(31, 0, 0);
        let pool = [
            0.0,
            -0.0,
            1.0,
            2.5,
            -3.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
            7.0,
        ];
        for case in 0..2_000 {
            let values: [f32; PACKET] = std::array::from_fn(|_| {
                if case % 2 == 0 {
                    pool[(rng.uniform() * 8.0) as usize % 8]
                } else {
                    (rng.uniform() as f32 - 0.5) * 100.0
                }
            });
            for mask in 0..256u32 {
                let reference = Scalar.masked_max(&values, mask);
                for kernel in kernels() {
                    let got = match kernel {
                        #[cfg(target_arch = "x86_64")]
                        Kernel::Avx2(k) => k.masked_max(&values, mask),
                        Kernel::Sse2 => simd::Sse2.masked_max(&values, mask),
                        Kernel::Scalar => Scalar.masked_max(&values, mask),
                    };
                    assert!(
                        got == reference,
                        "{values:?} {mask:#x}: {got} against {reference}"
                    );
                }
            }
        }
    }

    /// A span (`NodePacket::spanning`) of up to 64 rays lets through every
    /// box one of its rays' own tests does, on every kernel; where its
    /// search from the root finds no leaf, no ray's own traversal tests
    /// an item.
    #[test]
    fn a_span_lets_through_every_box_its_rays_do() {
        use crate::accel::simd::{Lanes, NodePacket, Scalar, packet_entries_scalar};
        let boxes = random_boxes(600, 19);
        let bvh = Bvh::build(boxes.iter().copied());
        let mut rng = PixelRng::new(29, 0, 0);
        let (mut through, mut culled, mut reached) = (0, 0, 0);
        for i in 0..600 {
            let eye = DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 160.0 - 30.0;
            let aim = DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 100.0 - eye;
            let (spread, jitter) = [(0.001, 0.0), (0.02, 0.0), (0.2, 0.0), (0.02, 1.0)][i % 4];
            let rays: Vec<(DVec3, DVec3)> = (0..1 + i % 64)
                .map(|_| {
                    let o = eye + DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * jitter;
                    let d = aim * (1.0 + spread * (rng.uniform() - 0.5))
                        + DVec3::new(rng.uniform(), rng.uniform(), rng.uniform())
                            * aim.length()
                            * spread;
                    (o, d)
                })
                .collect();
            let fold = |f: fn(DVec3, DVec3) -> DVec3, pick: fn(&(DVec3, DVec3)) -> DVec3| {
                rays.iter().map(pick).reduce(f).unwrap()
            };
            let Some(span) = NodePacket::spanning(
                fold(DVec3::min, |r| r.0),
                fold(DVec3::max, |r| r.0),
                fold(DVec3::min, |r| r.1),
                fold(DVec3::max, |r| r.1),
            ) else {
                continue;
            };
            let t_max = [f64::INFINITY, 60.0, 3.0][i % 3];
            let limit = NodeRay::box_limit(t_max);
            for node in &bvh.wide {
                let (mask, _) = packet_entries_scalar(node, &span, limit);
                for &(o, d) in &rays {
                    let (own, _) = Scalar.entries(node, &NodeRay::new(o, d), limit);
                    assert_eq!(own & !mask, 0, "span {i}");
                    through += own.count_ones();
                }
            }
            let may_meet = bvh.span_may_meet(&span, t_max);
            for kernel in kernels() {
                assert_eq!(
                    kernel.span_reaches_leaf(&bvh.wide, &span, limit, SPAN_BUDGET),
                    may_meet
                );
            }
            if may_meet {
                reached += 1;
                continue;
            }
            culled += 1;
            for &(o, d) in &rays {
                let ray = NodeRay::new(o, d);
                let tested = std::cell::Cell::new(0);
                bvh.any(&ray, t_max, |_| {
                    tested.set(tested.get() + 1);
                    false
                });
                assert_eq!(tested.get(), 0, "span {i}: a ray of it reached an item");
            }
        }
        assert!(
            through > 10_000 && culled > 50 && reached > 50,
            "{through} {culled} {reached}"
        );
    }

    #[test]
    fn traversals_match_brute_force() {
        let boxes = random_boxes(3000, 99);
        let bvh = Bvh::build(boxes.iter().copied());
        let mut rng = PixelRng::new(5, 5, 5);
        for _ in 0..2000 {
            let o = DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 120.0 - 10.0;
            let mut d = DVec3::new(
                rng.uniform() - 0.5,
                rng.uniform() - 0.5,
                rng.uniform() - 0.5,
            );
            if rng.uniform() < 0.2 {
                d.y = 0.0; // axis-parallel rays exercise the zero-component path
            }
            let ray = NodeRay::new(o, d);
            let expected = boxes
                .iter()
                .filter_map(|b| box_entry(b, o, d))
                .fold(f64::INFINITY, f64::min);
            for kernel in kernels() {
                let found = bvh.closest_on(kernel, &ray, f64::INFINITY, |p, t_max| {
                    box_entry(&boxes[bvh.order()[p] as usize], o, d).filter(|&t| t < t_max)
                });
                assert_eq!(found, expected, "{kernel:?}");
                // Any-hit within a segment: nothing before the nearest
                // entry, something just past it.
                let entered_before = |limit: f64| {
                    bvh.any_on(kernel, &ray, limit, |p| {
                        box_entry(&boxes[bvh.order()[p] as usize], o, d).is_some_and(|t| t < limit)
                    })
                };
                if expected.is_finite() {
                    assert!(!entered_before(expected * 0.999));
                    assert!(entered_before(expected * 1.001 + 1e-9));
                } else {
                    assert!(!entered_before(f64::INFINITY));
                }
            }
        }
    }

    /// The AVX2 searches find their next node their own way (the
    /// closest-hit one pushes a node's children without a branch per
    /// child, into a stack of its own; the any-hit one goes to the last
    /// interior child met without the stack); they must visit what the
    /// generic ones visit, in their order, so that the renderer's bits do
    /// not depend on the CPU. Checked on a random tree and on one too deep
    /// for the stack kept on the call stack.
    #[test]
    fn every_kernel_tests_the_same_items_in_the_same_order() {
        let random = random_boxes(3000, 41);
        // Exponentially spaced slabs: each SAH split peels off a few, so
        // the tree is deep.
        let deep: Vec<Aabb> = (0..600)
            .map(|i| {
                let x = 1.1f64.powi(i);
                Aabb {
                    min: DVec3::new(x, 0.0, 0.0),
                    max: DVec3::new(x * 1.05, 1.0, 1.0),
                }
            })
            .collect();
        let mut rng = PixelRng::new(43, 0, 0);
        let mut deep_seen = false;
        let mut needs = Vec::new();
        for boxes in [random, deep] {
            let bvh = Bvh::build(boxes.iter().copied());
            deep_seen |= bvh.stack_need > wide::STACK;
            needs.push(bvh.stack_need);
            let mut tested_here = 0;
            for _ in 0..400 {
                // From near a random box, so that rays meet some.
                let b = boxes[(rng.uniform() * boxes.len() as f64) as usize % boxes.len()];
                let o = b.min
                    + (b.max - b.min)
                        * DVec3::new(rng.uniform(), rng.uniform(), rng.uniform())
                        * 2.0;
                let d = DVec3::new(
                    rng.uniform() - 0.5,
                    rng.uniform() - 0.5,
                    rng.uniform() - 0.5,
                );
                let ray = NodeRay::new(o, d);
                let tested = |kernel: Kernel| {
                    let mut seen = Vec::new();
                    let t = bvh.closest_on(kernel, &ray, f64::INFINITY, |p, t_max: f64| {
                        seen.push((p, t_max.to_bits()));
                        box_entry(&boxes[bvh.order()[p] as usize], o, d).filter(|&t| t < t_max)
                    });
                    (t.to_bits(), seen)
                };
                let reference = tested(Kernel::Scalar);
                tested_here += reference.1.len();
                // Any-hit: run to its end (nothing blocks), and stopped at
                // the first item whose box is entered within half again
                // the closest entry's distance.
                let reach = f64::from_bits(reference.0) * 1.5 + 1e-9;
                let tested_any = |kernel: Kernel, blocks: bool| {
                    let mut seen = Vec::new();
                    let hit = bvh.any_on(kernel, &ray, reach, |p| {
                        seen.push(p);
                        blocks
                            && box_entry(&boxes[bvh.order()[p] as usize], o, d)
                                .is_some_and(|t| t < reach)
                    });
                    (hit, seen)
                };
                let any_reference = [false, true].map(|b| tested_any(Kernel::Scalar, b));
                for kernel in kernels() {
                    assert_eq!(tested(kernel), reference, "{kernel:?}");
                    let any = [false, true].map(|b| tested_any(kernel, b));
                    assert_eq!(any, any_reference, "{kernel:?}");
                }
            }
            assert!(tested_here > 600, "{tested_here} items tested");
        }
        assert!(
            deep_seen,
            "the deep tree must need the heap stack: {needs:?}"
        );
    }

    #[test]
    fn pathological_inputs_keep_the_tree_shallow() {
        // Exponentially spaced boxes: each SAH split peels off a few items.
        let boxes: Vec<Aabb> = (0..5000)
            .map(|i| {
                let x = 1.002f64.powi(i);
                Aabb {
                    min: DVec3::new(x, 0.0, 0.0),
                    max: DVec3::new(x * 1.001, 1.0, 1.0),
                }
            })
            .collect();
        let bvh = Bvh::build(boxes.iter().copied());
        assert!(
            bvh.stack_need <= (wide::WIDTH - 1) * (MEDIAN_DEPTH + 14) + wide::WIDTH,
            "stack need {}",
            bvh.stack_need
        );
        let ray = NodeRay::new(DVec3::new(0.0, 0.5, 0.5), DVec3::X);
        let t = bvh.closest(&ray, f64::INFINITY, |p, t_max| {
            let b = boxes[bvh.order()[p] as usize];
            (b.min.x < t_max).then_some(b.min.x)
        });
        assert_eq!(t, 1.0);
    }

    #[test]
    fn parallel_and_serial_builds_agree() {
        // Above the threshold the subtrees are built with rayon::join; the
        // result must not depend on that.
        let boxes = random_boxes(PARALLEL_THRESHOLD * 3, 7);
        let a = Bvh::build(boxes.iter().copied());
        let b = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| Bvh::build(boxes.iter().copied()));
        assert_eq!(a, b);
    }
}
