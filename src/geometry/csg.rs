//! Constructive solid geometry (POV-Ray's `union`, `intersection`,
//! `difference`, `merge` and `inverse`) by Roth's ray casting (1982):
//! each child says along which intervals of the ray's whole line it is
//! inside (`span.rs`; spheres, boxes, cones, tori, half-spaces, closed
//! meshes and CSG itself); the operation combines those interval lists as
//! sets, and the ray's hit is the first end of a combined interval in its
//! range. Nothing here knows a shape: it asks its children only for their
//! intervals, bounds and texture coordinates.
//!
//! - union and merge: A ∪ B ∪ …; intersection: A ∩ B ∩ …; difference:
//!   A ∩ ¬B ∩ ¬C …; `inverse`: the complement ¬A (its surfaces face in).
//!   At the top of a scene a union's children are placed as separate
//!   objects, every surface of each kept (POV-Ray's union, inner surfaces
//!   included); inside another operation a union is the set union, like
//!   merge (only the transparent case can tell them apart).
//! - Intervals are closed sets. A surface shared by two children (two
//!   boxes face to face, a hole cut flush with a face) belongs to the set's
//!   boundary only where the set changes there, and then it is the earlier
//!   child's; an interval of zero length after an operation is dropped.
//!   So coincident faces neither leave a sliver nor flicker between
//!   children: the answer is a function of the children's intervals
//!   alone, the same for every ray order, thread and SIMD path.
//! - The normal at an end is the outward normal of the combined solid
//!   (a child's, turned round where the child is subtracted or inverted),
//!   so refraction sees the CSG's boundary: a glass merge has no inner
//!   surface, an air bubble cut from a block is entered as air.

use glam::DVec3;
use smallvec::{Array, SmallVec};

use super::cuboid::slab_interval;
use super::span::{Interval, Surface};
use super::{Aabb, ShapeHit};
use crate::accel::Shape;
use crate::accel::bvh::Bvh;
use crate::math::Ray;

/// Children beyond this many are found through a BVH of their boxes
/// rather than one by one.
const INDEXED_CHILDREN: usize = 8;

/// The four operations.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CsgOp {
    /// Every child's solid; inside another operation, the set union.
    Union,
    /// Where all children are.
    Intersection,
    /// The first child less all the others.
    Difference,
    /// The set union, without the surfaces inside it.
    Merge,
}

impl CsgOp {
    /// The name as written in scene files.
    pub fn name(self) -> &'static str {
        match self {
            CsgOp::Union => "union",
            CsgOp::Intersection => "intersection",
            CsgOp::Difference => "difference",
            CsgOp::Merge => "merge",
        }
    }
}

/// One operand: a closed shape (or CSG), its material and whether it is
/// turned inside out.
#[derive(Clone, Debug, PartialEq)]
pub struct CsgChild {
    /// The solid.
    pub shape: Shape,
    /// Its material (the CSG's when the child has none of its own).
    pub material: u32,
    /// POV-Ray's `inverse`: the complement of the solid.
    pub inverse: bool,
}

/// A CSG node.
#[derive(Clone, Debug, PartialEq)]
pub struct Csg {
    op: CsgOp,
    children: Vec<CsgChild>,
    /// Each child's box (`None`: unbounded, or inverted).
    child_bounds: Vec<Option<Aabb>>,
    /// For many children: a tree over the bounded ones (with the child of
    /// each tree item), and the unbounded ones, tested by every ray.
    index: Option<(Bvh, Vec<u32>, Vec<u32>)>,
    /// How many children are bounded (and not inverted).
    bounded_count: usize,
    bounds: Option<Aabb>,
    /// The first this many children have boxes that hold `bounds` (a
    /// difference's first child, every child of an intersection whose
    /// children's boxes overlap): a line that meets `bounds` meets theirs.
    holding: usize,
    /// The material that fills the solid, when the CSG names one.
    medium: Option<u32>,
}

/// An end of an interval of the combined solid: the surface there, as a
/// query hands it out (one end at most becomes the hit): the normal and
/// what shading needs beyond it are worked out for that one end, from its
/// leaf.
#[derive(Clone, Copy, Debug)]
pub struct Boundary<'a> {
    /// Line parameter (±∞: no surface).
    pub t: f64,
    /// Which part of the leaf's surface (see `Surface::part`).
    pub part: u8,
    /// The leaf's own normal where it is known up front: a mesh's
    /// triangle (as wound); zero for analytic leaves, which give theirs
    /// when asked (`Shape::surface_normal`).
    given: DVec3,
    /// The leaf shape the surface belongs to (`None` at ±∞).
    pub leaf: Option<&'a Shape>,
    /// Material of the leaf's surface.
    pub material: u32,
    /// Whether the set's outward normal is the leaf's own turned round
    /// (the end of a subtracted or inverted child, a mesh wound inward).
    pub flipped: bool,
}

/// One interval of the combined solid.
#[derive(Clone, Copy, Debug)]
pub struct Span<'a> {
    /// Where the line enters.
    pub enter: Boundary<'a>,
    /// Where it leaves.
    pub exit: Boundary<'a>,
}

/// A list of disjoint intervals in ascending order.
pub type Spans<'a> = SmallVec<[Span<'a>; 4]>;

impl<'a> Boundary<'a> {
    /// The leaf's own outward normal here, for the ray the lists were
    /// built for.
    fn own_normal(&self, ray: &Ray) -> DVec3 {
        match self.leaf {
            Some(leaf) if !matches!(leaf, Shape::Mesh(_)) => leaf.surface_normal(
                ray,
                Surface {
                    t: self.t,
                    part: self.part,
                },
            ),
            _ => self.given,
        }
    }

    /// The outward unit normal of the set this boundary bounds (a
    /// child's, turned round where the child is subtracted or inverted;
    /// zero at ±∞), for the ray the lists were built for.
    pub fn normal(&self, ray: &Ray) -> DVec3 {
        let own = self.own_normal(ray);
        if self.flipped { -own } else { own }
    }

    /// The hit this boundary is for `ray`: the leaf's texture coordinates
    /// (and a mesh's shading normal and colour, from its triangle there).
    pub fn hit(&self, ray: &Ray) -> ShapeHit {
        // The leaf computes its coordinates from its own normal.
        let own = self.own_normal(ray);
        let normal = if self.flipped { -own } else { own };
        let mut h = ShapeHit::geometric(self.t, normal, ray.direction.dot(normal) < 0.0);
        h.material = Some(self.material);
        let Some(leaf) = self.leaf else {
            return h;
        };
        if let Shape::Mesh(m) = leaf {
            let reach = 1e-9 * self.t.abs().max(1.0);
            if let Some(m) = m.intersect(ray, self.t - reach, self.t + reach) {
                let sign = if m.normal.dot(normal) < 0.0 {
                    -1.0
                } else {
                    1.0
                };
                h.shading_normal = sign * m.shading_normal;
                h.uv = m.uv;
                h.color = m.color;
            }
            return h;
        }
        h.uv = leaf.uv(ray.at(self.t), &ShapeHit { normal: own, ..h });
        h
    }
}

/// Whether `End::tag` says the end is turned round.
const FLIPPED: u32 = 1 << 31;

/// An end as the lists of a query under way carry it: a [`Boundary`]
/// packed into 24 bytes, since these lists are built, combined and moved
/// for every ray. A mesh's normal, the one thing known up front, waits in
/// `Work::normals`, and the end holds its place there.
#[derive(Clone, Copy, Debug)]
struct End<'a> {
    /// Line parameter (±∞: no surface).
    t: f64,
    /// The leaf shape the surface belongs to (`None` at ±∞).
    leaf: Option<&'a Shape>,
    /// Material of the leaf's surface.
    material: u32,
    /// The leaf's surface part (a mesh's: the place of its normal in
    /// `Work::normals`), and `FLIPPED`.
    tag: u32,
}

/// One interval of the combined solid, as a query's lists carry it.
#[derive(Clone, Copy, Debug)]
struct Piece<'a> {
    enter: End<'a>,
    exit: End<'a>,
}

impl<'a> End<'a> {
    /// No surface, at t = ±∞.
    const fn at_infinity(t: f64) -> Self {
        End {
            t,
            leaf: None,
            material: 0,
            tag: 0,
        }
    }

    #[inline(always)]
    fn of_surface(s: Surface, material: u32, leaf: &'a Shape) -> Self {
        if !s.t.is_finite() {
            return End::at_infinity(s.t);
        }
        End {
            t: s.t,
            leaf: Some(leaf),
            material,
            tag: u32::from(s.part),
        }
    }

    /// A mesh's hit as an end, its normal kept in `normals`; `enters`
    /// says which end, so the normal faces against the line on entry and
    /// along it on exit whichever way the mesh is wound.
    fn of_mesh_hit(
        h: &ShapeHit,
        enters: bool,
        direction: DVec3,
        leaf: &'a Shape,
        normals: &mut Vec<DVec3>,
    ) -> Self {
        let outward = (h.normal.dot(direction) < 0.0) == enters;
        let place = normals.len() as u32;
        normals.push(h.normal);
        End {
            t: h.t,
            leaf: Some(leaf),
            material: h.material.unwrap_or(0),
            tag: if outward { place } else { place | FLIPPED },
        }
    }

    /// The same surface bounding the complement.
    #[inline(always)]
    fn turned(self) -> Self {
        End {
            tag: self.tag ^ FLIPPED,
            ..self
        }
    }

    fn flipped(&self) -> bool {
        self.tag & FLIPPED != 0
    }

    /// The end unpacked, its mesh normal (if any) taken from `normals`.
    fn boundary(&self, normals: &[DVec3]) -> Boundary<'a> {
        let tag = self.tag & !FLIPPED;
        let (part, given) = match self.leaf {
            Some(Shape::Mesh(_)) => (0, normals[tag as usize]),
            _ => (tag as u8, DVec3::ZERO),
        };
        Boundary {
            t: self.t,
            part,
            given,
            leaf: self.leaf,
            material: self.material,
            flipped: self.flipped(),
        }
    }
}

/// A ∪ B, appended to `out`. Overlapping or touching intervals join; on
/// equal parameters A's boundary is kept.
fn unite_into<'a, A: Array<Item = Piece<'a>>>(
    a: &[Piece<'a>],
    b: &[Piece<'a>],
    out: &mut SmallVec<A>,
) {
    let first = out.len();
    let (mut i, mut j) = (0, 0);
    while i < a.len() || j < b.len() {
        let next = if j >= b.len() || (i < a.len() && a[i].enter.t <= b[j].enter.t) {
            i += 1;
            a[i - 1]
        } else {
            j += 1;
            b[j - 1]
        };
        match out[first..].last_mut() {
            Some(last) if next.enter.t <= last.exit.t => {
                if next.exit.t > last.exit.t {
                    last.exit = next.exit;
                }
            }
            _ => out.push(next),
        }
    }
}

/// A ∩ B, appended to `out`. Each interval runs from the later entry to
/// the earlier exit; on equal parameters A's boundary is kept; empty
/// results are dropped. B comes one interval at a time (it may be a
/// complement worked out as it goes).
#[inline(always)]
fn intersect_into<'a, A: Array<Item = Piece<'a>>>(
    a: &[Piece<'a>],
    mut b: impl Iterator<Item = Piece<'a>>,
    out: &mut SmallVec<A>,
) {
    let mut i = 0;
    let mut pending = b.next();
    while let (Some(x), Some(y)) = (a.get(i), pending) {
        let enter = if x.enter.t >= y.enter.t {
            x.enter
        } else {
            y.enter
        };
        let exit = if x.exit.t <= y.exit.t { x.exit } else { y.exit };
        if enter.t < exit.t {
            out.push(Piece { enter, exit });
        }
        // Written so that a NaN end still advances (no endless loop).
        if x.exit.t.total_cmp(&y.exit.t).is_le() {
            i += 1;
        }
        if y.exit.t.total_cmp(&x.exit.t).is_le() {
            pending = b.next();
        }
    }
}

/// ¬A over the whole line, its boundaries A's turned round, one interval
/// at a time.
struct Complement<'s, 'a> {
    rest: std::slice::Iter<'s, Piece<'a>>,
    /// Where the next interval starts; `None` once the last is out.
    from: Option<End<'a>>,
}

impl<'s, 'a> Complement<'s, 'a> {
    fn of(a: &'s [Piece<'a>]) -> Self {
        Complement {
            rest: a.iter(),
            from: Some(End::at_infinity(f64::NEG_INFINITY)),
        }
    }
}

impl<'a> Iterator for Complement<'_, 'a> {
    type Item = Piece<'a>;

    #[inline(always)]
    fn next(&mut self) -> Option<Piece<'a>> {
        let mut from = self.from?;
        for s in self.rest.by_ref() {
            let enter = from;
            from = s.exit.turned();
            if enter.t < s.enter.t {
                self.from = Some(from);
                return Some(Piece {
                    enter,
                    exit: s.enter.turned(),
                });
            }
        }
        self.from = None;
        (from.t < f64::INFINITY).then_some(Piece {
            enter: from,
            exit: End::at_infinity(f64::INFINITY),
        })
    }
}

/// Whether any of `list` overlaps the open `window`: whether it has a
/// point there (its ends inside the window are then the set's there too).
#[inline(always)]
fn reaches(list: &[Piece], window: (f64, f64)) -> bool {
    list.iter()
        .any(|s| s.exit.t > window.0 && s.enter.t < window.1)
}

/// The interval lists of one query under way, on the caller's stack:
/// each node builds its list at the end of `stack`, its operands' lists
/// above its own, and combines them through `spare`. Lists are moved only
/// as long as they are (a handful of spans), never returned by value.
struct Work<'a> {
    window: (f64, f64),
    stack: SmallVec<[Piece<'a>; 8]>,
    spare: SmallVec<[Piece<'a>; 8]>,
    /// The normals of mesh ends (see `End`).
    normals: Vec<DVec3>,
}

impl<'a> Work<'a> {
    #[inline(always)]
    fn new(window: (f64, f64)) -> Self {
        Work {
            window,
            stack: SmallVec::new(),
            spare: SmallVec::new(),
            normals: Vec::new(),
        }
    }

    /// Replaces `stack[from..]` by `spare`'s list.
    #[inline(always)]
    fn settle(&mut self, from: usize) {
        self.stack.truncate(from);
        self.stack.extend_from_slice(&self.spare);
        self.spare.clear();
    }

    /// Turns `stack[from..]` into its complement.
    fn complement_from(&mut self, from: usize) {
        self.spare.clear();
        self.spare.extend(Complement::of(&self.stack[from..]));
        self.settle(from);
    }

    /// Combines `stack[base..mid]` (the result so far) with `stack[mid..]`
    /// (the next operand's list) by `op`, leaving the result at `base`.
    fn combine(&mut self, op: CsgOp, base: usize, mid: usize) {
        if op == CsgOp::Difference && self.stack.len() == mid {
            // Less nothing: the list as it is (every interval in it
            // encloses something, so ∩ (−∞, +∞) keeps each whole).
            return;
        }
        self.spare.clear();
        let (acc, next) = self.stack[base..].split_at(mid - base);
        match op {
            CsgOp::Union | CsgOp::Merge => unite_into(acc, next, &mut self.spare),
            CsgOp::Intersection => intersect_into(acc, next.iter().copied(), &mut self.spare),
            CsgOp::Difference => intersect_into(acc, Complement::of(next), &mut self.spare),
        }
        self.settle(base);
    }

    /// `end` as a query hands it out.
    fn boundary(&self, end: &End<'a>) -> Boundary<'a> {
        end.boundary(&self.normals)
    }
}

/// Whether the boxes of an intersection's bounded children overlap (in a
/// box that each of them holds).
fn intersection_overlaps(child_bounds: &[Option<Aabb>]) -> bool {
    let mut boxes = child_bounds.iter().flatten();
    let Some(first) = boxes.next() else {
        return false;
    };
    let (min, max) = boxes.fold((first.min, first.max), |(min, max), b| {
        (min.max(b.min), max.min(b.max))
    });
    min.cmple(max).all()
}

/// The children that may matter to a query.
type Candidates = SmallVec<[u32; 8]>;

/// A set of a CSG's children, child i as bit i (those past 64 always in).
pub type ChildMask = u64;

/// Every child.
pub const ALL_CHILDREN: ChildMask = ChildMask::MAX;

/// Whether child `i` is in `mask`.
#[inline(always)]
fn in_mask(mask: ChildMask, i: usize) -> bool {
    i >= ChildMask::BITS as usize || mask >> i & 1 == 1
}

/// Whether `ray` meets `b` with t within `window`.
#[inline]
fn meets(ray: &Ray, window: (f64, f64), b: &Aabb) -> bool {
    slab_interval(ray.origin, ray.direction, b.min, b.max)
        .is_some_and(|((t0, _), (t1, _))| t0 <= window.1 && t1 >= window.0)
}

impl Csg {
    /// The node over `children` (at least one): bounds each child, and
    /// indexes them when there are many.
    pub fn new(op: CsgOp, children: Vec<CsgChild>) -> Csg {
        let child_bounds: Vec<Option<Aabb>> = children
            .iter()
            .map(|c| if c.inverse { None } else { c.shape.bounds() })
            .collect();
        let bounded: Vec<u32> = (0..children.len() as u32)
            .filter(|&i| child_bounds[i as usize].is_some())
            .collect();
        let index = (children.len() > INDEXED_CHILDREN).then(|| {
            let bvh = Bvh::build(bounded.iter().filter_map(|&i| child_bounds[i as usize]));
            let order = bvh.order().iter().map(|&k| bounded[k as usize]).collect();
            let unbounded = (0..children.len() as u32)
                .filter(|&i| child_bounds[i as usize].is_none())
                .collect();
            (bvh, order, unbounded)
        });
        let bounds = match op {
            CsgOp::Union | CsgOp::Merge => child_bounds
                .iter()
                .try_fold(Aabb::EMPTY, |acc, b| b.map(|b| acc.union(&b))),
            CsgOp::Intersection => {
                let mut boxes = child_bounds.iter().flatten();
                boxes.next().map(|first| {
                    let overlap = boxes.fold(*first, |acc, b| Aabb {
                        min: acc.min.max(b.min),
                        max: acc.max.min(b.max),
                    });
                    // No overlap: nothing to draw; a point stands for it.
                    Aabb {
                        min: overlap.min,
                        max: overlap.max.max(overlap.min),
                    }
                })
            }
            CsgOp::Difference => child_bounds[0],
        };
        let holding = match op {
            CsgOp::Difference => 1,
            CsgOp::Intersection if intersection_overlaps(&child_bounds) => children.len(),
            _ => 0,
        };
        Csg {
            op,
            bounded_count: bounded.len(),
            holding,
            children,
            child_bounds,
            index,
            bounds,
            medium: None,
        }
    }

    /// The node with `medium` filling it (the CSG's own material): its
    /// index of refraction holds inside whichever part paints a surface.
    pub fn with_medium(mut self, medium: Option<u32>) -> Csg {
        self.medium = medium;
        self
    }

    /// The material filling the solid, if the CSG names one; without one
    /// each surface's own material stands for the medium behind it.
    pub fn medium(&self) -> Option<u32> {
        self.medium
    }

    /// The operation.
    pub fn op(&self) -> CsgOp {
        self.op
    }

    /// The operands.
    pub fn children(&self) -> &[CsgChild] {
        &self.children
    }

    /// The tightest box the operation allows: a union's is its children's
    /// union, an intersection's the overlap of its bounded children's, a
    /// difference's its first child's; `None` when unbounded.
    pub fn bounds(&self) -> Option<Aabb> {
        self.bounds
    }

    /// The children that rays staying in a region may meet, for queries
    /// of many rays there (shadow feelers in their hull): those that pass
    /// `may_meet` (given the child and its box), which must hold for every
    /// child such a ray meets; unbounded and inverted children always.
    /// `None` when no such ray can meet the solid (a difference's first
    /// child or one of an intersection's left out, or nothing left of a
    /// union).
    pub fn children_meeting(
        &self,
        may_meet: impl Fn(&CsgChild, &Aabb) -> bool,
    ) -> Option<ChildMask> {
        let mut mask = ALL_CHILDREN;
        for (i, (child, b)) in self.children.iter().zip(&self.child_bounds).enumerate() {
            if i >= ChildMask::BITS as usize {
                break;
            }
            if b.is_some_and(|b| !may_meet(child, &b)) {
                mask &= !(1 << i);
            }
        }
        let needed = match self.op {
            CsgOp::Intersection => ALL_CHILDREN,
            CsgOp::Difference => 1,
            CsgOp::Union | CsgOp::Merge => 0,
        };
        let any_left = self.children.len() > ChildMask::BITS as usize
            || mask & (ALL_CHILDREN >> (ChildMask::BITS as usize - self.children.len())) != 0;
        (mask & needed == needed && any_left).then_some(mask)
    }

    /// The children whose intervals along `ray` within `window` may not
    /// be empty, ascending, put in `out`; false when one that must be met
    /// (by an intersection, or a difference's first) is not. `met`: the
    /// node's box is known to meet the window, and so are the boxes that
    /// hold it (see `holding`), which are not tested again. The slab test
    /// keeps that to the bit: each operation in it is correctly rounded,
    /// so monotonic, and a box's faces lie outside (or on) those of a box
    /// it holds, so its computed interval holds the other's.
    /// Only the children in `mask` are looked at: the caller knows the
    /// others' boxes miss the window (see [`children_meeting`](Self::children_meeting)).
    #[inline]
    fn candidates(
        &self,
        ray: &Ray,
        window: (f64, f64),
        met: bool,
        mask: ChildMask,
        out: &mut Candidates,
    ) -> bool {
        let mut met_bounded = 0;
        match &self.index {
            Some((bvh, order, unbounded)) if mask.count_ones() as usize > INDEXED_CHILDREN => {
                out.extend(unbounded.iter().copied());
                bvh.visit(
                    |b| meets(ray, window, b),
                    |position| {
                        let child = order[position];
                        let b = self.child_bounds[child as usize];
                        if in_mask(mask, child as usize)
                            && b.is_some_and(|b| meets(ray, window, &b))
                        {
                            met_bounded += 1;
                            out.push(child);
                        }
                        true
                    },
                );
                out.sort_unstable();
            }
            _ => {
                for (i, b) in self.child_bounds.iter().enumerate() {
                    match b {
                        _ if !in_mask(mask, i) => {}
                        None => out.push(i as u32),
                        Some(b) if (met && i < self.holding) || meets(ray, window, b) => {
                            met_bounded += 1;
                            out.push(i as u32);
                        }
                        Some(_) => {}
                    }
                }
            }
        }
        let all_met = met_bounded == self.bounded_count;
        match self.op {
            CsgOp::Intersection => all_met,
            CsgOp::Difference => out.first() == Some(&0),
            _ => true,
        }
    }

    /// Where `ray` is inside the combined solid, exact within `window`
    /// (the set operations work point by point, so parts that cannot
    /// reach the window are left out; outside it the list is not the
    /// solid's). `(−∞, +∞)`: the whole line.
    pub fn spans<'a>(&'a self, ray: &Ray, window: (f64, f64)) -> Spans<'a> {
        let mut work = Work::new(window);
        self.spans_into(ray, &mut work, false, ALL_CHILDREN);
        work.stack
            .iter()
            .map(|s| Span {
                enter: work.boundary(&s.enter),
                exit: work.boundary(&s.exit),
            })
            .collect()
    }

    /// `spans`, appended to `work.stack`. An intersection or difference
    /// stops, its list left empty, once nothing of it reaches the window:
    /// the operands still to come can only take away, and intervals
    /// outside the window change no end inside it, here or above.
    /// `met`: whether this node's box is known to meet the window;
    /// `mask`: the children that may (see `candidates`).
    fn spans_into<'a>(&'a self, ray: &Ray, work: &mut Work<'a>, met: bool, mask: ChildMask) {
        let mut candidates = Candidates::new();
        if !self.candidates(ray, work.window, met, mask, &mut candidates) {
            return;
        }
        let base = work.stack.len();
        let mut ids = candidates.iter().map(|&i| &self.children[i as usize]);
        let Some(first) = ids.next() else {
            return;
        };
        if self.op == CsgOp::Intersection
            && let Some(piece) = single_piece(first, ray)
        {
            // Spheres and boxes, the commonest operands, have one interval
            // at most, and so has their intersection: it is kept here, off
            // the list, for as long as the operands are such.
            let Some(mut acc) = piece else {
                return;
            };
            loop {
                let Some(child) = ids.next() else {
                    work.stack.push(acc);
                    return;
                };
                if !reaches(&[acc], work.window) {
                    return;
                }
                match single_piece(child, ray) {
                    Some(None) => return,
                    Some(Some(next)) => {
                        // `intersect_into` of two one-interval lists.
                        let enter = if acc.enter.t >= next.enter.t {
                            acc.enter
                        } else {
                            next.enter
                        };
                        let exit = if acc.exit.t <= next.exit.t {
                            acc.exit
                        } else {
                            next.exit
                        };
                        if enter.t >= exit.t {
                            return;
                        }
                        acc = Piece { enter, exit };
                    }
                    None => {
                        work.stack.push(acc);
                        let mid = work.stack.len();
                        child_spans_into(child, ray, work);
                        work.combine(self.op, base, mid);
                        break;
                    }
                }
            }
        } else {
            child_spans_into(first, ray, work);
        }
        let joins = matches!(self.op, CsgOp::Union | CsgOp::Merge);
        for child in ids {
            let mid = work.stack.len();
            if !joins && !reaches(&work.stack[base..], work.window) {
                work.stack.truncate(base);
                return;
            }
            child_spans_into(child, ray, work);
            work.combine(self.op, base, mid);
        }
    }

    /// The nearest hit with t in (t_min, t_max): the first end of a
    /// combined interval there.
    pub fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<ShapeHit> {
        Some(self.nearest_boundary(ray, t_min, t_max)?.hit(ray))
    }

    /// The surface of the nearest hit with t in (t_min, t_max), before
    /// its texture coordinates are found: all a shadow feeler needs.
    pub fn nearest_boundary(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<Boundary<'_>> {
        self.nearest_boundary_among(ray, t_min, t_max, ALL_CHILDREN)
    }

    /// [`nearest_boundary`](Self::nearest_boundary) when only the children
    /// in `mask` may meet the ray within (t_min, t_max), as
    /// [`children_meeting`](Self::children_meeting) found them: the same
    /// answer (the others' intervals lie outside the window, where they
    /// change no end inside it), without testing the others' boxes.
    pub fn nearest_boundary_among(
        &self,
        ray: &Ray,
        t_min: f64,
        t_max: f64,
        mask: ChildMask,
    ) -> Option<Boundary<'_>> {
        if self.bounds.is_some_and(|b| !meets(ray, (t_min, t_max), &b)) {
            return None;
        }
        let mut work = Work::new((t_min, t_max));
        self.spans_into(ray, &mut work, self.bounds.is_some(), mask);
        let end = first_end(&work.stack, work.window)?;
        Some(work.boundary(end))
    }

    /// [`nearest_boundary_among`](Self::nearest_boundary_among), and the
    /// parameter of the last surface in (t_min, t_max) (−∞ when none):
    /// past it the ray meets nothing of the solid within the window, which
    /// a feeler continued through glass along the same line can skip.
    pub fn nearest_and_last_boundary_among(
        &self,
        ray: &Ray,
        t_min: f64,
        t_max: f64,
        mask: ChildMask,
    ) -> (Option<Boundary<'_>>, f64) {
        if self.bounds.is_some_and(|b| !meets(ray, (t_min, t_max), &b)) {
            return (None, f64::NEG_INFINITY);
        }
        let mut work = Work::new((t_min, t_max));
        self.spans_into(ray, &mut work, self.bounds.is_some(), mask);
        let Some(end) = first_end(&work.stack, work.window) else {
            return (None, f64::NEG_INFINITY);
        };
        let last = last_end(&work.stack, work.window).map_or(end.t, |e| e.t);
        (Some(work.boundary(end)), last)
    }

    /// The one child that is the whole solid within a window that only the
    /// children in `mask` may meet (see [`children_meeting`](Self::children_meeting)):
    /// a difference's first child with every subtrahend left out, or a
    /// union's one child left, when it is an analytic solid that is not
    /// inverted. The others' intervals lie outside the window, so every
    /// end of its own there is an end of the set, the set's outward normal
    /// its own: [`solo_ends`] answers the query from it alone, without the
    /// lists.
    #[inline]
    pub fn solo(&self, mask: ChildMask) -> Option<&CsgChild> {
        let n = self.children.len();
        if n > ChildMask::BITS as usize {
            return None;
        }
        let left = mask & (ALL_CHILDREN >> (ChildMask::BITS as usize - n));
        let child = match self.op {
            CsgOp::Difference if left == 1 => &self.children[0],
            CsgOp::Union | CsgOp::Merge if left.count_ones() == 1 => {
                &self.children[left.trailing_zeros() as usize]
            }
            _ => return None,
        };
        let analytic = matches!(
            &child.shape,
            Shape::Sphere(_) | Shape::Ellipsoid(_) | Shape::Cuboid(_) | Shape::Torus(_)
        ) || matches!(&child.shape, Shape::Cone(c) if !c.open);
        (analytic && !child.inverse).then_some(child)
    }
}

/// [`Csg::nearest_and_last_boundary_among`] for a CSG that `child` stands
/// for ([`Csg::solo`]): the first of its ends in the open `window` and the
/// parameter of the last (−∞ when none), the same surfaces with the same
/// bits (the child's interval ends, as the lists hold them), without the
/// lists or the CSG's box test.
#[inline]
pub fn solo_ends<'a>(
    child: &'a CsgChild,
    ray: &Ray,
    window: (f64, f64),
) -> (Option<Boundary<'a>>, f64) {
    let within = |s: &Surface| s.t > window.0 && s.t < window.1;
    let (mut first, mut last) = (None, f64::NEG_INFINITY);
    let intervals = match &child.shape {
        // The commonest, without the generic list (as the lists take them).
        Shape::Cuboid(b) => b.interval(ray).into_iter().collect(),
        Shape::Sphere(s) => s.interval(ray).into_iter().collect(),
        shape => shape.intervals(ray),
    };
    for i in &intervals {
        for s in [i.enter, i.exit] {
            if within(&s) {
                first = first.or(Some(s));
                last = s.t;
            }
        }
    }
    let boundary = first.map(|s| Boundary {
        t: s.t,
        part: s.part,
        given: DVec3::ZERO,
        leaf: Some(&child.shape),
        material: child.material,
        flipped: false,
    });
    (boundary, last)
}

/// The last end of `list` inside the open `window`.
#[inline(always)]
fn last_end<'l, 'a>(list: &'l [Piece<'a>], window: (f64, f64)) -> Option<&'l End<'a>> {
    list.iter()
        .rev()
        .flat_map(|s| [&s.exit, &s.enter])
        .find(|b| b.t > window.0 && b.t < window.1)
}

/// The first end of `list` inside the open `window`.
#[inline(always)]
fn first_end<'l, 'a>(list: &'l [Piece<'a>], window: (f64, f64)) -> Option<&'l End<'a>> {
    list.iter()
        .flat_map(|s| [&s.enter, &s.exit])
        .find(|b| b.t > window.0 && b.t < window.1)
}

/// The one interval (or none) of an operand that is a sphere or a box,
/// not inverted; `None` for any other.
#[inline(always)]
fn single_piece<'a>(child: &'a CsgChild, ray: &Ray) -> Option<Option<Piece<'a>>> {
    let interval = match &child.shape {
        _ if child.inverse => return None,
        Shape::Sphere(s) => s.interval(ray),
        Shape::Cuboid(b) => b.interval(ray),
        _ => return None,
    };
    Some(interval.map(|i| Piece {
        enter: End::of_surface(i.enter, child.material, &child.shape),
        exit: End::of_surface(i.exit, child.material, &child.shape),
    }))
}

/// The intervals of one operand, complemented when it is inverted,
/// appended to `work.stack`.
#[inline(always)]
fn child_spans_into<'a>(child: &'a CsgChild, ray: &Ray, work: &mut Work<'a>) {
    let from = work.stack.len();
    shape_spans_into(&child.shape, child.material, child.inverse, ray, work);
    if child.inverse {
        work.complement_from(from);
    }
}

/// The intervals of a shape: a CSG's own, a mesh's by crossing parity,
/// an analytic solid's from its file (a sphere's and a box's, the
/// commonest operands, without going through a list). Shapes without an
/// inside (refused when a scene is built) have none.
#[inline(always)]
fn shape_spans_into<'a>(
    shape: &'a Shape,
    material: u32,
    inverse: bool,
    ray: &Ray,
    work: &mut Work<'a>,
) {
    let piece = |i: Interval| Piece {
        enter: End::of_surface(i.enter, material, shape),
        exit: End::of_surface(i.exit, material, shape),
    };
    match shape {
        // A candidate's box met the window, unless it has none or the
        // child is inverted (then it was not tested).
        Shape::Csg(c) => c.spans_into(ray, work, !inverse && c.bounds.is_some(), ALL_CHILDREN),
        Shape::Mesh(m) => {
            for (a, b) in m.inside(ray) {
                let enter = End::of_mesh_hit(&a, true, ray.direction, shape, &mut work.normals);
                let exit = End::of_mesh_hit(&b, false, ray.direction, shape, &mut work.normals);
                work.stack.push(Piece { enter, exit });
            }
        }
        Shape::Sphere(s) => {
            if let Some(i) = s.interval(ray) {
                work.stack.push(piece(i));
            }
        }
        Shape::Cuboid(b) => {
            if let Some(i) = b.interval(ray) {
                work.stack.push(piece(i));
            }
        }
        other => {
            for i in other.intervals(ray) {
                work.stack.push(piece(i));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::PixelRng;

    fn end(t: f64) -> End<'static> {
        End::at_infinity(t)
    }

    fn spans(list: &[(f64, f64)]) -> Vec<Piece<'static>> {
        list.iter()
            .map(|&(a, b)| Piece {
                enter: end(a),
                exit: end(b),
            })
            .collect()
    }

    fn ends(s: &[Piece]) -> Vec<f64> {
        s.iter().flat_map(|s| [s.enter.t, s.exit.t]).collect()
    }

    fn complement<'a>(a: &[Piece<'a>]) -> Vec<Piece<'a>> {
        Complement::of(a).collect()
    }

    fn combine<'a>(op: CsgOp, a: &[Piece<'a>], b: &[Piece<'a>]) -> Vec<Piece<'a>> {
        let mut out: SmallVec<[Piece; 4]> = SmallVec::new();
        match op {
            CsgOp::Union | CsgOp::Merge => unite_into(a, b, &mut out),
            CsgOp::Intersection => intersect_into(a, b.iter().copied(), &mut out),
            CsgOp::Difference => intersect_into(a, Complement::of(b), &mut out),
        }
        out.into_vec()
    }

    #[test]
    fn the_ray_tracer_challenges_filtering_examples() {
        // A sphere crossed at 1 and 3, a cube at 2 and 4 (The Ray Tracer
        // Challenge, "Filtering a list of intersections").
        let (a, b) = (spans(&[(1.0, 3.0)]), spans(&[(2.0, 4.0)]));
        assert_eq!(ends(&combine(CsgOp::Union, &a, &b)), [1.0, 4.0]);
        assert_eq!(ends(&combine(CsgOp::Intersection, &a, &b)), [2.0, 3.0]);
        assert_eq!(ends(&combine(CsgOp::Difference, &a, &b)), [1.0, 2.0]);
    }

    #[test]
    fn the_ray_tracer_challenges_rule_table() {
        // (operation, hit on the left, inside left, inside right, allowed):
        // the 24 rows of "Evaluating the rule for a CSG operation". A hit
        // at t = 5 on one child; the other child contains 5 or lies away.
        use CsgOp::*;
        let rows = [
            (Union, true, true, true, false),
            (Union, true, true, false, true),
            (Union, true, false, true, false),
            (Union, true, false, false, true),
            (Union, false, true, true, false),
            (Union, false, true, false, false),
            (Union, false, false, true, true),
            (Union, false, false, false, true),
            (Intersection, true, true, true, true),
            (Intersection, true, true, false, false),
            (Intersection, true, false, true, true),
            (Intersection, true, false, false, false),
            (Intersection, false, true, true, true),
            (Intersection, false, true, false, true),
            (Intersection, false, false, true, false),
            (Intersection, false, false, false, false),
            (Difference, true, true, true, false),
            (Difference, true, true, false, true),
            (Difference, true, false, true, false),
            (Difference, true, false, false, true),
            (Difference, false, true, true, true),
            (Difference, false, true, false, true),
            (Difference, false, false, true, false),
            (Difference, false, false, false, false),
        ];
        for (op, lhit, inl, inr, allowed) in rows {
            // The hit child leaves at 5 when the ray is inside it, else
            // enters there; the other holds 5 inside or lies far away.
            let hit_child = |inside: bool| spans(&[if inside { (0.0, 5.0) } else { (5.0, 10.0) }]);
            let other = |inside: bool| spans(&[if inside { (0.0, 10.0) } else { (20.0, 30.0) }]);
            let (a, b) = if lhit {
                (hit_child(inl), other(inr))
            } else {
                (other(inl), hit_child(inr))
            };
            let kept = ends(&combine(op, &a, &b)).contains(&5.0);
            assert_eq!(kept, allowed, "{op:?} lhit={lhit} inl={inl} inr={inr}");
        }
    }

    /// Random interval lists on a coarse grid (so ends coincide often).
    fn random_spans(rng: &mut PixelRng) -> Vec<Piece<'static>> {
        let mut ends = Vec::new();
        let mut t = -1.0;
        while ends.len() < 8 {
            t += 1.0 + (rng.uniform() * 3.0).floor();
            if rng.uniform() < 0.3 {
                break;
            }
            ends.push(t);
        }
        ends.truncate(ends.len() / 2 * 2);
        let mut list: Vec<(f64, f64)> = ends.chunks(2).map(|p| (p[0], p[1])).collect();
        if rng.uniform() < 0.2 {
            // A half-line.
            match list.first_mut() {
                Some(first) => first.0 = f64::NEG_INFINITY,
                None => list.push((f64::NEG_INFINITY, 3.0)),
            }
        }
        spans(&list)
    }

    fn contains(s: &[Piece], t: f64) -> bool {
        s.iter().any(|s| s.enter.t <= t && t <= s.exit.t)
    }

    #[test]
    fn set_operations_agree_with_membership_everywhere_between_the_ends() {
        let mut rng = PixelRng::new(27, 1, 2);
        for _ in 0..2000 {
            let (a, b) = (random_spans(&mut rng), random_spans(&mut rng));
            for op in [CsgOp::Union, CsgOp::Intersection, CsgOp::Difference] {
                let out = combine(op, &a, &b);
                // Ascending, disjoint, none of zero length.
                for w in out.windows(2) {
                    assert!(w[0].exit.t < w[1].enter.t, "{op:?} {:?}", ends(&out));
                }
                assert!(out.iter().all(|s| s.enter.t < s.exit.t));
                // Off the grid, membership is the Boolean of the children's.
                for k in -3..60 {
                    let t = k as f64 * 0.5 + 0.25;
                    let (x, y) = (contains(&a, t), contains(&b, t));
                    let want = match op {
                        CsgOp::Union | CsgOp::Merge => x || y,
                        CsgOp::Intersection => x && y,
                        CsgOp::Difference => x && !y,
                    };
                    assert_eq!(contains(&out, t), want, "{op:?} at {t}: {:?}", ends(&out));
                }
            }
        }
    }

    /// `solo` picks the child that is the whole solid where the mask
    /// leaves one (a difference's first, a union's one), and nothing
    /// where the lists are needed; the answer from it is the lists'.
    #[test]
    fn a_lone_child_stands_for_the_solid_only_where_it_is_the_solid() {
        let ball = |x: f64, r: f64| CsgChild {
            shape: Shape::Sphere(crate::geometry::Sphere {
                center: DVec3::new(x, 0.0, 0.0),
                radius: r,
            }),
            material: 3,
            inverse: false,
        };
        let node = |op, children| Csg::new(op, children);
        let d = node(CsgOp::Difference, vec![ball(0.0, 1.0), ball(0.5, 0.3)]);
        assert!(std::ptr::eq(d.solo(0b01).unwrap(), &d.children[0]));
        assert!(d.solo(0b11).is_none() && d.solo(ALL_CHILDREN).is_none());
        let u = node(CsgOp::Union, vec![ball(0.0, 1.0), ball(3.0, 0.5)]);
        assert!(std::ptr::eq(u.solo(0b10).unwrap(), &u.children[1]));
        let i = node(CsgOp::Intersection, vec![ball(0.0, 1.0), ball(0.5, 1.0)]);
        assert!(i.solo(0b01).is_none());
        let mut inverted = ball(0.0, 1.0);
        inverted.inverse = true;
        let d2 = node(CsgOp::Difference, vec![inverted, ball(0.5, 0.3)]);
        assert!(d2.solo(0b01).is_none());
        // Along a line that misses the bubble, the ball's ends are the set's.
        let ray = Ray::new(DVec3::new(-3.0, 0.6, 0.0), DVec3::X);
        for window in [(0.0, 10.0), (0.0, 3.0), (3.0, 10.0), (0.0, 1.0)] {
            let (first, last) = solo_ends(&d.children[0], &ray, window);
            let (want, want_last) =
                d.nearest_and_last_boundary_among(&ray, window.0, window.1, ALL_CHILDREN);
            assert_eq!(
                first.map(|b| (b.t, b.normal(&ray), b.material)),
                want.map(|b| (b.t, b.normal(&ray), b.material))
            );
            assert_eq!(last, want_last);
        }
    }

    #[test]
    fn coincident_faces_leave_no_sliver_and_keep_the_earlier_childs_surface() {
        // A hole flush with a face: [1, 3] less [1, 2] is (2, 3].
        // b is a ball of radius 2 about the origin, left at 2.
        let ball = Shape::Sphere(crate::geometry::Sphere {
            center: DVec3::ZERO,
            radius: 2.0,
        });
        let on_ball = |t: f64| End::of_surface(Surface::at(t), 0, &ball);
        let a = spans(&[(1.0, 3.0)]);
        let b = [Piece {
            enter: on_ball(1.0),
            exit: on_ball(2.0),
        }];
        let d = combine(CsgOp::Difference, &a, &b);
        assert_eq!(ends(&d), [2.0, 3.0]);
        // Its entry is b's exit turned round.
        let ray = Ray::new(DVec3::ZERO, DVec3::X);
        assert!(d[0].enter.flipped());
        assert_eq!(d[0].enter.boundary(&[]).normal(&ray), -DVec3::X);
        // Two boxes face to face merge into one solid: no surface at 2.
        let m = combine(CsgOp::Merge, &spans(&[(1.0, 2.0)]), &spans(&[(2.0, 3.0)]));
        assert_eq!(ends(&m), [1.0, 3.0]);
        // Their intersection is a face: no interval at all.
        assert!(
            combine(
                CsgOp::Intersection,
                &spans(&[(1.0, 2.0)]),
                &spans(&[(2.0, 3.0)])
            )
            .is_empty()
        );
    }

    #[test]
    fn the_complement_of_the_complement_is_the_set() {
        let mut rng = PixelRng::new(5, 0, 0);
        for _ in 0..500 {
            let a = random_spans(&mut rng);
            assert_eq!(ends(&complement(&complement(&a))), ends(&a));
        }
    }
}
