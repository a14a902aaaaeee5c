//! Surface colour Od as a function of position.

use glam::{DVec2, DVec3};

/// A colour pattern over space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Texture {
    /// One colour everywhere.
    Solid(DVec3),
    /// A 3D checkerboard of cubes of side `size`: `even` where
    /// ⌊x/s⌋ + ⌊y/s⌋ + ⌊z/s⌋ is even, `odd` elsewhere.
    Checker {
        /// Colour of the even cells.
        even: DVec3,
        /// Colour of the odd cells.
        odd: DVec3,
        /// Cell side.
        size: f64,
    },
}

impl Texture {
    /// The colour at `point` on a surface with outward `normal` and
    /// texture coordinates `uv`.
    #[inline]
    pub fn color(&self, point: DVec3, normal: DVec3, uv: DVec2) -> DVec3 {
        let _ = uv;
        match *self {
            Texture::Solid(c) => c,
            Texture::Checker { even, odd, size } => {
                // A surface lying exactly on a cell boundary (a floor at
                // y = 0) would flicker between cells with the rounding of the
                // hit point; looking a hair inside the surface picks one side.
                let p = (point - normal * (1e-6 * size)) / size;
                let parity = p.x.floor() + p.y.floor() + p.z.floor();
                if parity.rem_euclid(2.0) == 0.0 {
                    even
                } else {
                    odd
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checker_alternates_and_is_stable_on_cell_boundaries() {
        let t = Texture::Checker {
            even: DVec3::ONE,
            odd: DVec3::ZERO,
            size: 2.0,
        };
        let n = DVec3::Y;
        assert_eq!(
            t.color(DVec3::new(1.0, 0.0, 1.0), n, DVec2::ZERO),
            DVec3::ZERO
        );
        assert_eq!(
            t.color(DVec3::new(3.0, 0.0, 1.0), n, DVec2::ZERO),
            DVec3::ONE
        );
        assert_eq!(
            t.color(DVec3::new(-1.0, 0.0, 1.0), n, DVec2::ZERO),
            DVec3::ONE
        );
        // Rounding noise around y = 0 does not change the cell.
        for dy in [-1e-15, 0.0, 1e-15] {
            assert_eq!(
                t.color(DVec3::new(1.0, dy, 1.0), n, DVec2::ZERO),
                DVec3::ZERO
            );
        }
    }
}
