//! Surface colour Od as a function of position or texture coordinates.

use std::io::{BufRead, Seek};
use std::sync::{Arc, LazyLock};

use crate::math::transcendental;
use glam::{DAffine2, DVec2, DVec3};
use image::{ColorType, DynamicImage, ImageDecoder};

/// Texels as compact as the file allows: 8-bit sRGB stays 8-bit (3 bytes a
/// texel, linearised by table at lookup); deeper and float images are
/// linear f32 (12 bytes), never widened to f64.
#[derive(Clone, Debug, PartialEq)]
enum Texels {
    Srgb8(Vec<[u8; 3]>),
    Linear(Vec<[f32; 3]>),
}

/// An image to look up by texture coordinates.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageTexture {
    width: usize,
    height: usize,
    texels: Texels,
}

/// Why an image could not become a texture.
#[derive(Debug, PartialEq)]
pub enum DecodeError {
    /// Decoding would need `needed` bytes, more than the budget left.
    OverBudget {
        /// Bytes the decoded image (and its decoding) would take.
        needed: u64,
    },
    /// The decoder's message.
    Image(String),
}

/// The sRGB decoding of each 8-bit value (IEC 61966-2-1).
static SRGB_TO_LINEAR: LazyLock<[f64; 256]> =
    LazyLock::new(|| std::array::from_fn(|i| srgb_to_linear(i as f64 / 255.0)));

/// The inverse sRGB transfer function of an encoded value in [0, 1].
pub fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        transcendental::pow((c + 0.055) / 1.055, 2.4)
    }
}

/// A float texel channel as a surface colour: float images (EXR, HDR) can
/// hold NaN, infinities and negative values, which a colour cannot be. NaN
/// and negatives read as 0, and values are capped at the scene's largest
/// colour value.
pub fn colour_value(c: f32) -> f32 {
    if c > 0.0 {
        c.min(crate::limits::MAX_VALUE as f32)
    } else {
        0.0
    }
}

impl ImageTexture {
    /// Decodes the image `reader` holds (PNG, JPEG, EXR, HDR, PNM), if it
    /// fits in `budget` bytes: the size is read from the header and checked
    /// before anything is decoded. Integer images are taken as sRGB, float
    /// images as linear.
    pub fn decode<R: BufRead + Seek>(
        reader: image::ImageReader<R>,
        budget: u64,
    ) -> Result<Self, DecodeError> {
        let image_error = |e: image::ImageError| DecodeError::Image(e.to_string());
        let mut decoder = reader.into_decoder().map_err(image_error)?;
        let (w, h) = decoder.dimensions();
        let texels = u64::from(w) * u64::from(h);
        let color = decoder.color_type();
        let eight_bit = matches!(
            color,
            ColorType::L8 | ColorType::La8 | ColorType::Rgb8 | ColorType::Rgba8
        );
        let stored = texels * if eight_bit { 3 } else { 12 };
        // The decoder's own buffer exists beside ours for a moment.
        let needed = stored.max(decoder.total_bytes());
        if needed > budget {
            return Err(DecodeError::OverBudget { needed });
        }
        let mut limits = image::Limits::default();
        limits.max_alloc = Some(decoder.total_bytes().saturating_add(1 << 20));
        decoder.set_limits(limits).map_err(image_error)?;
        let image = DynamicImage::from_decoder(decoder).map_err(image_error)?;
        let (width, height) = (w as usize, h as usize);
        let texels = if eight_bit {
            Texels::Srgb8(image.into_rgb8().pixels().map(|p| p.0).collect())
        } else if matches!(color, ColorType::Rgb32F | ColorType::Rgba32F) {
            Texels::Linear(
                image
                    .into_rgb32f()
                    .pixels()
                    .map(|p| p.0.map(colour_value))
                    .collect(),
            )
        } else {
            let decode = |c: f32| colour_value(srgb_to_linear(f64::from(c)) as f32);
            Texels::Linear(
                image
                    .into_rgb32f()
                    .pixels()
                    .map(|p| p.0.map(decode))
                    .collect(),
            )
        };
        Ok(ImageTexture {
            width,
            height,
            texels,
        })
    }

    /// A texture from 8-bit sRGB texels, row-major from the top.
    pub fn from_srgb8(width: usize, height: usize, texels: Vec<[u8; 3]>) -> Self {
        assert_eq!(texels.len(), width * height);
        ImageTexture {
            width,
            height,
            texels: Texels::Srgb8(texels),
        }
    }

    /// A texture from linear texels, row-major from the top (each channel
    /// taken through [`colour_value`]).
    pub fn from_linear(width: usize, height: usize, texels: Vec<[f32; 3]>) -> Self {
        assert_eq!(texels.len(), width * height);
        ImageTexture {
            width,
            height,
            texels: Texels::Linear(texels.into_iter().map(|t| t.map(colour_value)).collect()),
        }
    }

    /// Bytes the texels take.
    pub fn memory_bytes(&self) -> usize {
        match &self.texels {
            Texels::Srgb8(t) => t.len() * 3,
            Texels::Linear(t) => t.len() * 12,
        }
    }

    /// Width and height in texels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    #[inline]
    fn texel(&self, index: usize) -> DVec3 {
        match &self.texels {
            Texels::Srgb8(t) => {
                let table = &*SRGB_TO_LINEAR;
                let [r, g, b] = t[index];
                DVec3::new(table[r as usize], table[g as usize], table[b as usize])
            }
            Texels::Linear(t) => DVec3::from_array(t[index].map(f64::from)),
        }
    }

    /// Bilinear lookup, repeating outside [0, 1)²; v runs up the image.
    pub fn lookup(&self, uv: DVec2) -> DVec3 {
        if self.width == 0 || self.height == 0 || !uv.is_finite() {
            return DVec3::ONE;
        }
        let x = uv.x.rem_euclid(1.0) * self.width as f64 - 0.5;
        let y = (1.0 - uv.y.rem_euclid(1.0)) * self.height as f64 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let texel = |i: f64, j: f64| {
            let i = (i as i64).rem_euclid(self.width as i64) as usize;
            let j = (j as i64).rem_euclid(self.height as i64) as usize;
            self.texel(j * self.width + i)
        };
        let top = texel(x0, y0).lerp(texel(x0 + 1.0, y0), fx);
        let bottom = texel(x0, y0 + 1.0).lerp(texel(x0 + 1.0, y0 + 1.0), fx);
        top.lerp(bottom, fy)
    }
}

/// What a texture coordinate outside [0, 1] reads (glTF's wrap modes).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Wrap {
    /// The image tiles the plane.
    #[default]
    Repeat,
    /// The edge texels extend outwards.
    Clamp,
    /// The image tiles the plane, every other copy mirrored.
    Mirror,
}

/// The texel index `i` of an image `n` texels wide, brought into it by
/// the wrap mode.
pub fn wrap_index(i: i64, n: i64, wrap: Wrap) -> i64 {
    match wrap {
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::Clamp => i.clamp(0, n - 1),
        Wrap::Mirror => {
            let m = i.rem_euclid(2 * n);
            if m < n { m } else { 2 * n - 1 - m }
        }
    }
}

/// How an image is read: glTF's sampler and KHR_texture_transform.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sampling {
    /// Applied to the texture coordinates first, in glTF's convention (v
    /// running down the image).
    pub transform: DAffine2,
    /// Nearest texel (Blender's "Closest") instead of bilinear.
    pub nearest: bool,
    /// Wrap modes along u and v.
    pub wrap: [Wrap; 2],
}

impl Default for Sampling {
    fn default() -> Self {
        Sampling {
            transform: DAffine2::IDENTITY,
            nearest: false,
            wrap: [Wrap::Repeat; 2],
        }
    }
}

/// KHR_texture_transform's matrix: uv' = T(offset)·R(rotation)·S(scale)·uv
/// in glTF's texture space, the rotation (radians) counter-clockwise seen
/// with v running down: u' = cos·u + sin·v, v' = −sin·u + cos·v.
pub fn texture_transform(offset: DVec2, rotation: f64, scale: DVec2) -> DAffine2 {
    let (s, c) = transcendental::sin_cos(rotation);
    let r = glam::DMat2::from_cols(DVec2::new(c, -s), DVec2::new(s, c));
    DAffine2::from_mat2_translation(r * glam::DMat2::from_diagonal(scale), offset)
}

impl ImageTexture {
    /// The colour at `uv` (v running up the image, as Prism's texture
    /// coordinates do) read as `sampling` says.
    pub fn sample(&self, uv: DVec2, sampling: &Sampling) -> DVec3 {
        if self.width == 0 || self.height == 0 || !uv.is_finite() {
            return DVec3::ONE;
        }
        // Into glTF's space (v down), transformed.
        let g = sampling
            .transform
            .transform_point2(DVec2::new(uv.x, 1.0 - uv.y));
        if !g.is_finite() {
            return DVec3::ONE;
        }
        let (w, h) = (self.width as i64, self.height as i64);
        // Far outside the image every mode has repeated or clamped long
        // before; keep the integer conversion exact.
        let limit = 1e15;
        let x = (g.x * w as f64).clamp(-limit, limit);
        let y = (g.y * h as f64).clamp(-limit, limit);
        let texel = |i: f64, j: f64| {
            let i = wrap_index(i as i64, w, sampling.wrap[0]) as usize;
            let j = wrap_index(j as i64, h, sampling.wrap[1]) as usize;
            self.texel(j * self.width + i)
        };
        if sampling.nearest {
            return texel(x.floor(), y.floor());
        }
        let (x, y) = (x - 0.5, y - 0.5);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
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
        /// Whether a camera ray's hit sees the checker's mean over the
        /// box around its footprint (see [`box_filtered_checker`]) rather
        /// than the colour at its point.
        filtered: bool,
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
    /// An image read through a sampler and a texture transform (glTF).
    Sampled {
        /// The image.
        image: Arc<ImageTexture>,
        /// Multiplies the image.
        tint: DVec3,
        /// How it is read.
        sampling: Sampling,
    },
}

impl Texture {
    /// Whether the colour depends on a footprint given to
    /// [`color`](Self::color) (then the camera's rays carry differentials).
    pub fn filtered(&self) -> bool {
        matches!(self, Texture::Checker { filtered: true, .. })
    }

    /// The colour at `point` on a surface with outward `normal` and
    /// texture coordinates `uv` (asked for only by the textures that use
    /// them); a [`filtered`](Self::filtered) texture given a `footprint`
    /// (the point's offsets to its neighbours on the film, ∂p/∂x and
    /// ∂p/∂y times the sample spacing) averages over it.
    #[inline]
    pub fn color(
        &self,
        point: DVec3,
        normal: DVec3,
        footprint: Option<[DVec3; 2]>,
        uv: impl FnOnce() -> DVec2,
    ) -> DVec3 {
        match *self {
            Texture::Solid(c) => c,
            Texture::Checker {
                even,
                odd,
                size,
                filtered,
            } => {
                // A surface lying exactly on a cell boundary (a floor at
                // y = 0) would flicker between cells with the rounding of the
                // hit point; looking a hair inside the surface picks one side.
                let p = (point - normal * (1e-6 * size)) / size;
                if let Some([dx, dy]) = footprint.filter(|_| filtered) {
                    // The box around the footprint's parallelogram (the
                    // film square of side one spacing): half its sides.
                    let half = 0.5 * (dx.abs() + dy.abs()) / size;
                    return box_filtered_checker(p, half, even, odd);
                }
                if checker_cell_is_even(p) { even } else { odd }
            }
            Texture::UvChecker { even, odd, size } => {
                let cell = (uv() / size).floor();
                if (cell.x + cell.y).rem_euclid(2.0) == 0.0 {
                    even
                } else {
                    odd
                }
            }
            Texture::Image { ref image, tint } => tint * image.lookup(uv()),
            Texture::Sampled {
                ref image,
                tint,
                ref sampling,
            } => tint * image.sample(uv(), sampling),
        }
    }
}

/// Whether the cell of the 3D checker holding `p` (in cells) is even:
/// ⌊x⌋ + ⌊y⌋ + ⌊z⌋ even. Within ±2⁵⁰ the floors are integers of an `i64`
/// and their sum is exact either way, so the parity of their integer sum
/// is the answer, without libm's `floor` and `fmod` (function calls on
/// baseline x86-64); beyond, and for NaN, the float sum decides as before.
#[inline]
fn checker_cell_is_even(p: DVec3) -> bool {
    const EXACT: f64 = (1u64 << 50) as f64;
    // Comparisons, not `max_element`, which would pass NaN over.
    if p.x.abs() < EXACT && p.y.abs() < EXACT && p.z.abs() < EXACT {
        // Truncation, one less where it rounded up (negative non-integers).
        let floor = |x: f64| {
            let t = x as i64;
            t - i64::from(x < t as f64)
        };
        (floor(p.x) + floor(p.y) + floor(p.z)) & 1 == 0
    } else {
        (p.x.floor() + p.y.floor() + p.z.floor()).rem_euclid(2.0) == 0.0
    }
}

/// The mean of the unit 3D checker (`even` where ⌊x⌋ + ⌊y⌋ + ⌊z⌋ is
/// even, `odd` elsewhere) over the axis-aligned box of centre `p` and
/// half-sides `half`, in closed form: the checker is `mean + (even −
/// odd)/2 · s(x)·s(y)·s(z)` with s the square wave ±1 of period 2, and the
/// mean of a product of functions of one axis each over a box is the
/// product of their means, each [`square_wave_mean`]. pbrt's closed-form
/// checkerboard does the same in two dimensions.
pub fn box_filtered_checker(p: DVec3, half: DVec3, even: DVec3, odd: DVec3) -> DVec3 {
    let s = square_wave_mean(p.x, half.x)
        * square_wave_mean(p.y, half.y)
        * square_wave_mean(p.z, half.z);
    0.5 * (even + odd) + 0.5 * s * (even - odd)
}

/// The mean of the square wave s(x) = (−1)^⌊x⌋ over [c − h, c + h]:
/// (F(c + h) − F(c − h)) / 2h with F its integral, the triangle wave that
/// rises from 0 to 1 over an even cell and falls back over an odd one.
/// Below a half-width of 1e-6 cells the interval's mean is its centre's
/// value (a footprint edge-on to an axis, as a floor's in y; there the
/// difference of F would be mostly rounding).
pub fn square_wave_mean(c: f64, h: f64) -> f64 {
    fn integral(x: f64) -> f64 {
        let cell = x.floor();
        let f = x - cell;
        if cell.rem_euclid(2.0) == 0.0 {
            f
        } else {
            1.0 - f
        }
    }
    if h < 1e-6 {
        return if c.floor().rem_euclid(2.0) == 0.0 {
            1.0
        } else {
            -1.0
        };
    }
    if h >= 1e9 {
        return 0.0;
    }
    (integral(c + h) - integral(c - h)) / (2.0 * h)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::PixelRng;

    #[test]
    fn the_checker_parity_is_the_float_parity() {
        let float = |p: DVec3| (p.x.floor() + p.y.floor() + p.z.floor()).rem_euclid(2.0) == 0.0;
        let mut rng = PixelRng::new(5, 1, 2);
        let special = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            0.5,
            -0.5,
            -1e-300,
            1e-300,
            2.999_999_999_999_999_6,
            -2.000_000_000_000_000_4,
            1e15,
            -1e15,
            1.2e15 + 0.5,
            3e17,
            -3e17,
            1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ];
        for i in 0..200_000 {
            let pick = |rng: &mut PixelRng| match i % 3 {
                0 => special[rng.below(special.len())],
                1 => (rng.uniform() - 0.5) * 40.0,
                _ => ((rng.uniform() - 0.5) * 40.0).round(),
            };
            let p = DVec3::new(pick(&mut rng), pick(&mut rng), pick(&mut rng));
            assert_eq!(checker_cell_is_even(p), float(p), "{p}");
        }
    }

    #[test]
    fn float_texels_that_are_no_colour_are_made_one() {
        assert_eq!(colour_value(f32::NAN), 0.0);
        assert_eq!(colour_value(-3.0), 0.0);
        assert_eq!(colour_value(f32::INFINITY), 1e15);
        assert_eq!(colour_value(0.25), 0.25);
        let t = ImageTexture::from_linear(2, 1, vec![[f32::NAN, -1.0, 2.0], [f32::INFINITY; 3]]);
        for u in [0.0, 0.3, 0.5, 0.8, 1.0] {
            let c = t.lookup(DVec2::new(u, 0.5));
            assert!(c.is_finite() && c.min_element() >= 0.0, "{c}");
        }
    }

    #[test]
    fn bilinear_lookup_interpolates_and_repeats() {
        // 2×1 image: black on the left, white on the right.
        let img = ImageTexture::from_linear(2, 1, vec![[0.0; 3], [1.0; 3]]);
        assert_eq!(img.lookup(DVec2::new(0.25, 0.5)), DVec3::ZERO);
        assert_eq!(img.lookup(DVec2::new(0.75, 0.5)), DVec3::ONE);
        assert!((img.lookup(DVec2::new(0.5, 0.5)) - DVec3::splat(0.5)).length() < 1e-12);
        // Wraps around: u = 1.25 is u = 0.25.
        assert_eq!(img.lookup(DVec2::new(1.25, 0.5)), DVec3::ZERO);
    }

    #[test]
    fn wrap_modes_fold_indices_into_the_image() {
        let n = 4;
        let all = |w| (-5..9).map(|i| wrap_index(i, n, w)).collect::<Vec<_>>();
        assert_eq!(
            all(Wrap::Repeat),
            [3, 0, 1, 2, 3, 0, 1, 2, 3, 0, 1, 2, 3, 0]
        );
        assert_eq!(all(Wrap::Clamp), [0, 0, 0, 0, 0, 0, 1, 2, 3, 3, 3, 3, 3, 3]);
        // Mirrored: 0 1 2 3 3 2 1 0 0 1 …, and the same to the left.
        assert_eq!(
            all(Wrap::Mirror),
            [3, 3, 2, 1, 0, 0, 1, 2, 3, 3, 2, 1, 0, 0]
        );
    }

    #[test]
    fn texture_transform_is_offset_rotation_scale() {
        let t = texture_transform(DVec2::new(0.5, 0.25), 0.0, DVec2::splat(2.0));
        assert_eq!(
            t.transform_point2(DVec2::new(0.5, 0.5)),
            DVec2::new(1.5, 1.25)
        );
        // A quarter turn: u' = v, v' = −u.
        let r = texture_transform(DVec2::ZERO, std::f64::consts::FRAC_PI_2, DVec2::ONE);
        let p = r.transform_point2(DVec2::new(1.0, 0.0));
        assert!((p - DVec2::new(0.0, -1.0)).length() < 1e-15, "{p}");
        let p = r.transform_point2(DVec2::new(0.0, 1.0));
        assert!((p - DVec2::new(1.0, 0.0)).length() < 1e-15, "{p}");
    }

    #[test]
    fn sampling_reads_nearest_or_bilinear_through_the_transform() {
        // 2×1: black, white.
        let img = ImageTexture::from_linear(2, 1, vec![[0.0; 3], [1.0; 3]]);
        let linear = Sampling::default();
        // The default reads as `lookup` does.
        for u in [0.1, 0.25, 0.5, 0.6, 1.3, -0.2] {
            let uv = DVec2::new(u, 0.5);
            assert!(
                (img.sample(uv, &linear) - img.lookup(uv)).length() < 1e-12,
                "{u}"
            );
        }
        let nearest = Sampling {
            nearest: true,
            ..linear
        };
        assert_eq!(img.sample(DVec2::new(0.49, 0.5), &nearest), DVec3::ZERO);
        assert_eq!(img.sample(DVec2::new(0.51, 0.5), &nearest), DVec3::ONE);
        // Clamped: far right stays white, far left black.
        let clamp = Sampling {
            wrap: [Wrap::Clamp; 2],
            ..nearest
        };
        assert_eq!(img.sample(DVec2::new(7.0, 0.5), &clamp), DVec3::ONE);
        assert_eq!(img.sample(DVec2::new(-7.0, 0.5), &clamp), DVec3::ZERO);
        // Tiled twice (scale 2): u = 0.3 reads u = 0.6, white.
        let tiled = Sampling {
            transform: texture_transform(DVec2::ZERO, 0.0, DVec2::splat(2.0)),
            ..nearest
        };
        assert_eq!(img.sample(DVec2::new(0.3, 0.5), &tiled), DVec3::ONE);
        assert_eq!(img.sample(DVec2::new(0.2, 0.5), &tiled), DVec3::ZERO);
    }

    #[test]
    fn eight_bit_texels_stay_eight_bit_and_decode_by_table() {
        let img = ImageTexture::from_srgb8(1, 1, vec![[0, 188, 255]]);
        assert_eq!(img.memory_bytes(), 3);
        let c = img.lookup(DVec2::splat(0.5));
        assert_eq!(c.x, 0.0);
        assert_eq!(c.z, 1.0);
        // sRGB 188/255 is linear 0.5 (to the 8-bit step).
        assert!((c.y - 0.5).abs() < 0.003, "{c}");
        assert_eq!(c.y, srgb_to_linear(188.0 / 255.0));
    }

    #[test]
    fn decoding_is_refused_over_budget_from_the_header_alone() {
        // A 4000×4000 PNG header: 48 MB decoded, refused before decoding.
        let mut png = Vec::new();
        image::RgbImage::new(4000, 4000)
            .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .unwrap();
        let reader = |bytes: &[u8]| {
            image::ImageReader::new(std::io::Cursor::new(bytes.to_vec()))
                .with_guessed_format()
                .unwrap()
        };
        assert_eq!(
            ImageTexture::decode(reader(&png), 1 << 20),
            Err(DecodeError::OverBudget {
                needed: 4000 * 4000 * 3
            })
        );
        let t = ImageTexture::decode(reader(&png), 100 << 20).unwrap();
        assert_eq!(t.memory_bytes(), 4000 * 4000 * 3);
    }

    #[test]
    fn checker_alternates_and_is_stable_on_cell_boundaries() {
        let t = Texture::Checker {
            even: DVec3::ONE,
            odd: DVec3::ZERO,
            size: 2.0,
            filtered: false,
        };
        let n = DVec3::Y;
        assert_eq!(
            t.color(DVec3::new(1.0, 0.0, 1.0), n, None, || DVec2::ZERO),
            DVec3::ZERO
        );
        assert_eq!(
            t.color(DVec3::new(3.0, 0.0, 1.0), n, None, || DVec2::ZERO),
            DVec3::ONE
        );
        assert_eq!(
            t.color(DVec3::new(-1.0, 0.0, 1.0), n, None, || DVec2::ZERO),
            DVec3::ONE
        );
        // Rounding noise around y = 0 does not change the cell.
        for dy in [-1e-15, 0.0, 1e-15] {
            assert_eq!(
                t.color(DVec3::new(1.0, dy, 1.0), n, None, || DVec2::ZERO),
                DVec3::ZERO
            );
        }
    }

    /// The mean of s over [c − h, c + h] by the midpoint rule on a fine grid.
    fn square_wave_mean_brute(c: f64, h: f64) -> f64 {
        let n = 200_000;
        let sum: f64 = (0..n)
            .map(|k| {
                let x = c - h + 2.0 * h * (k as f64 + 0.5) / n as f64;
                if x.floor().rem_euclid(2.0) == 0.0 {
                    1.0
                } else {
                    -1.0
                }
            })
            .sum();
        sum / n as f64
    }

    #[test]
    fn square_wave_mean_matches_hand_values_and_brute_force() {
        // By hand: [0, 1] is all of an even cell, [0.5, 1.5] half and
        // half, [0.5, 2.0] two thirds odd, [−0.25, 0.75] one quarter odd.
        assert_eq!(square_wave_mean(0.5, 0.5), 1.0);
        assert_eq!(square_wave_mean(1.0, 0.5), 0.0);
        assert!((square_wave_mean(1.25, 0.75) - (0.5 - 1.0) / 1.5).abs() < 1e-15);
        assert!((square_wave_mean(0.25, 0.5) - 0.5).abs() < 1e-15);
        // A whole period averages to nothing wherever it starts.
        for c in [-3.3, 0.0, 0.7, 12.25] {
            assert!(square_wave_mean(c, 1.0).abs() < 1e-12, "{c}");
        }
        // Narrower than 1e-6 cells: the point's own value.
        assert_eq!(square_wave_mean(0.3, 1e-7), 1.0);
        assert_eq!(square_wave_mean(1.3, 0.0), -1.0);
        let mut rng = PixelRng::new(0x5eed, 3, 4);
        for _ in 0..40 {
            let c = (rng.uniform() - 0.5) * 40.0;
            let h = 1e-3 + rng.uniform() * 3.0;
            let (f, b) = (square_wave_mean(c, h), square_wave_mean_brute(c, h));
            assert!((f - b).abs() < 1e-4, "c {c} h {h}: {f} against {b}");
        }
    }

    #[test]
    fn box_filtered_checker_is_the_mean_of_the_point_checker_over_the_box() {
        let (even, odd) = (DVec3::new(0.9, 0.8, 0.1), DVec3::new(0.1, 0.2, 0.3));
        let point = Texture::Checker {
            even,
            odd,
            size: 1.0,
            filtered: false,
        };
        let mut rng = PixelRng::new(0x5eed, 7, 1);
        let n = 60;
        for _ in 0..6 {
            let c = DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 6.0 - 3.0;
            let h = DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 1.5 + 0.05;
            // The point checker's mean over an n³ grid of the box's cells'
            // midpoints (the normal only nudges the point by 1e-6).
            let mut sum = DVec3::ZERO;
            for i in 0..n {
                for j in 0..n {
                    for k in 0..n {
                        let f = (DVec3::new(i as f64, j as f64, k as f64) + 0.5) / n as f64;
                        let p = c - h + 2.0 * h * f;
                        sum += point.color(p, DVec3::ZERO, None, || DVec2::ZERO);
                    }
                }
            }
            let brute = sum / (n * n * n) as f64;
            let closed = box_filtered_checker(c, h, even, odd);
            // The grid's error: each cell face crossing the box costs up
            // to one grid slab in n.
            assert!(
                (closed - brute).abs().max_element() < 0.05,
                "centre {c} half {h}: {closed} against {brute}"
            );
        }
        // A box far wider than the cells sees the mean colour; a flat one
        // (a floor's footprint, no extent in y) the product over x and z.
        let wide = box_filtered_checker(DVec3::splat(0.3), DVec3::splat(1e4), even, odd);
        assert!((wide - 0.5 * (even + odd)).abs().max_element() < 1e-3);
        let flat = box_filtered_checker(
            DVec3::new(0.5, 0.5, 0.5),
            DVec3::new(0.5, 0.0, 0.5),
            even,
            odd,
        );
        assert!((flat - even).abs().max_element() < 1e-15, "{flat}");
    }

    #[test]
    fn a_filtered_checker_without_footprint_is_the_point_checker() {
        let (even, odd) = (DVec3::ONE, DVec3::ZERO);
        let filtered = Texture::Checker {
            even,
            odd,
            size: 0.5,
            filtered: true,
        };
        let point = Texture::Checker {
            even,
            odd,
            size: 0.5,
            filtered: false,
        };
        assert!(filtered.filtered() && !point.filtered());
        let mut rng = PixelRng::new(0x5eed, 9, 9);
        for _ in 0..100 {
            let p = DVec3::new(rng.uniform(), 0.0, rng.uniform()) * 10.0;
            let footprint = Some([DVec3::new(0.3, 0.0, 0.1), DVec3::new(-0.1, 0.0, 0.2)]);
            // Unfiltered textures ignore the footprint; a footprint of no
            // size gives the point's colour.
            assert_eq!(
                point.color(p, DVec3::Y, footprint, || DVec2::ZERO),
                point.color(p, DVec3::Y, None, || DVec2::ZERO)
            );
            assert_eq!(
                filtered.color(p, DVec3::Y, None, || DVec2::ZERO),
                point.color(p, DVec3::Y, None, || DVec2::ZERO)
            );
            assert_eq!(
                filtered.color(p, DVec3::Y, Some([DVec3::ZERO; 2]), || DVec2::ZERO),
                point.color(p, DVec3::Y, None, || DVec2::ZERO)
            );
        }
    }
}
