//! Shadow feelers towards a sphere light share their origin and end on the
//! light: every one of them lies in the convex hull of the shading point
//! and the light's sphere. Only primitives whose bounds meet that hull can
//! block any of them, so the scene is culled against it once per shading
//! point and light, and each feeler is tested against the few candidates
//! left, the last blocker first (POV-Ray's light buffer idea). The answer
//! is the one the full any-hit query gives: the culling is conservative,
//! with margins for rounding and for the feelers' pushed-off origins.

use glam::DVec3;

use super::simd::Job;
use super::{Aggregate, PACKET, Shape, simd};
use crate::geometry::Aabb;
use crate::geometry::csg::{ALL_CHILDREN, Boundary, ChildMask, Csg, CsgChild, CsgOp, solo_ends};
use crate::geometry::sphere::{sphere_blocks, sphere_first_root};
use crate::math::Ray;
use crate::math::ray::RELATIVE_OFFSET;

/// Past this many candidates the BVH query is used instead.
pub const MAX_CANDIDATES: usize = 16;

/// Box and primitive tests the search for candidates may spend per feeler
/// it serves. A feeler's own BVH query costs several, but in a dense scene
/// the search fails (too many candidates) after spending its budget: one
/// per feeler kept that loss within noise on a million spheres (bench note
/// in docs/performance.md), where two cost 5 % and four 17 %.
const BOX_TESTS_PER_FEELER: usize = 1;

/// The primitives that may block a shading point's feelers towards one
/// sphere light.
#[derive(Clone, Copy, Debug)]
pub struct ShadowCandidates {
    primitives: [u32; MAX_CANDIDATES],
    /// For a CSG candidate, the children that may block (see
    /// `Csg::children_meeting`); all for others.
    children: [ChildMask; MAX_CANDIDATES],
    len: usize,
}

/// A surface a transparent-shadow feeler passes through.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Blocker {
    /// Distance along the feeler.
    pub t: f64,
    /// Geometric normal there.
    pub normal: DVec3,
    /// Material index.
    pub material: u32,
}

/// What a batch of feelers met first ([`ShadowCandidates::nearest_batch`]):
/// per lane the nearest surface, and where the solid it belongs to ends.
#[derive(Clone, Copy, Debug)]
pub struct FirstBlockers<const N: usize> {
    /// The nearest surface each lane meets (`None`: none, or lane off).
    pub blockers: [Option<Blocker>; N],
    /// The candidate slot each lane's blocker belongs to.
    pub slots: [u32; N],
    /// How far along each lane's feeler its blocker's candidate has
    /// surfaces (+∞: not known): a CSG asked over the feeler's whole reach
    /// says, and so does a convex solid the feeler leaves or a flat shape
    /// ([`Shape::passed_for_good`]), so that a feeler continued past the
    /// last surface (out of a glass solid) skips it, as
    /// [`ShadowCandidates::nearest_along`] skips a CSG it asked itself.
    pub ends: [f64; N],
}

impl<const N: usize> Default for FirstBlockers<N> {
    fn default() -> Self {
        FirstBlockers {
            blockers: [None; N],
            slots: [u32::MAX; N],
            ends: [f64::INFINITY; N],
        }
    }
}

/// The convex hull of a point (the apex) and a sphere (the light), with
/// what the conservative tests need.
#[derive(Clone, Copy, Debug)]
struct FeelerHull {
    apex: DVec3,
    /// Unit vector from the apex to the light's centre.
    axis: DVec3,
    /// Distance from the apex to the light's centre.
    distance: f64,
    /// Sine and cosine of α, the half-angle of the cone of directions to
    /// the light.
    sin_alpha: f64,
    cos_alpha: f64,
    radius: f64,
    /// Slack for rounding and pushed-off origins, in length units.
    slack: f64,
    /// Half-spaces n·x ≤ d whose intersection holds the hull widened by
    /// the slack (see [`HullPlanes`]).
    planes: HullPlanes,
}

/// How many half-spaces bound the hull: four side planes through the apex
/// tangent to the light's sphere, and the near and far planes across the
/// axis.
const HULL_PLANES: usize = 6;

/// The hull's bounding half-spaces n·x ≤ d as a structure of arrays, with
/// |n| by component, for the boxes' support test.
#[derive(Clone, Copy, Debug)]
struct HullPlanes {
    normal: [[f64; HULL_PLANES]; 3],
    abs: [[f64; HULL_PLANES]; 3],
    offset: [f64; HULL_PLANES],
}

impl HullPlanes {
    /// The planes of the hull of `apex` and the ball (`apex` + `axis`·
    /// `distance`, `radius`), each pushed out by `slack`. A side plane has
    /// the normal n = −sin α·axis + cos α·w (w ⊥ axis, sin α = radius /
    /// distance) through the apex: n·(centre − apex) + radius = 0, so the
    /// ball and the apex lie on its inner side, and so does their hull.
    fn new(apex: DVec3, axis: DVec3, distance: f64, radius: f64, slack: f64) -> Self {
        let sin_alpha = radius / distance;
        let cos_alpha = (1.0 - sin_alpha * sin_alpha).max(0.0).sqrt();
        let frame = crate::math::Frame::from_z(axis);
        let side = |w: DVec3| -sin_alpha * axis + cos_alpha * w;
        let normals = [
            side(frame.x),
            side(-frame.x),
            side(frame.y),
            side(-frame.y),
            -axis,
            axis,
        ];
        let mut planes = HullPlanes {
            normal: [[0.0; HULL_PLANES]; 3],
            abs: [[0.0; HULL_PLANES]; 3],
            offset: [0.0; HULL_PLANES],
        };
        for (k, n) in normals.into_iter().enumerate() {
            for axis in 0..3 {
                planes.normal[axis][k] = n[axis];
                planes.abs[axis][k] = n[axis].abs();
            }
            // The far plane lies beyond the light's far side.
            let far = if k == HULL_PLANES - 1 {
                distance + radius
            } else {
                0.0
            };
            planes.offset[k] = n.dot(apex) + far + slack;
        }
        planes
    }

    /// Whether the box (`center` ± `half`) may meet every half-space: its
    /// nearest corner to each plane, n·c − |n|·h, lies on the inner side.
    #[inline]
    fn may_meet_box(&self, center: DVec3, half: DVec3) -> bool {
        let mut meets = true;
        for k in 0..HULL_PLANES {
            let near = self.normal[0][k] * center.x
                + self.normal[1][k] * center.y
                + self.normal[2][k] * center.z
                - (self.abs[0][k] * half.x + self.abs[1][k] * half.y + self.abs[2][k] * half.z);
            meets &= near <= self.offset[k];
        }
        meets
    }
}

impl FeelerHull {
    /// Whether a sphere (centre, radius) may meet the hull.
    fn may_meet_sphere(&self, center: DVec3, radius: f64) -> bool {
        let radius = radius + self.slack;
        let v = center - self.apex;
        let length = v.length();
        if length <= radius {
            return true;
        }
        let along = v.dot(self.axis);
        // Every feeler point lies between the apex and the light's far side.
        if along + radius < 0.0 || along - radius > self.distance + self.radius {
            return false;
        }
        // Within the cone widened by the sphere's angular radius β: the
        // angle θ to the axis is at most α + β. Both lie in [0, π], where
        // cos decreases, so as cosines: cos θ ≥ cos α·cos β − sin α·sin β
        // (a millionth less, for rounding).
        let sin_beta = radius / length;
        let cos_beta = (1.0 - sin_beta * sin_beta).max(0.0).sqrt();
        along / length >= self.cos_alpha * cos_beta - self.sin_alpha * sin_beta - 1e-6
    }

    /// Whether a box may meet the hull: not when it lies outside one of
    /// the hull's bounding planes.
    fn may_meet_box(&self, b: &Aabb) -> bool {
        self.planes
            .may_meet_box(0.5 * (b.min + b.max), 0.5 * (b.max - b.min))
    }

    /// Whether the plane n·x = d may cross a feeler: not when the apex and
    /// the whole light lie on the same side of it.
    fn may_cross_plane(&self, normal: DVec3, d: f64) -> bool {
        let apex = normal.dot(self.apex) - d;
        let light = normal.dot(self.apex + self.axis * self.distance) - d;
        let clear = self.radius + self.slack;
        !((apex >= 0.0 && light > clear) || (apex <= 0.0 && light < -clear))
    }

    /// Whether the whole light lies strictly beyond the plane through the
    /// apex with normal `outward`: then every feeler leaves that way.
    fn beyond_tangent_plane(&self, outward: DVec3) -> bool {
        outward.dot(self.axis) * self.distance > self.radius + self.slack
    }

    /// How far off a surface the apex may lie (rounding of the hit point)
    /// and still count as on it: far below the feelers' push-off.
    fn on_surface_tolerance(&self) -> f64 {
        1e-3 * RELATIVE_OFFSET * crate::math::max_abs_component(self.apex).max(1.0)
    }

    /// Whether feelers may meet a part of a CSG (`inverse`: its
    /// complement), by the tests primitives get: a sphere by its own test
    /// and, when the apex lies on it, by its tangent plane there (feelers
    /// that leave a ball cannot come back); a box or cone by its face
    /// planes; a half-space by its plane. A CSG part by its operation: an
    /// intersection only where all its parts may be met, a difference
    /// where its first may, a union where any may; `depth` more levels
    /// looked into, and none of many parts (a bounded cost per point).
    /// Only ever false where no feeler can meet the part.
    fn may_meet_part(&self, shape: &Shape, inverse: bool, depth: usize) -> bool {
        if inverse {
            return true;
        }
        let light = self.apex + self.axis * self.distance;
        match shape {
            Shape::Sphere(s) => {
                let v = self.apex - s.center;
                let length = v.length();
                self.may_meet_sphere(s.center, s.radius)
                    && !(length >= s.radius - self.on_surface_tolerance()
                        && self.beyond_tangent_plane(v / length))
            }
            Shape::Cuboid(b) => !b.separates(self.apex, light, self.radius, self.slack),
            Shape::Cone(c) => !c.separates(self.apex, light, self.radius + self.slack),
            // Inside is n·x < d: not met when the apex lies on the plane or
            // outside and the whole light outside.
            Shape::Plane(p) => {
                let apex = p.normal.dot(self.apex) - p.distance;
                let light = p.normal.dot(light) - p.distance;
                !(apex >= -self.on_surface_tolerance() && light > self.radius + self.slack)
            }
            Shape::Csg(c) if depth > 0 && c.children().len() <= CSG_CULL_PARTS => {
                let mut parts = c
                    .children()
                    .iter()
                    .map(|p| self.may_meet_part(&p.shape, p.inverse, depth - 1));
                match c.op() {
                    CsgOp::Union | CsgOp::Merge => parts.any(|m| m),
                    CsgOp::Intersection => parts.all(|m| m),
                    CsgOp::Difference => parts.next().unwrap_or(false),
                }
            }
            _ => true,
        }
    }
}

/// How many levels of CSG inside a candidate's parts `may_meet_part`
/// looks into, and at most how many parts each may have.
const CSG_CULL_DEPTH: usize = 4;
const CSG_CULL_PARTS: usize = 8;

impl Aggregate {
    /// The candidates that may block `feelers` feelers from `apex`, a point
    /// on primitive `on`, to the sphere light at `apex + to_center` of
    /// `radius`; `None` when there are more than a handful or finding them
    /// costs more than the feelers would save (then the BVH serves better).
    pub fn shadow_candidates(
        &self,
        apex: DVec3,
        on: u32,
        to_center: DVec3,
        radius: f64,
        feelers: usize,
    ) -> Option<ShadowCandidates> {
        let distance = to_center.length();
        if distance <= radius || !distance.is_finite() {
            return None;
        }
        // Feelers start at the apex or, with transparent shadows, anywhere
        // on the way to the light: no coordinate exceeds this.
        let scale = crate::math::max_abs_component(apex)
            .max(crate::math::max_abs_component(apex + to_center) + radius)
            .max(1.0);
        let axis = to_center / distance;
        // Origins are pushed off by RELATIVE_OFFSET·scale; f64 rounding
        // of the tests is far below a millionth of the scale.
        let slack = 2.0 * RELATIVE_OFFSET * scale + 1e-6 * (distance + radius);
        let hull = FeelerHull {
            apex,
            axis,
            distance,
            sin_alpha: radius / distance,
            cos_alpha: (1.0 - (radius / distance).powi(2)).max(0.0).sqrt(),
            radius,
            slack,
            planes: HullPlanes::new(apex, axis, distance, radius, slack),
        };
        let mut found = ShadowCandidates {
            primitives: [0; MAX_CANDIDATES],
            children: [ALL_CHILDREN; MAX_CANDIDATES],
            len: 0,
        };
        for &i in &self.unbounded {
            let blocks = match &self.primitives[i as usize].shape {
                Shape::Plane(p) => hull.may_cross_plane(p.normal, p.distance),
                _ => true,
            };
            if blocks && !found.push(i, ALL_CHILDREN) {
                return None;
            }
        }
        // The search may spend BOX_TESTS_PER_FEELER tests per feeler it
        // serves; past that (a dense scene around the cone), the BVH serves
        // better.
        let budget = std::cell::Cell::new(BOX_TESTS_PER_FEELER * feelers);
        let within_budget = || {
            let left = budget.get();
            budget.set(left.saturating_sub(1));
            left > 0
        };
        let complete = self.bvh.visit(
            |b| within_budget() && hull.may_meet_box(b),
            |position| {
                let i = self.leaf_primitives[position];
                let shape = &self.primitives[i as usize].shape;
                let mut children = ALL_CHILDREN;
                let may_block = match shape {
                    // A polygon lies in its plane: the plane test culls the
                    // floor under every point above it.
                    Shape::Polygon(p) => hull.may_cross_plane(p.plane.normal, p.plane.distance),
                    // Feelers that leave a sphere through its tangent plane
                    // at the point they start from cannot meet it again.
                    Shape::Sphere(s) if i == on => {
                        !hull.beyond_tangent_plane((apex - s.center) / s.radius)
                    }
                    // A sphere's own test is tighter than its box's.
                    Shape::Sphere(s) => hull.may_meet_sphere(s.center, s.radius),
                    // A box behind one of its face planes, as seen from
                    // the apex and the whole light (the floor slab under
                    // every point above it, the box the point lies on).
                    Shape::Cuboid(b) => {
                        let light = hull.apex + hull.axis * hull.distance;
                        !b.separates(hull.apex, light, hull.radius, hull.slack)
                            && hull.may_meet_box(&b.bounds())
                    }
                    // A cylinder or cone by the planes of its own box
                    // (a point on its end disc, the light beyond it).
                    Shape::Cone(c) => {
                        let light = hull.apex + hull.axis * hull.distance;
                        !c.separates(hull.apex, light, hull.radius + hull.slack)
                            && hull.may_meet_box(&c.bounds())
                    }
                    // A CSG by its box, then its children by their boxes
                    // and their solids (the CSG a point lies on, by the
                    // face or tangent plane of the part it lies on).
                    Shape::Csg(c) => {
                        c.bounds().is_none_or(|b| hull.may_meet_box(&b))
                            && c.children_meeting(|child, b| {
                                hull.may_meet_box(b)
                                    && hull.may_meet_part(
                                        &child.shape,
                                        child.inverse,
                                        CSG_CULL_DEPTH,
                                    )
                            })
                            .map(|mask| children = mask)
                            .is_some()
                    }
                    _ => shape.bounds().is_none_or(|b| hull.may_meet_box(&b)),
                };
                within_budget() && (!may_block || found.push(i, children))
            },
        );
        (complete && budget.get() > 0).then_some(found)
    }
}

impl ShadowCandidates {
    /// Adds `primitive`, of which only `children` may block if it is a
    /// CSG; false when full.
    fn push(&mut self, primitive: u32, children: ChildMask) -> bool {
        if self.len == MAX_CANDIDATES {
            return false;
        }
        self.primitives[self.len] = primitive;
        self.children[self.len] = children;
        self.len += 1;
        true
    }

    /// The nearest hit of `feeler` on the candidate in `slot` within
    /// (t_min, t_max), as [`Shape::feeler_hit`] finds it: a CSG's children
    /// that cannot block left out.
    #[inline(always)]
    fn feeler_hit(
        &self,
        slot: usize,
        shape: &Shape,
        feeler: &Ray,
        t_min: f64,
        t_max: f64,
    ) -> Option<(f64, DVec3, Option<u32>)> {
        match shape {
            Shape::Csg(c) => self
                .csg_ends(slot, c, feeler, t_min, t_max)
                .0
                .map(|b| (b.t, b.normal(feeler), Some(b.material))),
            _ => shape.feeler_hit(feeler, t_min, t_max),
        }
    }

    /// The nearest surface of the CSG candidate in `slot` within (t_min,
    /// t_max) and the parameter of its last there (−∞ when none), as
    /// [`Csg::nearest_and_last_boundary_among`] finds them: its children
    /// that cannot block left out, and from its one child alone where that
    /// child is the whole solid within reach ([`Csg::solo`]).
    #[inline(always)]
    fn csg_ends<'a>(
        &self,
        slot: usize,
        c: &'a Csg,
        feeler: &Ray,
        t_min: f64,
        t_max: f64,
    ) -> (Option<Boundary<'a>>, f64) {
        let mask = self.children[slot];
        csg_query(c, c.solo(mask), mask, feeler, (t_min, t_max))
    }

    /// Whether `feeler` meets the candidate in `slot` within (t_min,
    /// t_max), as [`Shape::occludes`] answers.
    #[inline(always)]
    fn occludes(&self, slot: usize, shape: &Shape, feeler: &Ray, t_min: f64, t_max: f64) -> bool {
        match shape {
            Shape::Csg(c) => self.csg_ends(slot, c, feeler, t_min, t_max).0.is_some(),
            _ => shape.occludes(feeler, t_min, t_max),
        }
    }

    /// How many primitives may block.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether nothing can block: every feeler reaches the light.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The nearest candidate `feeler` meets within `t_max`, as
    /// [`Aggregate::closest_hit`] would find it (for transparent shadows,
    /// which need every surface on the way): its distance, geometric normal
    /// and material, without the texture coordinates a feeler has no use for.
    pub fn nearest(&self, aggregate: &Aggregate, feeler: &Ray, t_max: f64) -> Option<Blocker> {
        let mut found = None;
        let mut closest = t_max;
        for (slot, &i) in self.primitives[..self.len].iter().enumerate() {
            let p = &aggregate.primitives[i as usize];
            if let Some((t, normal, material)) =
                self.feeler_hit(slot, &p.shape, feeler, 0.0, closest)
            {
                closest = t;
                found = Some(Blocker {
                    t,
                    normal,
                    material: material.unwrap_or(p.material),
                });
            }
        }
        found
    }

    /// [`nearest`](Self::nearest) for a feeler continued through glass,
    /// its origin `travelled` along the line from where the first feeler
    /// of the line set out. `beyond[slot]`: how far along the line a CSG
    /// candidate's surfaces end (+∞: not known); a candidate that ends
    /// behind the origin is skipped, and one asked over the whole window
    /// says where it ends. Feelers continued along one line meet the same
    /// surfaces: each starts past the last surface it passed, pushed off
    /// it by far less than any other surface lies from the line.
    pub fn nearest_along(
        &self,
        aggregate: &Aggregate,
        feeler: &Ray,
        t_max: f64,
        travelled: f64,
        beyond: &mut [f64; MAX_CANDIDATES],
    ) -> Option<Blocker> {
        let mut found = None;
        let mut closest = t_max;
        for (slot, &i) in self.primitives[..self.len].iter().enumerate() {
            if travelled > beyond[slot] {
                continue;
            }
            let p = &aggregate.primitives[i as usize];
            let hit = match &p.shape {
                Shape::Csg(c) => {
                    let (end, last) = self.csg_ends(slot, c, feeler, 0.0, closest);
                    // Over the whole window, the last end is the solid's
                    // last within reach; past the narrower window of a
                    // nearer hit, nothing is known.
                    if closest == t_max {
                        beyond[slot] = travelled + last.max(0.0);
                    }
                    end.map(|b| (b.t, b.normal(feeler), Some(b.material)))
                }
                shape => shape.feeler_hit(feeler, 0.0, closest),
            };
            if let Some((t, normal, material)) = hit {
                closest = t;
                found = Some(Blocker {
                    t,
                    normal,
                    material: material.unwrap_or(p.material),
                });
            }
        }
        found
    }

    /// Whether a candidate blocks `feeler` within `t_max`, as
    /// [`Aggregate::any_hit`] would answer. The blocker found moves to the
    /// front: the next feeler, close beside this one, likely meets it too.
    pub fn any_hit(&mut self, aggregate: &Aggregate, feeler: &Ray, t_max: f64) -> bool {
        for k in 0..self.len {
            let shape = &aggregate.primitives[self.primitives[k] as usize].shape;
            if self.occludes(k, shape, feeler, 0.0, t_max) {
                self.primitives[..=k].rotate_right(1);
                self.children[..=k].rotate_right(1);
                return true;
            }
        }
        false
    }
}

/// [`ShadowCandidates::csg_ends`] with the CSG's lone child (`Csg::solo`
/// of `mask`) already found.
#[inline(always)]
fn csg_query<'a>(
    c: &'a Csg,
    solo: Option<&'a CsgChild>,
    mask: ChildMask,
    feeler: &Ray,
    window: (f64, f64),
) -> (Option<Boundary<'a>>, f64) {
    match solo {
        Some(child) => solo_ends(child, feeler, window),
        None => c.nearest_and_last_boundary_among(feeler, window.0, window.1, mask),
    }
}

/// Shadow feelers of one shading point as a structure of arrays, for
/// [`ShadowCandidates::any_hit_batch`]. Lanes switched off are ignored.
#[derive(Clone, Copy, Debug)]
pub struct FeelerBatch<const N: usize> {
    /// Origin coordinates, x, y and z.
    pub origin: [[f64; N]; 3],
    /// Unit direction coordinates.
    pub direction: [[f64; N]; 3],
    /// How far each feeler reaches.
    pub t_max: [f64; N],
    /// Which lanes are feelers.
    pub active: [bool; N],
}

impl<const N: usize> Default for FeelerBatch<N> {
    fn default() -> Self {
        FeelerBatch {
            origin: [[0.0; N]; 3],
            direction: [[0.0; N]; 3],
            t_max: [0.0; N],
            active: [false; N],
        }
    }
}

impl<const N: usize> FeelerBatch<N> {
    /// Puts `ray`, reaching `t_max`, in lane `k`, switched on or off.
    #[inline(always)]
    pub fn set(&mut self, k: usize, ray: &Ray, t_max: f64, active: bool) {
        for axis in 0..3 {
            self.origin[axis][k] = ray.origin[axis];
            self.direction[axis][k] = ray.direction[axis];
        }
        self.t_max[k] = t_max;
        self.active[k] = active;
    }

    /// Lane `k` as a ray. The arrays are borrowed, not bound by value:
    /// `let [x, y, z] = self.origin` copied all six 16-lane arrays (768
    /// bytes) to the stack at every call, once per lane and candidate.
    #[inline(always)]
    fn ray(&self, k: usize) -> Ray {
        let [x, y, z] = &self.origin;
        let [dx, dy, dz] = &self.direction;
        Ray {
            origin: DVec3::new(x[k], y[k], z[k]),
            direction: DVec3::new(dx[k], dy[k], dz[k]),
        }
    }
}

impl ShadowCandidates {
    /// For each active lane of `feelers`, whether a candidate blocks it:
    /// what [`any_hit`](Self::any_hit) answers feeler by feeler. Spheres,
    /// what feelers to sphere lights mostly meet, are tested against every
    /// lane at once by [`sphere_blocks`] (vector code, no early exit to
    /// wait for); meshes by packets of eight open lanes; other shapes lane
    /// by lane, skipping blocked lanes.
    pub fn any_hit_batch<const N: usize>(
        &self,
        aggregate: &Aggregate,
        feelers: &FeelerBatch<N>,
    ) -> [bool; N] {
        simd::kernel().vectorize_job(AnyHitBatch {
            candidates: self,
            aggregate,
            feelers,
        })
    }

    /// [`any_hit_batch`](Self::any_hit_batch), compiled into its caller
    /// (through [`AnyHitBatch`]).
    #[inline(always)]
    fn any_hit_batch_here<const N: usize>(
        &self,
        aggregate: &Aggregate,
        feelers: &FeelerBatch<N>,
    ) -> [bool; N] {
        let mut blocked = [false; N];
        for (slot, &i) in self.primitives[..self.len].iter().enumerate() {
            match &aggregate.primitives[i as usize].shape {
                Shape::Sphere(s) => {
                    let ([x, y, z], [dx, dy, dz]) = (&feelers.origin, &feelers.direction);
                    for (k, blocked) in blocked.iter_mut().enumerate() {
                        *blocked |= sphere_blocks(
                            [x[k], y[k], z[k]],
                            [dx[k], dy[k], dz[k]],
                            feelers.t_max[k],
                            s.center,
                            s.radius,
                        );
                    }
                }
                Shape::Mesh(m) => {
                    // The open feelers, eight at a time, as packets: they
                    // leave one point for one light, so they share their
                    // node visits.
                    let mut lanes = [0usize; PACKET];
                    let mut rays = [feelers.ray(0); PACKET];
                    let mut t_max = [0.0; PACKET];
                    let mut len = 0;
                    for k in 0..N {
                        if feelers.active[k] && !blocked[k] {
                            (lanes[len], rays[len], t_max[len]) =
                                (k, feelers.ray(k), feelers.t_max[k]);
                            len += 1;
                        }
                        if len == PACKET || (k == N - 1 && len > 0) {
                            let hit = m.any_hit_packet(&rays[..len], 0.0, &t_max[..len]);
                            for (j, &lane) in lanes[..len].iter().enumerate() {
                                blocked[lane] |= hit >> j & 1 == 1;
                            }
                            len = 0;
                        }
                    }
                }
                shape => {
                    for (k, blocked) in blocked.iter_mut().enumerate() {
                        if feelers.active[k] && !*blocked {
                            *blocked =
                                self.occludes(slot, shape, &feelers.ray(k), 0.0, feelers.t_max[k]);
                        }
                    }
                }
            }
        }
        blocked
    }

    /// For each active lane of `feelers`, the nearest candidate it meets:
    /// what [`nearest`](Self::nearest) answers feeler by feeler, the same
    /// candidates in the same order, so the same one wins a tie. Spheres
    /// are tested against every lane at once by [`sphere_first_root`];
    /// other shapes lane by lane.
    ///
    /// The answers are written into `out` (not returned: a copy of them
    /// out of the vector code's frame cost a `memcpy` per batch).
    pub fn nearest_batch<const N: usize>(
        &self,
        aggregate: &Aggregate,
        feelers: &FeelerBatch<N>,
        out: &mut FirstBlockers<N>,
    ) {
        simd::kernel().vectorize_job(NearestBatch {
            candidates: self,
            aggregate,
            feelers,
            out,
        })
    }

    /// [`nearest_batch`](Self::nearest_batch), compiled into its caller
    /// (through [`NearestBatch`]).
    #[inline(always)]
    fn nearest_batch_here<const N: usize>(
        &self,
        aggregate: &Aggregate,
        feelers: &FeelerBatch<N>,
        out: &mut FirstBlockers<N>,
    ) {
        const NONE: u32 = u32::MAX;
        let mut closest = feelers.t_max;
        // Per lane, the candidate slot nearest so far, and its hit when
        // that is not a sphere (a sphere's is made from t at the end).
        let mut nearest = [NONE; N];
        let mut found = [None; N];
        // Where the nearest candidate so far ends along each lane, where a
        // CSG's query said (see `FirstBlockers::ends`; a convex solid's is
        // worked out at the end, for the nearest only).
        let mut ends = [f64::INFINITY; N];
        for (slot, &i) in self.primitives[..self.len].iter().enumerate() {
            let p = &aggregate.primitives[i as usize];
            match &p.shape {
                Shape::Sphere(s) => {
                    let ([x, y, z], [dx, dy, dz]) = (&feelers.origin, &feelers.direction);
                    for k in 0..N {
                        let (hit, t) = sphere_first_root(
                            [x[k], y[k], z[k]],
                            [dx[k], dy[k], dz[k]],
                            closest[k],
                            s.center,
                            s.radius,
                        );
                        closest[k] = if hit { t } else { closest[k] };
                        nearest[k] = if hit { slot as u32 } else { nearest[k] };
                        ends[k] = if hit { f64::INFINITY } else { ends[k] };
                    }
                }
                // Cones and cylinders: every lane at once too.
                Shape::Cone(c) => {
                    let (met, t, part) =
                        c.nearest_crossings(&feelers.origin, &feelers.direction, &closest);
                    for k in 0..N {
                        if !feelers.active[k] || !met[k] {
                            continue;
                        }
                        closest[k] = t[k];
                        nearest[k] = slot as u32;
                        ends[k] = f64::INFINITY;
                        let normal = c.crossing_normal(&feelers.ray(k), t[k], part[k]);
                        found[k] = Some(Blocker {
                            t: t[k],
                            normal,
                            material: p.material,
                        });
                    }
                }
                Shape::Csg(c) => {
                    // Whether one child stands for the CSG: once per batch.
                    let (mask, solo) = (self.children[slot], c.solo(self.children[slot]));
                    for k in 0..N {
                        if !feelers.active[k] {
                            continue;
                        }
                        let feeler = feelers.ray(k);
                        let (end, last) = csg_query(c, solo, mask, &feeler, (0.0, closest[k]));
                        // Over the whole reach the last end is the
                        // solid's last; within a nearer hit's, unknown.
                        let whole = closest[k] == feelers.t_max[k];
                        if let Some(b) = end {
                            closest[k] = b.t;
                            nearest[k] = slot as u32;
                            ends[k] = if whole { last } else { f64::INFINITY };
                            found[k] = Some(Blocker {
                                t: b.t,
                                normal: b.normal(&feeler),
                                material: b.material,
                            });
                        }
                    }
                }
                shape => {
                    for k in 0..N {
                        if !feelers.active[k] {
                            continue;
                        }
                        let hit = self.feeler_hit(slot, shape, &feelers.ray(k), 0.0, closest[k]);
                        if let Some((t, normal, material)) = hit {
                            closest[k] = t;
                            nearest[k] = slot as u32;
                            ends[k] = f64::INFINITY;
                            found[k] = Some(Blocker {
                                t,
                                normal,
                                material: material.unwrap_or(p.material),
                            });
                        }
                    }
                }
            }
        }
        for k in 0..N {
            if !feelers.active[k] || nearest[k] == NONE {
                out.blockers[k] = None;
                continue;
            }
            let p = &aggregate.primitives[self.primitives[nearest[k] as usize] as usize];
            let blocker = match &p.shape {
                Shape::Sphere(s) => {
                    let h = s.hit_at(&feelers.ray(k), closest[k]);
                    Blocker {
                        t: h.t,
                        normal: h.normal,
                        material: p.material,
                    }
                }
                // Every other kind kept its hit where it became the nearest.
                _ => match found[k] {
                    Some(b) => b,
                    None => {
                        out.blockers[k] = None;
                        continue;
                    }
                },
            };
            // A feeler leaving a convex solid (or crossing a flat shape)
            // has passed it for good: its surfaces end here. (A CSG said
            // where it ends above.)
            if !matches!(p.shape, Shape::Csg(_) | Shape::Torus(_) | Shape::Mesh(_)) {
                let direction = DVec3::new(
                    feelers.direction[0][k],
                    feelers.direction[1][k],
                    feelers.direction[2][k],
                );
                if p.shape.passed_for_good(direction, blocker.normal) {
                    ends[k] = blocker.t;
                }
            }
            out.blockers[k] = Some(blocker);
        }
        out.slots = nearest;
        out.ends = ends;
    }
}

/// [`ShadowCandidates::any_hit_batch`] as a [`Job`].
struct AnyHitBatch<'a, const N: usize> {
    candidates: &'a ShadowCandidates,
    aggregate: &'a Aggregate,
    feelers: &'a FeelerBatch<N>,
}

impl<const N: usize> Job for AnyHitBatch<'_, N> {
    type Output = [bool; N];
    #[inline(always)]
    fn run(self) -> [bool; N] {
        self.candidates
            .any_hit_batch_here(self.aggregate, self.feelers)
    }
}

/// [`ShadowCandidates::nearest_batch`] as a [`Job`].
struct NearestBatch<'a, const N: usize> {
    candidates: &'a ShadowCandidates,
    aggregate: &'a Aggregate,
    feelers: &'a FeelerBatch<N>,
    out: &'a mut FirstBlockers<N>,
}

impl<const N: usize> Job for NearestBatch<'_, N> {
    type Output = ();
    #[inline(always)]
    fn run(self) {
        self.candidates
            .nearest_batch_here(self.aggregate, self.feelers, self.out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::Primitive;
    use crate::geometry::sphere::sphere_roots;
    use crate::geometry::{Plane, Sphere};
    use crate::math::Frame;
    use crate::math::rng::PixelRng;
    use crate::math::sampling::{Strata, uniform_cone};

    fn sphere(center: DVec3, radius: f64) -> Primitive {
        Primitive {
            shape: ball(center, radius),
            material: 0,
        }
    }

    fn ball(center: DVec3, radius: f64) -> Shape {
        Shape::Sphere(Sphere { center, radius })
    }

    fn csg(
        op: crate::geometry::csg::CsgOp,
        children: Vec<crate::geometry::csg::CsgChild>,
    ) -> Shape {
        Shape::Csg(Box::new(crate::geometry::csg::Csg::new(op, children)))
    }

    /// A CSG part of material 0, not inverted.
    fn child(shape: Shape) -> crate::geometry::csg::CsgChild {
        crate::geometry::csg::CsgChild {
            shape,
            material: 0,
            inverse: false,
        }
    }

    /// Random spheres and a floor; many shading points on and above the
    /// floor; a sphere light. Every feeler gets the same answer from the
    /// candidates as from the full query.
    #[test]
    fn candidates_answer_every_feeler_as_the_full_queries_do() {
        let mut rng = PixelRng::new(7, 3, 1);
        let mut primitives: Vec<Primitive> = (0..40)
            .map(|_| {
                let c = DVec3::new(
                    rng.uniform() * 8.0 - 4.0,
                    rng.uniform() * 3.0,
                    rng.uniform() * 8.0 - 4.0,
                );
                sphere(c, 0.05 + rng.uniform() * 0.5)
            })
            .collect();
        primitives.push(Primitive {
            shape: Shape::Plane(Plane {
                normal: DVec3::Y,
                distance: 0.0,
            }),
            material: 0,
        });
        let aggregate = Aggregate::new(primitives);
        let (center, radius) = (DVec3::new(1.0, 6.0, 0.5), 0.8);
        let (mut culled, mut compared, mut blocked) = (0, 0, 0);
        for k in 0..600 {
            // Points on the floor, in the air, and on the spheres (facing
            // the light or not: feelers from the far side go through).
            let (apex, on, normal) = if k % 3 == 2 {
                let on = rng.below(40) as u32;
                let Shape::Sphere(s) = aggregate.primitives()[on as usize].shape else {
                    unreachable!()
                };
                let u = DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 2.0 - 1.0;
                let outward = u.try_normalize().unwrap_or(DVec3::Y);
                (s.center + s.radius * outward, on, outward)
            } else {
                let y = if k % 3 == 0 { 0.0 } else { rng.uniform() * 4.0 };
                let apex = DVec3::new(rng.uniform() * 10.0 - 5.0, y, rng.uniform() * 10.0 - 5.0);
                (apex, 40, DVec3::Y)
            };
            let to_center = center - apex;
            let Some(mut candidates) = aggregate.shadow_candidates(apex, on, to_center, radius, 64)
            else {
                continue;
            };
            culled += 1;
            let d2 = to_center.length_squared();
            let frame = Frame::from_z(to_center / d2.sqrt());
            let cos_max = (1.0 - radius * radius / d2).sqrt();
            let strata = Strata::new(64);
            // The feelers also go through the batched test, 16 at a time,
            // with every fifth lane switched off.
            let mut batch = FeelerBatch::<16>::default();
            let mut expected = [false; 16];
            let mut expected_nearest = [None; 16];
            for i in 0..64 {
                let direction = uniform_cone(&frame, cos_max, strata.point(i, &mut rng));
                let distance = sphere_roots(DVec3::ZERO, direction, to_center, radius)
                    .map_or(to_center.dot(direction), |(t0, _)| t0);
                let feeler = Ray::spawn(apex, normal, direction);
                let t_max = distance - (feeler.origin - apex).length();
                let full = aggregate.any_hit(&feeler, t_max);
                assert_eq!(candidates.any_hit(&aggregate, &feeler, t_max), full);
                // Transparent shadows walk every surface: the same nearest.
                let nearest = aggregate.closest_hit(&feeler, t_max).map(|h| Blocker {
                    t: h.t,
                    normal: h.normal,
                    material: h.material,
                });
                assert_eq!(candidates.nearest(&aggregate, &feeler, t_max), nearest);
                compared += 1;
                blocked += usize::from(full);
                let lane = i % 16;
                batch.set(lane, &feeler, t_max, i % 5 != 0);
                expected[lane] = full;
                expected_nearest[lane] = nearest;
                if lane == 15 {
                    let got = candidates.any_hit_batch(&aggregate, &batch);
                    let got_nearest = {
                        let mut out = FirstBlockers::default();
                        candidates.nearest_batch(&aggregate, &batch, &mut out);
                        out.blockers
                    };
                    for lane in (0..16).filter(|&l| batch.active[l]) {
                        assert_eq!(got[lane], expected[lane], "{apex} feeler {lane}");
                        assert_eq!(
                            got_nearest[lane], expected_nearest[lane],
                            "{apex} feeler {lane}"
                        );
                    }
                }
            }
        }
        // The test means something: most points were culled to a few
        // candidates, and some feelers were blocked, some not.
        assert!(culled > 450, "{culled}");
        assert!(
            blocked > compared / 20 && blocked < compared * 19 / 20,
            "{blocked}/{compared}"
        );
    }

    #[test]
    fn batched_cones_answer_as_each_feeler_alone_to_the_bit() {
        // Cones, cylinders and tips (capped and open, turned and stretched)
        // met by batches of feelers from points around, inside and on
        // them: `nearest_batch` (every lane at once) gives each lane the
        // blocker `nearest` gives that feeler alone, bit for bit.
        use crate::geometry::Cone;
        use crate::math::Transform;
        use glam::{DAffine3, DQuat};
        let mut rng = PixelRng::new(3, 8, 5);
        let mut primitives = Vec::new();
        for i in 0..12 {
            let axis = DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) - 0.5;
            let transform = Transform::from_affine(DAffine3::from_scale_rotation_translation(
                DVec3::new(
                    0.3 + rng.uniform(),
                    0.3 + rng.uniform(),
                    0.3 + rng.uniform(),
                ),
                DQuat::from_axis_angle(axis.normalize(), rng.uniform() * 3.0),
                DVec3::new(
                    rng.uniform() * 2.0 - 1.0,
                    rng.uniform(),
                    rng.uniform() * 2.0 - 1.0,
                ),
            ))
            .unwrap();
            primitives.push(Primitive {
                shape: Shape::Cone(Box::new(Cone {
                    base_radius: 0.4 * (i % 4) as f64,
                    cap_radius: 0.2 * (i % 3) as f64 + 0.1 * f64::from(u8::from(i % 4 == 0)),
                    open: i % 5 == 0,
                    transform,
                })),
                material: i,
            });
        }
        let aggregate = Aggregate::new(primitives);
        let candidates = ShadowCandidates {
            primitives: std::array::from_fn(|i| (i % 12) as u32),
            children: [ALL_CHILDREN; MAX_CANDIDATES],
            len: 12,
        };
        let (mut lanes, mut met) = (0, 0);
        for round in 0..400 {
            let apex = DVec3::new(
                rng.uniform() * 3.0 - 1.5,
                rng.uniform() * 1.5,
                rng.uniform() * 3.0 - 1.5,
            );
            let mut batch = FeelerBatch::<16>::default();
            for lane in 0..16 {
                let direction =
                    (DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) - 0.5).normalize();
                // Some lanes share an axis-parallel direction (d.z = 0 in
                // a cone's space is rare; a world axis is not).
                let direction = if lane == 3 { DVec3::Y } else { direction };
                let ray = Ray::new(apex, direction);
                batch.set(
                    lane,
                    &ray,
                    0.5 + rng.uniform() * 4.0,
                    (lane + round) % 7 != 0,
                );
            }
            let got = {
                let mut out = FirstBlockers::default();
                candidates.nearest_batch(&aggregate, &batch, &mut out);
                out.blockers
            };
            for lane in (0..16).filter(|&l| batch.active[l]) {
                let alone = candidates.nearest(&aggregate, &batch.ray(lane), batch.t_max[lane]);
                assert_eq!(got[lane], alone, "round {round} lane {lane}");
                lanes += 1;
                met += usize::from(alone.is_some());
            }
        }
        assert!(met > lanes / 10 && met < lanes * 9 / 10, "{met}/{lanes}");
    }

    /// `Shape::passed_for_good`, which lets the batch say a feeler's first
    /// solid ends where it leaves it: from there (pushed off as the next
    /// feeler is) the line meets the shape no more; it is claimed only
    /// for convex solids left and flat shapes, never for a torus or an
    /// open cone, which a line can meet again.
    #[test]
    fn a_line_that_passed_a_shape_for_good_meets_it_no_more() {
        use crate::geometry::{Cone, Cuboid, Torus};
        use crate::math::Transform;
        use glam::{DAffine3, DQuat};
        let mut rng = PixelRng::new(5, 7, 3);
        let (mut passed, mut again) = (0, 0);
        for i in 0..6000 {
            let axis = DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) - 0.5;
            let transform = Transform::from_affine(DAffine3::from_scale_rotation_translation(
                DVec3::new(
                    0.5 + rng.uniform(),
                    0.5 + rng.uniform(),
                    0.5 + rng.uniform(),
                ),
                DQuat::from_axis_angle(axis.normalize(), rng.uniform() * 3.0),
                DVec3::ZERO,
            ))
            .unwrap();
            let shape = match i % 5 {
                0 => Shape::Cuboid(Box::new(Cuboid::new(
                    DVec3::splat(-0.5),
                    DVec3::splat(0.5),
                    transform,
                ))),
                1 | 2 => Shape::Cone(Box::new(Cone {
                    base_radius: 0.5,
                    cap_radius: 0.25 * (i % 3) as f64,
                    open: i % 2 == 0,
                    transform,
                })),
                3 => ball(DVec3::ZERO, 0.6),
                _ => Shape::Torus(Box::new(Torus {
                    major_radius: 0.6,
                    minor_radius: 0.2,
                    transform,
                })),
            };
            let origin = DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 2.0 - 1.0;
            let direction =
                (DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) - 0.5).normalize();
            let Some(h) = shape.intersect(&Ray::new(origin, direction), 0.0, f64::INFINITY) else {
                continue;
            };
            let next = Ray::spawn(origin + h.t * direction, h.normal, direction);
            let met_again = shape.intersect(&next, 0.0, f64::INFINITY).is_some();
            if shape.passed_for_good(direction, h.normal) {
                assert!(!met_again, "{shape:?} {origin} {direction}");
                passed += 1;
            } else {
                again += usize::from(met_again);
            }
        }
        assert!(passed > 300 && again > 300, "{passed} {again}");
    }

    /// Turned boxes and cylinders and a floor slab: the face-plane culling
    /// drops only what cannot block, for points on the slab, in the air and
    /// on the solids themselves (feelers from their far sides included).
    #[test]
    fn candidates_among_boxes_and_cylinders_answer_as_the_full_queries_do() {
        use crate::geometry::{Cone, Cuboid};
        use crate::math::Transform;
        use glam::{DAffine3, DQuat};
        let mut rng = PixelRng::new(9, 4, 2);
        let turn = |rng: &mut PixelRng| {
            let axis = DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) - 0.5;
            let place = DVec3::new(
                rng.uniform() * 8.0 - 4.0,
                rng.uniform() * 3.0,
                rng.uniform() * 8.0 - 4.0,
            );
            Transform::from_affine(DAffine3::from_scale_rotation_translation(
                DVec3::new(
                    0.3 + rng.uniform(),
                    0.3 + rng.uniform(),
                    0.3 + rng.uniform(),
                ),
                DQuat::from_axis_angle(axis.normalize(), rng.uniform() * 3.0),
                place,
            ))
            .unwrap()
        };
        let mut primitives = Vec::new();
        for i in 0..30 {
            let transform = turn(&mut rng);
            let shape = if i % 2 == 0 {
                Shape::Cuboid(Box::new(Cuboid::new(
                    DVec3::splat(-0.5),
                    DVec3::splat(0.5),
                    transform,
                )))
            } else {
                Shape::Cone(Box::new(Cone {
                    base_radius: 0.4,
                    cap_radius: 0.2 * (i % 3) as f64,
                    open: i % 5 == 0,
                    transform,
                }))
            };
            primitives.push(Primitive { shape, material: 0 });
        }
        primitives.push(Primitive {
            shape: Shape::Cuboid(Box::new(Cuboid::new(
                DVec3::new(-10.0, -1.0, -10.0),
                DVec3::new(10.0, 0.0, 10.0),
                Transform::default(),
            ))),
            material: 0,
        });
        let aggregate = Aggregate::new(primitives);
        let (center, radius) = (DVec3::new(1.0, 6.0, 0.5), 0.8);
        let (mut culled, mut compared, mut blocked) = (0, 0, 0);
        for k in 0..600 {
            let (apex, on, normal) = if k % 3 == 2 {
                // A point on a solid: where a ray from outside meets it.
                let on = rng.below(30) as u32;
                let shape = &aggregate.primitives()[on as usize].shape;
                let target = shape.bounds().unwrap().centroid();
                let from = target
                    + (DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) - 0.5).normalize()
                        * 5.0;
                let ray = Ray::new(from, target - from);
                let Some(h) = shape.intersect(&ray, 0.0, f64::INFINITY) else {
                    continue;
                };
                (ray.at(h.t), on, h.normal)
            } else {
                let y = if k % 3 == 0 { 0.0 } else { rng.uniform() * 4.0 };
                let apex = DVec3::new(rng.uniform() * 10.0 - 5.0, y, rng.uniform() * 10.0 - 5.0);
                (apex, 30, DVec3::Y)
            };
            let to_center = center - apex;
            let Some(mut candidates) = aggregate.shadow_candidates(apex, on, to_center, radius, 64)
            else {
                continue;
            };
            culled += 1;
            let d2 = to_center.length_squared();
            let frame = Frame::from_z(to_center / d2.sqrt());
            let cos_max = (1.0 - radius * radius / d2).sqrt();
            let strata = Strata::new(32);
            for i in 0..32 {
                let direction = uniform_cone(&frame, cos_max, strata.point(i, &mut rng));
                let distance = sphere_roots(DVec3::ZERO, direction, to_center, radius)
                    .map_or(to_center.dot(direction), |(t0, _)| t0);
                // Feelers from the far side of a solid go through it.
                let side = if normal.dot(direction) < 0.0 {
                    -normal
                } else {
                    normal
                };
                let feeler = Ray::spawn(apex, side, direction);
                let t_max = distance - (feeler.origin - apex).length();
                let full = aggregate.any_hit(&feeler, t_max);
                assert_eq!(
                    candidates.any_hit(&aggregate, &feeler, t_max),
                    full,
                    "{apex}"
                );
                compared += 1;
                blocked += usize::from(full);
            }
        }
        assert!(culled > 300, "{culled}");
        assert!(
            blocked > compared / 20 && blocked < compared * 19 / 20,
            "{blocked}/{compared}"
        );
    }

    /// Dice-like CSGs (a box less, or merged with, a dozen balls; more
    /// children than go without an index): each feeler's query looks only
    /// at the children whose boxes meet the hull (the box alone where no
    /// ball does), and finds the nearest surface the full query finds, to
    /// the bit.
    #[test]
    fn csg_candidates_leave_out_children_off_the_hull_and_answer_the_same() {
        use crate::geometry::Cuboid;
        use crate::geometry::csg::CsgOp;
        use crate::math::Transform;
        let mut rng = PixelRng::new(3, 8, 1);
        let mut primitives = Vec::new();
        for n in 0..6 {
            let corner = DVec3::new(n as f64 * 1.5 - 4.0, 0.0, (n % 2) as f64 - 0.5);
            let cube = Cuboid::new(corner, corner + 1.0, Transform::default());
            let mut children = vec![child(Shape::Cuboid(Box::new(cube)))];
            for _ in 0..12 {
                let center = corner + DVec3::new(rng.uniform(), rng.uniform(), rng.uniform());
                let radius = 0.1 + 0.2 * rng.uniform();
                children.push(child(Shape::Sphere(Sphere { center, radius })));
            }
            let op = if n % 2 == 0 {
                CsgOp::Difference
            } else {
                CsgOp::Merge
            };
            primitives.push(Primitive {
                shape: csg(op, children),
                material: 0,
            });
        }
        let aggregate = Aggregate::new(primitives);
        let (center, radius) = (DVec3::new(0.5, 6.0, 0.5), 0.8);
        let (mut narrowed, mut compared, mut hit, mut solo) = (0, 0, 0, 0);
        for _ in 0..400 {
            let apex = DVec3::new(
                rng.uniform() * 10.0 - 5.0,
                rng.uniform() * 0.8 - 0.4,
                rng.uniform() * 3.0 - 1.5,
            );
            let to_center = center - apex;
            let Some(candidates) = aggregate.shadow_candidates(apex, 6, to_center, radius, 64)
            else {
                continue;
            };
            narrowed += usize::from(
                candidates.children[..candidates.len]
                    .iter()
                    .any(|&m| m != ALL_CHILDREN),
            );
            // Candidates answered from one child alone (`Csg::solo`).
            solo += (0..candidates.len)
                .filter(
                    |&k| match &aggregate.primitives[candidates.primitives[k] as usize].shape {
                        Shape::Csg(c) => c.solo(candidates.children[k]).is_some(),
                        _ => false,
                    },
                )
                .count();
            let d2 = to_center.length_squared();
            let frame = Frame::from_z(to_center / d2.sqrt());
            let cos_max = (1.0 - radius * radius / d2).sqrt();
            let strata = Strata::new(16);
            for i in 0..16 {
                let direction = uniform_cone(&frame, cos_max, strata.point(i, &mut rng));
                let feeler = Ray::new(apex, direction);
                let t_max = to_center.dot(direction);
                let full = aggregate
                    .closest_hit(&feeler, t_max)
                    .map(|h| (h.t, h.normal));
                let got = candidates
                    .nearest(&aggregate, &feeler, t_max)
                    .map(|b| (b.t, b.normal));
                assert_eq!(got, full, "{apex} {direction}");
                compared += 1;
                hit += usize::from(full.is_some());
            }
        }
        assert!(narrowed > 100 && solo > 50, "{narrowed} {solo}");
        assert!(
            hit > compared / 10 && hit < compared * 9 / 10,
            "{hit}/{compared}"
        );
    }

    /// Points on CSG solids (a die: a box ∩ a ball less balls; a lens; a
    /// dome, a ball ∩ a half-space; a ball drilled by a cylinder): the
    /// solid a point lies on is left out of its candidates when the light
    /// lies beyond the face or tangent plane of the part there, and every
    /// feeler (spawned off the surface, as rendering does) still finds the
    /// nearest surface the full query finds, to the bit, alone and batched.
    #[test]
    fn the_csg_a_point_lies_on_is_left_out_when_feelers_leave_it() {
        use crate::geometry::csg::CsgOp;
        use crate::geometry::{Cone, Cuboid, Plane};
        use crate::math::Transform;
        use glam::DAffine3;
        let mut rng = PixelRng::new(4, 2, 7);
        let mut solids = Vec::new();
        for n in 0..4 {
            let at = DVec3::new(n as f64 * 2.5 - 4.0, 0.5, 0.0);
            let cube = Cuboid::new(at - 0.5, at + 0.5, Transform::default());
            let mut die = vec![child(csg(
                CsgOp::Intersection,
                vec![child(Shape::Cuboid(Box::new(cube))), child(ball(at, 0.7))],
            ))];
            for k in 0..6 {
                let face = DVec3::new([0.5, -0.5, 0.0][k % 3], 0.0, [0.0, 0.5, -0.5][k % 3]);
                die.push(child(ball(
                    at + face + 0.1 * (k as f64 - 2.5) * DVec3::Y,
                    0.12,
                )));
            }
            solids.push(csg(CsgOp::Difference, die));
            let up = at + 2.0 * DVec3::Y;
            solids.push(csg(
                CsgOp::Intersection,
                vec![
                    child(ball(up - 0.6 * DVec3::X, 0.9)),
                    child(ball(up + 0.6 * DVec3::X, 0.9)),
                ],
            ));
            let side = at + 4.0 * DVec3::Z;
            let tilt = DVec3::new(0.3 * n as f64, -1.0, 0.2).normalize();
            solids.push(csg(
                CsgOp::Intersection,
                vec![
                    child(ball(side, 0.6)),
                    child(Shape::Plane(Plane {
                        normal: tilt,
                        distance: tilt.dot(side),
                    })),
                ],
            ));
            // A cylinder of radius 0.2 along z, through the ball and out.
            let bore = DAffine3::from_translation(at - 5.0 * DVec3::Z)
                * DAffine3::from_scale(DVec3::new(1.0, 1.0, 2.0));
            solids.push(csg(
                CsgOp::Difference,
                vec![
                    child(ball(at - 4.0 * DVec3::Z, 0.6)),
                    child(Shape::Cone(Box::new(Cone {
                        base_radius: 0.2,
                        cap_radius: 0.2,
                        open: false,
                        transform: Transform::from_affine(bore).unwrap(),
                    }))),
                ],
            ));
        }
        let count = solids.len() as u32;
        let mut primitives: Vec<Primitive> = solids
            .into_iter()
            .map(|shape| Primitive { shape, material: 0 })
            .collect();
        primitives.push(Primitive {
            shape: Shape::Plane(Plane {
                normal: DVec3::Y,
                distance: -0.01,
            }),
            material: 0,
        });
        let aggregate = Aggregate::new(primitives);
        let (center, radius) = (DVec3::new(0.5, 7.0, 1.5), 0.8);
        let (mut points, mut left_out, mut compared, mut hit) = (0, 0, 0, 0);
        for _ in 0..3000 {
            // A point on a solid: where a ray from around meets it.
            let on = rng.below(count as usize) as u32;
            let shape = &aggregate.primitives()[on as usize].shape;
            let target = shape.bounds().unwrap().centroid();
            let from = target
                + (DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) - 0.5).normalize() * 5.0;
            let ray = Ray::new(from, target - from);
            let Some(h) = shape.intersect(&ray, 0.0, f64::INFINITY) else {
                continue;
            };
            let (apex, normal) = (ray.at(h.t), h.normal);
            let to_center = center - apex;
            // Points that face the light, as the lit ones do.
            if normal.dot(to_center) <= 0.0 {
                continue;
            }
            let Some(candidates) = aggregate.shadow_candidates(apex, on, to_center, radius, 64)
            else {
                continue;
            };
            points += 1;
            left_out += usize::from(!candidates.primitives[..candidates.len].contains(&on));
            let d2 = to_center.length_squared();
            let frame = Frame::from_z(to_center / d2.sqrt());
            let cos_max = (1.0 - radius * radius / d2).sqrt();
            let strata = Strata::new(16);
            let mut batch = FeelerBatch::<16>::default();
            let mut expected = [None; 16];
            for (i, expected) in expected.iter_mut().enumerate() {
                let direction = uniform_cone(&frame, cos_max, strata.point(i, &mut rng));
                let distance = sphere_roots(DVec3::ZERO, direction, to_center, radius)
                    .map_or(to_center.dot(direction), |(t0, _)| t0);
                let feeler = Ray::spawn(apex, normal, direction);
                let t_max = distance - (feeler.origin - apex).length();
                let full = aggregate.closest_hit(&feeler, t_max).map(|h| Blocker {
                    t: h.t,
                    normal: h.normal,
                    material: h.material,
                });
                assert_eq!(
                    candidates.nearest(&aggregate, &feeler, t_max),
                    full,
                    "{apex}"
                );
                batch.set(i, &feeler, t_max, true);
                *expected = full;
                compared += 1;
                hit += usize::from(full.is_some());
            }
            assert_eq!(
                {
                    let mut out = FirstBlockers::default();
                    candidates.nearest_batch(&aggregate, &batch, &mut out);
                    out.blockers
                },
                expected,
                "{apex}"
            );
        }
        // Most points saw their own solid left out; some feelers were
        // blocked (by another solid, or by their own in a hollow).
        assert!(
            points > 1000 && left_out > points * 2 / 3 && left_out < points,
            "{left_out}/{points}"
        );
        assert!(hit > compared / 50, "{hit}/{compared}");
    }

    /// Feelers continued through CSG solids (lenses, merges of balls, a
    /// block with a bubble) meet, step by step, the surfaces the full
    /// query meets from each new origin: `nearest_along` skips only
    /// candidates whose surfaces end behind the origin, whether it found
    /// where they end itself or the batch that found the first surface
    /// did (`FirstBlockers::ends`).
    #[test]
    fn continued_feelers_skip_only_solids_left_behind() {
        use crate::geometry::Cuboid;
        use crate::geometry::csg::CsgOp;
        use crate::math::Transform;
        let mut rng = PixelRng::new(6, 1, 9);
        let mut primitives = Vec::new();
        for n in 0..6 {
            let at = DVec3::new(n as f64 * 1.6 - 4.0, 1.0 + 0.3 * (n % 3) as f64, 0.0);
            let (op, children) = match n % 3 {
                0 => (
                    CsgOp::Intersection,
                    vec![
                        child(ball(at - 0.5 * DVec3::Y, 0.8)),
                        child(ball(at + 0.5 * DVec3::Y, 0.8)),
                    ],
                ),
                1 => (
                    CsgOp::Merge,
                    vec![
                        child(ball(at - 0.3 * DVec3::X, 0.5)),
                        child(ball(at + 0.3 * DVec3::X, 0.4)),
                        child(ball(at + 0.4 * DVec3::Y, 0.3)),
                    ],
                ),
                _ => (
                    CsgOp::Difference,
                    vec![
                        child(Shape::Cuboid(Box::new(Cuboid::new(
                            at - 0.6,
                            at + 0.6,
                            Transform::default(),
                        )))),
                        child(ball(at + 0.1, 0.3)),
                    ],
                ),
            };
            primitives.push(Primitive {
                shape: csg(op, children),
                material: 0,
            });
            // Plain balls among them, some nearer the floor: a nearer hit
            // on one leaves the CSG's end unknown.
            primitives.push(sphere(
                at + DVec3::new(0.7, -0.4 + 0.5 * (n % 2) as f64, 0.3),
                0.25,
            ));
        }
        let aggregate = Aggregate::new(primitives);
        let (center, radius) = (DVec3::new(0.5, 6.0, 0.5), 1.5);
        let (mut chains, mut steps, mut skipped, mut known) = (0, 0, 0, 0);
        for _ in 0..300 {
            let apex = DVec3::new(rng.uniform() * 10.0 - 5.0, 0.0, rng.uniform() * 2.0 - 1.0);
            let to_center = center - apex;
            let Some(candidates) = aggregate.shadow_candidates(apex, 6, to_center, radius, 64)
            else {
                continue;
            };
            let d2 = to_center.length_squared();
            let frame = Frame::from_z(to_center / d2.sqrt());
            let cos_max = (1.0 - radius * radius / d2).sqrt();
            let strata = Strata::new(16);
            let mut batch = FeelerBatch::<16>::default();
            for i in 0..16 {
                let direction = uniform_cone(&frame, cos_max, strata.point(i, &mut rng));
                let feeler = Ray::spawn(apex, DVec3::Y, direction);
                batch.set(i, &feeler, to_center.dot(direction), true);
            }
            let mut first = FirstBlockers::default();
            candidates.nearest_batch(&aggregate, &batch, &mut first);
            for i in 0..16 {
                let mut feeler = batch.ray(i);
                let direction = feeler.direction;
                let mut remaining = batch.t_max[i];
                let mut blocker = first.blockers[i];
                assert_eq!(blocker, candidates.nearest(&aggregate, &feeler, remaining));
                let mut beyond = [f64::INFINITY; MAX_CANDIDATES];
                let (slot, ends) = (first.slots[i] as usize, first.ends[i]);
                if ends.is_finite() {
                    beyond[slot] = ends.max(0.0);
                }
                known += usize::from(ends.is_finite());
                let mut travelled = 0.0;
                chains += 1;
                // As `Whitted::transmission` walks the line.
                while let Some(b) = blocker {
                    let point = feeler.at(b.t);
                    let next = Ray::spawn(point, b.normal, direction);
                    let step = b.t + (next.origin - point).length();
                    (remaining, travelled, feeler) = (remaining - step, travelled + step, next);
                    let full = candidates.nearest(&aggregate, &feeler, remaining);
                    blocker = candidates.nearest_along(
                        &aggregate,
                        &feeler,
                        remaining,
                        travelled,
                        &mut beyond,
                    );
                    assert_eq!(blocker, full, "{apex} {direction}");
                    steps += 1;
                    skipped += beyond[..candidates.len]
                        .iter()
                        .filter(|&&b| travelled > b)
                        .count();
                }
            }
        }
        // Lines went through solids, solids left behind were skipped, and
        // the batch knew where many of the first solids end.
        assert!(
            steps > chains / 4 && skipped > steps / 4 && known > chains / 8,
            "{chains} {steps} {skipped} {known}"
        );
    }

    /// A polygon half across the light's cone and a ball beside it: the
    /// batched test answers as the full query does, lane by lane, through
    /// both its sphere and its shape-by-shape paths.
    #[test]
    fn a_batch_answers_as_the_full_query_through_polygons_and_spheres() {
        let quad = crate::geometry::Polygon::new(vec![
            DVec3::new(-2.0, 2.0, -2.0),
            DVec3::new(0.1, 2.0, -2.0),
            DVec3::new(0.1, 2.2, 2.0),
            DVec3::new(-2.0, 2.2, 2.0),
        ])
        .unwrap();
        let aggregate = Aggregate::new(vec![
            Primitive {
                shape: Shape::Polygon(Box::new(quad)),
                material: 0,
            },
            sphere(DVec3::new(0.5, 3.0, 0.3), 0.3),
        ]);
        let (apex, normal, to_center, radius) = (DVec3::ZERO, DVec3::Y, 5.0 * DVec3::Y, 1.0);
        let candidates = aggregate
            .shadow_candidates(apex, u32::MAX, to_center, radius, 64)
            .unwrap();
        assert_eq!(candidates.len(), 2);
        let frame = Frame::from_z(DVec3::Y);
        let cos_max = (1.0 - radius * radius / 25.0f64).sqrt();
        let mut rng = PixelRng::new(2, 7, 1);
        let mut blocked = 0;
        for _ in 0..100 {
            let mut batch = FeelerBatch::<16>::default();
            let mut expected = [false; 16];
            let mut expected_nearest = [None; 16];
            for (lane, expected) in expected.iter_mut().enumerate() {
                let u = glam::DVec2::new(rng.uniform(), rng.uniform());
                let direction = uniform_cone(&frame, cos_max, u);
                let feeler = Ray::spawn(apex, normal, direction);
                let t_max = crate::lights::distance_to_sphere(direction, to_center, radius);
                batch.set(lane, &feeler, t_max, true);
                *expected = aggregate.any_hit(&feeler, t_max);
                expected_nearest[lane] = candidates.nearest(&aggregate, &feeler, t_max);
            }
            assert_eq!(candidates.any_hit_batch(&aggregate, &batch), expected);
            assert_eq!(
                {
                    let mut out = FirstBlockers::default();
                    candidates.nearest_batch(&aggregate, &batch, &mut out);
                    out.blockers
                },
                expected_nearest
            );
            blocked += expected.iter().filter(|&&b| b).count();
        }
        // Some feelers pass, some are blocked.
        assert!(blocked > 200 && blocked < 1400, "{blocked}");
    }

    /// The hull's planes keep every box that holds a point of the hull
    /// (a point between the apex and a point of the light's ball), and
    /// cull boxes well off its side.
    #[test]
    fn the_hull_planes_keep_every_box_around_a_point_of_the_hull() {
        let mut rng = PixelRng::new(3, 8, 5);
        let mut u = || 2.0 * rng.uniform() - 1.0;
        let mut culled = 0;
        for _ in 0..2000 {
            let apex = DVec3::new(u(), u(), u()) * 5.0;
            let center = DVec3::new(u(), u(), u()) * 10.0;
            let radius = 0.05 + u().abs();
            let to_center = center - apex;
            let distance = to_center.length();
            if distance <= radius {
                continue;
            }
            let axis = to_center / distance;
            let planes = HullPlanes::new(apex, axis, distance, radius, 0.0);
            let inside = DVec3::new(u(), u(), u());
            let q = center + radius * inside.normalize_or_zero() * u().abs();
            let p = apex + (q - apex) * u().abs();
            let half = DVec3::new(u().abs(), u().abs(), u().abs()) * 0.01;
            let shift = DVec3::new(u(), u(), u()) * half;
            assert!(planes.may_meet_box(p + shift, half), "{apex} {center} {p}");
            // A small box off the side, beyond the widest part of the hull.
            let side = crate::math::Frame::from_z(axis).x;
            let off = apex + axis * distance * u().abs() + side * (radius * 1.5 + 0.1);
            culled += usize::from(!planes.may_meet_box(off, DVec3::splat(0.01)));
        }
        assert!(culled > 1500, "{culled}");
    }

    #[test]
    fn a_point_under_an_open_sky_has_no_candidates_and_the_floor_is_not_one() {
        let aggregate = Aggregate::new(vec![
            sphere(DVec3::new(5.0, 1.0, 0.0), 1.0),
            Primitive {
                shape: Shape::Plane(Plane {
                    normal: DVec3::Y,
                    distance: 0.0,
                }),
                material: 0,
            },
        ]);
        let c = aggregate
            .shadow_candidates(DVec3::ZERO, 1, DVec3::new(0.0, 5.0, 0.0), 1.0, 16)
            .unwrap();
        assert!(c.is_empty());
        // The ball beside the light's cone is a candidate once the light
        // moves behind it.
        let c = aggregate
            .shadow_candidates(DVec3::ZERO, 1, DVec3::new(10.0, 2.0, 0.0), 1.0, 16)
            .unwrap();
        assert_eq!(c.len(), 1);
    }
}
