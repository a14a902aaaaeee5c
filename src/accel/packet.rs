//! Traversal of the wide tree by packets of up to eight rays: one test of a
//! node answers for the whole packet (`Lanes::packet_entries`, interval
//! arithmetic over the rays), so coherent rays (a tile of camera rays, the
//! feelers from one point to a light) share the node visits one ray at a
//! time would each make. Each child the packet's test lets through is then
//! tested against each ray (`Lanes::ray_mask`: one box, eight rays), so a
//! ray visits only the boxes, and tests only the items, a traversal of its
//! own would (for rays from one origin, whose packet bound is tight, the
//! per-ray test waits for the leaves). Where only one or two of the rays
//! reach a node (rays that went apart), each is tested alone there
//! (`Lanes::entries`, the single-ray test), which costs less.
//!
//! Why each ray gets the hit it gets alone: every box a ray's own test lets
//! through, the packet's test lets through; items are tested by the same
//! exact test with the ray's own closest distance, and the kept hit does
//! not depend on the order (smallest t, then the item first in the mesh's
//! order). Only the number of boxes and items tested changes.

use super::simd::{Lanes, NodePacket, NodeRay, PACKET};
use super::wide::{Stack, WIDTH, WideNode, key_entry, key_lane};

/// A child of a wide node on the packet's closest-hit stack.
#[derive(Clone, Copy, Debug)]
pub struct PacketEntry {
    /// A lower bound of where the packet's rays enter its box.
    entry: f32,
    index: u32,
    /// Leaf child: item count; interior child: 0.
    count: u16,
    /// The rays that visit it (whose own test let its box through, or
    /// for rays from one origin and an interior child, the node's rays).
    rays: u16,
}

/// What the packet's closest-hit traversal asks of a leaf item.
pub trait PacketClosestTest {
    /// Tests item `position` against the rays in mask `rays`, ray k up to
    /// `t_max[k]`; where it keeps a hit, sets `t_max[k]` to its distance.
    /// Returns the mask of the rays whose `t_max` it set.
    fn test(&mut self, rays: u32, position: usize, t_max: &mut [f64; PACKET]) -> u32;
}

/// What the packet's any-hit traversal asks of a leaf item.
pub trait PacketAnyTest {
    /// The rays in mask `rays` that item `position` blocks.
    fn test(&mut self, rays: u32, position: usize) -> u32;
}

/// Up to how many rays a node is tested ray by ray rather than by the
/// packet's test.
const ALONE_UP_TO: u32 = 2;

/// The children of `node` that some ray in `rays` meets before its own
/// limit: the packet's test of all eight first, then each child it lets
/// through by each ray's own test (which removes what the packet's bound
/// lets through only because it spans the rays, such as every box between
/// the origins of rays that start apart). Returns the children's mask, a
/// lower bound of their entry distances, and each child's rays.
#[inline(always)]
fn children<L: Lanes>(
    lanes: L,
    node: &WideNode,
    packet: &NodePacket,
    rays: u32,
    limits: &[f32; PACKET],
) -> (u32, [f32; WIDTH], [u16; WIDTH]) {
    if rays.count_ones() <= ALONE_UP_TO {
        // Few rays left (they went apart): each ray's own test of the node
        // costs less than the packet's test and a per-ray test per child.
        let mut mask = 0;
        let mut near = [f32::INFINITY; WIDTH];
        let mut child_rays = [0u16; WIDTH];
        let mut scan = rays;
        while scan != 0 {
            let k = scan.trailing_zeros() as usize;
            scan &= scan - 1;
            let (m, n) = lanes.entries(node, &packet.ray(k), limits[k]);
            mask |= m;
            let mut lanes_hit = m;
            while lanes_hit != 0 {
                let lane = lanes_hit.trailing_zeros() as usize;
                lanes_hit &= lanes_hit - 1;
                child_rays[lane] |= 1 << k;
                if n[lane] < near[lane] {
                    near[lane] = n[lane];
                }
            }
        }
        return (mask, near, child_rays);
    }
    // The packet's node test culls by the largest of its rays' limits.
    let (mut mask, near) = lanes.packet_entries(node, packet, lanes.masked_max(limits, rays));
    let mut child_rays = [0u16; WIDTH];
    let mut scan = mask;
    while scan != 0 {
        let lane = scan.trailing_zeros() as usize;
        scan &= scan - 1;
        // Rays from one origin are bounded tightly by the packet's test
        // (their frustum's hull); their own tests wait for the leaves.
        let r = if packet.shares_origin() && node.count[lane] == 0 {
            rays
        } else {
            lanes.ray_mask(node, lane, packet, limits) & rays
        };
        if r == 0 {
            mask &= !(1 << lane);
        }
        child_rays[lane] = r as u16;
    }
    (mask, near, child_rays)
}

/// Closest-hit traversal of a packet; see `wide::closest`, which this
/// follows node for node. `t_max[k]` is ray k's limit on entry and its
/// closest hit's distance on return. Each ray visits only boxes its own
/// test lets through.
#[inline(always)]
pub fn closest<L: Lanes>(
    lanes: L,
    wide: &[WideNode],
    packet: &NodePacket,
    t_max: &mut [f64; PACKET],
    stack: &mut impl Stack<PacketEntry>,
    mut leaf: impl PacketClosestTest,
) {
    if wide.is_empty() {
        return;
    }
    let mut limits = t_max.map(NodeRay::box_limit);
    let (mut current, mut current_rays) = (0usize, packet.present());
    loop {
        let node = &wide[current];
        let (mask, near, child_rays) = children(lanes, node, packet, current_rays, &limits);
        if mask != 0 {
            let (met, keys) = lanes.order(mask, &near);
            for &key in keys[1..met].iter().rev() {
                let lane = key_lane(key);
                if node.count[lane] == 0 {
                    lanes.prefetch(&wide[node.child[lane] as usize]);
                }
                stack.push(PacketEntry {
                    index: node.child[lane],
                    count: node.count[lane],
                    rays: child_rays[lane],
                    entry: key_entry(key),
                });
            }
            let first = key_lane(keys[0]);
            let (child, count) = (node.child[first] as usize, node.count[first] as usize);
            if count == 0 {
                (current, current_rays) = (child, child_rays[first].into());
                continue;
            }
            test_leaf(
                &mut leaf,
                child,
                count,
                child_rays[first].into(),
                t_max,
                &mut limits,
            );
        }
        // Pop until an interior node to visit; leaves are tested on the way.
        loop {
            let Some(e) = stack.pop() else {
                return;
            };
            // Only its own rays' limits matter to an entry.
            if e.entry > lanes.masked_max(&limits, e.rays.into()) {
                continue;
            }
            if e.count == 0 {
                (current, current_rays) = (e.index as usize, e.rays.into());
                break;
            }
            test_leaf(
                &mut leaf,
                e.index as usize,
                e.count.into(),
                e.rays.into(),
                t_max,
                &mut limits,
            );
        }
    }
}

/// Tests the items `start..start + count` of a leaf against the rays in
/// mask `rays`, each up to its closest hit so far.
#[inline(always)]
fn test_leaf(
    leaf: &mut impl PacketClosestTest,
    start: usize,
    count: usize,
    rays: u32,
    t_max: &mut [f64; PACKET],
    limits: &mut [f32; PACKET],
) {
    for position in start..start + count {
        let mut closer = leaf.test(rays, position, t_max);
        while closer != 0 {
            let k = closer.trailing_zeros() as usize;
            closer &= closer - 1;
            limits[k] = NodeRay::box_limit(t_max[k]);
        }
    }
}

/// Any-hit traversal of a packet; see `wide::any`. Returns the mask of the
/// rays blocked within their `t_max`; a blocked ray is tested no further,
/// and the traversal ends when every ray is blocked. Each ray visits only
/// boxes its own test lets through.
#[inline(always)]
pub fn any<L: Lanes>(
    lanes: L,
    wide: &[WideNode],
    packet: &NodePacket,
    t_max: &[f64; PACKET],
    stack: &mut impl Stack<(u32, u32)>,
    mut leaf: impl PacketAnyTest,
) -> u32 {
    let present = packet.present();
    if wide.is_empty() {
        return 0;
    }
    let limits = t_max.map(NodeRay::box_limit);
    let mut open = present;
    let (mut current, mut current_rays) = (0usize, present);
    loop {
        let node = &wide[current];
        let (mut mask, _, child_rays) = children(lanes, node, packet, current_rays & open, &limits);
        while mask != 0 {
            let lane = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            let (child, count, rays) = (
                node.child[lane],
                node.count[lane],
                u32::from(child_rays[lane]),
            );
            if count == 0 {
                stack.push((child, rays));
                continue;
            }
            let start = child as usize;
            for position in start..start + count as usize {
                if rays & open == 0 {
                    break;
                }
                open &= !leaf.test(rays & open, position);
            }
            if open == 0 {
                return present;
            }
        }
        loop {
            match stack.pop() {
                Some((next, rays)) if rays & open != 0 => {
                    (current, current_rays) = (next as usize, rays);
                    break;
                }
                Some(_) => {}
                None => return present & !open,
            }
        }
    }
}

/// Whether some ray `span` stands for (`NodePacket::spanning`) may reach
/// a leaf: the packet's node test from the root down, opening every
/// interior child it lets through, until it lets a leaf through or has
/// tested `budget` nodes (then it may: a span that close to the items is
/// not worth more) or nothing is left open (then it cannot). As the test
/// lets through every box one of the rays' own tests would, with their
/// limits at most `limit`, no such ray's traversal then tests an item.
#[inline(always)]
pub fn span_reaches_leaf<L: Lanes>(
    lanes: L,
    wide: &[WideNode],
    span: &NodePacket,
    limit: f32,
    budget: usize,
) -> bool {
    if wide.is_empty() {
        return false;
    }
    // Each visit opens at most eight children.
    let mut open = arrayvec::ArrayVec::<u32, 64>::new();
    open.push(0);
    let mut visits = 0;
    while let Some(at) = open.pop() {
        if visits == budget {
            return true;
        }
        visits += 1;
        let node = &wide[at as usize];
        let (mut mask, _) = lanes.packet_entries(node, span, limit);
        while mask != 0 {
            let lane = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            if node.count[lane] != 0 || open.is_full() {
                return true;
            }
            open.push(node.child[lane]);
        }
    }
    false
}
