//! Bounding volume hierarchy: binned SAH build (parallel for large inputs)
//! into a flat depth-first node array, ordered closest-hit traversal and
//! early-exit any-hit traversal. Generic over what the leaves hold: the
//! caller supplies the leaf test.

use glam::{DVec3, Vec3A};

use crate::geometry::Aabb;

/// Items per leaf at most; fewer if the SAH says a split pays.
const MAX_LEAF: usize = 4;
/// Bins along the split axis.
const BINS: usize = 16;
/// Cost of visiting a node relative to one primitive test.
const TRAVERSAL_COST: f64 = 0.5;
/// Subtrees with more items than this are built on separate threads.
const PARALLEL_THRESHOLD: usize = 16 * 1024;
/// Traversal stack depth; SAH trees over f64 inputs stay far shallower.
const STACK: usize = 96;

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
    nodes: Vec<BvhNode>,
    /// Exact bounds of everything.
    bounds: Aabb,
    /// Item numbers in leaf order.
    order: Vec<u32>,
}

/// A ray prepared for box tests (in f32, four lanes at a time).
#[derive(Clone, Copy, Debug)]
pub struct BoxRay {
    origin: Vec3A,
    inv_dir: Vec3A,
}

impl BoxRay {
    /// Prepares `origin + t·direction` for slab tests.
    #[inline]
    pub fn new(origin: DVec3, direction: DVec3) -> Self {
        // A zero component would give 0·∞ = NaN on a slab through the
        // origin; a tiny value of the same sign gives the right answer.
        let safe = |d: f64| if d == 0.0 { 1e-300f64.copysign(d) } else { d };
        let inv_dir = DVec3::new(
            1.0 / safe(direction.x),
            1.0 / safe(direction.y),
            1.0 / safe(direction.z),
        );
        BoxRay {
            origin: origin.as_vec3().into(),
            inv_dir: inv_dir.as_vec3().into(),
        }
    }

    /// Whether the ray meets `b` with t in [0, t_max]. The far distance is
    /// enlarged by a few ulps so that rounding cannot miss a box that a
    /// primitive inside it is hit in (Ize 2013).
    #[inline]
    fn hits(&self, node: &BvhNode, t_max: f64) -> bool {
        self.entry(node, t_max as f32).is_some()
    }

    /// The distance at which the ray enters the node's box, if it does so
    /// before `t_max`.
    #[inline]
    fn entry(&self, node: &BvhNode, t_max: f32) -> Option<f32> {
        let t0 = (Vec3A::from_array(node.min) - self.origin) * self.inv_dir;
        let t1 = (Vec3A::from_array(node.max) - self.origin) * self.inv_dir;
        let near = t0.min(t1).max_element().max(0.0);
        let far = t0.max(t1).min_element() * (1.0 + 8.0 * f32::EPSILON);
        (near <= far.min(t_max)).then_some(near)
    }
}

struct BuildItem {
    bounds: Aabb,
    centroid: DVec3,
    index: u32,
}

impl Bvh {
    /// Builds a tree over items with the given bounds (item i = bounds[i]).
    pub fn build(bounds: &[Aabb]) -> Self {
        if bounds.is_empty() {
            return Bvh::default();
        }
        let mut items: Vec<BuildItem> = bounds
            .iter()
            .enumerate()
            .map(|(i, b)| BuildItem {
                bounds: *b,
                centroid: b.centroid(),
                index: i as u32,
            })
            .collect();
        let nodes = build_node(&mut items);
        Bvh {
            bounds: bounds.iter().fold(Aabb::EMPTY, |b, i| b.union(i)),
            nodes,
            order: items.iter().map(|i| i.index).collect(),
        }
    }

    /// Item numbers in leaf order: leaves refer to ranges of this.
    pub fn order(&self) -> &[u32] {
        &self.order
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Bounds of everything in the tree.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// Closest-hit traversal: visits leaves front to back and calls
    /// `test(position, t_max)` for every item position in them (an index
    /// into [`order`](Self::order)); `test` returns the distance of a
    /// closer hit, which then shrinks `t_max`. Returns the final `t_max`.
    ///
    /// Both children's boxes are tested at their parent; the nearer is
    /// visited first and the farther is pushed with its entry distance, so
    /// it is skipped without another box test once a closer hit is known.
    #[inline]
    pub fn closest(
        &self,
        ray: &BoxRay,
        mut t_max: f64,
        mut test: impl FnMut(usize, f64) -> Option<f64>,
    ) -> f64 {
        let Some(root) = self.nodes.first() else {
            return t_max;
        };
        if !ray.hits(root, t_max) {
            return t_max;
        }
        let mut stack = [(0u32, 0f32); STACK];
        let mut top = 0;
        let mut current = 0usize;
        loop {
            let node = &self.nodes[current];
            if node.count > 0 {
                let start = node.offset as usize;
                for position in start..start + node.count as usize {
                    if let Some(t) = test(position, t_max) {
                        t_max = t;
                    }
                }
            } else {
                let (left, right) = (current + 1, node.offset as usize);
                let limit = t_max as f32;
                match (
                    ray.entry(&self.nodes[left], limit),
                    ray.entry(&self.nodes[right], limit),
                ) {
                    (Some(a), Some(b)) => {
                        let (near, far, far_t) = if a <= b {
                            (left, right, b)
                        } else {
                            (right, left, a)
                        };
                        if top < STACK {
                            stack[top] = (far as u32, far_t);
                            top += 1;
                        }
                        current = near;
                        continue;
                    }
                    (Some(_), None) => {
                        current = left;
                        continue;
                    }
                    (None, Some(_)) => {
                        current = right;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            // Next pushed node that may still hold a closer hit.
            loop {
                if top == 0 {
                    return t_max;
                }
                top -= 1;
                let (node, entry) = stack[top];
                if f64::from(entry) <= t_max {
                    current = node as usize;
                    break;
                }
            }
        }
    }

    /// Any-hit traversal: true as soon as `test(position)` is true for an
    /// item in a leaf the ray meets within `t_max`. Children are tested at
    /// their parent, so a missed child is never pushed.
    #[inline]
    pub fn any(&self, ray: &BoxRay, t_max: f64, mut test: impl FnMut(usize) -> bool) -> bool {
        let Some(root) = self.nodes.first() else {
            return false;
        };
        if !ray.hits(root, t_max) {
            return false;
        }
        let limit = t_max as f32;
        let mut stack = [0u32; STACK];
        let mut top = 0;
        let mut current = 0usize;
        loop {
            let node = &self.nodes[current];
            if node.count > 0 {
                let start = node.offset as usize;
                if (start..start + node.count as usize).any(&mut test) {
                    return true;
                }
            } else {
                let (left, right) = (current + 1, node.offset as usize);
                let hit_left = ray.entry(&self.nodes[left], limit).is_some();
                let hit_right = ray.entry(&self.nodes[right], limit).is_some();
                if hit_left && hit_right {
                    if top < STACK {
                        stack[top] = right as u32;
                        top += 1;
                    }
                    current = left;
                    continue;
                } else if hit_left || hit_right {
                    current = if hit_left { left } else { right };
                    continue;
                }
            }
            if top == 0 {
                return false;
            }
            top -= 1;
            current = stack[top] as usize;
        }
    }
}

/// Builds the subtree over `items` (reordered in place) as a node array
/// with offsets relative to the start of `items` and of the array.
fn build_node(items: &mut [BuildItem]) -> Vec<BvhNode> {
    let bounds = items.iter().fold(Aabb::EMPTY, |b, i| b.union(&i.bounds));
    let leaf = |count: usize| vec![BvhNode::new(&bounds, 0, count as u16, 0)];
    let n = items.len();
    if n == 1 {
        return leaf(1);
    }
    let centroids = items.iter().fold(Aabb::EMPTY, |b, i| Aabb {
        min: b.min.min(i.centroid),
        max: b.max.max(i.centroid),
    });
    let extent = centroids.max - centroids.min;
    let widest = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let (mid, axis) = if extent[widest] <= 0.0 {
        // All centroids coincide: no split separates them.
        if n <= MAX_LEAF {
            return leaf(n);
        }
        (n / 2, widest)
    } else {
        match sah_split(items, &centroids, bounds.surface_area()) {
            Some(split) => split,
            None if n <= MAX_LEAF => return leaf(n),
            None => {
                // The SAH prefers a leaf but it would be too big: median.
                items.select_nth_unstable_by(n / 2, |a, b| {
                    a.centroid[widest].total_cmp(&b.centroid[widest])
                });
                (n / 2, widest)
            }
        }
    };
    let (left_items, right_items) = items.split_at_mut(mid);
    let (left, right) = if n > PARALLEL_THRESHOLD {
        rayon::join(|| build_node(left_items), || build_node(right_items))
    } else {
        (build_node(left_items), build_node(right_items))
    };
    let mut nodes = Vec::with_capacity(1 + left.len() + right.len());
    nodes.push(BvhNode::new(
        &bounds,
        (1 + left.len()) as u32,
        0,
        axis as u8,
    ));
    append(&mut nodes, left, 1, 0);
    let base = nodes.len() as u32;
    append(&mut nodes, right, base, mid as u32);
    nodes
}

/// Appends a subtree built alone, shifting its node and item offsets.
fn append(nodes: &mut Vec<BvhNode>, subtree: Vec<BvhNode>, node_base: u32, item_base: u32) {
    nodes.extend(subtree.into_iter().map(|mut node| {
        if node.count > 0 {
            node.offset += item_base;
        } else {
            node.offset += node_base;
        }
        node
    }));
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
            let b = bin_of(axis, item.centroid[axis]);
            bin_counts[b] += 1;
            bin_bounds[b] = bin_bounds[b].union(&item.bounds);
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
        if bin_of(best_axis, items[i].centroid[best_axis]) < best_bin {
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
            let bvh = Bvh::build(&boxes);
            let mut seen = vec![0; n];
            for &i in bvh.order() {
                seen[i as usize] += 1;
            }
            assert!(seen.iter().all(|&c| c == 1), "n = {n}");
            // Every node's bounds contain its children's.
            for (i, node) in bvh.nodes.iter().enumerate() {
                if node.count == 0 {
                    for child in [i + 1, node.offset as usize] {
                        let c = bvh.nodes[child].bounds();
                        assert!(node.bounds().union(&c) == node.bounds());
                    }
                } else {
                    for p in node.offset as usize..(node.offset + node.count as u32) as usize {
                        let b = boxes[bvh.order()[p] as usize];
                        assert!(node.bounds().union(&b) == node.bounds());
                    }
                }
            }
        }
    }

    #[test]
    fn traversals_match_brute_force() {
        let boxes = random_boxes(3000, 99);
        let bvh = Bvh::build(&boxes);
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
            let ray = BoxRay::new(o, d);
            let expected = boxes
                .iter()
                .filter_map(|b| box_entry(b, o, d))
                .fold(f64::INFINITY, f64::min);
            let found = bvh.closest(&ray, f64::INFINITY, |p, t_max| {
                box_entry(&boxes[bvh.order()[p] as usize], o, d).filter(|&t| t < t_max)
            });
            assert_eq!(found, expected);
            // Any-hit within a segment: nothing before the nearest entry,
            // something just past it.
            let entered_before = |limit: f64| {
                bvh.any(&ray, limit, |p| {
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

    #[test]
    fn parallel_and_serial_builds_agree() {
        // Above the threshold the subtrees are built with rayon::join; the
        // result must not depend on that.
        let boxes = random_boxes(PARALLEL_THRESHOLD * 3, 7);
        let a = Bvh::build(&boxes);
        let b = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| Bvh::build(&boxes));
        assert_eq!(a, b);
    }
}
