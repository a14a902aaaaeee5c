//! The order a query traces its rays in. Rays given in no order (origins
//! scattered through the scene, directions every way: ambient occlusion,
//! view factors, random sampling) are traced grouped by their direction's
//! octant, then by their origin's cell on a grid over the scene, the cells
//! in Morton order. Rays next to each other in that order start near each
//! other and head the same way, so they visit the same nodes and
//! triangles: those stay in the cache, and the branches of one ray's
//! search predict the next one's. Each ray's answer is its own, whatever
//! was traced before it, so the order changes only the speed; the answers
//! are put back in the rays' order.
//!
//! Rays already in an order of their own (a camera's rows, a lidar's
//! sweep) are traced as given: their packets and spans rely on it.

use rayon::prelude::*;

use super::QueryError;
use super::rays::{QueryOptions, RayChunk, Rays};
use super::tiles::Tiles;
use crate::geometry::Aabb;
use crate::math::rng::splitmix64;

/// Cells per axis of the grid origins are sorted on, as a power of two.
/// A coarse grid is enough: what matters is that neighbours in the order
/// share the top of the tree and the part of the mesh near their origins,
/// and 16³ cells times 8 octants is 32,768 buckets, sorted in one
/// counting pass.
const CELL_BITS: u32 = 4;

/// Buckets of the counting sort: octant, then the Morton code of the cell.
const BUCKETS: usize = 8 << (3 * CELL_BITS);

/// Fewer rays than this are traced as given: sorting pays through what
/// later rays find in the cache, which a small batch does not reach.
/// Measured on the bench's incoherent rays (one thread, batches of 16 Ki
/// and 64 Ki of them): the 940k-triangle bunny took 0.94–1.06 times as
/// long sorted, the 1M-triangle terrain 0.85–1.00 times; a batch of 1M,
/// 0.74–0.92 times.
const MIN_RAYS: usize = 1 << 14;

/// Pairs of neighbouring rays looked at to tell whether a batch is in an
/// order of its own.
const SAMPLES: usize = 256;

/// Rays per task of the key pass.
const CHUNK: usize = 1 << 14;

/// The order a query traces its rays in, where not as given.
#[derive(Debug)]
pub(crate) enum TraceOrder {
    /// Sorted by octant and origin cell: scattered rays through a mesh
    /// beyond the cache.
    Sorted(Sorted),
    /// A camera's rows, tile by tile within each chunk (`query::tiles`).
    Tiled(Tiles),
}

/// Rays sorted by octant and origin cell, and the inverse order.
#[derive(Debug)]
pub(crate) struct Sorted {
    /// Ray `rays[s]` is traced s-th.
    pub rays: Vec<u32>,
    /// Ray i is traced `slot[i]`-th.
    pub slot: Vec<u32>,
}

/// The sorted order to trace `rays` in through a scene of bounds `scene`,
/// or `None` to leave them as they are (few rays, or rays whose neighbours
/// start near each other and head the same way). Checks the rays' coordinates
/// when they are still to be checked ([`Rays::deferred`]), with the error
/// [`Rays::new`] gives.
pub(crate) fn sorted_order(
    rays: &Rays,
    scene: Aabb,
    options: &QueryOptions,
) -> Result<Option<Sorted>, QueryError> {
    let n = rays.len();
    if n < MIN_RAYS || n > u32::MAX as usize || in_order(rays, scene) {
        return Ok(None);
    }
    let grid = Grid::new(scene);
    let mut keys = vec![0u16; n];
    options.run(|| {
        keys.par_chunks_mut(CHUNK)
            .enumerate()
            .try_for_each(|(c, keys)| {
                if options.cancelled() {
                    return Err(QueryError::Cancelled);
                }
                rays.check_chunk(c * CHUNK, keys.len())?;
                for (k, key) in keys.iter_mut().enumerate() {
                    let (origin, direction) = rays.ray(c * CHUNK + k);
                    *key = grid.key(origin.to_array(), direction.to_array());
                }
                Ok(())
            })
    })?;
    Ok(Some(counting_sort(&keys)))
}

/// Whether most neighbouring pairs of a sample of `rays` head the same way
/// (their directions' signs agree) from origins within one cell of the
/// grid: a camera's or a lidar's rays. Coordinates not yet checked may be
/// NaN; such a pair counts as apart, and the key pass reports the row.
fn in_order(rays: &Rays, scene: Aabb) -> bool {
    let n = rays.len();
    let near = scene.diagonal() / f64::from(1u32 << CELL_BITS);
    let together = (0..SAMPLES as u64)
        .filter(|&s| {
            // Pairs at fixed pseudo-random places: evenly spaced ones
            // can fall in step with a camera's rows, all on a row's end.
            let k = (splitmix64(s) % (n as u64 - 1)) as usize;
            let ((o0, d0), (o1, d1)) = (rays.ray(k), rays.ray(k + 1));
            octant(d0.to_array()) == octant(d1.to_array()) && o0.distance(o1) <= near
        })
        .count();
    together * 2 >= SAMPLES
}

/// Bit i set where the direction's component i is negative.
#[inline(always)]
fn octant(d: [f64; 3]) -> u16 {
    u16::from(d[0] < 0.0) | u16::from(d[1] < 0.0) << 1 | u16::from(d[2] < 0.0) << 2
}

/// The grid over the scene origins are sorted on; origins outside it go to
/// its nearest cells.
struct Grid {
    min: [f64; 3],
    /// Cells per unit length, per axis.
    scale: [f64; 3],
}

impl Grid {
    fn new(scene: Aabb) -> Self {
        let cells = f64::from(1u32 << CELL_BITS);
        let size = scene.max - scene.min;
        Grid {
            min: scene.min.to_array(),
            // A flat scene (a plane of triangles) has one cell across.
            scale: size
                .to_array()
                .map(|s| if s > 0.0 { cells / s } else { 0.0 }),
        }
    }

    /// The sort key of a ray: its octant, then its origin's cell in Morton
    /// order.
    #[inline(always)]
    fn key(&self, origin: [f64; 3], direction: [f64; 3]) -> u16 {
        let top = f64::from((1u32 << CELL_BITS) - 1);
        let mut morton = 0u16;
        for (axis, ((o, min), scale)) in origin.iter().zip(self.min).zip(self.scale).enumerate() {
            // `as` saturates, and takes NaN to 0 (clamp passes NaN on).
            let cell = ((o - min) * scale).clamp(0.0, top) as u16;
            morton |= spread(cell) << axis;
        }
        octant(direction) << (3 * CELL_BITS) | morton
    }
}

/// The bits of a cell coordinate, three places apart.
#[inline(always)]
fn spread(cell: u16) -> u16 {
    (0..CELL_BITS).fold(0, |acc, b| acc | (cell >> b & 1) << (3 * b))
}

/// The order of the keys' rays by key, rays of one key in their own order.
fn counting_sort(keys: &[u16]) -> Sorted {
    let mut next = vec![0u32; BUCKETS];
    for &key in keys {
        next[usize::from(key)] += 1;
    }
    let mut start = 0;
    for count in &mut next {
        (*count, start) = (start, start + *count);
    }
    let mut order = Sorted {
        rays: vec![0; keys.len()],
        slot: vec![0; keys.len()],
    };
    for (i, &key) in keys.iter().enumerate() {
        let s = &mut next[usize::from(key)];
        order.rays[*s as usize] = i as u32;
        order.slot[i] = *s;
        *s += 1;
    }
    order
}

/// A chunk's rays gathered in trace order (see [`chunk_rays`]).
#[derive(Debug, Default)]
pub(crate) struct Gathered {
    origins: Vec<f64>,
    directions: Vec<f64>,
}

/// The rays a query's chunk traces, and the number of the first of them:
/// rays `first..first + len` of the batch as given (checked here where
/// the batch is still to be checked); or gathered into `gathered` and
/// numbered from 0: in a sorted order, the rays in its slots
/// `first..first + len` (the key pass checked them), in tiles, the
/// chunk's rays tile by tile (checked here). Gathered a chunk at a time,
/// the rays stay in the cache while they are traced, and no copy of the
/// whole batch is made.
pub(crate) fn chunk_rays<'a: 'b, 'b>(
    rays: &Rays<'a>,
    order: Option<&TraceOrder>,
    first: usize,
    len: usize,
    gathered: &'b mut Gathered,
) -> Result<(RayChunk<'b>, usize), QueryError> {
    if !matches!(order, Some(TraceOrder::Sorted(_))) {
        rays.check_chunk(first, len)?;
    }
    let Gathered {
        origins,
        directions,
    } = gathered;
    origins.clear();
    directions.clear();
    origins.reserve(3 * len);
    directions.reserve(3 * len);
    let mut gather = |first: usize, count: usize| rays.extend(first, count, origins, directions);
    match order {
        None => match rays.in_double() {
            Some(chunk) => return Ok((chunk, first)),
            // Coordinates in single precision are widened a chunk at a
            // time, so that the searches read double precision.
            None => gather(first, len),
        },
        Some(TraceOrder::Sorted(sorted)) => sorted.rays[first..first + len]
            .iter()
            .for_each(|&i| gather(i as usize, 1)),
        Some(TraceOrder::Tiled(tiles)) => tiles
            .chunk(len)
            .runs(0..len, |i, count| gather(first + i, count)),
    }
    Ok((rays.gathered(origins, directions), 0))
}

/// `sorted` put back in the rays' order: entry i of the answer is entry
/// `slot[i]` of `sorted`.
pub(crate) fn unsort<T: Copy + Default + Send + Sync>(sorted: &[T], slot: &[u32]) -> Vec<T> {
    let mut out = vec![T::default(); sorted.len()];
    out.par_chunks_mut(CHUNK)
        .zip(slot.par_chunks(CHUNK))
        .for_each(|(out, slot)| {
            for (value, &s) in out.iter_mut().zip(slot) {
                *value = sorted[s as usize];
            }
        });
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::PixelRng;
    use glam::DVec3;

    fn unit_box() -> Aabb {
        Aabb {
            min: DVec3::ZERO,
            max: DVec3::ONE,
        }
    }

    #[test]
    fn keys_put_the_octant_first_and_cells_in_morton_order() {
        let grid = Grid::new(unit_box());
        let cell = |x: f64, y: f64, z: f64| grid.key([x, y, z], [1.0, 1.0, 1.0]);
        assert_eq!(cell(0.0, 0.0, 0.0), 0);
        assert_eq!(cell(1.0 / 16.0, 0.0, 0.0), 1);
        assert_eq!(cell(0.0, 1.0 / 16.0, 0.0), 2);
        assert_eq!(cell(0.0, 0.0, 1.0 / 16.0), 4);
        assert_eq!(cell(2.0 / 16.0, 0.0, 0.0), 8);
        // Outside the grid: the nearest cell.
        assert_eq!(cell(-5.0, -5.0, -5.0), 0);
        assert_eq!(cell(5.0, 5.0, 5.0), (1 << 12) - 1);
        // The octant above every cell.
        assert_eq!(grid.key([0.0; 3], [-1.0, 1.0, 1.0]), 1 << 12);
        assert_eq!(grid.key([1.0; 3], [1.0, -1.0, -1.0]), 6 << 12 | 4095);
        // A flat scene: one cell across its flat axis.
        let flat = Grid::new(Aabb {
            min: DVec3::ZERO,
            max: DVec3::new(1.0, 1.0, 0.0),
        });
        assert_eq!(flat.key([0.0, 0.0, 3.0], [1.0; 3]), 0);
    }

    #[test]
    fn the_counting_sort_is_a_stable_sort_by_key() {
        let mut rng = PixelRng::new(7, 0, 0);
        let keys: Vec<u16> = (0..5000)
            .map(|_| (rng.uniform() * BUCKETS as f64) as u16 % 64 * 512)
            .collect();
        let order = counting_sort(&keys);
        let mut expected: Vec<u32> = (0..keys.len() as u32).collect();
        expected.sort_by_key(|&i| keys[i as usize]);
        assert_eq!(order.rays, expected);
        for (s, &i) in order.rays.iter().enumerate() {
            assert_eq!(order.slot[i as usize] as usize, s);
        }
        let sorted: Vec<u16> = order.rays.iter().map(|&i| keys[i as usize]).collect();
        assert_eq!(unsort(&sorted, &order.slot), keys);
    }

    #[test]
    fn rays_in_an_order_of_their_own_are_left_so() {
        let n = MIN_RAYS * 2;
        let mut rng = PixelRng::new(3, 0, 0);
        // A pinhole camera's rays: one origin, neighbours a pixel apart,
        // rows of 128 (in step with evenly spaced samples, which would
        // all fall on a row's end, where the direction's signs change).
        let origins = vec![0.5; 3 * n];
        let directions: Vec<f64> = (0..n)
            .flat_map(|k| {
                [
                    (k % 128) as f64 / 128.0 - 0.5,
                    (k / 128) as f64 / 256.0 - 0.5,
                    1.0,
                ]
            })
            .collect();
        let camera = Rays::new(&origins, &directions, 0.0, f64::INFINITY).unwrap();
        let options = QueryOptions::default();
        assert!(
            sorted_order(&camera, unit_box(), &options)
                .unwrap()
                .is_none()
        );
        // Origins and directions at random: sorted.
        let scattered: Vec<f64> = (0..3 * n).map(|_| rng.uniform()).collect();
        let ways: Vec<f64> = (0..3 * n).map(|_| rng.uniform() - 0.5).collect();
        let random = Rays::new(&scattered, &ways, 0.0, f64::INFINITY).unwrap();
        let order = sorted_order(&random, unit_box(), &options)
            .unwrap()
            .unwrap();
        let grid = Grid::new(unit_box());
        let key = |i: u32| {
            let (o, d) = random.ray(i as usize);
            grid.key(o.to_array(), d.to_array())
        };
        assert!(order.rays.windows(2).all(|w| key(w[0]) <= key(w[1])));
        // Too few rays: as given.
        let few = Rays::new(&scattered[..300], &ways[..300], 0.0, f64::INFINITY).unwrap();
        assert!(sorted_order(&few, unit_box(), &options).unwrap().is_none());
    }

    #[test]
    fn bad_rays_are_reported_by_the_key_pass() {
        let n = MIN_RAYS * 2;
        let mut rng = PixelRng::new(5, 0, 0);
        let mut origins: Vec<f64> = (0..3 * n).map(|_| rng.uniform()).collect();
        let directions: Vec<f64> = (0..3 * n).map(|_| rng.uniform() - 0.5).collect();
        origins[3 * 20_000 + 1] = f64::NAN;
        let deferred = Rays::deferred(&origins, &directions, 0.0, f64::INFINITY).unwrap();
        let err = sorted_order(&deferred, unit_box(), &QueryOptions::default()).unwrap_err();
        let eager = Rays::new(&origins, &directions, 0.0, f64::INFINITY).unwrap_err();
        assert_eq!(err.to_string(), eager.to_string());
    }
}
