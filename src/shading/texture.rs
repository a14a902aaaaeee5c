//! Surface colour Od as a function of position or texture coordinates.

use std::path::Path;
use std::sync::Arc;

use glam::{DVec2, DVec3};

/// An image to look up by texture coordinates, stored as linear RGB.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageTexture {
    width: usize,
    height: usize,
    texels: Vec<DVec3>,
}

impl ImageTexture {
    /// Reads an image file (PNG, JPEG, …); 8-bit images are taken as sRGB
    /// and decoded to linear values.
    pub fn load(path: &Path) -> Result<Self, String> {
        let img = image::open(path).map_err(|e| e.to_string())?;
        let linear = !matches!(
            img.color(),
            image::ColorType::L8
                | image::ColorType::La8
                | image::ColorType::Rgb8
                | image::ColorType::Rgba8
        );
        let rgb = img.to_rgb32f();
        let decode = |c: f32| {
            let c = f64::from(c);
            if linear {
                c
            } else if c <= 0.04045 {
                c / 12.92
            } else {
                ((c + 0.055) / 1.055).powf(2.4)
            }
        };
        Ok(ImageTexture {
            width: rgb.width() as usize,
            height: rgb.height() as usize,
            texels: rgb
                .pixels()
                .map(|p| DVec3::new(decode(p[0]), decode(p[1]), decode(p[2])))
                .collect(),
        })
    }

    /// A texture from 8-bit sRGB pixels with `channels` bytes each (the
    /// first three are RGB), row-major from the top.
    pub fn from_srgb8(width: usize, height: usize, pixels: &[u8], channels: usize) -> Self {
        let decode = |c: u8| {
            let c = f64::from(c) / 255.0;
            if c <= 0.04045 {
                c / 12.92
            } else {
                ((c + 0.055) / 1.055).powf(2.4)
            }
        };
        let texels = pixels
            .chunks_exact(channels)
            .take(width * height)
            .map(|p| DVec3::new(decode(p[0]), decode(p[1]), decode(p[2])))
            .collect::<Vec<_>>();
        let texels = if texels.len() == width * height {
            texels
        } else {
            vec![DVec3::ONE; width * height]
        };
        ImageTexture {
            width,
            height,
            texels,
        }
    }

    /// A texture from linear texels, row-major from the top.
    pub fn from_texels(width: usize, height: usize, texels: Vec<DVec3>) -> Self {
        assert_eq!(texels.len(), width * height);
        ImageTexture {
            width,
            height,
            texels,
        }
    }

    /// Bilinear lookup, repeating outside [0, 1)²; v runs up the image.
    pub fn lookup(&self, uv: DVec2) -> DVec3 {
        if self.texels.is_empty() {
            return DVec3::ONE;
        }
        let x = uv.x.rem_euclid(1.0) * self.width as f64 - 0.5;
        let y = (1.0 - uv.y.rem_euclid(1.0)) * self.height as f64 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let texel = |i: f64, j: f64| {
            let i = (i as i64).rem_euclid(self.width as i64) as usize;
            let j = (j as i64).rem_euclid(self.height as i64) as usize;
            self.texels[j * self.width + i]
        };
        let top = texel(x0, y0).lerp(texel(x0 + 1.0, y0), fx);
        let bottom = texel(x0, y0 + 1.0).lerp(texel(x0 + 1.0, y0 + 1.0), fx);
        top.lerp(bottom, fy)
    }
}

/// A colour pattern over space.
#[derive(Clone, Debug, PartialEq)]
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
    /// A checkerboard of squares of side `size` in texture coordinates.
    UvChecker {
        /// Colour of the even squares.
        even: DVec3,
        /// Colour of the odd squares.
        odd: DVec3,
        /// Square side in texture-coordinate units.
        size: f64,
    },
    /// An image by texture coordinates (bilinear), times a tint.
    Image {
        /// The image.
        image: Arc<ImageTexture>,
        /// Multiplies the image (OBJ's Kd with map_Kd).
        tint: DVec3,
    },
}

impl Texture {
    /// The colour at `point` on a surface with outward `normal` and
    /// texture coordinates `uv`.
    #[inline]
    pub fn color(&self, point: DVec3, normal: DVec3, uv: DVec2) -> DVec3 {
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
            Texture::UvChecker { even, odd, size } => {
                let cell = (uv / size).floor();
                if (cell.x + cell.y).rem_euclid(2.0) == 0.0 {
                    even
                } else {
                    odd
                }
            }
            Texture::Image { ref image, tint } => tint * image.lookup(uv),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bilinear_lookup_interpolates_and_repeats() {
        // 2×1 image: black on the left, white on the right.
        let img = ImageTexture::from_texels(2, 1, vec![DVec3::ZERO, DVec3::ONE]);
        assert_eq!(img.lookup(DVec2::new(0.25, 0.5)), DVec3::ZERO);
        assert_eq!(img.lookup(DVec2::new(0.75, 0.5)), DVec3::ONE);
        assert!((img.lookup(DVec2::new(0.5, 0.5)) - DVec3::splat(0.5)).length() < 1e-12);
        // Wraps around: u = 1.25 is u = 0.25.
        assert_eq!(img.lookup(DVec2::new(1.25, 0.5)), DVec3::ZERO);
    }

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
