//! A camera's rays traced in tiles. A query's rays go in groups of eight
//! (a packet, `accel::packet`); taken as given, a camera's group is eight
//! pixels of one row, a strip seven pixels long. Taken as a tile of four
//! pixels by two rows, the group's rays lie closer together (three pixels
//! by one), so the packet's bound over them is tighter and its rays part
//! later. On the bench's 1000 × 1000 camera, nearest hits on the large
//! meshes take 7–8 % fewer instructions, gathering included; on the small
//! bunny, what the packets save is about what the gathering costs.
//!
//! A query is not told the image's width, so it is found from the rays
//! (`Tiles::find`): the first jump between neighbouring rays much larger
//! than the steps before it ends the first row, and rows further on are
//! checked to be as wide and to lie a row's step apart. Rays that do not
//! pass are traced as given. Either way each ray's answer is its own, so
//! the tiles change only the speed.
//!
//! A query's chunk is then whole pairs of rows (a band), its rays gathered
//! tile by tile; their answers go back to their places in the chunk.

use std::ops::Range;

use super::rays::Rays;
use crate::accel::PACKET;

/// Columns of a tile; its rows are two, so that a tile is a packet.
pub(crate) const COLUMNS: usize = 4;

/// Rows of a tile.
const ROWS: usize = PACKET / COLUMNS;

/// Fewer rays than this are traced as given (a few rows, whose tiles
/// would save less than the rows are looked at for).
const MIN_RAYS: usize = 4096;

/// Widest row looked for.
const MAX_WIDTH: usize = 1 << 14;

/// Neighbours further apart than this (squared distance, see
/// `Tiles::find`) are no camera's worth tiling: a group of eight such rays
/// is not traced as a packet (`trace::coherent`: directions within 8°,
/// about 0.14 apart as unit vectors). Scattered rays are told by their
/// first steps.
const MAX_STEP: f64 = 0.02;

/// Rows further on checked to be as wide as the first, and to lie a row's
/// step below the row before.
const CHECKED_ROWS: usize = 16;

/// How much larger (in squared distance) the jump from a row's last ray
/// to the next row's first is than the steps along the row: four times
/// the distance.
const JUMP: f64 = 16.0;

/// The rays of a batch as rows of `width`, traced in tiles of
/// [`COLUMNS`] × [`ROWS`].
#[derive(Debug)]
pub(crate) struct Tiles {
    width: usize,
    /// The ray a full chunk traces p-th is its ray `order[p]`.
    order: Vec<u32>,
}

impl Tiles {
    /// The rows of `rays`, if they are a camera's (see the module's
    /// introduction), with chunks of about `chunk` rays. `scale` (the
    /// scene's size) weighs origins against unit directions. Coordinates
    /// not yet checked may be NaN: a comparison with one fails, and the
    /// chunk's check reports the row.
    pub(crate) fn find(rays: &Rays, chunk: usize, scale: f64) -> Option<Tiles> {
        let n = rays.len();
        if n < MIN_RAYS {
            return None;
        }
        let scale = if scale.is_finite() && scale > 0.0 {
            scale
        } else {
            1.0
        };
        // The squared distance between rays i and j: their origins in
        // the scene's size, their directions as unit vectors.
        let apart = |i: usize, j: usize| {
            let ((oi, di), (oj, dj)) = (rays.ray(i), rays.ray(j));
            ((oi - oj) / scale).length_squared()
                + (di.normalize() - dj.normalize()).length_squared()
        };
        let width = first_row(n, &apart)?;
        let rows = n / width;
        if width < 2 * COLUMNS || !width.is_multiple_of(COLUMNS) || rows < 2 * ROWS {
            return None;
        }
        let checked = (0..CHECKED_ROWS).all(|c| {
            // Rows 1 to rows − 2, each checked against the row below: it
            // starts after a jump, and at its start, middle and end the
            // row below is nearer than four rays along. A tile then spans
            // less than a row of eight: three steps along and one down,
            // against seven along.
            let start = (1 + c * (rows - 2) / CHECKED_ROWS) * width;
            apart(start - 1, start) > JUMP * apart(start, start + 1)
                && [0, width / 2, width - 1 - COLUMNS].iter().all(|&x| {
                    let (i, below) = (start + x, apart(start + x, start + x + width));
                    below > 0.0 && below <= apart(i, i + COLUMNS)
                })
        });
        if !checked {
            return None;
        }
        let band = ROWS * width;
        let len = band * (chunk / band).max(1);
        let order = (0..len)
            .map(|p| {
                let (b, q) = (p / band, p % band);
                let (tile, lane) = (q / PACKET, q % PACKET);
                (b * band + lane / COLUMNS * width + tile * COLUMNS + lane % COLUMNS) as u32
            })
            .collect();
        Some(Tiles { width, order })
    }

    /// Rays per chunk: whole bands of rows.
    pub(crate) fn chunk_len(&self) -> usize {
        self.order.len()
    }

    /// The order of a chunk of `len` rays. A chunk short of full (the
    /// batch's last) traces its whole bands in tiles and the rest as
    /// given.
    pub(crate) fn chunk(&self, len: usize) -> TiledChunk<'_> {
        let band = ROWS * self.width;
        TiledChunk {
            order: &self.order[..len.min(self.order.len()) / band * band],
        }
    }
}

/// The order of one chunk's rays, tile by tile.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TiledChunk<'t> {
    /// The rays of the chunk's whole bands, in the order they are traced;
    /// the rest are traced as given.
    order: &'t [u32],
}

impl TiledChunk<'_> {
    /// The ray the chunk traces p-th, by its index in the chunk.
    #[inline(always)]
    pub(crate) fn ray(&self, p: usize) -> usize {
        self.order.get(p).map_or(p, |&i| i as usize)
    }

    /// Calls `each(first, count)` for the rays the chunk traces in
    /// `traced` (positions in its order), as runs of rays next to each
    /// other in the chunk (a tile's row, or the rest as given), in order.
    #[inline(always)]
    pub(crate) fn runs(&self, traced: Range<usize>, mut each: impl FnMut(usize, usize)) {
        let mut p = traced.start;
        while p < traced.end {
            let count = if p < self.order.len() {
                (COLUMNS - p % COLUMNS).min(traced.end - p)
            } else {
                traced.end - p
            };
            each(self.ray(p), count);
            p += count;
        }
    }
}

/// The width of the first row: the first ray after a jump from its
/// neighbour much larger than every step before it (`apart` the squared
/// distance between two rays).
fn first_row(n: usize, apart: &impl Fn(usize, usize) -> f64) -> Option<usize> {
    let mut widest = apart(0, 1);
    for i in 1..(n - 1).min(MAX_WIDTH) {
        if widest > MAX_STEP {
            return None;
        }
        let step = apart(i, i + 1);
        if step > JUMP * widest {
            return Some(i + 1);
        }
        widest = widest.max(step);
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::PixelRng;

    /// A pinhole camera's rays, `width` × `rows` pixels (square), and
    /// `extra` rays of a row cut short.
    fn camera(width: usize, rows: usize, extra: usize) -> (Vec<f64>, Vec<f64>) {
        let n = width * rows + extra;
        let directions = (0..n)
            .flat_map(|k| {
                let (x, y) = ((k % width) as f64, (k / width) as f64);
                [x / width as f64 - 0.5, 0.5 - y / width as f64, -1.0]
            })
            .collect();
        ([0.0, 1.0, 5.0].repeat(n), directions)
    }

    fn find(o: &[f64], d: &[f64]) -> Option<Tiles> {
        Tiles::find(&Rays::new(o, d, 0.0, f64::INFINITY).unwrap(), 1024, 2.0)
    }

    #[test]
    fn a_cameras_rows_are_found() {
        for (width, rows) in [(64, 80), (1000, 6), (4096, 4)] {
            let (o, d) = camera(width, rows, 17);
            let tiles = find(&o, &d).expect("a camera");
            assert_eq!(tiles.width, width);
            // Whole bands of two rows, as many as a chunk of 1,024 holds.
            assert_eq!(tiles.chunk_len(), (2 * width) * (1024 / (2 * width)).max(1));
        }
        // An orthographic camera: one direction, origins on a grid.
        let (d, o) = camera(128, 40, 0);
        let tiles = find(&o, &d).expect("an orthographic camera");
        assert_eq!(tiles.width, 128);
    }

    #[test]
    fn each_group_of_eight_is_a_tile_of_four_by_two() {
        let (o, d) = camera(16, 300, 5);
        let tiles = find(&o, &d).unwrap();
        let len = tiles.chunk_len();
        assert_eq!(len, 1024);
        let chunk = tiles.chunk(len);
        let mut seen = vec![false; len];
        for p in 0..len {
            let i = chunk.ray(p);
            assert!(!std::mem::replace(&mut seen[i], true), "ray {i} twice");
            // The tile's first ray, and this ray's place from it.
            let first = chunk.ray(p / PACKET * PACKET);
            let (dx, dy) = (i % 16 - first % 16, i / 16 - first / 16);
            assert_eq!((dx, dy), (p % PACKET % COLUMNS, p % PACKET / COLUMNS));
        }
        // A short chunk: its whole bands in tiles, the rest as given.
        let short = 3 * 32 + 20;
        let chunk = tiles.chunk(short);
        let traced: Vec<usize> = (0..short).map(|p| chunk.ray(p)).collect();
        assert_eq!(traced[..PACKET], [0, 1, 2, 3, 16, 17, 18, 19]);
        assert_eq!(traced[96..], (96..short).collect::<Vec<_>>());
        // The same as runs of rays next to each other.
        let mut runs = Vec::new();
        chunk.runs(2..short, |first, count| runs.extend(first..first + count));
        assert_eq!(runs, traced[2..]);
    }

    #[test]
    fn rays_that_are_not_a_cameras_rows_are_left_as_given() {
        let mut rng = PixelRng::new(9, 0, 0);
        let mut draw = |n: usize| (0..n).map(|_| rng.uniform() - 0.5).collect::<Vec<_>>();
        let (o, d) = (draw(3 * 8192), draw(3 * 8192));
        assert!(find(&o, &d).is_none(), "scattered rays");
        // Too few rays.
        let (o, d) = camera(32, 130, 0);
        assert!(find(&o, &d).is_some());
        assert!(find(&o[..3 * 32 * 120], &d[..3 * 32 * 120]).is_none());
        // Rows not a whole number of tiles wide.
        let (o, d) = camera(130, 40, 0);
        assert!(find(&o, &d).is_none());
        // Four samples of each pixel, one after another: the first "row"
        // found (the samples) has nothing below it.
        let (o, d) = camera(100, 50, 0);
        let four = |v: &[f64]| v.chunks(3).flat_map(|r| r.repeat(4)).collect::<Vec<f64>>();
        assert!(find(&four(&o), &four(&d)).is_none());
        // Rows of changing width: the checked rows do not end where the
        // first does.
        let mut bent = camera(64, 100, 0).1;
        bent.drain(3 * 64 * 50..3 * (64 * 50 + 8));
        let o = vec![0.0; bent.len()];
        assert!(find(&o, &bent).is_none());
        // Rows far apart (a sweep of a few lines): a tile would span
        // more than a row of eight.
        let (o, mut d) = camera(64, 100, 0);
        d.chunks_mut(3).for_each(|r| r[1] *= 8.0);
        assert!(find(&o, &d).is_none());
    }
}
