//! The binary BVH collapsed into an 8-wide one: each node holds the boxes of
//! up to eight children in structure-of-arrays form, so one SIMD slab test
//! decides all eight (one AVX2 instruction per step, or two SSE2 ones, or a
//! scalar loop: see `simd`), and the tree is about a third as deep as the
//! binary one it comes from.
//!
//! The traversals here are generic over that node test and inlined into
//! each instruction set's entry point, so the whole loop is compiled for it.

use std::ops::DerefMut;

use arrayvec::ArrayVec;

use super::bvh::BvhNode;
use super::simd::{Lanes, NodeRay};

/// Child slots per node.
pub const WIDTH: usize = 8;
/// Marks an empty slot.
const EMPTY: u32 = u32::MAX;

/// The planes of a node's boxes, in the order `planes` stores them.
pub const MIN_X: usize = 0;
/// Rows 3–5 hold the maxima (see [`MIN_X`]).
pub const MAX_X: usize = 3;

/// One 8-wide node: 256 bytes, four cache lines.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct WideNode {
    /// min x, min y, min z, max x, max y, max z of each slot's box, in
    /// f32 rounded outwards.
    pub planes: [[f32; WIDTH]; 6],
    /// Interior child: its node index; leaf child: first item position;
    /// empty slot: `EMPTY`.
    pub(super) child: [u32; WIDTH],
    /// Leaf child: item count; interior child: 0.
    pub(super) count: [u16; WIDTH],
    /// Bit i set when slot i holds a child.
    pub valid: u32,
}

impl WideNode {
    const EMPTY_NODE: WideNode = WideNode {
        // Empty slots are masked out by `valid`; an inverted box keeps
        // them out of the scalar path too.
        planes: [
            [f32::INFINITY; WIDTH],
            [f32::INFINITY; WIDTH],
            [f32::INFINITY; WIDTH],
            [f32::NEG_INFINITY; WIDTH],
            [f32::NEG_INFINITY; WIDTH],
            [f32::NEG_INFINITY; WIDTH],
        ],
        child: [EMPTY; WIDTH],
        count: [0; WIDTH],
        valid: 0,
    };

    /// The box of slot `lane`, widened to f64.
    fn lane_box(&self, lane: usize) -> crate::geometry::Aabb {
        let p = |row: usize| f64::from(self.planes[row][lane]);
        crate::geometry::Aabb {
            min: glam::DVec3::new(p(0), p(1), p(2)),
            max: glam::DVec3::new(p(3), p(4), p(5)),
        }
    }

    /// The occupied slots as (box, child, count), for inspection.
    #[cfg(test)]
    pub fn slots(&self) -> impl Iterator<Item = (crate::geometry::Aabb, u32, u16)> + '_ {
        (0..WIDTH)
            .filter(move |&i| self.valid & (1 << i) != 0)
            .map(move |i| (self.lane_box(i), self.child[i], self.count[i]))
    }
}

/// A child of a wide node, as the closest-hit traversal stack holds it.
#[derive(Clone, Copy, Debug)]
pub struct StackEntry {
    /// Where the ray enters its box.
    entry: f32,
    index: u32,
    count: u32,
}

/// Collapses the binary tree `nodes` (root at 0) into wide nodes, root at 0.
pub fn collapse(nodes: &[BvhNode]) -> Vec<WideNode> {
    let mut wide = crate::huge_pages::with_capacity(nodes.len() / 6 + 1);
    if nodes.is_empty() {
        return wide;
    }
    if nodes[0].count() > 0 {
        // A single leaf: one node with one slot.
        let mut root = WideNode::EMPTY_NODE;
        set_slot(&mut root, 0, &nodes[0], nodes[0].offset(), nodes[0].count());
        wide.push(root);
        return wide;
    }
    collapse_into(nodes, 0, &mut wide);
    wide
}

/// Binary subtrees over at most this many items become one leaf of the
/// wide tree: a node of 256 bytes holding two or three tiny leaves costs
/// more (memory and a visit) than testing the few items together.
const MERGE_LEAF: u32 = 4;

/// The item positions under binary node `at`: its leftmost leaf's start
/// to its rightmost leaf's end (a subtree's items are contiguous).
fn item_range(nodes: &[BvhNode], at: usize) -> (u32, u32) {
    let mut left = at;
    while nodes[left].count() == 0 {
        left += 1;
    }
    let mut right = at;
    while nodes[right].count() == 0 {
        right = nodes[right].offset() as usize;
    }
    (
        nodes[left].offset(),
        nodes[right].offset() + u32::from(nodes[right].count()),
    )
}

/// Where a child of a wide node points: a leaf (first position, count),
/// or a binary interior node to collapse further.
fn as_leaf(nodes: &[BvhNode], c: usize) -> Option<(u32, u16)> {
    let node = &nodes[c];
    if node.count() > 0 {
        return Some((node.offset(), node.count()));
    }
    let (start, end) = item_range(nodes, c);
    (end - start <= MERGE_LEAF).then(|| (start, (end - start) as u16))
}

/// Builds the wide node for binary interior node `at`, returning its index.
fn collapse_into(nodes: &[BvhNode], at: usize, wide: &mut Vec<WideNode>) -> u32 {
    let mut children = vec![
        (at + 1, as_leaf(nodes, at + 1)),
        (
            nodes[at].offset() as usize,
            as_leaf(nodes, nodes[at].offset() as usize),
        ),
    ];
    // Open up the interior child with the largest box until eight
    // children show.
    while open_largest(nodes, &mut children, |_, leaf| leaf.is_none()) {}
    // Slots still free (every child is a leaf): split merged leaves back
    // into their binary halves, largest first. The node costs one test
    // however many slots it fills, and smaller leaves hold fewer of the
    // triangles a ray's box test lets through.
    while open_largest(nodes, &mut children, |c, _| nodes[c].count() == 0) {}
    let index = wide.len();
    wide.push(WideNode::EMPTY_NODE);
    for (slot, &(c, leaf)) in children.iter().enumerate() {
        let (target, count) = match leaf {
            Some(leaf) => leaf,
            None => (collapse_into(nodes, c, wide), 0),
        };
        let mut w = wide[index];
        set_slot(&mut w, slot, &nodes[c], target, count);
        wide[index] = w;
    }
    index as u32
}

/// Replaces the child with the largest box of those `openable` accepts
/// (binary node, what `as_leaf` made of it) by its two binary children, if
/// a slot is free and there is one; returns whether it did.
fn open_largest(
    nodes: &[BvhNode],
    children: &mut Vec<(usize, Option<(u32, u16)>)>,
    openable: impl Fn(usize, Option<(u32, u16)>) -> bool,
) -> bool {
    if children.len() >= WIDTH {
        return false;
    }
    let area = |c: usize| nodes[c].bounds().surface_area();
    let Some((k, _)) = children
        .iter()
        .enumerate()
        .filter(|(_, (c, leaf))| openable(*c, *leaf))
        .max_by(|a, b| area(a.1.0).total_cmp(&area(b.1.0)))
    else {
        return false;
    };
    let (c, _) = children.remove(k);
    let right = nodes[c].offset() as usize;
    children.insert(k, (right, as_leaf(nodes, right)));
    children.insert(k, (c + 1, as_leaf(nodes, c + 1)));
    true
}

fn set_slot(w: &mut WideNode, slot: usize, node: &BvhNode, child: u32, count: u16) {
    let (min, max) = node.raw_bounds();
    for axis in 0..3 {
        w.planes[MIN_X + axis][slot] = min[axis];
        w.planes[MAX_X + axis][slot] = max[axis];
    }
    w.child[slot] = child;
    w.count[slot] = count;
    w.valid |= 1 << slot;
}

/// A traversal stack: a fixed array on the call stack (left unwritten until
/// used: zeroing it for every ray cost 5 % of the bunny's queries) or, for
/// the rare tree too deep for it, a heap vector.
pub trait Stack<T>: DerefMut<Target = [T]> {
    /// Pushes `item`; the caller has made room (see [`stack_need`]).
    fn push(&mut self, item: T);
    /// Pops the top item.
    fn pop(&mut self) -> Option<T>;
}

impl<T, const N: usize> Stack<T> for ArrayVec<T, N> {
    #[inline(always)]
    fn push(&mut self, item: T) {
        ArrayVec::push(self, item);
    }
    #[inline(always)]
    fn pop(&mut self) -> Option<T> {
        ArrayVec::pop(self)
    }
}

impl<T> Stack<T> for Vec<T> {
    #[inline(always)]
    fn push(&mut self, item: T) {
        Vec::push(self, item);
    }
    #[inline(always)]
    fn pop(&mut self) -> Option<T> {
        Vec::pop(self)
    }
}

/// What the closest-hit traversal asks of a leaf item: the distance of a
/// hit at or before `t_max` that it keeps. A trait rather than a closure
/// so that an implementation can insist on being inlined into the
/// traversal (a closure there stayed a call: 16 % of the bunny's profile).
pub trait ClosestTest {
    /// Tests item `position` against the ray up to `t_max`.
    fn test(&mut self, position: usize, t_max: f64) -> Option<f64>;

    /// Asks the cache for what testing the `count` items from `position`
    /// will read: first (`Fetch::Items`) the items, then (`Fetch::Data`)
    /// what they point to. A hint only; `closest_stream` gives other
    /// rays a turn between the two and before the test.
    #[inline(always)]
    fn prefetch(&self, _position: usize, _count: usize, _what: Fetch) {}
}

/// What [`ClosestTest::prefetch`] asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fetch {
    /// A leaf's items (a mesh's triangles: their vertex indices).
    Items,
    /// What the items point to (the vertices).
    Data,
}

impl<F: FnMut(usize, f64) -> Option<f64>> ClosestTest for F {
    #[inline(always)]
    fn test(&mut self, position: usize, t_max: f64) -> Option<f64> {
        self(position, t_max)
    }
}

/// What the any-hit traversal asks of a leaf item: whether it blocks.
pub trait AnyTest {
    /// Whether item `position` is hit within the segment.
    fn test(&mut self, position: usize) -> bool;

    /// Asks the cache for what testing the `count` items from `position`
    /// will read (see [`ClosestTest::prefetch`]).
    #[inline(always)]
    fn prefetch(&self, _position: usize, _count: usize, _what: Fetch) {}
}

impl<F: FnMut(usize) -> bool> AnyTest for F {
    #[inline(always)]
    fn test(&mut self, position: usize) -> bool {
        self(position)
    }
}

/// Traversal stack size kept on the call stack. A visit pops one entry and
/// pushes at most eight, so a tree of depth d needs at most 7·d + 8
/// entries; trees deeper than that use a heap stack.
pub const STACK: usize = 96;

/// The stack entries a traversal of `wide` can need at most.
pub fn stack_need(wide: &[WideNode]) -> usize {
    fn depth(wide: &[WideNode], at: usize) -> usize {
        let node = &wide[at];
        1 + (0..WIDTH)
            .filter(|&i| node.valid & (1 << i) != 0 && node.count[i] == 0)
            .map(|i| depth(wide, node.child[i] as usize))
            .max()
            .unwrap_or(0)
    }
    if wide.is_empty() {
        0
    } else {
        (WIDTH - 1) * depth(wide, 0) + WIDTH
    }
}

/// [`closest`] with a stack for a tree whose traversal needs `need`
/// entries at most ([`stack_need`]): on the call stack where it fits.
#[inline(always)]
pub fn closest_sized<L: Lanes>(
    lanes: L,
    wide: &[WideNode],
    need: usize,
    ray: &NodeRay,
    t_max: f64,
    leaf: impl ClosestTest,
) -> f64 {
    if need <= STACK {
        closest(
            lanes,
            wide,
            ray,
            t_max,
            &mut ArrayVec::<_, STACK>::new(),
            leaf,
        )
    } else {
        closest(lanes, wide, ray, t_max, &mut Vec::with_capacity(need), leaf)
    }
}

/// Closest-hit traversal over wide nodes; see `Bvh::closest`.
///
/// Of the children a node's test lets through, the nearest is taken at
/// once and the others pushed far to near, so they come back nearest first.
/// An entry further than the closest hit found meanwhile is dropped when
/// popped.
#[inline(always)]
pub fn closest<L: Lanes>(
    lanes: L,
    wide: &[WideNode],
    ray: &NodeRay,
    mut t_max: f64,
    stack: &mut impl Stack<StackEntry>,
    mut leaf: impl ClosestTest,
) -> f64 {
    if wide.is_empty() {
        return t_max;
    }
    let mut limit = NodeRay::box_limit(t_max);
    let mut current = 0usize;
    loop {
        let node = &wide[current];
        let (met, keys) = lanes.ordered_entries(node, ray, limit);
        if met != 0 {
            // The nearest child is taken at once; the others go on the
            // stack far to near, so they come back nearest first.
            for &key in keys[1..met].iter().rev() {
                let lane = key_lane(key);
                // Its node is visited after the nearest child's subtree:
                // time enough for the cache to fetch it.
                if node.count[lane] == 0 {
                    lanes.prefetch(&wide[node.child[lane] as usize]);
                }
                stack.push(StackEntry {
                    index: node.child[lane],
                    count: node.count[lane].into(),
                    entry: key_entry(key),
                });
            }
            let first = key_lane(keys[0]);
            let (child, count) = (node.child[first] as usize, node.count[first] as usize);
            if count == 0 {
                current = child;
                continue;
            }
            test_leaf(&mut leaf, child, count, &mut t_max, &mut limit);
        }
        // Pop until an interior node to visit; leaves are tested on the way.
        loop {
            let Some(e) = stack.pop() else {
                return t_max;
            };
            if e.entry > limit {
                continue;
            }
            if e.count == 0 {
                current = e.index as usize;
                break;
            }
            let start = e.index as usize;
            test_leaf(&mut leaf, start, e.count as usize, &mut t_max, &mut limit);
        }
    }
}

/// Tests the leaf items `start..start + count` against the ray in turn,
/// each up to the closest hit so far: `t_max` and its box limit follow
/// each hit found.
#[inline(always)]
pub(super) fn test_leaf(
    leaf: &mut impl ClosestTest,
    start: usize,
    count: usize,
    t_max: &mut f64,
    limit: &mut f32,
) {
    for position in start..start + count {
        if let Some(t) = leaf.test(position, *t_max) {
            *t_max = t;
            *limit = NodeRay::box_limit(t);
        }
    }
}

/// Closest-hit traversal of the first `count` of K rays in turns, each
/// ray with its own stack, limit and leaf test: what [`closest`] does for
/// each, one step per turn, where a step is a node visit, a leaf's items
/// asked for, its data asked for, or its test. What a ray will read next
/// is prefetched at the end of its step, so its cache misses wait while
/// the other rays take theirs: on a mesh larger than the cache, incoherent
/// rays otherwise wait on a node, a leaf's indices, then its vertices, one
/// after the other. Each ray visits the nodes and tests the items its own
/// traversal would, so its answer is its answer alone.
#[inline(always)]
pub fn closest_stream<L: Lanes, T: ClosestTest, const K: usize>(
    lanes: L,
    wide: &[WideNode],
    rays: &[NodeRay; K],
    count: usize,
    t_max: &mut [f64; K],
    stacks: &mut [impl Stack<StackEntry>; K],
    tests: &mut [T; K],
) {
    /// Where a ray's traversal stands.
    #[derive(Clone, Copy)]
    enum Step {
        Node(usize),
        /// A leaf's first item and count, its data asked for or not.
        Leaf(usize, usize, Fetch),
        Pop,
        Done,
    }
    if wide.is_empty() {
        return;
    }
    let mut limit: [f32; K] = std::array::from_fn(|k| NodeRay::box_limit(t_max[k]));
    let mut step = [Step::Node(0); K];
    let mut active: u32 = (1u32 << count.min(K)) - 1;
    while active != 0 {
        let mut scan = active;
        while scan != 0 {
            let k = scan.trailing_zeros() as usize;
            scan &= scan - 1;
            let stack = &mut stacks[k];
            let mut next = step[k];
            match next {
                Step::Node(at) => {
                    let node = &wide[at];
                    let (met, keys) = lanes.ordered_entries(node, &rays[k], limit[k]);
                    next = Step::Pop;
                    if met != 0 {
                        for &key in keys[1..met].iter().rev() {
                            let lane = key_lane(key);
                            stack.push(StackEntry {
                                index: node.child[lane],
                                count: node.count[lane].into(),
                                entry: key_entry(key),
                            });
                        }
                        let first = key_lane(keys[0]);
                        let (child, items) =
                            (node.child[first] as usize, node.count[first] as usize);
                        next = if items == 0 {
                            lanes.prefetch(&wide[child]);
                            Step::Node(child)
                        } else {
                            tests[k].prefetch(child, items, Fetch::Items);
                            Step::Leaf(child, items, Fetch::Items)
                        };
                    }
                }
                Step::Leaf(start, items, Fetch::Items) => {
                    tests[k].prefetch(start, items, Fetch::Data);
                    next = Step::Leaf(start, items, Fetch::Data);
                }
                Step::Leaf(start, items, Fetch::Data) => {
                    for position in start..start + items {
                        if let Some(t) = tests[k].test(position, t_max[k]) {
                            t_max[k] = t;
                            limit[k] = NodeRay::box_limit(t);
                        }
                    }
                    next = Step::Pop;
                }
                Step::Pop | Step::Done => {}
            }
            if let Step::Pop = next {
                next = Step::Done;
                while let Some(e) = stack.pop() {
                    if e.entry > limit[k] {
                        continue;
                    }
                    let (at, items) = (e.index as usize, e.count as usize);
                    next = if items == 0 {
                        lanes.prefetch(&wide[at]);
                        Step::Node(at)
                    } else {
                        tests[k].prefetch(at, items, Fetch::Items);
                        Step::Leaf(at, items, Fetch::Items)
                    };
                    break;
                }
            }
            if let Step::Done = next {
                active &= !(1 << k);
            }
            step[k] = next;
        }
    }
}

/// Any-hit traversal of the first `count` of K rays in turns, each ray
/// with its own stack and leaf test: what [`any`] does for each, one step
/// per turn (a node visit, a leaf's items asked for, its data asked for,
/// or its test), with what a ray reads next prefetched at the end of its
/// step, as [`closest_stream`] does. Leaves go on the stack beside
/// interior nodes rather than being tested at once, so a ray may test its
/// leaves in another order than [`any`]; whether some item blocks it does
/// not depend on the order. Returns the mask of the rays blocked.
#[inline(always)]
pub fn any_stream<L: Lanes, T: AnyTest, const K: usize>(
    lanes: L,
    wide: &[WideNode],
    rays: &[NodeRay; K],
    count: usize,
    t_max: &[f64; K],
    stacks: &mut [impl Stack<StackEntry>; K],
    tests: &mut [T; K],
) -> u32 {
    /// Where a ray's traversal stands.
    #[derive(Clone, Copy)]
    enum Step {
        Node(usize),
        /// A leaf's first item and count, its data asked for or not.
        Leaf(usize, usize, Fetch),
        Pop,
    }
    if wide.is_empty() {
        return 0;
    }
    let limit: [f32; K] = std::array::from_fn(|k| NodeRay::box_limit(t_max[k]));
    let mut step = [Step::Node(0); K];
    let mut active: u32 = (1u32 << count.min(K)) - 1;
    let mut blocked = 0u32;
    while active != 0 {
        let mut scan = active;
        while scan != 0 {
            let k = scan.trailing_zeros() as usize;
            scan &= scan - 1;
            let stack = &mut stacks[k];
            let mut next = step[k];
            match next {
                Step::Node(at) => {
                    let node = &wide[at];
                    let (mut mask, _) = lanes.entries(node, &rays[k], limit[k]);
                    while mask != 0 {
                        let lane = mask.trailing_zeros() as usize;
                        mask &= mask - 1;
                        stack.push(StackEntry {
                            index: node.child[lane],
                            count: node.count[lane].into(),
                            entry: 0.0,
                        });
                    }
                    next = Step::Pop;
                }
                Step::Leaf(start, items, Fetch::Items) => {
                    tests[k].prefetch(start, items, Fetch::Data);
                    next = Step::Leaf(start, items, Fetch::Data);
                }
                Step::Leaf(start, items, Fetch::Data) => {
                    if (start..start + items).any(|p| tests[k].test(p)) {
                        blocked |= 1 << k;
                        active &= !(1 << k);
                        continue;
                    }
                    next = Step::Pop;
                }
                Step::Pop => {}
            }
            if let Step::Pop = next {
                match stack.pop() {
                    None => {
                        active &= !(1 << k);
                        continue;
                    }
                    Some(e) => {
                        let (at, items) = (e.index as usize, e.count as usize);
                        next = if items == 0 {
                            lanes.prefetch(&wide[at]);
                            Step::Node(at)
                        } else {
                            tests[k].prefetch(at, items, Fetch::Items);
                            Step::Leaf(at, items, Fetch::Items)
                        };
                    }
                }
            }
            step[k] = next;
        }
    }
    blocked
}

/// A child a node test lets through, as a sort key: its entry distance's
/// bits (a non-negative f32 orders as its bits do) with the lowest three
/// replaced by its lane, so that keys sort nearest first (ties, and
/// distances within 8 ulps, by lane) and one u32 carries both. The order
/// decides only what is tested first, never the answer.
#[inline(always)]
pub(super) fn child_key(near: f32, lane: usize) -> u32 {
    (near.to_bits() & !7) | lane as u32
}

/// The lane of a [`child_key`].
#[inline(always)]
pub(super) fn key_lane(key: u32) -> usize {
    (key & 7) as usize
}

/// The entry distance of a [`child_key`], rounded down (to a multiple of
/// 8 ulps), so that culling by it keeps every box the exact one keeps.
#[inline(always)]
pub(super) fn key_entry(key: u32) -> f32 {
    f32::from_bits(key & !7)
}

/// Any-hit traversal over wide nodes; see `Bvh::any`. Leaves are tested as
/// soon as their box is met, interior children go on the stack.
#[inline(always)]
pub fn any<L: Lanes>(
    lanes: L,
    wide: &[WideNode],
    ray: &NodeRay,
    t_max: f64,
    stack: &mut impl Stack<u32>,
    mut leaf: impl AnyTest,
) -> bool {
    if wide.is_empty() {
        return false;
    }
    let limit = NodeRay::box_limit(t_max);
    let mut current = 0usize;
    loop {
        let node = &wide[current];
        let (mut mask, _) = lanes.entries(node, ray, limit);
        while mask != 0 {
            let lane = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            let (child, count) = (node.child[lane], node.count[lane]);
            if count > 0 {
                let start = child as usize;
                if (start..start + count as usize).any(|p| leaf.test(p)) {
                    return true;
                }
            } else {
                stack.push(child);
            }
        }
        match stack.pop() {
            Some(next) => current = next as usize,
            None => return false,
        }
    }
}

/// Visits the item positions of every leaf whose box may hold an item
/// within `reach`, the boxes met at each node nearest first: `lower(box)`
/// bounds from below the distance (in any monotone measure, such as its
/// square) of anything in the box, and `test(position, reach)` returns the
/// reach it leaves (lowered once an item is found within it). A box whose
/// bound exceeds the reach at the time it is taken up is skipped. `stack`
/// is cleared first. Returns the final reach.
pub fn nearest_items(
    wide: &[WideNode],
    stack: &mut Vec<(f64, u32, u16)>,
    mut reach: f64,
    lower: impl Fn(&crate::geometry::Aabb) -> f64,
    mut test: impl FnMut(usize, f64) -> f64,
) -> f64 {
    stack.clear();
    if wide.is_empty() {
        return reach;
    }
    stack.push((f64::NEG_INFINITY, 0, 0));
    while let Some((bound, child, count)) = stack.pop() {
        if bound > reach {
            continue;
        }
        if count > 0 {
            let start = child as usize;
            for position in start..start + usize::from(count) {
                reach = test(position, reach);
            }
            continue;
        }
        let node = &wide[child as usize];
        // Pushed farthest first, so that the nearest is taken up next: each
        // box met inserted below those nearer than it (of equal bounds, the
        // later lane is taken up first; the answer does not depend on it).
        let base = stack.len();
        for lane in 0..WIDTH {
            if node.valid & (1 << lane) == 0 {
                continue;
            }
            let bound = lower(&node.lane_box(lane));
            if bound > reach {
                continue;
            }
            let mut at = stack.len();
            while at > base && stack[at - 1].0 < bound {
                at -= 1;
            }
            stack.insert(at, (bound, node.child[lane], node.count[lane]));
        }
    }
    reach
}

/// Visits, in no particular order, the item positions of every leaf whose
/// box passes `keep`, descending only into boxes that pass it. Stops and
/// returns false as soon as `visit` returns false.
pub fn visit(
    wide: &[WideNode],
    stack: &mut impl Stack<u32>,
    keep: impl Fn(&crate::geometry::Aabb) -> bool,
    mut visit: impl FnMut(usize) -> bool,
) -> bool {
    if wide.is_empty() {
        return true;
    }
    let mut current = 0usize;
    loop {
        let node = &wide[current];
        for lane in 0..WIDTH {
            if node.valid & (1 << lane) == 0 {
                continue;
            }
            if !keep(&node.lane_box(lane)) {
                continue;
            }
            let (child, count) = (node.child[lane], node.count[lane]);
            if count > 0 {
                let start = child as usize;
                if !(start..start + count as usize).all(&mut visit) {
                    return false;
                }
            } else {
                stack.push(child);
            }
        }
        match stack.pop() {
            Some(next) => current = next as usize,
            None => return true,
        }
    }
}
