//! The image being rendered: linear radiance per pixel, over the whole
//! frame or over a region of it (a farm task's part).

use glam::DVec3;

use super::Region;

/// Linear RGB radiance over `window`, a region of a `width` × `height`
/// frame; row-major from the window's top-left. Coordinates are the
/// frame's.
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    width: u32,
    height: u32,
    window: Region,
    pixels: Vec<DVec3>,
}

impl Film {
    /// A black film over the whole frame.
    pub fn new(width: u32, height: u32) -> Self {
        Film::window(width, height, Region::full(width, height))
    }

    /// A black film over `window` of a `width` × `height` frame.
    pub fn window(width: u32, height: u32, window: Region) -> Self {
        debug_assert!(Region::full(width, height).contains(&window));
        Film {
            width,
            height,
            window,
            pixels: vec![DVec3::ZERO; window.area() as usize],
        }
    }

    /// Width of the frame in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height of the frame in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The pixels this film holds.
    pub fn region(&self) -> Region {
        self.window
    }

    /// Whether it holds the whole frame.
    pub fn is_full(&self) -> bool {
        self.window == Region::full(self.width, self.height)
    }

    /// The value of pixel (x, y), which must lie in the window.
    pub fn get(&self, x: u32, y: u32) -> DVec3 {
        self.pixels[self.index(x, y)]
    }

    /// Sets pixel (x, y), which must lie in the window.
    pub fn set(&mut self, x: u32, y: u32, value: DVec3) {
        let i = self.index(x, y);
        self.pixels[i] = value;
    }

    /// Applies `f` to every component of every pixel.
    pub fn map(&mut self, f: impl Fn(f64) -> f64) {
        for p in &mut self.pixels {
            *p = DVec3::new(f(p.x), f(p.y), f(p.z));
        }
    }

    /// The window's pixels, row-major from its top-left.
    pub fn pixels(&self) -> &[DVec3] {
        &self.pixels
    }

    /// The root-mean-square difference from `other` (of the same window),
    /// over every channel of every pixel: how far a render is from a
    /// reference.
    pub fn rmse(&self, other: &Film) -> f64 {
        assert_eq!(self.window, other.window, "films of different windows");
        let sum: f64 = self
            .pixels
            .iter()
            .zip(&other.pixels)
            .map(|(a, b)| (*a - *b).length_squared())
            .sum();
        (sum / (3 * self.pixels.len()) as f64).sqrt()
    }

    /// Copies `values` (row-major over `part`, which must lie in the
    /// window) into place.
    pub fn paste(&mut self, part: Region, values: &[DVec3]) {
        debug_assert!(self.window.contains(&part) && values.len() as u64 == part.area());
        let row = part.width() as usize;
        for (y, line) in (part.y0..part.y1).zip(values.chunks_exact(row)) {
            let start = self.index(part.x0, y);
            self.pixels[start..start + row].copy_from_slice(line);
        }
    }

    fn index(&self, x: u32, y: u32) -> usize {
        debug_assert!(x >= self.window.x0 && x < self.window.x1);
        debug_assert!(y >= self.window.y0 && y < self.window.y1);
        (y - self.window.y0) as usize * self.window.width() as usize + (x - self.window.x0) as usize
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rmse_is_over_every_channel_of_every_pixel() {
        let a = Film::new(2, 2);
        let mut b = Film::new(2, 2);
        assert_eq!(a.rmse(&b), 0.0);
        // One channel of one pixel of four off by 2: √(4 / 12).
        b.set(1, 0, DVec3::new(0.0, 2.0, 0.0));
        assert!((a.rmse(&b) - (4.0f64 / 12.0).sqrt()).abs() < 1e-15);
        assert_eq!(a.rmse(&b), b.rmse(&a));
    }
}
