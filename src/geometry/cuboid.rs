//! POV-Ray's `box`: an axis-aligned box between two corners, in its own
//! space (a transform may turn, shear or stretch it).
//!
//! The slab test (Kay and Kajiya): along each axis the ray is inside the
//! slab min ≤ o + t·d ≤ max for t between (min − o)/d and (max − o)/d; it is
//! inside the box where all three intervals overlap, from the largest entry
//! to the smallest exit.
//!
//! Normals: the face's outward axis. Texture coordinates: on a face normal
//! to axis i, the other two coordinates (in the order (y, z), (x, z),
//! (x, y)) taken 0 to 1 across the box.

use glam::{DVec2, DVec3};

use super::span::{Interval, Intervals, Surface, interval};
use super::{Aabb, ShapeHit};
use crate::math::{Ray, Transform};

/// A box between `min` and `max` in its own space, placed by `transform`.
#[derive(Clone, Debug, PartialEq)]
pub struct Cuboid {
    /// The lower corner, in object space.
    pub min: DVec3,
    /// The upper corner, in object space.
    pub max: DVec3,
    /// Object to world.
    pub transform: Transform,
    /// The world unit normal of each face, by `Surface::part` (see
    /// `inside`): what `transform.normal` gives for the face's axis,
    /// worked out once, since feelers and CSG ask it of every box they hit.
    faces: [DVec3; 6],
}

/// The ray's parameter interval inside the box `[min, max]` as
/// ((t_enter, entry axis), (t_exit, exit axis)), or `None` when it misses.
/// A direction component of 0 leaves that slab open when the origin lies
/// in it (no 0/0 on its faces).
#[inline]
pub fn slab_interval(
    origin: DVec3,
    direction: DVec3,
    min: DVec3,
    max: DVec3,
) -> Option<((f64, usize), (f64, usize))> {
    let (mut enter, mut exit) = ((f64::NEG_INFINITY, 0), (f64::INFINITY, 0));
    // One slab, narrowing (enter, exit); false when the ray misses it.
    // Called axis by axis in turn, not looped over: indexing a vector by
    // a variable axis compiled to a branch per component, and the loop
    // was not unrolled.
    let mut slab = |axis: usize, o: f64, d: f64, min: f64, max: f64| {
        if d == 0.0 {
            return !(o < min || o > max);
        }
        let (a, b) = ((min - o) / d, (max - o) / d);
        let (near, far) = if a <= b { (a, b) } else { (b, a) };
        if near > enter.0 {
            enter = (near, axis);
        }
        if far < exit.0 {
            exit = (far, axis);
        }
        true
    };
    let met = slab(0, origin.x, direction.x, min.x, max.x)
        && slab(1, origin.y, direction.y, min.y, max.y)
        && slab(2, origin.z, direction.z, min.z, max.z);
    if !met {
        return None;
    }
    (enter.0 <= exit.0).then_some((enter, exit))
}

impl Cuboid {
    /// The box between `min` and `max` in its own space, placed by
    /// `transform`.
    pub fn new(min: DVec3, max: DVec3, transform: Transform) -> Self {
        let faces = std::array::from_fn(|part| transform.normal(face_axis(part as u8)));
        Cuboid {
            min,
            max,
            transform,
            faces,
        }
    }

    /// The nearest hit in (t_min, t_max), from outside or inside.
    pub fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<ShapeHit> {
        let (origin, direction) = self.transform.ray_to_object(ray);
        let ((t0, a0), (t1, a1)) = slab_interval(origin, direction, self.min, self.max)?;
        // Entering, the face looks against the ray; leaving, along it.
        let (t, axis, sign) = if t0 > t_min && t0 < t_max {
            (t0, a0, -direction[a0].signum())
        } else if t1 > t_min && t1 < t_max {
            (t1, a1, direction[a1].signum())
        } else {
            return None;
        };
        let normal = self.faces[face_part(axis, sign) as usize];
        Some(ShapeHit::geometric(
            t,
            normal,
            ray.direction.dot(normal) < 0.0,
        ))
    }

    /// Where the whole line of `ray` is inside: the slab interval.
    pub fn inside(&self, ray: &Ray) -> Intervals {
        self.interval(ray).into_iter().collect()
    }

    /// [`inside`](Self::inside)'s one interval, if any.
    #[inline(always)]
    pub fn interval(&self, ray: &Ray) -> Option<Interval> {
        let (origin, direction) = self.transform.ray_to_object(ray);
        let ((t0, a0), (t1, a1)) = slab_interval(origin, direction, self.min, self.max)?;
        let face = |t: f64, axis: usize, sign: f64| Surface {
            t,
            part: face_part(axis, sign),
        };
        interval(
            face(t0, a0, -direction[a0].signum()),
            face(t1, a1, direction[a1].signum()),
        )
    }

    /// The outward unit normal of face `s.part` (see `inside`).
    pub fn surface_normal(&self, _ray: &Ray, s: Surface) -> DVec3 {
        self.faces[usize::from(s.part)]
    }

    /// Whether one face plane of the box separates the point `apex` and
    /// the whole ball (`center`, `radius` + `slack`) from it; see
    /// [`box_separates`].
    pub fn separates(&self, apex: DVec3, center: DVec3, radius: f64, slack: f64) -> bool {
        box_separates(
            &self.transform,
            self.min,
            self.max,
            apex,
            center,
            radius + slack,
        )
    }

    /// Texture coordinates at the world point `point` (see the module).
    pub fn uv(&self, point: DVec3) -> DVec2 {
        let p = self.transform.to_object.transform_point3(point);
        let size = self.max - self.min;
        let f = (p - self.min) / size;
        // The face is the axis where the point lies nearest a side.
        let dist = (p - self.min).abs().min((self.max - p).abs()) / size;
        let axis = if dist.x <= dist.y && dist.x <= dist.z {
            0
        } else if dist.y <= dist.z {
            1
        } else {
            2
        };
        match axis {
            0 => DVec2::new(f.y, f.z),
            1 => DVec2::new(f.x, f.z),
            _ => DVec2::new(f.x, f.y),
        }
    }

    /// The bounding box of the placed box.
    pub fn bounds(&self) -> Aabb {
        placed_bounds(&self.transform, self.min, self.max)
    }
}

/// The face (`Surface::part`) normal to `axis` that faces along `sign`: the
/// axis, and whether it faces +axis (a sign that is not positive: −axis).
#[inline(always)]
fn face_part(axis: usize, sign: f64) -> u8 {
    (2 * axis) as u8 + u8::from(sign > 0.0)
}

/// The object-space outward normal of face `part`.
fn face_axis(part: u8) -> DVec3 {
    let mut n = DVec3::ZERO;
    n[usize::from(part / 2)] = if part % 2 == 1 { 1.0 } else { -1.0 };
    n
}

/// Whether one face plane of the object-space box `[min, max]` placed by
/// `transform` has the world point `apex` and the whole world ball
/// (`center`, `radius`) on its outer side: then no segment from the apex
/// to the ball meets the box, nor anything inside it (the box lies behind
/// that plane). Worked in object space, where the ball's radius grows at
/// most by the map's Frobenius norm. For shadow feelers: the floor slab
/// under every point above it, the box a point lies on.
pub fn box_separates(
    transform: &Transform,
    min: DVec3,
    max: DVec3,
    apex: DVec3,
    center: DVec3,
    radius: f64,
) -> bool {
    let m = transform.to_object.matrix3;
    let stretch =
        (m.x_axis.length_squared() + m.y_axis.length_squared() + m.z_axis.length_squared()).sqrt();
    let (a, c) = (
        transform.to_object.transform_point3(apex),
        transform.to_object.transform_point3(center),
    );
    let r = radius * stretch;
    (0..3).any(|i| (a[i] >= max[i] && c[i] - r > max[i]) || (a[i] <= min[i] && c[i] + r < min[i]))
}

/// The world bounding box of the object-space box `[min, max]` placed by
/// `transform` (Arvo's method: the centre mapped, and along each world
/// axis the half extents weighted by the absolute matrix entries, which is
/// where the farthest corner lies, without transforming eight corners).
pub fn placed_bounds(transform: &Transform, min: DVec3, max: DVec3) -> Aabb {
    let m = transform.to_world.matrix3;
    let center = transform.point(0.5 * (min + max));
    let half = 0.5 * (max - min);
    let abs = glam::DMat3::from_cols(m.x_axis.abs(), m.y_axis.abs(), m.z_axis.abs());
    // Widened by a few roundings, so every corner lies within.
    let reach = abs * half * (1.0 + 8.0 * f64::EPSILON) + center.abs() * (4.0 * f64::EPSILON);
    Aabb {
        min: center - reach,
        max: center + reach,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::PixelRng;
    use glam::DAffine3;

    fn unit_box() -> Cuboid {
        Cuboid::new(
            DVec3::splat(-1.0),
            DVec3::new(1.0, 2.0, 3.0),
            Transform::default(),
        )
    }

    #[test]
    fn hand_worked_hits() {
        let b = unit_box();
        // From +x towards the origin: enters the face x = 1 at t = 4.
        let ray = Ray::new(DVec3::new(5.0, 0.0, 0.0), DVec3::NEG_X);
        let h = b.intersect(&ray, 0.0, f64::INFINITY).unwrap();
        assert_eq!((h.t, h.normal, h.front_face), (4.0, DVec3::X, true));
        // From inside: leaves through y = 2, normal +y, not a front face.
        let ray = Ray::new(DVec3::ZERO, DVec3::Y);
        let h = b.intersect(&ray, 0.0, f64::INFINITY).unwrap();
        assert_eq!((h.t, h.normal, h.front_face), (2.0, DVec3::Y, false));
        // Parallel to a slab, outside it: a miss; inside it: a hit.
        let ray = Ray::new(DVec3::new(5.0, 3.0, 0.0), DVec3::NEG_X);
        assert!(b.intersect(&ray, 0.0, f64::INFINITY).is_none());
        // Along a face's plane (origin exactly on x = 1, d.x = 0): no NaN.
        let ray = Ray::new(DVec3::new(1.0, -5.0, 0.0), DVec3::Y);
        let h = b.intersect(&ray, 0.0, f64::INFINITY).unwrap();
        assert_eq!(h.t, 4.0);
        // Texture coordinates on the +x face.
        assert_eq!(b.uv(DVec3::new(1.0, 0.5, 1.0)), DVec2::new(0.5, 0.5));
    }

    /// Against a brute force: march along the ray in fine steps and find
    /// the first step where inside-ness changes.
    #[test]
    fn hits_agree_with_a_march_on_random_rays_through_a_turned_box() {
        let mut rng = PixelRng::new(7, 1, 2);
        let mut u = || 2.0 * rng.uniform() - 1.0;
        let to_world = DAffine3::from_scale_rotation_translation(
            DVec3::new(1.0, 2.0, 0.5),
            glam::DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 0.7),
            DVec3::new(0.3, -0.2, 0.1),
        );
        let unit = unit_box();
        let b = Cuboid::new(
            unit.min,
            unit.max,
            Transform::from_affine(to_world).unwrap(),
        );
        let inside = |p: DVec3| {
            let q = b.transform.to_object.transform_point3(p);
            q.cmpge(b.min).all() && q.cmple(b.max).all()
        };
        let mut hits = 0;
        for _ in 0..2000 {
            let origin = DVec3::new(u(), u(), u()) * 8.0;
            // Aimed near the box, so most rays meet it.
            let target = b
                .transform
                .point(DVec3::new(1.3 * u(), 0.5 + 1.8 * u(), 1.0 + 2.3 * u()));
            let direction = (target - origin).normalize();
            let ray = Ray::new(origin, direction);
            let step = 1e-3;
            let start = inside(origin);
            let march = (1..20_000)
                .map(|i| i as f64 * step)
                .find(|&t| inside(ray.at(t)) != start);
            match (b.intersect(&ray, 0.0, f64::INFINITY), march) {
                (Some(h), Some(t)) => {
                    hits += 1;
                    assert!((h.t - t).abs() <= step, "{} vs {t}", h.t);
                    assert_eq!(h.front_face, !start);
                    // The point lies on the surface: on a face of the box.
                    let q = b.transform.to_object.transform_point3(ray.at(h.t));
                    let on = (q - b.min).abs().min((b.max - q).abs()).min_element();
                    assert!(on < 1e-9, "{on}");
                }
                (None, None) => {}
                // A graze the march steps over, or a crossing past its end.
                (h, t) => assert!(
                    h.is_none_or(|h| h.t > 19.9 || grazes(&b, &ray, h.t))
                        && t.is_none_or(|t| t > 19.9),
                    "{h:?} vs {t:?}"
                ),
            }
        }
        assert!(hits > 200, "{hits}");
    }

    /// Whether the ray only touches the box near t (an edge or corner).
    fn grazes(b: &Cuboid, ray: &Ray, t: f64) -> bool {
        let (o, d) = b.transform.ray_to_object(ray);
        slab_interval(o, d, b.min, b.max)
            .is_some_and(|((t0, _), (t1, _))| t1 - t0 < 2e-3 && (t - t0).abs() < 2e-3)
    }
}
