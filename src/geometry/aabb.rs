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
