//! Thin helpers over glam: rays, orthonormal frames, transforms, sampling and
//! the per-pixel random streams.

pub mod differential;
pub mod frame;
pub mod permutation;
pub mod ray;
pub mod rng;
pub mod sampling;
pub mod transcendental;
pub mod transform;

pub use differential::RayDifferential;
pub use frame::Frame;
pub use ray::Ray;
pub use transform::Transform;

use glam::DVec3;

/// Largest absolute component, the scale used for floating-point tolerances.
#[inline]
pub fn max_abs_component(v: DVec3) -> f64 {
    v.abs().max_element()
}
