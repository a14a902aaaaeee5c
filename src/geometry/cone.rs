//! POV-Ray's `cone` and `cylinder`: a truncated cone between two end
//! points with a radius at each (equal radii: a cylinder; a radius of 0: a
//! tip), capped by discs or open.
//!
//! In its own space the axis runs along z from 0 (`base`) to 1 (`cap`) and
//! the radius is r(z) = r₀ + k·z with k = r₁ − r₀. A point of the ray
//! o + t·d lies on the side where x² + y² = (r₀ + k·z)², the quadratic
//! a·t² + b·t + c = 0 with
//!   a = dx² + dy² − k²·dz²,
//!   b = 2(ox·dx + oy·dy − k·dz·(r₀ + k·oz)),
//!   c = ox² + oy² − (r₀ + k·oz)²,
//! a root counting where 0 ≤ z ≤ 1. The caps are the discs z = 0 (radius
//! r₀) and z = 1 (radius r₁).
//!
//! Normals: on the side the gradient (x, y, −k·(r₀ + k·z)), outward; on
//! the caps ∓z. Texture coordinates: on the side u = ½ + atan2(y, x)/2π
//! around the axis and v = z along it; on a cap u = ½ + x/2r, v = ½ + y/2r.

use glam::{DVec2, DVec3};

use super::cuboid::placed_bounds;
use super::span::{Intervals, Surface, interval};
use super::{Aabb, ShapeHit};
use crate::math::{Ray, Transform, transcendental};

/// A truncated cone (or cylinder) in its own space, placed by `transform`.
#[derive(Clone, Debug, PartialEq)]
pub struct Cone {
    /// Radius at z = 0 (the base), in object units.
    pub base_radius: f64,
    /// Radius at z = 1 (the cap).
    pub cap_radius: f64,
    /// Without the end discs.
    pub open: bool,
    /// Object to world: (0, 0, 0) to the base, (0, 0, 1) to the cap.
    pub transform: Transform,
}

/// The real roots of a·t² + b·t + c = 0, smaller first, computed without
/// cancellation (q = −(b + sign(b)√Δ)/2, roots q/a and c/q); a linear
/// equation (a = 0) has its one root twice.
pub fn quadratic_roots(a: f64, b: f64, c: f64) -> Option<(f64, f64)> {
    if a == 0.0 {
        if b == 0.0 {
            return None;
        }
        let t = -c / b;
        return Some((t, t));
    }
    let discriminant = b * b - 4.0 * a * c;
    if discriminant < 0.0 {
        return None;
    }
    let q = -0.5 * (b + discriminant.sqrt().copysign(b));
    if q == 0.0 {
        return Some((0.0, 0.0));
    }
    let (t0, t1) = (q / a, c / q);
    Some(if t0 <= t1 { (t0, t1) } else { (t1, t0) })
}

/// The parts of a closed cone's surface (`Surface::part`).
const SIDE: u8 = 0;
const BASE: u8 = 1;
const CAP: u8 = 2;

impl Cone {
    fn slope(&self) -> f64 {
        self.cap_radius - self.base_radius
    }

    /// The side's quadratic a·t² + b·t + c = 0 along the object-space ray
    /// (o, d): x² + y² = (r0 + k·z)², one expression for every query so
    /// that each finds the same roots to the bit.
    #[inline(always)]
    fn side_quadratic(&self, o: DVec3, d: DVec3) -> (f64, f64, f64) {
        let (r0, k) = (self.base_radius, self.slope());
        let ro = r0 + k * o.z;
        let a = d.x * d.x + d.y * d.y - k * k * d.z * d.z;
        let b = 2.0 * (o.x * d.x + o.y * d.y - k * d.z * ro);
        let c = o.x * o.x + o.y * o.y - ro * ro;
        (a, b, c)
    }

    /// The side's outward normal at object-space point `p`, not unit.
    #[inline(always)]
    fn side_normal(&self, p: DVec3) -> DVec3 {
        let (r0, k) = (self.base_radius, self.slope());
        DVec3::new(p.x, p.y, -k * (r0 + k * p.z))
    }

    /// The nearest crossing of the object-space ray (o, d) with the
    /// surface in (t_min, t_max), as (t, object-space outward normal): the
    /// side's roots in ascending order, then the base and the cap, the
    /// first of equal ones kept.
    #[inline(always)]
    fn nearest_crossing(&self, o: DVec3, d: DVec3, t_min: f64, t_max: f64) -> Option<(f64, DVec3)> {
        let mut best: Option<(f64, DVec3)> = None;
        let mut consider = |t: f64, n: DVec3| {
            if t > t_min && t < t_max && best.is_none_or(|(b, _)| t.total_cmp(&b).is_lt()) {
                best = Some((t, n));
            }
        };
        let (a, b, c) = self.side_quadratic(o, d);
        if let Some((t0, t1)) = quadratic_roots(a, b, c) {
            let roots = [t0, t1];
            let distinct = if t0 == t1 { &roots[..1] } else { &roots[..] };
            for &t in distinct {
                let p = o + t * d;
                if (0.0..=1.0).contains(&p.z) {
                    consider(t, self.side_normal(p));
                }
            }
        }
        if !self.open && d.z != 0.0 {
            for (z, r, n) in [
                (0.0, self.base_radius, -DVec3::Z),
                (1.0, self.cap_radius, DVec3::Z),
            ] {
                let t = (z - o.z) / d.z;
                let p = o + t * d;
                if r > 0.0 && p.x * p.x + p.y * p.y <= r * r {
                    consider(t, n);
                }
            }
        }
        best
    }

    /// For each of `N` rays (origins and directions by coordinate, as a
    /// structure of arrays), the nearest crossing in (0, t_max\[k\]) as
    /// `nearest_crossing` finds it, without a
    /// branch (every case computed, then chosen by masks and selects), so
    /// that the loop over the rays compiles to vector code: the same
    /// operations on the same values lane by lane, so the same bits.
    /// Each lane gives (met, t, part): the side, the base or the cap
    /// (see [`crossing_normal`](Self::crossing_normal)).
    #[inline(always)]
    pub fn nearest_crossings<const N: usize>(
        &self,
        origin: &[[f64; N]; 3],
        direction: &[[f64; N]; 3],
        t_max: &[f64; N],
    ) -> ([bool; N], [f64; N], [u8; N]) {
        let (mut met, mut best, mut part) = ([false; N], [0.0; N], [SIDE; N]);
        let m = &self.transform.to_object;
        let (r0, r1) = (self.base_radius, self.cap_radius);
        for lane in 0..N {
            let o = m.transform_point3(DVec3::new(
                origin[0][lane],
                origin[1][lane],
                origin[2][lane],
            ));
            let d = m.transform_vector3(DVec3::new(
                direction[0][lane],
                direction[1][lane],
                direction[2][lane],
            ));
            let (a, b, c) = self.side_quadratic(o, d);
            // `quadratic_roots`, both of its cases worked out.
            let linear = a == 0.0;
            let t_linear = -c / b;
            let discriminant = b * b - 4.0 * a * c;
            let q = -0.5 * (b + discriminant.sqrt().copysign(b));
            let (u0, u1) = (q / a, c / q);
            let (s0, s1) = if u0 <= u1 { (u0, u1) } else { (u1, u0) };
            let (s0, s1) = if q == 0.0 { (0.0, 0.0) } else { (s0, s1) };
            let has_roots = if linear {
                b != 0.0
            } else {
                // Not negative (a NaN goes on, as there).
                discriminant >= 0.0 || discriminant.is_nan()
            };
            let (t0, t1) = if linear {
                (t_linear, t_linear)
            } else {
                (s0, s1)
            };
            let limit = t_max[lane];
            let (mut found, mut nearest, mut which) = (false, 0.0, SIDE);
            let mut consider = |ok: bool, t: f64, p: u8| {
                let take = ok & (t > 0.0) & (t < limit) & (!found | (t < nearest));
                found |= take;
                nearest = if take { t } else { nearest };
                which = if take { p } else { which };
            };
            let z0 = (o + t0 * d).z;
            consider(has_roots & (0.0..=1.0).contains(&z0), t0, SIDE);
            let z1 = (o + t1 * d).z;
            consider(has_roots & (t0 != t1) & (0.0..=1.0).contains(&z1), t1, SIDE);
            let caps = !self.open & (d.z != 0.0);
            for (z, r, p) in [(0.0, r0, BASE), (1.0, r1, CAP)] {
                let t = (z - o.z) / d.z;
                let at = o + t * d;
                consider(
                    caps & (r > 0.0) & (at.x * at.x + at.y * at.y <= r * r),
                    t,
                    p,
                );
            }
            met[lane] = found;
            best[lane] = nearest;
            part[lane] = which;
        }
        (met, best, part)
    }

    /// The unit world normal of the crossing of `ray` at `t` on `part`
    /// (see [`nearest_crossings`](Self::nearest_crossings)), as
    /// [`intersect`](Self::intersect) gives it.
    #[inline(always)]
    pub fn crossing_normal(&self, ray: &Ray, t: f64, part: u8) -> DVec3 {
        let n = match part {
            BASE => -DVec3::Z,
            CAP => DVec3::Z,
            _ => {
                let (o, d) = self.transform.ray_to_object(ray);
                self.side_normal(o + t * d)
            }
        };
        self.transform.normal(n)
    }

    /// The nearest hit in (t_min, t_max), from outside or inside.
    pub fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<ShapeHit> {
        let (o, d) = self.transform.ray_to_object(ray);
        let (t, n) = self.nearest_crossing(o, d, t_min, t_max)?;
        let normal = self.transform.normal(n);
        Some(ShapeHit::geometric(
            t,
            normal,
            ray.direction.dot(normal) < 0.0,
        ))
    }

    /// Where the whole line of `ray` is inside the closed solid: where the
    /// side's quadratic is ≤ 0 (between its roots when a > 0; outside them
    /// when a < 0, a ray steeper than the cone meeting both nappes)
    /// within the slab 0 ≤ z ≤ 1. Each end takes the normal of the
    /// constraint that bounds it there (the cap's on a tie: the rim).
    pub fn inside(&self, ray: &Ray) -> Intervals {
        let (o, d) = self.transform.ray_to_object(ray);
        let inf = f64::INFINITY;
        let (a, b, c) = self.side_quadratic(o, d);
        let mut side: arrayvec::ArrayVec<(f64, f64), 2> = arrayvec::ArrayVec::new();
        if a == 0.0 {
            match b {
                0.0 if c <= 0.0 => side.push((-inf, inf)),
                0.0 => {}
                b if b > 0.0 => side.push((-inf, -c / b)),
                b => side.push((-c / b, inf)),
            }
        } else {
            match quadratic_roots(a, b, c) {
                None if a < 0.0 => side.push((-inf, inf)),
                None => {}
                Some((t0, t1)) if a > 0.0 => side.push((t0, t1)),
                Some((t0, t1)) => {
                    side.push((-inf, t0));
                    side.push((t1, inf));
                }
            }
        }
        // The slab between the base (z = 0, normal −z) and the cap (z = 1).
        let (slab, enter_cap, exit_cap) = if d.z == 0.0 {
            if !(0.0..=1.0).contains(&o.z) {
                return Intervals::new();
            }
            ((-inf, inf), SIDE, SIDE)
        } else {
            let (t0, t1) = (-o.z / d.z, (1.0 - o.z) / d.z);
            if d.z > 0.0 {
                ((t0, t1), BASE, CAP)
            } else {
                ((t1, t0), CAP, BASE)
            }
        };
        let mut out = Intervals::new();
        for (s0, s1) in side {
            let enter = if slab.0 >= s0 {
                (slab.0, enter_cap)
            } else {
                (s0, SIDE)
            };
            let exit = if slab.1 <= s1 {
                (slab.1, exit_cap)
            } else {
                (s1, SIDE)
            };
            let surface = |(t, part): (f64, u8)| Surface { t, part };
            if let Some(i) = interval(surface(enter), surface(exit)) {
                out.push(i);
            }
        }
        out
    }

    /// The outward unit normal where `ray` crosses the closed solid's
    /// surface at `s` (see `inside`): the side's from the point, the
    /// base's −z, the cap's +z (object space).
    pub fn surface_normal(&self, ray: &Ray, s: Surface) -> DVec3 {
        let n = match s.part {
            BASE => -DVec3::Z,
            CAP => DVec3::Z,
            _ => {
                let (o, d) = self.transform.ray_to_object(ray);
                self.side_normal(o + s.t * d)
                    .try_normalize()
                    .unwrap_or(DVec3::Z * self.slope().signum())
            }
        };
        self.transform.normal(n)
    }

    /// Whether the object-space point lies inside the closed solid.
    pub fn contains(&self, p: DVec3) -> bool {
        let r = self.base_radius + self.slope() * p.z;
        (0.0..=1.0).contains(&p.z) && p.x * p.x + p.y * p.y <= r * r
    }

    /// Texture coordinates at the world point `point` (see the module).
    pub fn uv(&self, point: DVec3, normal: DVec3) -> DVec2 {
        let p = self.transform.to_object.transform_point3(point);
        // A cap's world normal is the axis's; the side's is not.
        let axis = self.transform.normal(DVec3::Z);
        if !self.open && normal.dot(axis).abs() > 1.0 - 1e-9 {
            let r = if p.z < 0.5 {
                self.base_radius
            } else {
                self.cap_radius
            };
            return DVec2::new(0.5 + p.x / (2.0 * r), 0.5 + p.y / (2.0 * r));
        }
        DVec2::new(
            0.5 + transcendental::atan2(p.y, p.x) / std::f64::consts::TAU,
            p.z,
        )
    }

    /// Whether a face plane of the cone's own box (its end planes, and
    /// the sides at its larger radius) separates `apex` and the ball
    /// (`center`, `radius`) from it; see `cuboid::box_separates`.
    pub fn separates(&self, apex: DVec3, center: DVec3, radius: f64) -> bool {
        let r = self.base_radius.max(self.cap_radius);
        super::cuboid::box_separates(
            &self.transform,
            DVec3::new(-r, -r, 0.0),
            DVec3::new(r, r, 1.0),
            apex,
            center,
            radius,
        )
    }

    /// The bounding box of the placed cone.
    pub fn bounds(&self) -> Aabb {
        let r = self.base_radius.max(self.cap_radius);
        placed_bounds(
            &self.transform,
            DVec3::new(-r, -r, 0.0),
            DVec3::new(r, r, 1.0),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Frame;
    use crate::math::rng::PixelRng;
    use glam::{DAffine3, DMat3};

    /// The cone from `base` to `cap`, as the scene builds it.
    fn placed(base: DVec3, cap: DVec3, r0: f64, r1: f64, open: bool) -> Cone {
        let axis = cap - base;
        let f = Frame::from_z(axis.normalize());
        let to_world = DAffine3::from_mat3_translation(DMat3::from_cols(f.x, f.y, axis), base);
        Cone {
            base_radius: r0,
            cap_radius: r1,
            open,
            transform: Transform::from_affine(to_world).unwrap(),
        }
    }

    #[test]
    fn quadratic_roots_are_exact_on_hand_worked_cases() {
        assert_eq!(quadratic_roots(1.0, -3.0, 2.0), Some((1.0, 2.0)));
        assert_eq!(quadratic_roots(1.0, 0.0, 1.0), None);
        assert_eq!(quadratic_roots(0.0, 2.0, -4.0), Some((2.0, 2.0)));
        // Cancellation: roots 1e-8 and 1e8 both to full precision.
        let (a, b) = quadratic_roots(1.0, -(1e8 + 1e-8), 1.0).unwrap();
        assert!((a - 1e-8).abs() < 1e-22 && (b - 1e8).abs() < 1e-6);
    }

    #[test]
    fn hand_worked_cylinder_and_cone_hits() {
        // A cylinder of radius 1 along y from 0 to 2.
        let c = placed(DVec3::ZERO, DVec3::new(0.0, 2.0, 0.0), 1.0, 1.0, false);
        let h = c
            .intersect(
                &Ray::new(DVec3::new(5.0, 1.0, 0.0), DVec3::NEG_X),
                0.0,
                f64::INFINITY,
            )
            .unwrap();
        assert!((h.t - 4.0).abs() < 1e-12 && (h.normal - DVec3::X).length() < 1e-12);
        // Down the axis from above: the top cap at y = 2.
        let h = c
            .intersect(
                &Ray::new(DVec3::new(0.2, 5.0, 0.0), DVec3::NEG_Y),
                0.0,
                f64::INFINITY,
            )
            .unwrap();
        assert!((h.t - 3.0).abs() < 1e-12 && (h.normal - DVec3::Y).length() < 1e-12);
        // Open: the ray down the axis passes through.
        let open = Cone {
            open: true,
            ..c.clone()
        };
        assert!(
            open.intersect(
                &Ray::new(DVec3::new(0.2, 5.0, 0.0), DVec3::NEG_Y),
                0.0,
                f64::INFINITY
            )
            .is_none()
        );
        // A cone of radius 1 at y = 0 to a tip at y = 1: the side at
        // height ½ has radius ½, its normal (1, 1, 0)/√2 in the x-y plane.
        let cone = placed(DVec3::ZERO, DVec3::Y, 1.0, 0.0, false);
        let h = cone
            .intersect(
                &Ray::new(DVec3::new(3.0, 0.5, 0.0), DVec3::NEG_X),
                0.0,
                f64::INFINITY,
            )
            .unwrap();
        assert!((h.t - 2.5).abs() < 1e-12, "{}", h.t);
        let n = DVec3::new(1.0, 1.0, 0.0).normalize();
        assert!((h.normal - n).length() < 1e-12, "{}", h.normal);
    }

    /// Against a march on the inside test, random rays and cones.
    #[test]
    fn hits_agree_with_a_march_on_random_rays() {
        let mut rng = PixelRng::new(9, 3, 4);
        let mut u = || 2.0 * rng.uniform() - 1.0;
        let mut hits = 0;
        for i in 0..1500 {
            let base = DVec3::new(u(), u(), u());
            let cap = base + DVec3::new(u(), u(), u()) * 2.0;
            let (r0, r1) = (
                u().abs() + 0.1,
                if i % 3 == 0 { 0.0 } else { u().abs() + 0.1 },
            );
            let c = placed(base, cap, r0, r1, false);
            let origin = DVec3::new(u(), u(), u()) * 5.0;
            // Aimed near the cone, so most rays meet it.
            let target =
                c.transform
                    .point(DVec3::new(1.2 * r0 * u(), 1.2 * r0 * u(), 0.5 + 0.6 * u()));
            let ray = Ray::new(origin, (target - origin).normalize());
            let inside = |p: DVec3| c.contains(c.transform.to_object.transform_point3(p));
            let step = 1e-3;
            let start = inside(origin);
            let march = (1..12_000)
                .map(|i| i as f64 * step)
                .find(|&t| inside(ray.at(t)) != start);
            let hit = c.intersect(&ray, 0.0, f64::INFINITY);
            if let (Some(h), Some(t)) = (hit, march) {
                hits += 1;
                // The march can step over a sliver: the hit is never later.
                assert!(h.t <= t + 1e-9, "{} vs {t}", h.t);
                if (h.t - t).abs() <= step {
                    assert_eq!(h.front_face, !start);
                }
            } else if let Some(t) = march {
                panic!("a crossing at {t} missed");
            }
        }
        assert!(hits > 300, "{hits}");
    }
}
