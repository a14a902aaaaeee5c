//! Axis-aligned bounding boxes, what an acceleration structure sorts by.

use glam::DVec3;

/// An axis-aligned box `[min, max]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Lower corner.
    pub min: DVec3,
    /// Upper corner.
    pub max: DVec3,
}

impl Aabb {
    /// The smallest box holding all `points` (at least one).
    pub fn from_points(points: impl IntoIterator<Item = DVec3>) -> Self {
        let mut b = Aabb {
            min: DVec3::INFINITY,
            max: DVec3::NEG_INFINITY,
        };
        for p in points {
            b.min = b.min.min(p);
            b.max = b.max.max(p);
        }
        b
    }

    /// The length of the diagonal, the "size" that tolerances scale with.
    pub fn diagonal(&self) -> f64 {
        (self.max - self.min).length()
    }
}

impl Default for Aabb {
    /// The empty box.
    fn default() -> Self {
        Aabb::EMPTY
    }
}

impl Aabb {
    /// The empty box (union identity).
    pub const EMPTY: Aabb = Aabb {
        min: DVec3::INFINITY,
        max: DVec3::NEG_INFINITY,
    };

    /// The smallest box holding both.
    #[inline]
    pub fn union(&self, other: &Aabb) -> Aabb {
        Aabb {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    /// The centre point.
    #[inline]
    pub fn centroid(&self) -> DVec3 {
        0.5 * (self.min + self.max)
    }

    /// Surface area (0 for an empty box), the SAH's measure of how likely a
    /// random ray is to hit the box.
    #[inline]
    pub fn surface_area(&self) -> f64 {
        let d = (self.max - self.min).max(DVec3::ZERO);
        2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
    }

    /// The box of the eight corners of `self` mapped by `f` (for affine maps
    /// this bounds the mapped box).
    pub fn transformed(&self, f: impl Fn(DVec3) -> DVec3) -> Aabb {
        Aabb::from_points((0..8).map(|i| {
            f(DVec3::new(
                if i & 1 == 0 { self.min.x } else { self.max.x },
                if i & 2 == 0 { self.min.y } else { self.max.y },
                if i & 4 == 0 { self.min.z } else { self.max.z },
            ))
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn union_area_and_centroid() {
        let a = Aabb::from_points([DVec3::ZERO, DVec3::new(1.0, 2.0, 3.0)]);
        assert_eq!(a.surface_area(), 2.0 * (2.0 + 6.0 + 3.0));
        assert_eq!(a.centroid(), DVec3::new(0.5, 1.0, 1.5));
        assert_eq!(Aabb::EMPTY.union(&a), a);
        assert_eq!(Aabb::EMPTY.surface_area(), 0.0);
        let moved = a.transformed(|p| p + DVec3::X);
        assert_eq!(moved.min, DVec3::X);
        assert_eq!(a.diagonal(), 14f64.sqrt());
    }
}
