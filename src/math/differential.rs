//! Ray differentials (Igehy 1999, as pbrt keeps them): a camera ray's
//! neighbours on the film, one sample spacing to the right and one below,
//! which say how large a patch of surface the ray's sample stands for, so
//! a texture can be averaged over that patch instead of point-sampled.

use glam::DVec3;

use super::Ray;

/// The rays through the film points one sample spacing to the right of
/// and below a camera ray's, through the same point of the lens.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayDifferential {
    /// Through (x + spacing, y).
    pub right: Ray,
    /// Through (x, y + spacing).
    pub below: Ray,
}

impl RayDifferential {
    /// The footprint at `point`, on a surface with geometric normal
    /// `normal`: the offsets from `point` to where the two neighbouring
    /// rays meet the surface's tangent plane there (∂p/∂x and ∂p/∂y times
    /// the spacing). `None` where a neighbour runs parallel to the plane or
    /// meets it behind its origin (a grazing view, whose footprint is
    /// unbounded): the texture is then point-sampled.
    pub fn footprint(&self, point: DVec3, normal: DVec3) -> Option<[DVec3; 2]> {
        let offset = |ray: &Ray| {
            let facing = normal.dot(ray.direction);
            let t = normal.dot(point - ray.origin) / facing;
            (t.is_finite() && t >= 0.0).then(|| ray.at(t) - point)
        };
        Some([offset(&self.right)?, offset(&self.below)?])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::transcendental::sin_cos;

    #[test]
    fn a_floor_seen_from_above_has_the_similar_triangles_footprint() {
        // A pinhole at height h looking straight down: neighbouring rays
        // through directions tilted by δ meet the floor h·δ apart.
        let h = 4.0;
        let eye = DVec3::new(0.0, h, 0.0);
        let delta = 0.01;
        let d = RayDifferential {
            right: Ray::new(eye, DVec3::new(delta, -1.0, 0.0)),
            below: Ray::new(eye, DVec3::new(0.0, -1.0, delta)),
        };
        let [dx, dy] = d.footprint(DVec3::ZERO, DVec3::Y).unwrap();
        assert!(
            (dx - DVec3::new(h * delta, 0.0, 0.0)).length() < 1e-12,
            "{dx}"
        );
        assert!(
            (dy - DVec3::new(0.0, 0.0, h * delta)).length() < 1e-12,
            "{dy}"
        );
        // A point at grazing view whose neighbour never comes down to the
        // plane has no footprint.
        let grazing = RayDifferential {
            right: Ray::new(eye, DVec3::X),
            below: d.below,
        };
        assert_eq!(grazing.footprint(DVec3::ZERO, DVec3::Y), None);
        let upward = RayDifferential {
            right: Ray::new(eye, DVec3::new(0.1, 1.0, 0.0)),
            below: d.below,
        };
        assert_eq!(upward.footprint(DVec3::ZERO, DVec3::Y), None);
    }

    #[test]
    fn a_tilted_view_stretches_the_footprint_by_one_over_the_cosine() {
        // Looking at the floor at 60° from the normal from distance r, a
        // small angle δ in the plane of incidence covers r·δ / cos 60°.
        let r = 5.0;
        let theta = 60f64.to_radians();
        let (sin_theta, cos_theta) = sin_cos(theta);
        let eye = DVec3::new(-r * sin_theta, r * cos_theta, 0.0);
        let centre = -eye.normalize();
        let delta = 1e-4;
        let tilt = |a: f64| {
            // Rotate the view direction by `a` about z.
            let (s, c) = sin_cos(a);
            DVec3::new(
                c * centre.x - s * centre.y,
                s * centre.x + c * centre.y,
                0.0,
            )
        };
        let d = RayDifferential {
            right: Ray::new(eye, tilt(delta)),
            below: Ray::new(eye, centre + DVec3::Z * delta),
        };
        let [dx, dy] = d.footprint(DVec3::ZERO, DVec3::Y).unwrap();
        let expected = r * delta / cos_theta;
        assert!(
            (dx.length() / expected - 1.0).abs() < 1e-3,
            "{dx} {expected}"
        );
        assert!(dx.y.abs() < 1e-15);
        // Across the plane of incidence: no stretch.
        assert!((dy.length() / (r * delta) - 1.0).abs() < 1e-3, "{dy}");
    }
}
