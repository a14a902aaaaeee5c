//! A ray `P(t) = O + t·D` and the offset rule for secondary rays.

use glam::DVec3;

/// A half-line with a unit direction: `P(t) = origin + t·direction`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Origin O.
    pub origin: DVec3,
    /// Unit direction D.
    pub direction: DVec3,
}

/// Relative size of the offset that lifts a secondary ray off its surface.
///
/// Hit points computed in f64 carry a relative error of a few ulps
/// (~1e-15); 1e-9 of the point's magnitude clears that by six orders of
/// magnitude while staying far below anything visible.
pub const RELATIVE_OFFSET: f64 = 1e-9;

impl Ray {
    /// A ray from `origin` along `direction`, which is normalised here.
    #[inline]
    pub fn new(origin: DVec3, direction: DVec3) -> Self {
        Ray {
            origin,
            direction: direction.normalize(),
        }
    }

    /// The point at parameter `t`.
    #[inline]
    pub fn at(&self, t: f64) -> DVec3 {
        self.origin + t * self.direction
    }

    /// A secondary ray leaving the surface at `point` (geometric normal
    /// `normal`) in `direction`, with its origin pushed to the side the ray
    /// leaves by an amount that scales with the point's magnitude.
    #[inline]
    pub fn spawn(point: DVec3, normal: DVec3, direction: DVec3) -> Self {
        Ray {
            origin: offset_origin(point, normal, direction),
            direction,
        }
    }
}

/// Moves `point` along `normal` towards the side `direction` points to, by
/// `RELATIVE_OFFSET · max(1, |point|∞)`, so a secondary ray cannot hit the
/// surface it starts on.
#[inline]
pub fn offset_origin(point: DVec3, normal: DVec3, direction: DVec3) -> DVec3 {
    let eps = RELATIVE_OFFSET * super::max_abs_component(point).max(1.0);
    if direction.dot(normal) >= 0.0 {
        point + eps * normal
    } else {
        point - eps * normal
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn at_follows_the_ray_equation() {
        let r = Ray::new(DVec3::new(1.0, 2.0, 3.0), DVec3::new(0.0, 0.0, 2.0));
        assert_eq!(r.direction, DVec3::Z);
        assert_eq!(r.at(2.5), DVec3::new(1.0, 2.0, 5.5));
    }

    #[test]
    fn offset_goes_to_the_side_of_the_outgoing_ray_and_scales() {
        let n = DVec3::Y;
        let up = offset_origin(DVec3::ZERO, n, DVec3::new(0.0, 1.0, 1.0));
        let down = offset_origin(DVec3::ZERO, n, DVec3::new(0.0, -1.0, 1.0));
        assert!(up.y > 0.0 && down.y < 0.0);
        let far = offset_origin(DVec3::new(1e6, 0.0, 0.0), n, DVec3::Y);
        assert!((far.y / up.y - 1e6).abs() < 1e-3);
    }
}
