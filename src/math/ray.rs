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

/// The two origins [`Ray::spawn`] can give rays leaving one surface point
/// (lifted to the front or to the back of the surface), each with its
/// distance from the point: worked out once for the many shadow feelers
/// of a point instead of once per feeler, with the same bits.
#[derive(Clone, Copy, Debug)]
pub struct SpawnOrigins {
    normal: DVec3,
    front: (DVec3, f64),
    back: (DVec3, f64),
}

impl SpawnOrigins {
    /// The origins of rays leaving `point` on the surface with geometric
    /// normal `normal`.
    #[inline]
    pub fn new(point: DVec3, normal: DVec3) -> Self {
        let lifted = |side: DVec3| {
            let origin = offset_origin(point, normal, side);
            (origin, (origin - point).length())
        };
        SpawnOrigins {
            normal,
            front: lifted(normal),
            back: lifted(-normal),
        }
    }

    /// `SpawnOrigins::new(point, normal).spawn(direction)`, to the bit,
    /// working out only the origin on the side the ray leaves by (one
    /// square root, not two, for a point with a single feeler).
    #[inline]
    pub fn spawn_one(point: DVec3, normal: DVec3, direction: DVec3) -> (Ray, f64) {
        let side = if direction.dot(normal) >= 0.0 {
            normal
        } else {
            -normal
        };
        let origin = offset_origin(point, normal, side);
        (Ray { origin, direction }, (origin - point).length())
    }

    /// [`Ray::spawn`] from the point in `direction`, and how far its
    /// origin lies from the point.
    #[inline]
    pub fn spawn(&self, direction: DVec3) -> (Ray, f64) {
        // The side test of `offset_origin`.
        let (origin, gap) = if direction.dot(self.normal) >= 0.0 {
            self.front
        } else {
            self.back
        };
        (Ray { origin, direction }, gap)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spawn_origins_are_those_of_ray_spawn() {
        let mut rng = super::super::rng::PixelRng::new(5, 0, 0);
        let mut u = || 2.0 * rng.uniform() - 1.0;
        for _ in 0..10_000 {
            let point = DVec3::new(u(), u(), u()) * 1e3 * u().abs();
            let normal = DVec3::new(u(), u(), u()).normalize();
            let origins = SpawnOrigins::new(point, normal);
            let direction = DVec3::new(u(), u(), u()).normalize();
            let (ray, gap) = origins.spawn(direction);
            let expected = Ray::spawn(point, normal, direction);
            assert_eq!(ray, expected);
            assert_eq!(gap, (expected.origin - point).length());
            let bits = |(r, g): (Ray, f64)| (r.origin.to_array().map(f64::to_bits), g.to_bits());
            assert_eq!(
                bits(SpawnOrigins::spawn_one(point, normal, direction)),
                bits((ray, gap))
            );
        }
        // A degenerate normal too (both sides coincide).
        let origins = SpawnOrigins::new(DVec3::ONE, DVec3::ZERO);
        assert_eq!(
            origins.spawn(DVec3::X).0,
            Ray::spawn(DVec3::ONE, DVec3::ZERO, DVec3::X)
        );
    }

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
