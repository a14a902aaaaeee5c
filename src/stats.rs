//! Ray counts by kind, summed per tile and then over the image: plain data
//! that the shading model counts into and the render loop reports.

use std::ops::AddAssign;
use std::time::Duration;

/// How many rays of each kind a render traced.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RayStats {
    /// Primary rays.
    pub camera: u64,
    /// Reflected rays.
    pub reflection: u64,
    /// Refracted rays.
    pub refraction: u64,
    /// Shadow feelers.
    pub shadow: u64,
}

impl RayStats {
    /// All rays.
    pub fn total(&self) -> u64 {
        self.camera + self.reflection + self.refraction + self.shadow
    }

    /// Millions of rays per second over `elapsed`.
    pub fn mrays_per_second(&self, elapsed: Duration) -> f64 {
        self.total() as f64 / elapsed.as_secs_f64().max(1e-9) / 1e6
    }
}

impl AddAssign for RayStats {
    fn add_assign(&mut self, o: Self) {
        self.camera += o.camera;
        self.reflection += o.reflection;
        self.refraction += o.refraction;
        self.shadow += o.shadow;
    }
}
