//! The image being rendered: linear radiance per pixel.

use glam::DVec3;

/// A width × height grid of linear RGB radiance, row-major from the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    width: u32,
    height: u32,
    pixels: Vec<DVec3>,
}

impl Film {
    /// A black film.
    pub fn new(width: u32, height: u32) -> Self {
        Film {
            width,
            height,
            pixels: vec![DVec3::ZERO; width as usize * height as usize],
        }
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The value of pixel (x, y).
    pub fn get(&self, x: u32, y: u32) -> DVec3 {
        self.pixels[self.index(x, y)]
    }

    /// Sets pixel (x, y).
    pub fn set(&mut self, x: u32, y: u32, value: DVec3) {
        let i = self.index(x, y);
        self.pixels[i] = value;
    }

    /// All pixels, row-major from the top-left.
    pub fn pixels(&self) -> &[DVec3] {
        &self.pixels
    }

    fn index(&self, x: u32, y: u32) -> usize {
        y as usize * self.width as usize + x as usize
    }
}
