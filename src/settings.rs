//! How to render: the settings every layer reads (the scene file's
//! `[render]`, the command line's overrides, the render loop). Plain data
//! below the modules that use them.

use crate::limits;

/// Whitted's adaptive anti-aliasing (1980; POV-Ray's `+AM2`): samples at
/// the pixel corners (shared with the neighbours) and centre, and a square
/// cut in four where they differ by more than `threshold`, at most `depth`
/// times (see `render/adaptive.rs`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Adaptive {
    /// Largest difference of the corners of a square (in any colour
    /// channel of linear radiance) left without a cut.
    pub threshold: f64,
    /// Most cuts (0..=`MAX_ADAPTIVE_DEPTH`; 0: five samples a pixel).
    pub depth: u32,
    /// Whether each sample point moves at random within half the spacing
    /// of its level (the same point for every pixel that shares it).
    pub jitter: bool,
}

/// An open shutter (motion blur): each camera sample sees the scene at
/// its own time between `open` and `close`, in frames after the frame
/// being rendered, taken at `samples` instants (see `Scene::motion`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shutter {
    /// When the shutter opens, in frames from the frame's start.
    pub open: f64,
    /// When it closes (≥ `open`).
    pub close: f64,
    /// Instants the exposure is cut into, each at the middle of its share.
    pub samples: u32,
}

impl Shutter {
    /// The instant of share `k` of `samples`, in frames from the frame's
    /// start: the middle of [open + k/n, open + (k+1)/n] of the exposure.
    pub fn instant(&self, k: u32) -> f64 {
        let share = (f64::from(k) + 0.5) / f64::from(self.samples);
        self.open + share * (self.close - self.open)
    }
}

/// How to render: resolution, sampling and recursion limits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples per pixel on a stratified grid (1: the pixel centre).
    pub spp: u32,
    /// Longest ray path, counting the camera ray.
    pub max_depth: u32,
    /// Secondary rays below this weight in the pixel are not traced.
    pub min_weight: f64,
    /// Seed of the per-pixel random streams.
    pub seed: u64,
    /// Animation frame; keys the random streams with the seed (frame 0's
    /// streams are those of a still).
    pub frame: u32,
    /// Worker threads; `None` uses every core.
    pub threads: Option<usize>,
    /// Exposure in stops (EV): 8-bit images store radiance × 2^EV. The
    /// film, EXR and HDR files keep the linear radiance.
    pub exposure: f64,
    /// Width over height that a model's camera asks for (glTF
    /// `aspectRatio`) when the scene file does not set both sides: a
    /// command-line override of one side then derives the other.
    pub aspect: Option<f64>,
    /// Adaptive anti-aliasing instead of `spp` stratified samples.
    pub adaptive: Option<Adaptive>,
    /// An open shutter: motion blur of what the scene animates.
    pub shutter: Option<Shutter>,
}

/// The image size for a camera made for images `aspect` wide per unit of
/// height, given the sides the user set: both kept as they are; one set,
/// the other derived (rounded, at least 1); none, the default width and
/// the height it implies. A derived side past the limits (an aspect ratio
/// of 1e-30 in a file) is an error that says to set the sides.
pub fn image_shape(
    aspect: f64,
    width: Option<u32>,
    height: Option<u32>,
) -> Result<(u32, u32), String> {
    let derived = |v: f64| -> Result<u32, String> {
        let v = v.round().max(1.0);
        if v <= f64::from(limits::MAX_IMAGE_SIDE) {
            Ok(v as u32)
        } else {
            Err(format!(
                "the camera's aspect ratio {aspect:e} (width over height) makes a side of {v:e} \
                 pixels, more than {}; set both --width and --height (or [render] width and \
                 height)",
                limits::MAX_IMAGE_SIDE
            ))
        }
    };
    let (w, h) = match (width, height) {
        (Some(w), Some(h)) => return Ok((w, h)),
        (Some(w), None) => (w, derived(f64::from(w) / aspect)?),
        (None, Some(h)) => (derived(f64::from(h) * aspect)?, h),
        (None, None) => {
            let w = RenderSettings::default().width;
            (w, derived(f64::from(w) / aspect)?)
        }
    };
    let pixels = u64::from(w) * u64::from(h);
    if pixels > limits::MAX_PIXELS {
        return Err(format!(
            "the camera's aspect ratio {aspect:e} makes a {w}x{h} image, {pixels} pixels, more \
             than {}; set both --width and --height (or [render] width and height)",
            limits::MAX_PIXELS
        ));
    }
    Ok((w, h))
}

/// 2^`ev`: the factor an exposure of `ev` stops puts on radiance.
pub fn exposure_scale(ev: f64) -> f64 {
    crate::math::transcendental::pow(2.0, ev)
}

impl RenderSettings {
    /// Checks the settings against [`limits`]; the message says what is wrong.
    pub fn check(&self) -> Result<(), String> {
        use limits::*;
        if let Some(aspect) = self.aspect
            && (self.width == 0 || self.height == 0)
        {
            // A side a model camera's shape could not give (see
            // `image_shape`): its error, which says to set the sides.
            let side = |s: u32| (s != 0).then_some(s);
            image_shape(aspect, side(self.width), side(self.height))?;
        }
        let pixels = u64::from(self.width) * u64::from(self.height);
        if self.width == 0
            || self.height == 0
            || self.width > MAX_IMAGE_SIDE
            || self.height > MAX_IMAGE_SIDE
        {
            Err(format!(
                "image size {}x{}: each side must be between 1 and {MAX_IMAGE_SIDE}",
                self.width, self.height
            ))
        } else if pixels > MAX_PIXELS {
            Err(format!(
                "image size {}x{} has {pixels} pixels, more than {MAX_PIXELS}",
                self.width, self.height
            ))
        } else if self.spp == 0 || self.spp > MAX_SPP {
            Err(format!("spp {} must be between 1 and {MAX_SPP}", self.spp))
        } else if self.max_depth == 0 || self.max_depth > MAX_DEPTH {
            Err(format!(
                "max_depth {} must be between 1 and {MAX_DEPTH}",
                self.max_depth
            ))
        } else if let Some(a) = self.adaptive
            && (a.depth > MAX_ADAPTIVE_DEPTH || a.threshold.is_nan() || a.threshold < 0.0)
        {
            Err(format!(
                "adaptive anti-aliasing: depth {} must be between 0 and {MAX_ADAPTIVE_DEPTH} and threshold {} a number ≥ 0",
                a.depth, a.threshold
            ))
        } else if let Some(sh) = self.shutter
            && (!sh.open.is_finite()
                || !sh.close.is_finite()
                || sh.close < sh.open
                || sh.samples == 0
                || sh.samples > MAX_SHUTTER_SAMPLES)
        {
            Err(format!(
                "shutter [{}, {}] with {} samples: it must open before it closes, at finite times, \
                 with 1 to {MAX_SHUTTER_SAMPLES} samples",
                sh.open, sh.close, sh.samples
            ))
        } else {
            Ok(())
        }
    }
}

impl RenderSettings {
    /// The settings that change pixels, besides the seed and the frame, in
    /// one canonical line: `640x480 spp=4 max_depth=8 min_weight=0.001`.
    /// (Threads and regions change no pixel.)
    pub fn pixel_key(&self) -> String {
        let mut key = format!(
            "{}x{} spp={} max_depth={} min_weight={}",
            self.width, self.height, self.spp, self.max_depth, self.min_weight
        );
        // The exposure changes the 8-bit encodings only, so parts carry it
        // for their merge; without one, keys stay as they were.
        if self.exposure != 0.0 {
            key.push_str(&format!(" exposure={}", self.exposure));
        }
        if let Some(a) = self.adaptive {
            let jitter = if a.jitter { "/jitter" } else { "" };
            key.push_str(&format!(" adaptive={}/{}{jitter}", a.threshold, a.depth));
        }
        if let Some(sh) = self.shutter {
            key.push_str(&format!(" shutter={}/{}/{}", sh.open, sh.close, sh.samples));
        }
        key
    }

    /// How pixels are sampled, for messages: `4 spp`, or `adaptive
    /// 0.3/3` (threshold/depth).
    pub fn sampling(&self) -> String {
        match self.adaptive {
            None => format!("{} spp", self.spp),
            Some(a) => format!("adaptive {}/{}", a.threshold, a.depth),
        }
    }

    /// The exposure recorded in a [`pixel_key`](Self::pixel_key), 0 when
    /// there is none.
    pub fn exposure_in_key(key: &str) -> f64 {
        key.split(' ')
            .find_map(|w| w.strip_prefix("exposure="))
            .and_then(|v| v.parse().ok())
            .filter(|v: &f64| v.is_finite())
            .unwrap_or(0.0)
    }
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 640,
            height: 480,
            spp: 4,
            max_depth: 8,
            min_weight: 1e-3,
            seed: 0,
            frame: 0,
            threads: None,
            exposure: 0.0,
            aspect: None,
            adaptive: None,
            shutter: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_camera_aspect_shapes_the_sides_not_given() {
        // Blender's 1920×1080: 16:9.
        let a = 16.0 / 9.0;
        assert_eq!(image_shape(a, None, None), Ok((640, 360)));
        assert_eq!(image_shape(a, Some(1280), None), Ok((1280, 720)));
        assert_eq!(image_shape(a, None, Some(1080)), Ok((1920, 1080)));
        assert_eq!(image_shape(a, Some(100), Some(100)), Ok((100, 100)));
        // A needle-thin aspect still gives a side of at least one pixel.
        assert_eq!(image_shape(1e9, Some(10), None), Ok((10, 1)));
        // A side past the limit is derived from the file, never clamped
        // into a silently huge image: an error naming the options.
        let e = image_shape(1e-30, None, None).unwrap_err();
        assert!(e.contains("--width") && e.contains("--height"), "{e}");
        assert!(image_shape(1e-30, Some(1), None).is_err());
        assert!(image_shape(1e30, None, Some(2)).is_err());
        // Sides within the limit but too many pixels together.
        assert!(image_shape(1.0, Some(32_768), None).is_err());
        assert_eq!(image_shape(1e-30, Some(1), Some(1)), Ok((1, 1)));
    }

    #[test]
    fn exposure_doubles_per_stop() {
        assert_eq!(exposure_scale(0.0), 1.0);
        assert_eq!(exposure_scale(1.0), 2.0);
        assert_eq!(exposure_scale(-2.0), 0.25);
        assert!((exposure_scale(0.5) - std::f64::consts::SQRT_2).abs() < 1e-15);
    }
}
