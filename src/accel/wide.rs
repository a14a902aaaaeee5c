//! The binary BVH collapsed into a 4-wide one: each node holds the boxes of
//! up to four children in structure-of-arrays form, so one SIMD slab test
//! (four f32 lanes) decides all four, and the tree is about half as deep
//! as the binary one it comes from.

use glam::{Vec3A, Vec4};

use super::bvh::BvhNode;

/// Child slots per node.
pub const WIDTH: usize = 4;
/// Marks an empty slot.
const EMPTY: u32 = u32::MAX;

/// One 4-wide node: 128 bytes, two cache lines.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct WideNode {
    min_x: [f32; WIDTH],
    min_y: [f32; WIDTH],
    min_z: [f32; WIDTH],
    max_x: [f32; WIDTH],
    max_y: [f32; WIDTH],
    max_z: [f32; WIDTH],
    /// Interior child: its node index; leaf child: first item position;
    /// empty slot: `EMPTY`.
    child: [u32; WIDTH],
    /// Leaf child: item count; interior child: 0.
    count: [u16; WIDTH],
    /// Bit i set when slot i holds a child.
    valid: u32,
}

impl WideNode {
    const EMPTY_NODE: WideNode = WideNode {
        // Empty slots are masked out by `valid`.
        min_x: [f32::INFINITY; WIDTH],
        min_y: [f32::INFINITY; WIDTH],
        min_z: [f32::INFINITY; WIDTH],
        max_x: [f32::NEG_INFINITY; WIDTH],
        max_y: [f32::NEG_INFINITY; WIDTH],
        max_z: [f32::NEG_INFINITY; WIDTH],
        child: [EMPTY; WIDTH],
        count: [0; WIDTH],
        valid: 0,
    };

    /// Entry distances of the ray into the four child boxes (before
    /// `t_max`), as a lane mask and the distances.
    #[inline]
    fn entries(&self, origin: Vec3A, inv_dir: Vec3A, t_max: f32) -> (u32, [f32; WIDTH]) {
        let slab = |min: &[f32; WIDTH], max: &[f32; WIDTH], o: f32, inv: f32| {
            let t0 = (Vec4::from_array(*min) - Vec4::splat(o)) * inv;
            let t1 = (Vec4::from_array(*max) - Vec4::splat(o)) * inv;
            (t0.min(t1), t0.max(t1))
        };
        let (nx, fx) = slab(&self.min_x, &self.max_x, origin.x, inv_dir.x);
        let (ny, fy) = slab(&self.min_y, &self.max_y, origin.y, inv_dir.y);
        let (nz, fz) = slab(&self.min_z, &self.max_z, origin.z, inv_dir.z);
        let near = nx.max(ny).max(nz).max(Vec4::ZERO);
        let far = fx.min(fy).min(fz) * (1.0 + 8.0 * f32::EPSILON);
        let mask = near.cmple(far.min(Vec4::splat(t_max))).bitmask() & self.valid;
        (mask, near.to_array())
    }
}

impl WideNode {
    /// The box of slot `lane`, widened to f64.
    fn lane_box(&self, lane: usize) -> crate::geometry::Aabb {
        crate::geometry::Aabb {
            min: glam::DVec3::new(
                self.min_x[lane].into(),
                self.min_y[lane].into(),
                self.min_z[lane].into(),
            ),
            max: glam::DVec3::new(
                self.max_x[lane].into(),
                self.max_y[lane].into(),
                self.max_z[lane].into(),
            ),
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

/// A child of a wide node, as the traversal stack holds it.
#[derive(Clone, Copy, Debug, Default)]
pub struct StackEntry {
    index: u32,
    count: u16,
    entry: f32,
}

/// Collapses the binary tree `nodes` (root at 0) into wide nodes, root at 0.
pub fn collapse(nodes: &[BvhNode]) -> Vec<WideNode> {
    let mut wide = Vec::with_capacity(nodes.len() / 2 + 1);
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

/// Builds the wide node for binary interior node `at`, returning its index.
fn collapse_into(nodes: &[BvhNode], at: usize, wide: &mut Vec<WideNode>) -> u32 {
    // Open up the child with the largest box until four children show.
    let mut children = vec![at + 1, nodes[at].offset() as usize];
    while children.len() < WIDTH {
        let Some((k, _)) = children
            .iter()
            .enumerate()
            .filter(|(_, c)| nodes[**c].count() == 0)
            .max_by(|a, b| {
                nodes[*a.1]
                    .bounds()
                    .surface_area()
                    .total_cmp(&nodes[*b.1].bounds().surface_area())
            })
        else {
            break;
        };
        let c = children.remove(k);
        children.insert(k, nodes[c].offset() as usize);
        children.insert(k, c + 1);
    }
    let index = wide.len();
    wide.push(WideNode::EMPTY_NODE);
    for (slot, &c) in children.iter().enumerate() {
        let node = &nodes[c];
        let (target, count) = if node.count() > 0 {
            (node.offset(), node.count())
        } else {
            (collapse_into(nodes, c, wide), 0)
        };
        let mut w = wide[index];
        set_slot(&mut w, slot, node, target, count);
        wide[index] = w;
    }
    index as u32
}

fn set_slot(w: &mut WideNode, slot: usize, node: &BvhNode, child: u32, count: u16) {
    let (min, max) = node.raw_bounds();
    w.min_x[slot] = min[0];
    w.min_y[slot] = min[1];
    w.min_z[slot] = min[2];
    w.max_x[slot] = max[0];
    w.max_y[slot] = max[1];
    w.max_z[slot] = max[2];
    w.child[slot] = child;
    w.count[slot] = count;
    w.valid |= 1 << slot;
}

/// Traversal stack size kept on the call stack. A visit pops one entry and
/// pushes at most four, so a tree of depth d needs at most 3·d + 4 entries;
/// trees deeper than that use a heap stack (zeroing a larger array for
/// every ray costs measurable time).
pub const STACK: usize = 64;

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
        3 * depth(wide, 0) + 4
    }
}

/// Closest-hit traversal over wide nodes; see `Bvh::closest`.
#[inline]
pub fn closest(
    wide: &[WideNode],
    origin: Vec3A,
    inv_dir: Vec3A,
    mut t_max: f64,
    stack: &mut [StackEntry],
    mut test: impl FnMut(usize, f64) -> Option<f64>,
) -> f64 {
    if wide.is_empty() {
        return t_max;
    }
    let mut top = 0usize;
    let mut current = 0usize;
    loop {
        let node = &wide[current];
        let (mut mask, near) = node.entries(origin, inv_dir, t_max as f32);
        // Push hit children far to near, so the nearest is popped first.
        let mut order = [0usize; WIDTH];
        let mut n = 0;
        while mask != 0 {
            let lane = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            let mut k = n;
            while k > 0 && near[order[k - 1]] < near[lane] {
                order[k] = order[k - 1];
                k -= 1;
            }
            order[k] = lane;
            n += 1;
        }
        for &lane in &order[..n] {
            stack[top] = StackEntry {
                index: node.child[lane],
                count: node.count[lane],
                entry: near[lane],
            };
            top += 1;
        }
        // Pop until an interior node to visit; leaves are tested on the way.
        loop {
            if top == 0 {
                return t_max;
            }
            top -= 1;
            let e = stack[top];
            if f64::from(e.entry) > t_max {
                continue;
            }
            if e.count == 0 {
                current = e.index as usize;
                break;
            }
            let start = e.index as usize;
            for position in start..start + e.count as usize {
                if let Some(t) = test(position, t_max) {
                    t_max = t;
                }
            }
        }
    }
}

/// Any-hit traversal over wide nodes; see `Bvh::any`.
#[inline]
pub fn any(
    wide: &[WideNode],
    origin: Vec3A,
    inv_dir: Vec3A,
    t_max: f64,
    stack: &mut [u32],
    mut test: impl FnMut(usize) -> bool,
) -> bool {
    if wide.is_empty() {
        return false;
    }
    let limit = t_max as f32;
    let mut top = 0usize;
    let mut current = 0usize;
    loop {
        let node = &wide[current];
        let (mut mask, _) = node.entries(origin, inv_dir, limit);
        while mask != 0 {
            let lane = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            let (child, count) = (node.child[lane], node.count[lane]);
            if count > 0 {
                let start = child as usize;
                if (start..start + count as usize).any(&mut test) {
                    return true;
                }
            } else {
                stack[top] = child;
                top += 1;
            }
        }
        if top == 0 {
            return false;
        }
        top -= 1;
        current = stack[top] as usize;
    }
}

/// Visits, in no particular order, the item positions of every leaf whose
/// box passes `keep`, descending only into boxes that pass it. Stops and
/// returns false as soon as `visit` returns false.
pub fn visit(
    wide: &[WideNode],
    stack: &mut [u32],
    keep: impl Fn(&crate::geometry::Aabb) -> bool,
    mut visit: impl FnMut(usize) -> bool,
) -> bool {
    if wide.is_empty() {
        return true;
    }
    let mut top = 0usize;
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
                stack[top] = child;
                top += 1;
            }
        }
        if top == 0 {
            return true;
        }
        top -= 1;
        current = stack[top] as usize;
    }
}
