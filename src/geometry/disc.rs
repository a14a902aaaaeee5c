//! POV-Ray's `disc`: a flat ring in a plane, from `hole_radius` to
//! `radius` around `center`, facing `normal` (seen from both sides).
//!
//! In its own space the disc lies in z = 0: the ray meets the plane at
//! t = −oz/dz (none when dz = 0, the ray in or parallel to the plane) and
//! the hit counts where h² ≤ x² + y² ≤ R².
//!
//! Normal: `normal`. Texture coordinates: u = ½ + x/2R, v = ½ + y/2R.

use glam::{DVec2, DVec3};

use super::cuboid::placed_bounds;
use super::{Aabb, ShapeHit};
use crate::math::{Ray, Transform};

/// A disc (or ring) in its own plane z = 0, placed by `transform`.
#[derive(Clone, Debug, PartialEq)]
pub struct Disc {
    /// Outer radius, in object units.
    pub radius: f64,
    /// Inner radius (0: no hole).
    pub hole_radius: f64,
    /// Object to world: the origin to the centre, +z to the normal.
    pub transform: Transform,
}

impl Disc {
    /// The hit in (t_min, t_max), if any.
    pub fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<ShapeHit> {
        let (o, d) = self.transform.ray_to_object(ray);
        if d.z == 0.0 {
            return None;
        }
        let t = -o.z / d.z;
        if !(t > t_min && t < t_max) {
            return None;
        }
        let p = o + t * d;
        let rho2 = p.x * p.x + p.y * p.y;
        if rho2 > self.radius * self.radius || rho2 < self.hole_radius * self.hole_radius {
            return None;
        }
        let normal = self.transform.normal(DVec3::Z);
        Some(ShapeHit::geometric(
            t,
            normal,
            ray.direction.dot(normal) < 0.0,
        ))
    }

    /// Texture coordinates at the world point `point` (see the module).
    pub fn uv(&self, point: DVec3) -> DVec2 {
        let p = self.transform.to_object.transform_point3(point);
        DVec2::new(
            0.5 + p.x / (2.0 * self.radius),
            0.5 + p.y / (2.0 * self.radius),
        )
    }

    /// The bounding box of the placed disc.
    pub fn bounds(&self) -> Aabb {
        let r = self.radius;
        placed_bounds(
            &self.transform,
            DVec3::new(-r, -r, 0.0),
            DVec3::new(r, r, 0.0),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ring_is_hit_between_its_radii_from_both_sides() {
        let disc = Disc {
            radius: 2.0,
            hole_radius: 1.0,
            transform: Transform::default(),
        };
        let down = |x: f64| Ray::new(DVec3::new(x, 0.0, 3.0), DVec3::NEG_Z);
        assert!(
            disc.intersect(&down(0.5), 0.0, f64::INFINITY).is_none(),
            "the hole"
        );
        let h = disc.intersect(&down(1.5), 0.0, f64::INFINITY).unwrap();
        assert_eq!((h.t, h.normal, h.front_face), (3.0, DVec3::Z, true));
        assert!(
            disc.intersect(&down(2.5), 0.0, f64::INFINITY).is_none(),
            "outside"
        );
        let up = Ray::new(DVec3::new(1.5, 0.0, -1.0), DVec3::Z);
        let h = disc.intersect(&up, 0.0, f64::INFINITY).unwrap();
        assert_eq!((h.t, h.front_face), (1.0, false));
        // In its plane: no hit, no NaN.
        let along = Ray::new(DVec3::new(-5.0, 0.0, 0.0), DVec3::X);
        assert!(disc.intersect(&along, 0.0, f64::INFINITY).is_none());
        assert_eq!(disc.uv(DVec3::new(2.0, 0.0, 0.0)), DVec2::new(1.0, 0.5));
    }
}
