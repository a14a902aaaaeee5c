//! A query's input (a batch of rays, checked once), its options (threads,
//! cancellation) and its outputs as flat arrays, one entry per ray.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};

use glam::DVec3;

use super::QueryError;
use super::tiles::COLUMNS;
use crate::limits::{MAX_COORDINATE, MAX_THREADS, MIN_LENGTH};

/// Points or vectors, `x, y, z` of each in turn (a C-contiguous N×3
/// array): a batch's origins or directions, a mesh's vertices,
/// `contains`' points. In double precision, or in single precision, read
/// in place and widened (exactly) where they are read: a batch's rays a
/// chunk at a time as they are traced, with no copy of the batch.
#[derive(Clone, Copy, Debug)]
pub enum Coordinates<'a> {
    /// Double precision.
    F64(&'a [f64]),
    /// Single precision.
    F32(&'a [f32]),
}

impl<'a> From<&'a [f64]> for Coordinates<'a> {
    fn from(values: &'a [f64]) -> Self {
        Coordinates::F64(values)
    }
}

impl<'a> From<&'a [f32]> for Coordinates<'a> {
    fn from(values: &'a [f32]) -> Self {
        Coordinates::F32(values)
    }
}

impl<'a> From<&'a Vec<f64>> for Coordinates<'a> {
    fn from(values: &'a Vec<f64>) -> Self {
        Coordinates::F64(values)
    }
}

impl<'a> From<&'a Vec<f32>> for Coordinates<'a> {
    fn from(values: &'a Vec<f32>) -> Self {
        Coordinates::F32(values)
    }
}

impl<'a, const N: usize> From<&'a [f64; N]> for Coordinates<'a> {
    fn from(values: &'a [f64; N]) -> Self {
        Coordinates::F64(values)
    }
}

impl<'a, const N: usize> From<&'a [f32; N]> for Coordinates<'a> {
    fn from(values: &'a [f32; N]) -> Self {
        Coordinates::F32(values)
    }
}

/// A coordinate type [`Coordinates`] holds.
trait Coordinate: Copy + std::fmt::Display {
    fn wide(self) -> f64;
}

impl Coordinate for f64 {
    #[inline(always)]
    fn wide(self) -> f64 {
        self
    }
}

impl Coordinate for f32 {
    #[inline(always)]
    fn wide(self) -> f64 {
        f64::from(self)
    }
}

/// Calls `$f` on the slice of a [`Coordinates`], whichever its type.
macro_rules! each_type {
    ($c:expr, $v:ident => $f:expr) => {
        match $c {
            Coordinates::F64($v) => $f,
            Coordinates::F32($v) => $f,
        }
    };
}

impl Coordinates<'_> {
    /// Number of values (three a point).
    pub fn len(&self) -> usize {
        each_type!(*self, v => v.len())
    }

    /// Whether there are no values.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Point `k`, widened.
    #[inline(always)]
    pub fn point(&self, k: usize) -> DVec3 {
        match *self {
            Coordinates::F64(v) => DVec3::from_slice(&v[3 * k..]),
            Coordinates::F32(v) => DVec3::new(
                f64::from(v[3 * k]),
                f64::from(v[3 * k + 1]),
                f64::from(v[3 * k + 2]),
            ),
        }
    }

    /// Points `first..first + count` appended to `out`, widened.
    #[inline(always)]
    fn extend(&self, first: usize, count: usize, out: &mut Vec<f64>) {
        let rows = 3 * first..3 * (first + count);
        match *self {
            // A tile's row as one copy of known size: a few vector moves
            // rather than a call.
            Coordinates::F64(v) => match <&[f64; 3 * COLUMNS]>::try_from(&v[rows.clone()]) {
                Ok(tile) => out.extend_from_slice(tile),
                Err(_) => out.extend_from_slice(&v[rows]),
            },
            Coordinates::F32(v) => out.extend(v[rows].iter().map(|&x| f64::from(x))),
        }
    }
}

/// A batch of rays: their [`Coordinates`] (origins and directions), every
/// ray searched for hits with t in (`t_min`, `t_max`). Directions need not
/// be unit; t is measured in their lengths (the point of a hit is
/// `origin + t·direction`).
#[derive(Clone, Copy, Debug)]
pub struct Rays<'a> {
    origins: Coordinates<'a>,
    directions: Coordinates<'a>,
    /// Hits at t ≤ t_min are not seen.
    pub t_min: f64,
    /// Hits at t ≥ t_max are not seen.
    pub t_max: f64,
    /// Whether the coordinates are still to be checked (by the query,
    /// chunk by chunk on its workers: [`Rays::deferred`]).
    unchecked: bool,
}

impl<'a> Rays<'a> {
    /// Checks the batch: the same whole number of rays (at least one) in
    /// both slices, coordinates finite and within ±1e30 (the scene's
    /// bound), no direction shorter than 1e-30 in every component, and
    /// 0 ≤ t_min < t_max (t_max may be +∞).
    pub fn new(
        origins: &'a [f64],
        directions: &'a [f64],
        t_min: f64,
        t_max: f64,
    ) -> Result<Self, QueryError> {
        Self::from_coordinates(origins.into(), directions.into(), t_min, t_max)
    }

    /// [`Rays::new`] for coordinates in either precision (each checked as
    /// `Rays::new` checks them, after widening).
    pub fn from_coordinates(
        origins: Coordinates<'a>,
        directions: Coordinates<'a>,
        t_min: f64,
        t_max: f64,
    ) -> Result<Self, QueryError> {
        let n = rows("origins", origins.len())?;
        if rows("directions", directions.len())? != n {
            return Err(QueryError::invalid(
                "directions",
                format!("{} rays, but origins has {n}", directions.len() / 3),
            ));
        }
        each_type!(origins, v => finite_rows("origins", v))?;
        each_type!(directions, v => finite_rows("directions", v))?;
        if let Some(k) = each_type!(directions, v => first_zero_row(v)) {
            return Err(QueryError::invalid(
                "directions",
                format!("row {k} is zero (every component below {MIN_LENGTH:e})"),
            ));
        }
        // The trees are walked ahead of the origin only (as the
        // renderer's rays go).
        if t_min.is_nan() || t_min < 0.0 {
            return Err(QueryError::invalid(
                "tmin",
                format!("must be 0 or more, got {t_min}"),
            ));
        }
        if t_max.is_nan() {
            return Err(QueryError::invalid("tmax", "is NaN"));
        }
        if t_min >= t_max {
            return Err(QueryError::invalid(
                "tmax",
                format!("must be above tmin ({t_min}), got {t_max}"),
            ));
        }
        Ok(Rays {
            origins,
            directions,
            t_min,
            t_max,
            unchecked: false,
        })
    }

    /// The batch [`Rays::new`] makes, but with the coordinates (finite,
    /// within bounds, no zero direction) checked by each query on its
    /// workers, a chunk of rays just before they are traced, instead of
    /// here on the calling thread. A query given a bad batch returns the
    /// error `Rays::new` would have; the number of rays and `t_min`,
    /// `t_max` are checked here (a bad `t_min` or `t_max` with bad
    /// coordinates reports the coordinates, as `Rays::new` does).
    pub fn deferred(
        origins: &'a [f64],
        directions: &'a [f64],
        t_min: f64,
        t_max: f64,
    ) -> Result<Self, QueryError> {
        Self::deferred_from_coordinates(origins.into(), directions.into(), t_min, t_max)
    }

    /// [`Rays::deferred`] for coordinates in either precision.
    pub fn deferred_from_coordinates(
        origins: Coordinates<'a>,
        directions: Coordinates<'a>,
        t_min: f64,
        t_max: f64,
    ) -> Result<Self, QueryError> {
        let n = rows("origins", origins.len())?;
        if rows("directions", directions.len())? != n
            || t_min.is_nan()
            || t_min < 0.0
            || t_max.is_nan()
            || t_min >= t_max
        {
            // The error, in Rays::new's order.
            return Self::from_coordinates(origins, directions, t_min, t_max);
        }
        Ok(Rays {
            origins,
            directions,
            t_min,
            t_max,
            unchecked: true,
        })
    }

    /// For a query's worker: whether rays `first..first + count` may be
    /// traced, or else the error [`Rays::new`] gives the whole batch.
    pub(crate) fn check_chunk(&self, first: usize, count: usize) -> Result<(), QueryError> {
        if !self.unchecked {
            return Ok(());
        }
        let rows = 3 * first..3 * (first + count);
        let bounded = each_type!(self.origins, v => bounded(&v[rows.clone()]))
            && each_type!(self.directions, v => bounded(&v[rows.clone()]));
        if bounded && !each_type!(self.directions, v => any_zero_row(&v[rows.clone()])) {
            return Ok(());
        }
        // Rare: the first bad row of the whole batch, as Rays::new
        // reports it.
        Self::from_coordinates(self.origins, self.directions, self.t_min, self.t_max).map(|_| ())
    }

    /// Rays gathered from this batch (so checked already), with its
    /// `t_min` and `t_max`.
    pub(crate) fn gathered<'b>(&self, origins: &'b [f64], directions: &'b [f64]) -> RayChunk<'b> {
        RayChunk {
            origins,
            directions,
            t_min: self.t_min,
            t_max: self.t_max,
        }
    }

    /// The batch as the searches read it, where its coordinates are in
    /// double precision (else its chunks are widened, see `chunk_rays`).
    pub(crate) fn in_double(&self) -> Option<RayChunk<'a>> {
        match (self.origins, self.directions) {
            (Coordinates::F64(origins), Coordinates::F64(directions)) => Some(RayChunk {
                origins,
                directions,
                t_min: self.t_min,
                t_max: self.t_max,
            }),
            _ => None,
        }
    }

    /// Number of rays.
    pub fn len(&self) -> usize {
        self.origins.len() / 3
    }

    /// Always false: a batch holds at least one ray.
    pub fn is_empty(&self) -> bool {
        self.origins.is_empty()
    }

    /// Rays `first..first + count` appended to `origins` and `directions`,
    /// in double precision.
    #[inline(always)]
    pub(crate) fn extend(
        &self,
        first: usize,
        count: usize,
        origins: &mut Vec<f64>,
        directions: &mut Vec<f64>,
    ) {
        self.origins.extend(first, count, origins);
        self.directions.extend(first, count, directions);
    }

    /// Ray `k` as (origin, direction).
    #[inline]
    pub fn ray(&self, k: usize) -> (DVec3, DVec3) {
        (self.origins.point(k), self.directions.point(k))
    }
}

/// Rays of a batch as a query's searches read them, a chunk at a time: in
/// double precision, checked, with the batch's `t_min` and `t_max`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RayChunk<'a> {
    origins: &'a [f64],
    directions: &'a [f64],
    pub t_min: f64,
    pub t_max: f64,
}

impl<'a> RayChunk<'a> {
    /// Ray `k` as (origin, direction).
    #[inline]
    pub fn ray(&self, k: usize) -> (DVec3, DVec3) {
        (
            DVec3::from_slice(&self.origins[3 * k..]),
            DVec3::from_slice(&self.directions[3 * k..]),
        )
    }

    /// The least and greatest coordinates, axis by axis, of the origins
    /// and of the directions of rays `first..first + n` (n ≥ 1): origin
    /// minima, origin maxima, direction minima, direction maxima. `None`
    /// when one of the first four rays' directions has other signs than
    /// the first's, the common case of incoherent rays, told cheaply.
    pub(crate) fn span(&self, first: usize, n: usize) -> Option<[DVec3; 4]> {
        let rows = |v: &'a [f64]| v[3 * first..3 * (first + n)].chunks_exact(3);
        let signs = |d: &[f64]| (d[0] > 0.0, d[1] > 0.0, d[2] > 0.0);
        let mut directions = rows(self.directions);
        let d0 = directions.next()?;
        if directions.clone().take(3).any(|d| signs(d) != signs(d0)) {
            return None;
        }
        // Selects rather than f64::min and max (no NaN here): one vector
        // instruction each.
        let mut bounds = [[0.0; 3]; 4];
        for (rows, lo, hi) in [(rows(self.origins), 0, 1), (rows(self.directions), 2, 3)] {
            let mut rows = rows;
            let first_row = rows.next()?;
            let (mut min, mut max) = (
                [first_row[0], first_row[1], first_row[2]],
                [first_row[0], first_row[1], first_row[2]],
            );
            for row in rows {
                for axis in 0..3 {
                    let v = row[axis];
                    min[axis] = if v < min[axis] { v } else { min[axis] };
                    max[axis] = if v > max[axis] { v } else { max[axis] };
                }
            }
            (bounds[lo], bounds[hi]) = (min, max);
        }
        Some(bounds.map(DVec3::from_array))
    }
}

/// Checks points (vertices, `contains`' argument: as `Rays::new` checks
/// origins) and returns how many there are.
pub(crate) fn check_points(name: &'static str, points: Coordinates) -> Result<usize, QueryError> {
    let n = rows(name, points.len())?;
    each_type!(points, v => finite_rows(name, v))?;
    Ok(n)
}

/// Whether a direction is below `MIN_LENGTH` in every component.
#[inline]
fn zero_direction<T: Coordinate>(d: &[T]) -> bool {
    (d[0].wide().abs() < MIN_LENGTH)
        & (d[1].wide().abs() < MIN_LENGTH)
        & (d[2].wide().abs() < MIN_LENGTH)
}

/// Whether a row of directions is zero (see [`zero_direction`]): a pass
/// without an early exit, which the compiler turns into vector code.
fn any_zero_row<T: Coordinate>(directions: &[T]) -> bool {
    directions
        .chunks_exact(3)
        .fold(false, |seen, d| seen | zero_direction(d))
}

/// The first zero row of directions, looked for only when there is one.
fn first_zero_row<T: Coordinate>(directions: &[T]) -> Option<usize> {
    any_zero_row(directions)
        .then(|| directions.chunks_exact(3).position(zero_direction))
        .flatten()
}

/// Whether every value is finite and within ±`MAX_COORDINATE`.
fn bounded<T: Coordinate>(values: &[T]) -> bool {
    // Without an early exit (vector code); NaN fails the comparison as
    // infinity does.
    values
        .iter()
        .fold(true, |ok, v| ok & (v.wide().abs() <= MAX_COORDINATE))
}

fn rows(name: &'static str, len: usize) -> Result<usize, QueryError> {
    if len == 0 {
        return Err(QueryError::invalid(name, "is empty"));
    }
    if !len.is_multiple_of(3) {
        return Err(QueryError::invalid(
            name,
            format!("{len} values are not rows of 3 (x, y, z)"),
        ));
    }
    Ok(len / 3)
}

fn finite_rows<T: Coordinate>(name: &'static str, values: &[T]) -> Result<(), QueryError> {
    if bounded(values) {
        return Ok(());
    }
    match values
        .iter()
        .position(|v| !v.wide().is_finite() || v.wide().abs() > MAX_COORDINATE)
    {
        None => Ok(()),
        Some(i) => Err(QueryError::invalid(
            name,
            format!(
                "row {} holds {}, not a finite number within ±{MAX_COORDINATE:e}",
                i / 3,
                values[i]
            ),
        )),
    }
}

/// How a query runs.
#[derive(Clone, Copy, Debug, Default)]
pub struct QueryOptions<'a> {
    /// Worker threads (1 to 1024); `None`: rayon's global pool (one per
    /// core). The answers are the same for any count.
    pub threads: Option<usize>,
    /// Raised by another thread to stop the query, which then returns
    /// [`QueryError::Cancelled`] (checked between batches of rays).
    pub cancel: Option<&'a AtomicBool>,
}

impl QueryOptions<'_> {
    pub(crate) fn cancelled(&self) -> bool {
        self.cancel.is_some_and(|c| c.load(Ordering::Relaxed))
    }

    /// Runs `job` on a pool of the chosen size: rayon's global pool when
    /// it has that many threads, else one built on first use and kept
    /// for the queries after (see [`pool`]).
    pub(crate) fn run<T: Send>(
        &self,
        job: impl FnOnce() -> Result<T, QueryError> + Send,
    ) -> Result<T, QueryError> {
        match self.threads {
            None => job(),
            Some(n) if n == 0 || n > MAX_THREADS as usize => Err(QueryError::invalid(
                "threads",
                format!("must be between 1 and {MAX_THREADS}, got {n}"),
            )),
            // Outside any pool, current_num_threads is the global pool's.
            Some(n)
                if rayon::current_thread_index().is_none() && n == rayon::current_num_threads() =>
            {
                job()
            }
            Some(n) => pool(n)?.install(job),
        }
    }
}

/// Pools kept for thread counts other than the global pool's: building one
/// per query (spawning and joining its threads) cost the calling thread
/// before the work was shared.
const KEPT_POOLS: usize = 4;

/// The pool of `n` threads: the one kept, else a new one, kept in place of
/// the least recently used when `KEPT_POOLS` are kept (a query still on
/// that one holds it until it ends).
fn pool(n: usize) -> Result<Arc<rayon::ThreadPool>, QueryError> {
    static POOLS: Mutex<Vec<(usize, Arc<rayon::ThreadPool>)>> = Mutex::new(Vec::new());
    let mut pools = POOLS.lock().unwrap_or_else(PoisonError::into_inner);
    if let Some(i) = pools.iter().position(|(k, _)| *k == n) {
        let kept = pools.remove(i);
        let pool = Arc::clone(&kept.1);
        pools.push(kept);
        return Ok(pool);
    }
    let pool = Arc::new(
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .map_err(|e| QueryError::invalid("threads", e.to_string()))?,
    );
    if pools.len() == KEPT_POOLS {
        pools.remove(0);
    }
    pools.push((n, Arc::clone(&pool)));
    Ok(pool)
}

/// The nearest hit of each ray, as flat arrays indexed by ray; a ray that
/// hits nothing has t = +∞, mesh and triangle −1, u = v = 0 and a zero
/// normal.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Hits {
    /// Ray parameter of the hit.
    pub t: Vec<f64>,
    /// Id of the mesh hit (−1: none).
    pub mesh_id: Vec<i64>,
    /// Index of the triangle hit in its mesh's face list (−1: none).
    pub triangle_id: Vec<i64>,
    /// Barycentric weight of the triangle's second vertex: the hit is
    /// (1 − u − v)·a + u·b + v·c.
    pub u: Vec<f64>,
    /// Barycentric weight of the third vertex.
    pub v: Vec<f64>,
    /// Unit geometric normal (right-hand rule of the face's vertex order,
    /// through the mesh's transform), `x, y, z` per ray.
    pub normal: Vec<f64>,
}

impl Hits {
    /// The arrays as [`HitsMut`], for [`RayScene::intersect_into`].
    ///
    /// [`RayScene::intersect_into`]: super::RayScene::intersect_into
    pub fn as_mut(&mut self) -> HitsMut<'_> {
        HitsMut {
            t: &mut self.t,
            mesh_id: &mut self.mesh_id,
            triangle_id: &mut self.triangle_id,
            u: &mut self.u,
            v: &mut self.v,
            normal: &mut self.normal,
        }
    }
}

/// Arrays of the caller's for [`RayScene::intersect_into`] to write the
/// nearest hits into, as [`Hits`] holds them: one entry per ray (the
/// normal three), every entry written, whatever it held before. A caller
/// that queries again and again can so reuse one set of arrays: memory
/// fresh from the system is faulted in at its first write, which for a
/// million rays' answers (64 MB) can take longer than the query.
///
/// [`RayScene::intersect_into`]: super::RayScene::intersect_into
#[derive(Debug)]
pub struct HitsMut<'a> {
    /// See [`Hits::t`].
    pub t: &'a mut [f64],
    /// See [`Hits::mesh_id`].
    pub mesh_id: &'a mut [i64],
    /// See [`Hits::triangle_id`].
    pub triangle_id: &'a mut [i64],
    /// See [`Hits::u`].
    pub u: &'a mut [f64],
    /// See [`Hits::v`].
    pub v: &'a mut [f64],
    /// See [`Hits::normal`]: `x, y, z` per ray.
    pub normal: &'a mut [f64],
}

/// Every hit of each ray, sorted by t (ties by mesh id, then triangle),
/// as flat arrays: ray k's hits are entries `offsets[k]..offsets[k + 1]`.
/// A ray through an edge or vertex hits each triangle that holds it (the
/// watertight test never misses them all), so it lists each.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Crossings {
    /// N + 1 offsets into the other arrays.
    pub offsets: Vec<i64>,
    /// Ray parameter of each hit.
    pub t: Vec<f64>,
    /// Mesh id of each hit.
    pub mesh_id: Vec<i64>,
    /// Triangle index of each hit.
    pub triangle_id: Vec<i64>,
    /// Barycentric u of each hit (see [`Hits::u`]).
    pub u: Vec<f64>,
    /// Barycentric v of each hit.
    pub v: Vec<f64>,
}
