//! The ray queries of [`RayScene`]: nearest hit, any hit, every hit. The
//! first three take rays in runs of [`SPAN`]: a run whose directions share
//! their signs is first tested as one span against each mesh's tree, and
//! answered as misses when it reaches no leaf (a camera's rays beside the
//! meshes). The rest go in groups of eight; a coherent group (nearly
//! parallel rays from nearby origins: a camera's, a lidar's) goes through
//! each mesh's tree as a packet, an incoherent one through a large mesh as
//! a stream (each ray's next reads prefetched while the others step),
//! otherwise ray by ray. In a scene of one untransformed mesh the
//! incoherent groups skip the group's copies: their rays are traced one
//! by one, or, beyond the cache, left for streams of [`STREAM`] rays at
//! the end of their chunk. Each path gives, to the bit, the hit the
//! renderer's `Mesh::intersect` gives that ray alone, so the choice
//! changes only the speed. So does the order the rays are traced in: a
//! large batch of scattered rays through a mesh beyond the cache is sorted
//! first (see `query::order`), its answers put back in the rays' order.

use std::sync::{Mutex, PoisonError};

use glam::DVec3;
use rayon::prelude::*;

use super::QueryError;
use super::order::{Gathered, TraceOrder, chunk_rays, sorted_order, unsort};
use super::rays::{Crossings, Hits, HitsMut, QueryOptions, RayChunk, Rays};
use super::scene::{Placed, RayScene};
use super::tiles::{TiledChunk, Tiles};
use crate::accel::{NodePacket, PACKET, prefetch};
use crate::geometry::Aabb;
use crate::geometry::cuboid::slab_interval;
use crate::geometry::mesh::{FacetHit, Mesh, STREAM};
use crate::geometry::triangle::axis_permutation;
use crate::huge_pages;

/// Rays per task, and between checks of the cancel flag.
const CHUNK: usize = 1024;

/// Rays per bulk test of the meshes' trees (`RayScene::span_misses`):
/// beside a mesh, a camera's rows hold long runs of rays that meet
/// nothing, which then cost a few node tests between them rather than a
/// packet's set-up and search each eight.
const SPAN: usize = 32;

/// Scenes of more meshes than this are not tested by spans (a search per
/// mesh per span).
const SPAN_MESHES: usize = 8;

// Spans hold whole groups, so the groups are those without spans.
const _: () = assert!(CHUNK.is_multiple_of(SPAN) && SPAN.is_multiple_of(PACKET));

/// How many rays ahead the answers traced in an order of the query's own
/// are asked for as they are put back in the rays' order.
const UNSORT_AHEAD: usize = 16;

/// A mesh whose tree and triangles take more than this goes through
/// streams for incoherent rays (it no longer fits the cache, so hiding
/// its misses pays; `Mesh::intersect_stream`).
const STREAM_BYTES: usize = 8 << 20;

/// The nearest hit of one ray so far.
#[derive(Clone, Copy, Debug)]
struct Nearest {
    t: f64,
    mesh: u32,
    hit: Option<FacetHit>,
}

const MISS: Nearest = Nearest {
    t: f64::INFINITY,
    mesh: u32::MAX,
    hit: None,
};

/// One ray's answer to a nearest-hit query, the fields of [`Hits`] in one
/// cache line: how the answers of rays traced in an order of the query's
/// own wait to be put back in the rays' order (one line read per ray).
#[derive(Clone, Copy, Debug)]
#[repr(align(64))]
struct Answer {
    t: f64,
    u: f64,
    v: f64,
    normal: [f64; 3],
    mesh_id: i64,
    triangle_id: i64,
}

/// The answer of a hit `h` on mesh `mesh`, its normal `normal` in world
/// space.
#[inline(always)]
fn answer(mesh: u32, h: &FacetHit, normal: DVec3) -> Answer {
    Answer {
        t: h.t,
        u: h.barycentric.y,
        v: h.barycentric.z,
        normal: normal.to_array(),
        mesh_id: i64::from(mesh),
        triangle_id: i64::from(h.triangle),
    }
}

/// A miss: u, v and the normal zero.
const NO_HIT: Answer = Answer {
    t: f64::INFINITY,
    u: 0.0,
    v: 0.0,
    normal: [0.0; 3],
    mesh_id: -1,
    triangle_id: -1,
};

/// Where a chunk's nearest-hit answers go.
trait AnswerSink {
    /// Rays in the chunk.
    fn len(&self) -> usize;
    /// Sets the answer of the chunk's ray `i`.
    fn put(&mut self, i: usize, answer: &Answer);
    /// Sets the answers of the chunk's rays `range` to misses.
    fn misses(&mut self, range: std::ops::Range<usize>) {
        range.for_each(|i| self.put(i, &NO_HIT));
    }
}

impl AnswerSink for &mut [Answer] {
    fn len(&self) -> usize {
        <[Answer]>::len(self)
    }
    #[inline(always)]
    fn put(&mut self, i: usize, answer: &Answer) {
        self[i] = *answer;
    }
}

/// The waiting answers of the last sorted nearest-hit query (one 64-byte
/// record a ray), kept for the next: memory new to the process is
/// faulted in at its first write, 64 MB for a million rays, which took a
/// tenth of such a query's time (15 Ki faults a query) when each chunk
/// wrote into a vector of its own.
static WAITING: Mutex<Vec<Answer>> = Mutex::new(Vec::new());

/// Waiting answers kept at most between queries (128 MiB); a larger
/// query's are let go.
const KEEP_WAITING: usize = 1 << 21;

/// What the answer arrays hold before a query writes them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Written {
    /// Zeros (`intersect`'s own arrays): a miss's u, v and normal are so
    /// already.
    Zeros,
    /// Anything (a caller's, reused): every field is written.
    Anything,
}

/// A chunk of the arrays of [`HitsMut`].
struct HitsChunk<'h> {
    t: &'h mut [f64],
    mesh_id: &'h mut [i64],
    triangle_id: &'h mut [i64],
    u: &'h mut [f64],
    v: &'h mut [f64],
    normal: &'h mut [f64],
    held: Written,
}

impl AnswerSink for HitsChunk<'_> {
    fn len(&self) -> usize {
        self.t.len()
    }
    #[inline(always)]
    fn put(&mut self, i: usize, a: &Answer) {
        self.t[i] = a.t;
        self.mesh_id[i] = a.mesh_id;
        self.triangle_id[i] = a.triangle_id;
        self.u[i] = a.u;
        self.v[i] = a.v;
        self.normal[3 * i..3 * i + 3].copy_from_slice(&a.normal);
    }
    #[inline(always)]
    fn misses(&mut self, range: std::ops::Range<usize>) {
        for i in range {
            match self.held {
                Written::Zeros => {
                    self.t[i] = f64::INFINITY;
                    self.mesh_id[i] = -1;
                    self.triangle_id[i] = -1;
                }
                Written::Anything => self.put(i, &NO_HIT),
            }
        }
    }
}

/// One hit of an all-hits query.
#[derive(Clone, Copy, Debug)]
struct Crossing {
    t: f64,
    mesh: u32,
    triangle: u32,
    barycentric: DVec3,
}

impl RayScene {
    /// The nearest hit of each ray with t in (t_min, t_max): of triangles
    /// hit at the same t, the one first in its mesh's face list, and of
    /// meshes, the lowest id.
    pub fn intersect(&self, rays: &Rays, options: &QueryOptions) -> Result<Hits, QueryError> {
        let n = rays.len();
        // Zeros, which the allocator takes from the system as they are (no
        // pass over them here): each worker faults in and writes its own
        // chunks, 2 MiB at a time where the memory is fresh from the
        // system (`huge_pages::zeros`).
        let mut hits = Hits {
            t: huge_pages::zeros(0.0, n),
            mesh_id: huge_pages::zeros(0, n),
            triangle_id: huge_pages::zeros(0, n),
            u: huge_pages::zeros(0.0, n),
            v: huge_pages::zeros(0.0, n),
            normal: huge_pages::zeros(0.0, 3 * n),
        };
        let order = self.trace_order(rays, options)?;
        self.intersect_in(rays, order.as_ref(), hits.as_mut(), Written::Zeros, options)?;
        Ok(hits)
    }

    /// [`intersect`](Self::intersect) into the caller's arrays, each of
    /// one entry per ray (`normal` three); each entry is written, a miss's
    /// too. Arrays of other lengths are an `Invalid` error naming the
    /// array (`t`, `mesh_id`, ...), and nothing is written.
    pub fn intersect_into(
        &self,
        rays: &Rays,
        out: HitsMut<'_>,
        options: &QueryOptions,
    ) -> Result<(), QueryError> {
        let n = rays.len();
        for (name, len, per_ray) in [
            ("t", out.t.len(), 1),
            ("mesh_id", out.mesh_id.len(), 1),
            ("triangle_id", out.triangle_id.len(), 1),
            ("u", out.u.len(), 1),
            ("v", out.v.len(), 1),
            ("normal", out.normal.len(), 3),
        ] {
            if len != per_ray * n {
                return Err(QueryError::invalid(
                    name,
                    format!(
                        "must hold {} entries for {n} rays, holds {len}",
                        per_ray * n
                    ),
                ));
            }
        }
        let order = self.trace_order(rays, options)?;
        self.intersect_in(rays, order.as_ref(), out, Written::Anything, options)
    }

    /// [`intersect_into`](Self::intersect_into) with the rays traced in
    /// `order`, or as given.
    fn intersect_in(
        &self,
        rays: &Rays,
        order: Option<&TraceOrder>,
        out: HitsMut<'_>,
        held: Written,
        options: &QueryOptions,
    ) -> Result<(), QueryError> {
        let n = rays.len();
        let scale = self.bounds().diagonal();
        let chunk = chunk_len(order);
        let HitsMut {
            t,
            mesh_id,
            triangle_id,
            u,
            v,
            normal,
        } = out;
        let chunks = t
            .par_chunks_mut(chunk)
            .zip(mesh_id.par_chunks_mut(chunk))
            .zip(triangle_id.par_chunks_mut(chunk))
            .zip(u.par_chunks_mut(chunk))
            .zip(v.par_chunks_mut(chunk))
            .zip(normal.par_chunks_mut(3 * chunk))
            .map(
                |(((((t, mesh_id), triangle_id), u), v), normal)| HitsChunk {
                    t,
                    mesh_id,
                    triangle_id,
                    u,
                    v,
                    normal,
                    held,
                },
            )
            .enumerate();
        // Written in place, chunk by chunk (a vector of whole hits would
        // be three times the answer's size to fault in and read back),
        // tiles' answers each to its ray's place.
        let slot = match order {
            Some(TraceOrder::Sorted(sorted)) => &sorted.slot,
            _ => {
                options.run(|| {
                    chunks.try_for_each(|(c, mut out)| {
                        let first = c * chunk;
                        match order {
                            Some(TraceOrder::Tiled(tiles)) => {
                                let mut out = InTiles::new(out, tiles);
                                self.nearest_chunk(rays, order, first, &mut out, scale, options)
                            }
                            _ => self.nearest_chunk(rays, order, first, &mut out, scale, options),
                        }
                    })
                })?;
                return Ok(());
            }
        };
        // Each chunk's answers wait in its piece of one vector of whole
        // answers, kept from query to query (see `WAITING`), then each
        // ray's is read back from its slot: one cache line a ray.
        let mut waiting =
            std::mem::take(&mut *WAITING.lock().unwrap_or_else(PoisonError::into_inner));
        options.run(|| {
            if waiting.len() < n {
                // Written by the workers, each its own part.
                (0..n)
                    .into_par_iter()
                    .map(|_| NO_HIT)
                    .collect_into_vec(&mut waiting);
            }
            let waiting = &mut waiting[..n];
            waiting
                .par_chunks_mut(CHUNK)
                .enumerate()
                .try_for_each(|(c, mut out)| {
                    self.nearest_chunk(rays, order, c * CHUNK, &mut out, scale, options)
                })?;
            let waiting = &*waiting;
            chunks
                .zip(slot.par_chunks(CHUNK))
                .for_each(|((_, mut out), slots)| {
                    for (i, &s) in slots.iter().enumerate() {
                        // The answers' random reads, asked for ahead.
                        if let Some(&ahead) = slots.get(i + UNSORT_AHEAD) {
                            prefetch(&waiting[ahead as usize]);
                        }
                        out.put(i, &waiting[s as usize]);
                    }
                });
            Ok(())
        })?;
        if waiting.len() <= KEEP_WAITING {
            *WAITING.lock().unwrap_or_else(PoisonError::into_inner) = waiting;
        }
        Ok(())
    }

    /// The nearest hits of the chunk of `out.len()` rays from `first` as
    /// `order` has them (see `chunk_rays`), into `out` (entry k for the
    /// chunk's k-th traced).
    fn nearest_chunk(
        &self,
        rays: &Rays,
        order: Option<&TraceOrder>,
        first: usize,
        out: &mut impl AnswerSink,
        scale: f64,
        options: &QueryOptions,
    ) -> Result<(), QueryError> {
        if options.cancelled() {
            return Err(QueryError::Cancelled);
        }
        let mut gathered = Gathered::default();
        let (rays, base) = chunk_rays(rays, order, first, out.len(), &mut gathered)?;
        let rays = &rays;
        let single = self.single_mesh();
        let mut alone = ByAxes::new();
        self.runs(rays, base, out.len(), |block, end, may_hit| {
            if !may_hit {
                out.misses(block..end);
                return;
            }
            for first in (block..end).step_by(PACKET) {
                let count = PACKET.min(end - first);
                let coherent = coherent(count, |k| rays.ray(base + first + k), scale);
                if let Some((mesh, beyond_cache)) = single
                    && !coherent
                {
                    if beyond_cache {
                        (first..first + count).for_each(|k| alone.push_in_order(k));
                        continue;
                    }
                    // Straight from the rays to the answers, in their
                    // order: no group's copies of the rays and of their
                    // hits. (Taken a permutation at a time, as `occluded`
                    // takes them, with the search compiled per
                    // permutation, they were slower: 166 against 157 ms
                    // on the bench's bunny, its answers then written
                    // out of order.)
                    for k in first..first + count {
                        let (o, d) = rays.ray(base + k);
                        match mesh.intersect_facet(o, d, rays.t_min, rays.t_max) {
                            Some(h) => out.put(k, &answer(0, &h, h.normal)),
                            None => out.misses(k..k + 1),
                        }
                    }
                    continue;
                }
                let mut group = [MISS; PACKET];
                let group = &mut group[..count];
                self.nearest_group(rays, base + first, group, coherent);
                for (k, near) in group.iter().enumerate() {
                    let Some(h) = near.hit else {
                        out.misses(first + k..first + k + 1);
                        continue;
                    };
                    let world = self.meshes[near.mesh as usize].world_normal(h.normal);
                    out.put(first + k, &answer(near.mesh, &h, world));
                }
            }
        });
        // Those left of a mesh beyond the cache, STREAM at a time.
        if let Some((mesh, true)) = single {
            alone.streams(|ks| {
                let (world, t_max) = stream_rays(rays, base, ks);
                let mut hits = [None; STREAM];
                let hits = &mut hits[..ks.len()];
                mesh.intersect_facet_stream(
                    &world[..ks.len()],
                    rays.t_min,
                    &t_max[..ks.len()],
                    hits,
                );
                for (&k, h) in ks.iter().zip(hits) {
                    let k = usize::from(k);
                    match h {
                        Some(h) => out.put(k, &answer(0, h, h.normal)),
                        None => out.misses(k..k + 1),
                    }
                }
            });
        }
        Ok(())
    }

    /// The mesh of a scene of one untransformed mesh, and whether it lies
    /// beyond the cache (`STREAM_BYTES`): its incoherent rays are left to
    /// be traced one by one (within the cache) or in streams of their own
    /// (beyond it), without the groups' copies of the rays, of their hits
    /// and their box tests (`nearest_group` would do no more than that
    /// for them). Asked once per chunk.
    fn single_mesh(&self) -> Option<(&Mesh, bool)> {
        match self.meshes.as_slice() {
            [placed] if placed.transform.is_none() => {
                Some((&placed.mesh, placed.mesh.memory_bytes() > STREAM_BYTES))
            }
            _ => None,
        }
    }

    /// The any-hit and counting queries' answers (a miss's is
    /// `T::default()`), chunk by chunk (see `each_chunk`): the rays in
    /// groups of eight; a group of incoherent rays through the mesh of
    /// `single_mesh` is left alone (a permutation at a time within the
    /// cache, in its order beyond it), the others go to `group` (the
    /// chunk's rays from their first, the group's first index and its
    /// answers, whether it is coherent, the rays it leaves alone). Then
    /// the rays left alone go one by one to `one` (mesh, origin,
    /// direction), or [`STREAM`] at a time to `stream` (mesh, rays,
    /// limits, answers).
    fn in_groups<T: Copy + Default + Send + Sync>(
        &self,
        rays: &Rays,
        order: Option<&TraceOrder>,
        options: &QueryOptions,
        group: impl Fn(&RayChunk, usize, usize, &mut [T], bool, &mut ByAxes) + Sync,
        one: impl Fn(&Mesh, DVec3, DVec3) -> T + Sync,
        stream: impl Fn(&Mesh, &[(DVec3, DVec3)], &[f64], &mut [T]) + Sync,
    ) -> Result<Vec<T>, QueryError> {
        let scale = self.bounds().diagonal();
        self.each_chunk(rays, order, options, |rays, base, out: &mut [T]| {
            self.answer_chunk(rays, base, out, scale, &group, &one, &stream);
        })
    }

    /// [`in_groups`](Self::in_groups) for the chunk's rays from `base`,
    /// into `out`.
    #[allow(clippy::too_many_arguments)]
    fn answer_chunk<T: Copy + Default>(
        &self,
        rays: &RayChunk,
        base: usize,
        out: &mut [T],
        scale: f64,
        group: &impl Fn(&RayChunk, usize, usize, &mut [T], bool, &mut ByAxes),
        one: &impl Fn(&Mesh, DVec3, DVec3) -> T,
        stream: &impl Fn(&Mesh, &[(DVec3, DVec3)], &[f64], &mut [T]),
    ) {
        let single = self.single_mesh();
        let mut alone = ByAxes::new();
        self.runs(rays, base, out.len(), |block, end, may_hit| {
            if !may_hit {
                return;
            }
            for (g, answers) in out[block..end].chunks_mut(PACKET).enumerate() {
                let first = block + g * PACKET;
                let n = answers.len();
                let coherent = coherent(n, |k| rays.ray(base + first + k), scale);
                match single {
                    Some((_, true)) if !coherent => {
                        (first..first + n).for_each(|k| alone.push_in_order(k));
                    }
                    Some((_, false)) if !coherent => {
                        (first..first + n).for_each(|k| alone.push(k, rays.ray(base + k).1));
                    }
                    _ => group(rays, base, first, answers, coherent, &mut alone),
                }
            }
        });
        match single {
            Some((mesh, true)) => alone.streams(|ks| {
                let (world, t_max) = stream_rays(rays, base, ks);
                let n = ks.len();
                let mut answers = [T::default(); STREAM];
                stream(mesh, &world[..n], &t_max[..n], &mut answers[..n]);
                for (&k, &a) in ks.iter().zip(&answers[..n]) {
                    out[usize::from(k)] = a;
                }
            }),
            Some((mesh, false)) => alone.each(|k| {
                let (o, d) = rays.ray(base + k);
                out[k] = one(mesh, o, d);
            }),
            None => {}
        }
    }

    /// Whether each ray hits anything with t in (t_min, t_max).
    pub fn occluded(&self, rays: &Rays, options: &QueryOptions) -> Result<Vec<bool>, QueryError> {
        let order = self.trace_order(rays, options)?;
        self.occluded_in(rays, order.as_ref(), options)
    }

    /// [`occluded`](Self::occluded) with the rays traced in `order`, or
    /// as given.
    fn occluded_in(
        &self,
        rays: &Rays,
        order: Option<&TraceOrder>,
        options: &QueryOptions,
    ) -> Result<Vec<bool>, QueryError> {
        // Rays that meet nothing stay unblocked.
        let (t_min, t_max) = (rays.t_min, rays.t_max);
        self.in_groups(
            rays,
            order,
            options,
            |rays, chunk, first, out, coherent, alone| {
                self.blocked_group(rays, chunk, first, out, coherent, alone)
            },
            |mesh, o, d| mesh.any_hit(o, d, t_min, t_max),
            |mesh, world, limits, out| {
                let blocked = mesh.any_hit_stream(world, t_min, limits);
                for (i, b) in out.iter_mut().enumerate() {
                    *b = blocked & (1 << i) != 0;
                }
            },
        )
    }

    /// How many triangles each ray hits with t in (t_min, t_max) (a ray
    /// through an edge or vertex counts each triangle that holds it).
    pub fn count_intersections(
        &self,
        rays: &Rays,
        options: &QueryOptions,
    ) -> Result<Vec<u32>, QueryError> {
        let order = self.trace_order(rays, options)?;
        self.count_in(rays, order.as_ref(), options)
    }

    /// [`count_intersections`](Self::count_intersections) with the rays
    /// traced in `order`, or as given.
    fn count_in(
        &self,
        rays: &Rays,
        order: Option<&TraceOrder>,
        options: &QueryOptions,
    ) -> Result<Vec<u32>, QueryError> {
        // Rays that meet nothing keep a count of 0.
        let (t_min, t_max) = (rays.t_min, rays.t_max);
        self.in_groups(
            rays,
            order,
            options,
            |rays, chunk, first, out, coherent, alone| {
                self.count_group(rays, chunk, first, out, coherent, alone)
            },
            |mesh, o, d| mesh.count_hits(o, d, t_min, t_max),
            |mesh, world, limits, out| mesh.count_hits_stream(world, t_min, limits, out),
        )
    }

    /// One answer per ray, each piece of at most [`CHUNK`] rays answered
    /// by `trace(rays, base, out)` (the piece's rays from `base` of
    /// `rays`, its answers into `out`), a chunk of rays on a worker at a
    /// time as `order` has them (see `chunk_rays`); the answers in the
    /// rays' order.
    fn each_chunk<T: Copy + Default + Send + Sync>(
        &self,
        rays: &Rays,
        order: Option<&TraceOrder>,
        options: &QueryOptions,
        trace: impl Fn(&RayChunk, usize, &mut [T]) + Sync,
    ) -> Result<Vec<T>, QueryError> {
        let mut answers = huge_pages::zeros(T::default(), rays.len());
        let chunk = chunk_len(order);
        options.run(|| {
            answers
                .par_chunks_mut(chunk)
                .enumerate()
                .try_for_each(|(c, out)| {
                    if options.cancelled() {
                        return Err(QueryError::Cancelled);
                    }
                    let len = out.len();
                    let mut gathered = Gathered::default();
                    let (rays, base) = chunk_rays(rays, order, c * chunk, len, &mut gathered)?;
                    // Tiles' answers wait in their order, then go each to
                    // its ray's place.
                    let tiles = match order {
                        Some(TraceOrder::Tiled(tiles)) => Some(tiles),
                        _ => None,
                    };
                    let mut in_tiles = Vec::new();
                    let traced = match tiles {
                        Some(_) => {
                            in_tiles.resize(len, T::default());
                            &mut in_tiles[..]
                        }
                        None => &mut *out,
                    };
                    for (p, piece) in traced.chunks_mut(CHUNK).enumerate() {
                        trace(&rays, base + p * CHUNK, piece);
                    }
                    if let Some(tiles) = tiles {
                        let mut p = 0;
                        tiles.chunk(len).runs(0..len, |first, count| {
                            out[first..first + count].copy_from_slice(&in_tiles[p..p + count]);
                            p += count;
                        });
                    }
                    Ok(())
                })
        })?;
        match order {
            Some(TraceOrder::Sorted(sorted)) => options.run(|| Ok(unsort(&answers, &sorted.slot))),
            _ => Ok(answers),
        }
    }

    /// The order to trace `rays` in, or `None` for as given: sorted (see
    /// `query::order`) where the rays are scattered and the scene has a
    /// mesh beyond the cache (`STREAM_BYTES`), where what the order keeps
    /// in the cache pays for sorting, gathering the rays and putting their
    /// answers back (a cache-resident mesh's rays, the bench's
    /// 3,674-triangle bunny, lost 6–26 % of their time to those); in tiles
    /// where they are a camera's rows (see `query::tiles`).
    fn trace_order(
        &self,
        rays: &Rays,
        options: &QueryOptions,
    ) -> Result<Option<TraceOrder>, QueryError> {
        let beyond_cache = self
            .meshes
            .iter()
            .any(|m| m.mesh.memory_bytes() > STREAM_BYTES);
        if beyond_cache && let Some(sorted) = sorted_order(rays, self.bounds(), options)? {
            return Ok(Some(TraceOrder::Sorted(sorted)));
        }
        let tiles = Tiles::find(rays, CHUNK, self.bounds().diagonal());
        Ok(tiles.map(TraceOrder::Tiled))
    }

    /// Every hit of each ray with t in (t_min, t_max), sorted by t (ties
    /// by mesh id, then triangle index).
    pub fn all_intersections(
        &self,
        rays: &Rays,
        options: &QueryOptions,
    ) -> Result<Crossings, QueryError> {
        let n = rays.len();
        let parts: Vec<(Vec<u32>, Vec<Crossing>)> = options.run(|| {
            (0..n.div_ceil(CHUNK))
                .into_par_iter()
                .map(|c| {
                    if options.cancelled() {
                        return Err(QueryError::Cancelled);
                    }
                    let first = c * CHUNK;
                    rays.check_chunk(first, CHUNK.min(n - first))?;
                    let mut counts = Vec::new();
                    let mut all = Vec::new();
                    for k in c * CHUNK..((c + 1) * CHUNK).min(n) {
                        let start = all.len();
                        self.crossings(rays, k, |x| all.push(x));
                        all[start..].sort_by(|a: &Crossing, b: &Crossing| {
                            a.t.total_cmp(&b.t)
                                .then(a.mesh.cmp(&b.mesh))
                                .then(a.triangle.cmp(&b.triangle))
                        });
                        counts.push((all.len() - start) as u32);
                    }
                    Ok((counts, all))
                })
                .collect()
        })?;
        let total = parts.iter().map(|p| p.1.len()).sum();
        let mut out = Crossings {
            offsets: Vec::with_capacity(n + 1),
            t: Vec::with_capacity(total),
            mesh_id: Vec::with_capacity(total),
            triangle_id: Vec::with_capacity(total),
            u: Vec::with_capacity(total),
            v: Vec::with_capacity(total),
        };
        out.offsets.push(0);
        let mut offset = 0i64;
        for (counts, all) in parts {
            for c in counts {
                offset += i64::from(c);
                out.offsets.push(offset);
            }
            for x in all {
                out.t.push(x.t);
                out.mesh_id.push(i64::from(x.mesh));
                out.triangle_id.push(i64::from(x.triangle));
                out.u.push(x.barycentric.y);
                out.v.push(x.barycentric.z);
            }
        }
        Ok(out)
    }

    /// Calls `each(start, end, may_hit)` for the runs of [`SPAN`] rays
    /// (counted from `chunk`) that cover rays `chunk..chunk + len`, in
    /// order: `may_hit` is false where [`span_misses`](Self::span_misses)
    /// rules the run out.
    fn runs(
        &self,
        rays: &RayChunk,
        chunk: usize,
        len: usize,
        mut each: impl FnMut(usize, usize, bool),
    ) {
        // Scenes spans do not apply to, told once per chunk: more meshes
        // than SPAN_MESHES, or a transformed one (its rays are traced in
        // the mesh's own space).
        let spans =
            self.meshes.len() <= SPAN_MESHES && self.meshes.iter().all(|m| m.transform.is_none());
        for start in (0..len).step_by(SPAN) {
            let end = (start + SPAN).min(len);
            let missed = spans && self.span_misses(rays, chunk + start, end - start);
            each(start, end, !missed);
        }
    }

    /// Whether rays `first..first + n` certainly hit nothing: the range
    /// of their origins and directions, axis by axis, as one node packet
    /// (`NodePacket::spanning`), reaches no leaf of any mesh's tree
    /// (`Mesh::span_may_meet`: a few node tests from the root), its test
    /// letting through every box one of the rays' own tests would. Only runs
    /// whose directions share their signs are tested (a camera's or a
    /// lidar's; incoherent ones are told by their first four rays). The
    /// meshes must be untransformed (see [`runs`](Self::runs)).
    fn span_misses(&self, rays: &RayChunk, first: usize, n: usize) -> bool {
        let Some([origin_lo, origin_hi, direction_lo, direction_hi]) = rays.span(first, n) else {
            return false;
        };
        // Directions of unlike signs on an axis (past the first four rays)
        // are refused here.
        let Some(span) = NodePacket::spanning(origin_lo, origin_hi, direction_lo, direction_hi)
        else {
            return false;
        };
        !self
            .meshes
            .iter()
            .any(|placed| placed.mesh.span_may_meet(&span, rays.t_max))
    }

    /// The nearest hits of rays `first..first + out.len()` (at most
    /// [`PACKET`]), `coherent` when they are worth a packet (see
    /// `coherent`).
    fn nearest_group(&self, rays: &RayChunk, first: usize, out: &mut [Nearest], coherent: bool) {
        let n = out.len();
        let world: [(DVec3, DVec3); PACKET] = gather(rays, first, n);
        // Rays through a scene of one mesh leave the box test to its
        // tree's root (a ray that misses the box finds no hit there
        // either; a packet's root test drops such rays as the box test
        // would).
        let skip_box = self.meshes.len() == 1;
        for (id, placed) in self.meshes.iter().enumerate() {
            let (reach, live) =
                reach_into::<PACKET>(placed, &world[..n], rays.t_min, skip_box, |k| {
                    Some(out[k].t.min(rays.t_max))
                });
            if live == 0 {
                continue;
            }
            let moved: [(DVec3, DVec3); PACKET];
            let local = match placed.transform {
                None => &world,
                Some(_) => {
                    moved = std::array::from_fn(|k| placed.local(world[k].0, world[k].1));
                    &moved
                }
            };
            let mut found = [None; PACKET];
            let mesh = &placed.mesh;
            if coherent && live > 1 {
                mesh.intersect_facet_packet(&local[..n], rays.t_min, &reach[..n], &mut found[..n]);
            } else if live > 1 && mesh.memory_bytes() > STREAM_BYTES {
                mesh.intersect_facet_stream(&local[..n], rays.t_min, &reach[..n], &mut found[..n]);
            } else {
                for k in (0..n).filter(|&k| reach[k] > f64::NEG_INFINITY) {
                    found[k] = mesh.intersect_facet(local[k].0, local[k].1, rays.t_min, reach[k]);
                }
            }
            for (near, hit) in out.iter_mut().zip(found) {
                // Strictly nearer than what is held (each search stopped
                // short of it), so a lower id keeps a tie.
                if let Some(h) = hit {
                    *near = Nearest {
                        t: h.t,
                        mesh: id as u32,
                        hit: Some(h),
                    };
                }
            }
        }
    }

    /// Whether rays `chunk + first..chunk + first + out.len()` are
    /// blocked; rays of a scene of one mesh without a transform to be
    /// traced alone are left in `alone` (by their index in the chunk).
    // Not inlined into the chunk's loop: inlined there it took 2 % more
    // instructions on incoherent rays.
    #[inline(never)]
    fn blocked_group(
        &self,
        rays: &RayChunk,
        chunk: usize,
        first: usize,
        out: &mut [bool],
        coherent: bool,
        alone: &mut ByAxes,
    ) {
        let n = out.len();
        let world: [(DVec3, DVec3); PACKET] = gather(rays, chunk + first, n);
        // As in `nearest_group`.
        let skip_box = self.meshes.len() == 1;
        for placed in &self.meshes {
            // Rays already blocked are done.
            let (reach, live) =
                reach_into::<PACKET>(placed, &world[..n], rays.t_min, skip_box, |k| {
                    (!out[k]).then_some(rays.t_max)
                });
            if live == 0 {
                continue;
            }
            let moved: [(DVec3, DVec3); PACKET];
            let local = match placed.transform {
                None => &world,
                Some(_) => {
                    moved = std::array::from_fn(|k| placed.local(world[k].0, world[k].1));
                    &moved
                }
            };
            if coherent && live > 1 {
                let mask = placed
                    .mesh
                    .any_hit_packet(&local[..n], rays.t_min, &reach[..n]);
                for (k, b) in out.iter_mut().enumerate() {
                    *b |= mask & (1 << k) != 0;
                }
            } else if live > 1 && placed.mesh.memory_bytes() > STREAM_BYTES {
                let mask = placed
                    .mesh
                    .any_hit_stream(&local[..n], rays.t_min, &reach[..n]);
                for (k, b) in out.iter_mut().enumerate() {
                    *b |= mask & (1 << k) != 0;
                }
            } else if skip_box && placed.transform.is_none() {
                // Every ray reaches the one mesh with t_max (none held
                // back by a box test or an earlier mesh).
                for (k, &(_, d)) in world[..n].iter().enumerate() {
                    alone.push(first + k, d);
                }
            } else {
                for k in (0..n).filter(|&k| reach[k] > f64::NEG_INFINITY) {
                    out[k] = placed
                        .mesh
                        .any_hit(local[k].0, local[k].1, rays.t_min, reach[k]);
                }
            }
        }
    }

    /// The hit counts of rays `first..first + out.len()` (at most
    /// [`PACKET`]): coherent ones as a packet,
    /// incoherent ones through a large mesh in a stream, otherwise ray by
    /// ray. Every hit is counted, so the any-hit traversals serve (run to
    /// their ends), which sort no children.
    ///
    /// As in `blocked_group`, the rays start at `chunk + first`, and those
    /// of a scene of one mesh without a transform to be traced alone are
    /// left in `alone`.
    fn count_group(
        &self,
        rays: &RayChunk,
        chunk: usize,
        first: usize,
        out: &mut [u32],
        coherent: bool,
        alone: &mut ByAxes,
    ) {
        let n = out.len();
        let world: [(DVec3, DVec3); PACKET] = gather(rays, chunk + first, n);
        // As in `nearest_group`.
        let skip_box = self.meshes.len() == 1;
        for placed in &self.meshes {
            let (reach, live) =
                reach_into::<PACKET>(placed, &world[..n], rays.t_min, skip_box, |_| {
                    Some(rays.t_max)
                });
            if live == 0 {
                continue;
            }
            let moved: [(DVec3, DVec3); PACKET];
            let local = match placed.transform {
                None => &world,
                Some(_) => {
                    moved = std::array::from_fn(|k| placed.local(world[k].0, world[k].1));
                    &moved
                }
            };
            let mesh = &placed.mesh;
            if coherent && live > 1 {
                mesh.count_hits_packet(&local[..n], rays.t_min, &reach[..n], out);
            } else if live > 1 && mesh.memory_bytes() > STREAM_BYTES {
                mesh.count_hits_stream(&local[..n], rays.t_min, &reach[..n], out);
            } else if skip_box && placed.transform.is_none() {
                // Every ray reaches the one mesh with t_max, its count 0.
                for (k, &(_, d)) in world[..n].iter().enumerate() {
                    alone.push(first + k, d);
                }
            } else {
                for k in (0..n).filter(|&k| reach[k] > f64::NEG_INFINITY) {
                    let (o, d) = local[k];
                    let hits = mesh.count_hits(o, d, rays.t_min, reach[k]);
                    out[k] = out[k].saturating_add(hits);
                }
            }
        }
    }

    /// Calls `each` with every hit of ray `k`, mesh by mesh, in tree order.
    fn crossings(&self, rays: &Rays, k: usize, mut each: impl FnMut(Crossing)) {
        let (origin, direction) = rays.ray(k);
        let (t_min, t_max) = (rays.t_min, rays.t_max);
        for (id, placed) in self.meshes.iter().enumerate() {
            if !meets(&placed.bounds, origin, direction, t_min, t_max) {
                continue;
            }
            let (o, d) = placed.local(origin, direction);
            placed.mesh.each_hit(o, d, t_min, t_max, |triangle, h| {
                each(Crossing {
                    t: h.t,
                    mesh: id as u32,
                    triangle,
                    barycentric: h.barycentric,
                });
            });
        }
    }
}

/// Rays per chunk of a query traced in `order`.
fn chunk_len(order: Option<&TraceOrder>) -> usize {
    match order {
        Some(TraceOrder::Tiled(tiles)) => tiles.chunk_len(),
        _ => CHUNK,
    }
}

/// A chunk's nearest-hit answers in tiles, each put in its ray's place in
/// `sink`, which starts as misses (a tile's misses would be two runs of
/// four).
struct InTiles<'t, S> {
    sink: S,
    chunk: TiledChunk<'t>,
}

impl<'t, S: AnswerSink> InTiles<'t, S> {
    fn new(mut sink: S, tiles: &'t Tiles) -> Self {
        let len = sink.len();
        sink.misses(0..len);
        let chunk = tiles.chunk(len);
        InTiles { sink, chunk }
    }
}

impl<S: AnswerSink> AnswerSink for InTiles<'_, S> {
    fn len(&self) -> usize {
        self.sink.len()
    }
    #[inline(always)]
    fn put(&mut self, p: usize, answer: &Answer) {
        self.sink.put(self.chunk.ray(p), answer);
    }
    /// Misses already.
    fn misses(&mut self, _: std::ops::Range<usize>) {}
}

/// Rays of a chunk to be traced alone, by the watertight test's axis
/// permutation of each: the single-ray searches are compiled once per
/// permutation and branch to the ray's, which incoherent rays taken in
/// their order mispredict (one in six right), and each ray's search then
/// starts in code another permutation's may have left the cache.
struct ByAxes {
    rays: [[u16; CHUNK]; 6],
    count: [usize; 6],
}

// Ray indices within a chunk fit the u16 of `ByAxes`.
const _: () = assert!(CHUNK <= 1 << 16);

impl ByAxes {
    fn new() -> Self {
        ByAxes {
            rays: [[0; CHUNK]; 6],
            count: [0; 6],
        }
    }

    /// Leaves ray `k` (its index in the chunk), of direction `d`.
    #[inline(always)]
    fn push(&mut self, k: usize, d: DVec3) {
        let p = usize::from(axis_permutation(d));
        self.rays[p][self.count[p]] = k as u16;
        self.count[p] += 1;
    }

    /// Leaves ray `k` in the rays' order (for streams, which take any
    /// permutations; the order keeps a sorted batch's neighbours together).
    #[inline(always)]
    fn push_in_order(&mut self, k: usize) {
        self.rays[0][self.count[0]] = k as u16;
        self.count[0] += 1;
    }

    /// Calls `trace` with each ray left, a permutation after another.
    fn each(&self, mut trace: impl FnMut(usize)) {
        for (rays, &count) in self.rays.iter().zip(&self.count) {
            rays[..count].iter().for_each(|&k| trace(usize::from(k)));
        }
    }

    /// Calls `trace` with the rays left, [`STREAM`] at a time (fewer at
    /// the end of each permutation's).
    fn streams(&self, mut trace: impl FnMut(&[u16])) {
        for (rays, &count) in self.rays.iter().zip(&self.count) {
            rays[..count].chunks(STREAM).for_each(&mut trace);
        }
    }
}

/// Rays `first..first + n` of `rays` (n ≥ 1), lanes past the last
/// repeating it. A loop: `array::from_fn`'s closure stayed a call per ray,
/// its result passed through memory.
#[inline(always)]
fn gather<const N: usize>(rays: &RayChunk, first: usize, n: usize) -> [(DVec3, DVec3); N] {
    let mut world = [(DVec3::ZERO, DVec3::ZERO); N];
    for (k, ray) in world.iter_mut().enumerate() {
        *ray = rays.ray(first + k.min(n - 1));
    }
    world
}

/// The rays of the chunk's indices `ks` (at most [`STREAM`]), from
/// `base`, and their limits, for a mesh's stream.
#[inline(always)]
fn stream_rays(
    rays: &RayChunk,
    base: usize,
    ks: &[u16],
) -> ([(DVec3, DVec3); STREAM], [f64; STREAM]) {
    let mut world = [(DVec3::ZERO, DVec3::ZERO); STREAM];
    for (ray, &k) in world.iter_mut().zip(ks) {
        *ray = rays.ray(base + usize::from(k));
    }
    (world, [rays.t_max; STREAM])
}

/// How far each of `world`'s rays reaches into `placed`: `limit(k)`, or
/// −∞ (left out) where that is `None` or, unless `skip_box`, the ray misses
/// the mesh's box within it; and how many are not left out.
#[inline(always)]
fn reach_into<const N: usize>(
    placed: &Placed,
    world: &[(DVec3, DVec3)],
    t_min: f64,
    skip_box: bool,
    limit: impl Fn(usize) -> Option<f64>,
) -> ([f64; N], usize) {
    let mut reach = [f64::NEG_INFINITY; N];
    let mut live = 0;
    for (k, &(origin, direction)) in world.iter().enumerate() {
        if let Some(limit) = limit(k)
            && (skip_box || meets(&placed.bounds, origin, direction, t_min, limit))
        {
            reach[k] = limit;
            live += 1;
        }
    }
    (reach, live)
}

/// Whether the ray's stretch (t_min, t_max) may meet box `b`: the slab
/// test on the box grown by a billionth of its size, so that rounding in
/// the test never loses a triangle the watertight test would hit.
#[inline]
pub(crate) fn meets(b: &Aabb, origin: DVec3, direction: DVec3, t_min: f64, t_max: f64) -> bool {
    let pad = DVec3::splat(
        (b.max - b.min).max_element() * 1e-9
            + b.min.abs().max(b.max.abs()).max_element() * 1e-12
            + f64::MIN_POSITIVE,
    );
    slab_interval(origin, direction, b.min - pad, b.max + pad)
        .is_some_and(|((enter, _), (exit, _))| enter <= t_max && exit >= t_min)
}

/// Whether a group of rays is worth tracing as a packet: three or more,
/// within 8° of the first's direction, from origins within 2% of the
/// scene's size of the first's (a camera's rays, a lidar's).
fn coherent(n: usize, ray: impl Fn(usize) -> (DVec3, DVec3), scale: f64) -> bool {
    if n < 3 {
        return false;
    }
    let (o0, d0) = ray(0);
    // cos θ > 0.99 as cos θ > 0 and cos² θ > 0.99², without a root or a
    // division per ray (a camera's groups all ask it).
    let (near, d0_squared) = ((0.02 * scale).powi(2), d0.length_squared());
    (1..n).all(|k| {
        let (o, d) = ray(k);
        let cos = d.dot(d0);
        cos > 0.0
            && cos * cos > 0.9801 * d.length_squared() * d0_squared
            && (o - o0).length_squared() <= near
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::PixelRng;
    use glam::{DMat4, DQuat};

    /// `n` triangles of size about 0.3 scattered through [-1, 1]³.
    fn soup(rng: &mut PixelRng, n: usize) -> (Vec<f64>, Vec<u32>) {
        let vertices = (0..9 * n)
            .map(|_| 2.0 * rng.uniform() - 1.0)
            .collect::<Vec<_>>();
        // Each triangle's corners pulled towards its first.
        let vertices = vertices
            .chunks_exact(9)
            .flat_map(|t| {
                let a = [t[0], t[1], t[2]];
                [0, 1, 2].map(|c| [0, 1, 2].map(|x| a[x] + 0.15 * (t[3 * c + x] - a[x])))
            })
            .flatten()
            .collect();
        (vertices, (0..3 * n as u32).collect())
    }

    /// Origins in [-1.2, 1.2]³ and directions every way, at random.
    fn scattered(rng: &mut PixelRng, n: usize) -> (Vec<f64>, Vec<f64>) {
        let mut draw = |s: f64| {
            (0..3 * n)
                .map(|_| s * (2.0 * rng.uniform() - 1.0))
                .collect()
        };
        (draw(1.2), draw(1.0))
    }

    fn threads(n: usize) -> QueryOptions<'static> {
        QueryOptions {
            threads: Some(n),
            cancel: None,
        }
    }

    /// `intersect_in` into arrays that start as garbage (a reused set's
    /// old answers), so an entry left unwritten shows.
    fn nearest_in(
        scene: &RayScene,
        rays: &Rays,
        order: Option<&TraceOrder>,
        options: &QueryOptions,
    ) -> Result<Hits, QueryError> {
        let n = rays.len();
        let mut hits = Hits {
            t: vec![-7.0; n],
            mesh_id: vec![7; n],
            triangle_id: vec![7; n],
            u: vec![f64::NAN; n],
            v: vec![7.0; n],
            normal: vec![f64::NAN; 3 * n],
        };
        scene.intersect_in(rays, order, hits.as_mut(), Written::Anything, options)?;
        Ok(hits)
    }

    #[test]
    fn rays_in_a_sorted_order_answer_as_given() {
        let mut rng = PixelRng::new(11, 0, 0);
        let mut scene = RayScene::new();
        let (v, f) = soup(&mut rng, 400);
        scene.add_mesh(&v, &f, None).unwrap();
        let (v, f) = soup(&mut rng, 300);
        let m = DMat4::from_scale_rotation_translation(
            DVec3::new(1.2, 0.8, 1.0),
            DQuat::from_rotation_z(0.6),
            DVec3::new(0.1, 0.0, -0.2),
        );
        scene.add_mesh(&v, &f, Some(m)).unwrap();
        let (o, d) = scattered(&mut rng, 20_000);
        let rays = Rays::new(&o, &d, 0.0, 2.5).unwrap();
        let sorted = sorted_order(&rays, scene.bounds(), &threads(1)).unwrap();
        let sorted = sorted.expect("scattered rays are sorted");
        assert!(
            sorted
                .rays
                .iter()
                .enumerate()
                .any(|(s, &i)| s != i as usize)
        );
        let order = TraceOrder::Sorted(sorted);
        for n in [1, 2] {
            let sorted = nearest_in(&scene, &rays, Some(&order), &threads(n)).unwrap();
            let given = nearest_in(&scene, &rays, None, &threads(n)).unwrap();
            assert!(given == scene.intersect(&rays, &threads(n)).unwrap());
            assert!(sorted == given);
            assert!(given.mesh_id.iter().filter(|&&m| m == 1).count() > 1000);
            assert_eq!(
                scene.occluded_in(&rays, Some(&order), &threads(n)).unwrap(),
                scene.occluded_in(&rays, None, &threads(n)).unwrap()
            );
            assert_eq!(
                scene.count_in(&rays, Some(&order), &threads(n)).unwrap(),
                scene.count_in(&rays, None, &threads(n)).unwrap()
            );
        }
        // Fewer other rays after those: the waiting answers kept from the
        // query before (see `WAITING`) are all written again.
        let (o, d) = scattered(&mut rng, 17_000);
        let rays = Rays::new(&o, &d, 0.0, 2.5).unwrap();
        let order = sorted_order(&rays, scene.bounds(), &threads(1)).unwrap();
        let order = TraceOrder::Sorted(order.expect("scattered rays are sorted"));
        for n in [2, 1] {
            let sorted = nearest_in(&scene, &rays, Some(&order), &threads(n)).unwrap();
            assert!(sorted == nearest_in(&scene, &rays, None, &threads(n)).unwrap());
        }
    }

    #[test]
    fn answers_into_arrays_of_the_wrong_length_are_refused_untouched() {
        let mut rng = PixelRng::new(13, 0, 0);
        let mut scene = RayScene::new();
        let (v, f) = soup(&mut rng, 50);
        scene.add_mesh(&v, &f, None).unwrap();
        let (o, d) = scattered(&mut rng, 100);
        let rays = Rays::new(&o, &d, 0.0, f64::INFINITY).unwrap();
        let hits = scene.intersect(&rays, &threads(1)).unwrap();
        for (k, name) in ["t", "mesh_id", "triangle_id", "u", "v", "normal"]
            .into_iter()
            .enumerate()
        {
            let mut out = hits.clone();
            out.t.fill(-1.0);
            match k {
                0 => out.t.push(0.0),
                1 => out.mesh_id.pop().map(drop).unwrap(),
                2 => out.triangle_id.clear(),
                3 => out.u.push(0.0),
                4 => out.v.pop().map(drop).unwrap(),
                _ => out.normal.truncate(100),
            }
            let e = scene.intersect_into(&rays, out.as_mut(), &threads(1));
            assert!(
                matches!(e, Err(QueryError::Invalid { argument, .. }) if argument == name),
                "{name}: {e:?}"
            );
            assert!(out.t.iter().all(|&t| t == -1.0 || t == 0.0));
        }
    }

    #[test]
    fn only_scenes_beyond_the_cache_sort_their_rays() {
        let mut rng = PixelRng::new(12, 0, 0);
        let (o, d) = scattered(&mut rng, 20_000);
        let rays = Rays::new(&o, &d, 0.0, f64::INFINITY).unwrap();
        let mut small = RayScene::new();
        let (v, f) = soup(&mut rng, 1000);
        small.add_mesh(&v, &f, None).unwrap();
        assert!(small.trace_order(&rays, &threads(1)).unwrap().is_none());
        // A 400 × 400 grid of squares: 320,000 triangles.
        let n = 400;
        let vertices: Vec<f64> = (0..=n)
            .flat_map(|y| {
                (0..=n).flat_map(move |x| [x as f64 / n as f64, y as f64 / n as f64, 0.0])
            })
            .collect();
        let id = |x: u32, y: u32| y * (n + 1) + x;
        let faces: Vec<u32> = (0..n)
            .flat_map(|y| {
                (0..n).flat_map(move |x| {
                    [
                        id(x, y),
                        id(x + 1, y),
                        id(x + 1, y + 1),
                        id(x, y),
                        id(x + 1, y + 1),
                        id(x, y + 1),
                    ]
                })
            })
            .collect();
        let mut big = RayScene::new();
        big.add_mesh(&vertices, &faces, None).unwrap();
        assert!(big.memory_bytes() > STREAM_BYTES);
        assert!(big.trace_order(&rays, &threads(1)).unwrap().is_some());
        // A camera's rays, from one point, pixel by pixel: as given.
        let camera: Vec<f64> = (0..20_000)
            .flat_map(|k| {
                [
                    (k % 200) as f64 / 200.0 - 0.5,
                    (k / 200) as f64 / 100.0 - 0.5,
                    -1.0,
                ]
            })
            .collect();
        let eye = [0.5, 0.5, 2.0].repeat(20_000);
        let camera = Rays::new(&eye, &camera, 0.0, f64::INFINITY).unwrap();
        let order = big.trace_order(&camera, &threads(1)).unwrap();
        assert!(matches!(order, Some(TraceOrder::Tiled(_))));
    }

    #[test]
    fn a_cameras_rays_in_tiles_answer_as_given() {
        let mut rng = PixelRng::new(13, 0, 0);
        let mut scene = RayScene::new();
        let (v, f) = soup(&mut rng, 400);
        scene.add_mesh(&v, &f, None).unwrap();
        let (v, f) = soup(&mut rng, 300);
        let m = DMat4::from_rotation_translation(DQuat::from_rotation_x(0.4), DVec3::X * 0.3);
        scene.add_mesh(&v, &f, Some(m)).unwrap();
        // Rows of 64 (eight bands a chunk), of 600 (one band, traced in
        // pieces) and of 1,200 (a band beyond a chunk), each with a last
        // band cut short; a pinhole camera's rays and an orthographic
        // one's.
        for (width, rows, pinhole) in [(64, 70, true), (600, 9, false), (1200, 5, true)] {
            let n = width * rows + width / 2;
            let pixel = |k: usize| {
                // Square pixels, the rows about the middle.
                let (x, y) = ((k % width) as f64, (k / width) as f64 - rows as f64 / 2.0);
                [x / width as f64 * 2.4 - 1.2, y / width as f64 * 2.4]
            };
            let (o, d): (Vec<f64>, Vec<f64>) = if pinhole {
                let d = (0..n).flat_map(|k| {
                    let [x, y] = pixel(k);
                    [x, y, -2.0]
                });
                ([0.1, 0.0, 3.0].repeat(n), d.collect())
            } else {
                let o = (0..n).flat_map(|k| {
                    let [x, y] = pixel(k);
                    [x, y, 3.0]
                });
                (o.collect(), [0.2, 0.1, -1.0].repeat(n))
            };
            let rays = Rays::new(&o, &d, 0.0, f64::INFINITY).unwrap();
            let order = scene.trace_order(&rays, &threads(1)).unwrap();
            assert!(matches!(order, Some(TraceOrder::Tiled(_))), "{width}");
            for t in [1, 2] {
                let tiled = nearest_in(&scene, &rays, order.as_ref(), &threads(t));
                let given = nearest_in(&scene, &rays, None, &threads(t)).unwrap();
                assert!(given == scene.intersect(&rays, &threads(t)).unwrap());
                assert!(tiled.unwrap() == given);
                let hit = given.t.iter().filter(|t| t.is_finite()).count();
                assert!(hit > n / 10 && hit < n * 9 / 10, "{hit} of {n}");
                assert_eq!(
                    scene.occluded_in(&rays, order.as_ref(), &threads(t)),
                    scene.occluded_in(&rays, None, &threads(t))
                );
                assert_eq!(
                    scene.count_in(&rays, order.as_ref(), &threads(t)),
                    scene.count_in(&rays, None, &threads(t))
                );
            }
            // A bad row in a batch still to be checked: each query reports
            // it as `Rays::new` does, tiles or not.
            let mut bad = d.clone();
            bad[3 * (width * (rows - 1) + 2) + 2] = f64::NAN;
            let eager = Rays::new(&o, &bad, 0.0, f64::INFINITY).unwrap_err();
            let deferred = Rays::deferred(&o, &bad, 0.0, f64::INFINITY).unwrap();
            assert!(matches!(
                scene.trace_order(&deferred, &threads(1)).unwrap(),
                Some(TraceOrder::Tiled(_))
            ));
            assert_eq!(scene.intersect(&deferred, &threads(2)).unwrap_err(), eager);
            assert_eq!(scene.occluded(&deferred, &threads(2)).unwrap_err(), eager);
            let counted = scene.count_intersections(&deferred, &threads(2));
            assert_eq!(counted.unwrap_err(), eager);
        }
    }
}
