//! Rectangles of pixels: what a farm task renders (`--crop`, `--tile I/N`),
//! and the tiles a render is cut into.

use std::fmt;

/// Pixels x0 ≤ x < x1, y0 ≤ y < y1 of a frame (y down from the top).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Region {
    /// First column.
    pub x0: u32,
    /// One past the last column.
    pub x1: u32,
    /// First row.
    pub y0: u32,
    /// One past the last row.
    pub y1: u32,
}

impl Region {
    /// The whole `width` × `height` frame.
    pub fn full(width: u32, height: u32) -> Self {
        Region {
            x0: 0,
            x1: width,
            y0: 0,
            y1: height,
        }
    }

    /// Checked bounds: non-empty, not reversed, inside the frame.
    pub fn crop(
        x0: u32,
        x1: u32,
        y0: u32,
        y1: u32,
        width: u32,
        height: u32,
    ) -> Result<Self, String> {
        if x0 >= x1 || y0 >= y1 {
            Err(format!(
                "crop {x0},{x1},{y0},{y1} is empty or reversed: it needs X0 < X1 and Y0 < Y1"
            ))
        } else if x1 > width || y1 > height {
            Err(format!(
                "crop {x0},{x1},{y0},{y1} reaches outside the {width}x{height} image"
            ))
        } else {
            Ok(Region { x0, x1, y0, y1 })
        }
    }

    /// Part `index` of `count` of a `width` × `height` frame: the frame cut
    /// into `count` bands of whole rows, band i holding rows
    /// ⌊i·height/count⌋ .. ⌊(i+1)·height/count⌋. Bands differ by at most one
    /// row, cover the frame exactly and never overlap. Needs
    /// 1 ≤ count ≤ height and index < count.
    pub fn tile(index: u32, count: u32, width: u32, height: u32) -> Result<Self, String> {
        if count == 0 || count > height {
            return Err(format!(
                "tile count {count} must be between 1 and the image height {height}"
            ));
        }
        if index >= count {
            return Err(format!(
                "tile {index}/{count}: the index must be below the count (0 to {})",
                count - 1
            ));
        }
        let row = |i: u32| (u64::from(i) * u64::from(height) / u64::from(count)) as u32;
        Ok(Region {
            x0: 0,
            x1: width,
            y0: row(index),
            y1: row(index + 1),
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.x1 - self.x0
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.y1 - self.y0
    }

    /// Number of pixels.
    pub fn area(&self) -> u64 {
        u64::from(self.width()) * u64::from(self.height())
    }

    /// Whether the two share a pixel.
    pub fn overlaps(&self, other: &Region) -> bool {
        self.x0 < other.x1 && other.x0 < self.x1 && self.y0 < other.y1 && other.y0 < self.y1
    }

    /// Whether `other` lies wholly inside.
    pub fn contains(&self, other: &Region) -> bool {
        self.x0 <= other.x0 && other.x1 <= self.x1 && self.y0 <= other.y0 && other.y1 <= self.y1
    }

    /// The pixels in both, if any.
    pub fn intersection(&self, other: &Region) -> Option<Region> {
        let r = Region {
            x0: self.x0.max(other.x0),
            x1: self.x1.min(other.x1),
            y0: self.y0.max(other.y0),
            y1: self.y1.min(other.y1),
        };
        (r.x0 < r.x1 && r.y0 < r.y1).then_some(r)
    }

    /// This region cut into squares of side `side` (smaller at the right
    /// and bottom edges), row by row.
    pub fn tiles(&self, side: u32) -> Vec<Region> {
        let mut tiles = Vec::new();
        for y0 in (self.y0..self.y1).step_by(side as usize) {
            for x0 in (self.x0..self.x1).step_by(side as usize) {
                tiles.push(Region {
                    x0,
                    x1: (x0 + side).min(self.x1),
                    y0,
                    y1: (y0 + side).min(self.y1),
                });
            }
        }
        tiles
    }
}

/// `X0,X1,Y0,Y1`, the form `--crop` takes.
impl fmt::Display for Region {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{},{},{},{}", self.x0, self.x1, self.y0, self.y1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_cover_the_frame_exactly_once_and_differ_by_at_most_a_row() {
        for (w, h) in [(1, 1), (7, 5), (640, 480), (33, 1000)] {
            for count in 1..=h.min(40) {
                let parts: Vec<Region> = (0..count)
                    .map(|i| Region::tile(i, count, w, h).unwrap())
                    .collect();
                let mut covered = vec![0u8; (w * h) as usize];
                for p in &parts {
                    for y in p.y0..p.y1 {
                        for x in p.x0..p.x1 {
                            covered[(y * w + x) as usize] += 1;
                        }
                    }
                }
                assert!(covered.iter().all(|&c| c == 1), "{w}x{h} in {count}");
                let rows: Vec<u32> = parts.iter().map(|p| p.height()).collect();
                assert!(rows.iter().max().unwrap() - rows.iter().min().unwrap() <= 1);
            }
        }
        // Hand-worked: 10 rows in 4 bands: 0..2, 2..5, 5..7, 7..10.
        let bands: Vec<(u32, u32)> = (0..4)
            .map(|i| Region::tile(i, 4, 3, 10).unwrap())
            .map(|r| (r.y0, r.y1))
            .collect();
        assert_eq!(bands, [(0, 2), (2, 5), (5, 7), (7, 10)]);
    }

    #[test]
    fn bad_bounds_are_refused() {
        assert!(Region::crop(5, 5, 0, 1, 10, 10).is_err());
        assert!(Region::crop(6, 5, 0, 1, 10, 10).is_err());
        assert!(Region::crop(0, 11, 0, 1, 10, 10).is_err());
        assert!(Region::crop(0, 10, 0, 10, 10, 10).is_ok());
        assert!(Region::tile(4, 4, 10, 10).is_err());
        assert!(Region::tile(0, 0, 10, 10).is_err());
        assert!(Region::tile(0, 11, 10, 10).is_err());
    }

    #[test]
    fn overlap_and_containment() {
        let a = Region::crop(0, 4, 0, 4, 9, 9).unwrap();
        let b = Region::crop(3, 6, 3, 6, 9, 9).unwrap();
        let c = Region::crop(4, 6, 0, 4, 9, 9).unwrap();
        assert!(a.overlaps(&b) && !a.overlaps(&c));
        assert_eq!(
            a.intersection(&b),
            Some(Region::crop(3, 4, 3, 4, 9, 9).unwrap())
        );
        assert!(Region::full(9, 9).contains(&b) && !a.contains(&b));
        assert_eq!(a.tiles(3).len(), 4);
        assert_eq!(a.to_string(), "0,4,0,4");
    }
}
