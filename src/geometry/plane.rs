//! Infinite planes `v·n = d` (lecture notes, "Plane Definition").

use glam::DVec3;

use super::ShapeHit;
use super::span::{Interval, Intervals, Surface};
use super::steps::Steps;
use crate::math::Ray;

/// Below this |n·D| (cosine between the ray and the plane) the ray counts as
/// parallel: the hit would lie more than 10¹² ray lengths away.
pub const PARALLEL_COSINE: f64 = 1e-12;

/// A plane stored as its unit normal `n` and distance `d` from the origin:
/// the points `v` with `v·n = d`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    /// Unit normal n.
    pub normal: DVec3,
    /// Signed distance d of the plane from the origin along n.
    pub distance: f64,
}

/// The result of [`plane_hit`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlaneHit {
    /// Ray parameter t = (d − n·O)/(n·D).
    pub t: f64,
    /// n·D > 0: the ray travels the way the normal points, it sees the back.
    pub back_face: bool,
}

/// Ray-plane intersection as the notes give it: n·D first (≈0: parallel, no
/// hit; > 0: back face), then t = (d − n·O)/(n·D), kept if t_min < t < t_max.
#[inline]
pub fn plane_hit(
    normal: DVec3,
    distance: f64,
    ray: &Ray,
    t_min: f64,
    t_max: f64,
) -> Option<PlaneHit> {
    plane_hit_steps(normal, distance, ray, t_min, t_max, &mut ())
}

/// [`plane_hit`], telling `steps` n·d and t.
#[inline(always)]
pub fn plane_hit_steps<S: Steps>(
    normal: DVec3,
    distance: f64,
    ray: &Ray,
    t_min: f64,
    t_max: f64,
    steps: &mut S,
) -> Option<PlaneHit> {
    let n_dot_d = normal.dot(ray.direction);
    if n_dot_d.abs() < PARALLEL_COSINE {
        steps.plane(n_dot_d, None);
        return None;
    }
    let t = (distance - normal.dot(ray.origin)) / n_dot_d;
    steps.plane(n_dot_d, Some(t));
    (t > t_min && t < t_max).then_some(PlaneHit {
        t,
        back_face: n_dot_d > 0.0,
    })
}

impl Plane {
    /// The plane through `point` with normal `normal` (normalised here).
    pub fn through(point: DVec3, normal: DVec3) -> Self {
        let normal = normal.normalize();
        Plane {
            normal,
            distance: normal.dot(point),
        }
    }

    /// Signed distance of `p` from the plane.
    #[inline]
    pub fn signed_distance(&self, p: DVec3) -> f64 {
        self.normal.dot(p) - self.distance
    }

    /// Where the whole line of `ray` lies in the half-space behind the
    /// plane, n·p < d (POV-Ray's inside): from −∞ to the plane when the
    /// ray travels along the normal, from the plane on when against it;
    /// all or nothing when it runs parallel.
    pub fn inside(&self, ray: &Ray) -> Intervals {
        let n_dot_d = self.normal.dot(ray.direction);
        let behind = self.signed_distance(ray.origin);
        let (lo, hi) = (
            Surface::at_infinity(f64::NEG_INFINITY),
            Surface::at_infinity(f64::INFINITY),
        );
        let mut out = Intervals::new();
        if n_dot_d.abs() < PARALLEL_COSINE {
            if behind < 0.0 {
                out.push(Interval {
                    enter: lo,
                    exit: hi,
                });
            }
            return out;
        }
        let at = Surface::at(-behind / n_dot_d);
        if at.t.is_nan() {
            return out;
        }
        out.push(if n_dot_d > 0.0 {
            Interval {
                enter: lo,
                exit: at,
            }
        } else {
            Interval {
                enter: at,
                exit: hi,
            }
        });
        out
    }

    /// Intersects `ray`; see [`plane_hit`].
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<ShapeHit> {
        self.intersect_steps(ray, t_min, t_max, &mut ())
    }

    /// [`intersect`](Self::intersect), telling `steps` each step.
    #[inline(always)]
    pub fn intersect_steps<S: Steps>(
        &self,
        ray: &Ray,
        t_min: f64,
        t_max: f64,
        steps: &mut S,
    ) -> Option<ShapeHit> {
        plane_hit_steps(self.normal, self.distance, ray, t_min, t_max, steps)
            .map(|h| ShapeHit::geometric(h.t, self.normal, !h.back_face))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::PixelRng;

    fn floor() -> Plane {
        Plane {
            normal: DVec3::Y,
            distance: -1.0,
        }
    }

    #[test]
    fn parallel_ray_misses() {
        let r = Ray::new(DVec3::ZERO, DVec3::X);
        assert_eq!(plane_hit(DVec3::Y, -1.0, &r, 0.0, f64::INFINITY), None);
        // Even when it lies in the plane.
        let r = Ray::new(DVec3::new(0.0, -1.0, 0.0), DVec3::Z);
        assert_eq!(floor().intersect(&r, 0.0, f64::INFINITY), None);
    }

    #[test]
    fn front_hit_point_is_on_the_plane() {
        // From (0, 2, 0) down a 45° slope towards y = -1: t = 3√2.
        let r = Ray::new(DVec3::new(0.0, 2.0, 0.0), DVec3::new(1.0, -1.0, 0.0));
        let h = plane_hit(DVec3::Y, -1.0, &r, 0.0, f64::INFINITY).unwrap();
        assert!(!h.back_face);
        assert!((h.t - 3.0 * 2f64.sqrt()).abs() < 1e-12);
        assert!((r.at(h.t) - DVec3::new(3.0, -1.0, 0.0)).length() < 1e-12);
    }

    #[test]
    fn back_face_is_reported() {
        let r = Ray::new(DVec3::new(0.0, -5.0, 0.0), DVec3::Y);
        let h = plane_hit(DVec3::Y, -1.0, &r, 0.0, f64::INFINITY).unwrap();
        assert!(h.back_face);
        assert!((h.t - 4.0).abs() < 1e-12);
        assert!(
            !floor()
                .intersect(&r, 0.0, f64::INFINITY)
                .unwrap()
                .front_face
        );
    }

    #[test]
    fn interval_is_open() {
        let r = Ray::new(DVec3::ZERO, -DVec3::Y);
        assert!(plane_hit(DVec3::Y, -1.0, &r, 0.0, 1.0).is_none());
        assert!(plane_hit(DVec3::Y, -1.0, &r, 1.0, 2.0).is_none());
        assert!(plane_hit(DVec3::Y, -1.0, &r, 0.5, 1.5).is_some());
        // Plane behind the origin.
        assert!(plane_hit(DVec3::Y, 1.0, &r, 0.0, f64::INFINITY).is_none());
    }

    #[test]
    fn random_hits_lie_on_the_plane() {
        let mut rng = PixelRng::new(11, 0, 0);
        let mut u = || rng.uniform() * 2.0 - 1.0;
        for _ in 0..10_000 {
            let plane = Plane::through(DVec3::new(u(), u(), u()) * 10.0, DVec3::new(u(), u(), u()));
            let ray = Ray::new(DVec3::new(u(), u(), u()) * 10.0, DVec3::new(u(), u(), u()));
            if let Some(h) = plane.intersect(&ray, 0.0, f64::INFINITY) {
                assert!(h.t > 0.0);
                assert!(plane.signed_distance(ray.at(h.t)).abs() < 1e-9 * h.t.max(1.0));
                assert_eq!(h.front_face, ray.direction.dot(plane.normal) < 0.0);
            } else {
                // A miss means parallel or the plane is behind.
                let behind =
                    plane.signed_distance(ray.origin) * ray.direction.dot(plane.normal) >= 0.0;
                assert!(behind || ray.direction.dot(plane.normal).abs() < PARALLEL_COSINE);
            }
        }
    }
}
