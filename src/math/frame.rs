//! Orthonormal frames built around one vector.

use glam::DVec3;

/// An orthonormal basis (x, y, z) with `z` the given axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// First tangent.
    pub x: DVec3,
    /// Second tangent.
    pub y: DVec3,
    /// The axis the frame was built around.
    pub z: DVec3,
}

impl Frame {
    /// A frame around the unit vector `z` (Duff et al. 2017, branchless and
    /// continuous except at one pole).
    pub fn from_z(z: DVec3) -> Self {
        let sign = 1f64.copysign(z.z);
        let a = -1.0 / (sign + z.z);
        let b = z.x * z.y * a;
        let x = DVec3::new(1.0 + sign * z.x * z.x * a, sign * b, -sign * z.x);
        let y = DVec3::new(b, sign + z.y * z.y * a, -z.y);
        Frame { x, y, z }
    }

    /// Local coordinates to world.
    #[inline]
    pub fn to_world(&self, v: DVec3) -> DVec3 {
        self.x * v.x + self.y * v.y + self.z * v.z
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::PixelRng;

    #[test]
    fn frames_are_orthonormal_for_random_axes() {
        let mut rng = PixelRng::new(7, 0, 0);
        for _ in 0..1000 {
            let z = DVec3::new(
                rng.uniform() - 0.5,
                rng.uniform() - 0.5,
                rng.uniform() - 0.5,
            )
            .normalize();
            let f = Frame::from_z(z);
            for (a, b) in [(f.x, f.y), (f.y, f.z), (f.x, f.z)] {
                assert!(a.dot(b).abs() < 1e-12);
            }
            for v in [f.x, f.y, f.z] {
                assert!((v.length() - 1.0).abs() < 1e-12);
            }
            assert!((f.x.cross(f.y) - f.z).length() < 1e-12, "right-handed");
        }
    }
}
