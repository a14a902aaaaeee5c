//! How to render: the settings every layer reads (the scene file's
//! `[render]`, the command line's overrides, the render loop). Plain data
//! below the modules that use them.

use crate::limits;

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
}

impl RenderSettings {
    /// Checks the settings against [`limits`]; the message says what is wrong.
    pub fn check(&self) -> Result<(), String> {
        use limits::*;
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
        format!(
            "{}x{} spp={} max_depth={} min_weight={}",
            self.width, self.height, self.spp, self.max_depth, self.min_weight
        )
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
        }
    }
}
