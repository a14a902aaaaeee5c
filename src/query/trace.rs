//! The ray queries of [`RayScene`]: nearest hit, any hit, every hit. The
//! first three take rays in runs of [`SPAN`]: a run whose directions share
//! their signs is first tested as one span against each mesh's tree, and
//! answered as misses when it reaches no leaf (a camera's rays beside the
//! meshes). The rest go in groups of eight; a coherent group (nearly parallel rays
//! from nearby origins: a camera's, a lidar's) goes through each mesh's
//! tree as a packet, an incoherent one through a large mesh as a stream
//! (each ray's next reads prefetched while the others step), otherwise ray
//! by ray. Each path gives, to the bit, the hit the renderer's
//! `Mesh::intersect` gives that ray alone, so the choice changes only the
//! speed.

use glam::DVec3;
use rayon::prelude::*;

use super::QueryError;
use super::rays::{Crossings, Hits, QueryOptions, Rays};
use super::scene::{Placed, RayScene};
use crate::accel::{NodePacket, PACKET};
use crate::geometry::Aabb;
use crate::geometry::cuboid::slab_interval;
use crate::geometry::mesh::{FacetHit, STREAM};
use crate::geometry::triangle::axis_permutation;

// A counting group is a packet or a stream, as its rays are.
const _: () = assert!(STREAM == PACKET);

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
        let scale = self.bounds().diagonal();
        // Written in place, chunk by chunk: a vector of whole hits would
        // be three times the answer's size to fault in and read back.
        // Zeros, which the allocator takes from the system as they are
        // (no pass over them here): each worker faults in and writes its
        // own chunks, a miss's t and ids included.
        let mut hits = Hits {
            t: vec![0.0; n],
            mesh_id: vec![0; n],
            triangle_id: vec![0; n],
            u: vec![0.0; n],
            v: vec![0.0; n],
            normal: vec![0.0; 3 * n],
        };
        let Hits {
            t,
            mesh_id,
            triangle_id,
            u,
            v,
            normal,
        } = &mut hits;
        options.run(|| {
            t.par_chunks_mut(CHUNK)
                .zip(mesh_id.par_chunks_mut(CHUNK))
                .zip(triangle_id.par_chunks_mut(CHUNK))
                .zip(u.par_chunks_mut(CHUNK))
                .zip(v.par_chunks_mut(CHUNK))
                .zip(normal.par_chunks_mut(3 * CHUNK))
                .enumerate()
                .try_for_each(|(c, (((((t, mesh_id), triangle_id), u), v), normal))| {
                    if options.cancelled() {
                        return Err(QueryError::Cancelled);
                    }
                    rays.check_chunk(c * CHUNK, t.len())?;
                    self.runs(rays, c * CHUNK, t.len(), |block, end, may_hit| {
                        if !may_hit {
                            // u, v and the normal stay zero.
                            t[block..end].fill(f64::INFINITY);
                            mesh_id[block..end].fill(-1);
                            triangle_id[block..end].fill(-1);
                            return;
                        }
                        for first in (block..end).step_by(PACKET) {
                            let count = PACKET.min(end - first);
                            let mut group = [MISS; PACKET];
                            let group = &mut group[..count];
                            self.nearest_group(rays, c * CHUNK + first, group, scale);
                            for (k, near) in group.iter().enumerate() {
                                let i = first + k;
                                let Some(h) = near.hit else {
                                    // u, v and the normal stay zero.
                                    t[i] = f64::INFINITY;
                                    mesh_id[i] = -1;
                                    triangle_id[i] = -1;
                                    continue;
                                };
                                t[i] = h.t;
                                mesh_id[i] = i64::from(near.mesh);
                                triangle_id[i] = i64::from(h.triangle);
                                u[i] = h.barycentric.y;
                                v[i] = h.barycentric.z;
                                let world = self.meshes[near.mesh as usize].world_normal(h.normal);
                                normal[3 * i..3 * i + 3].copy_from_slice(&world.to_array());
                            }
                        }
                    });
                    Ok(())
                })
        })?;
        Ok(hits)
    }

    /// Whether each ray hits anything with t in (t_min, t_max).
    pub fn occluded(&self, rays: &Rays, options: &QueryOptions) -> Result<Vec<bool>, QueryError> {
        let mut blocked = vec![false; rays.len()];
        let scale = self.bounds().diagonal();
        options.run(|| {
            blocked
                .par_chunks_mut(CHUNK)
                .enumerate()
                .try_for_each(|(c, out)| {
                    if options.cancelled() {
                        return Err(QueryError::Cancelled);
                    }
                    rays.check_chunk(c * CHUNK, out.len())?;
                    let mut alone = ByAxes::new();
                    // Rays that meet nothing stay unblocked.
                    self.runs(rays, c * CHUNK, out.len(), |block, end, may_hit| {
                        if may_hit {
                            for (g, group) in out[block..end].chunks_mut(PACKET).enumerate() {
                                let first = block + g * PACKET;
                                self.blocked_group(
                                    rays,
                                    c * CHUNK,
                                    first,
                                    group,
                                    scale,
                                    &mut alone,
                                );
                            }
                        }
                    });
                    // The rays left to trace alone, a permutation at a
                    // time (see `ByAxes`).
                    if let Some(placed) = self.meshes.first() {
                        alone.each(|k| {
                            let (o, d) = rays.ray(c * CHUNK + k);
                            out[k] = placed.mesh.any_hit(o, d, rays.t_min, rays.t_max);
                        });
                    }
                    Ok(())
                })
        })?;
        Ok(blocked)
    }

    /// How many triangles each ray hits with t in (t_min, t_max) (a ray
    /// through an edge or vertex counts each triangle that holds it).
    pub fn count_intersections(
        &self,
        rays: &Rays,
        options: &QueryOptions,
    ) -> Result<Vec<u32>, QueryError> {
        let mut counts = vec![0u32; rays.len()];
        let scale = self.bounds().diagonal();
        options.run(|| {
            counts
                .par_chunks_mut(CHUNK)
                .enumerate()
                .try_for_each(|(c, out)| {
                    if options.cancelled() {
                        return Err(QueryError::Cancelled);
                    }
                    rays.check_chunk(c * CHUNK, out.len())?;
                    let mut alone = ByAxes::new();
                    // Rays that meet nothing keep a count of 0.
                    self.runs(rays, c * CHUNK, out.len(), |block, end, may_hit| {
                        if may_hit {
                            for (g, group) in out[block..end].chunks_mut(STREAM).enumerate() {
                                let first = block + g * STREAM;
                                self.count_group(rays, c * CHUNK, first, group, scale, &mut alone);
                            }
                        }
                    });
                    // As in `occluded`.
                    if let Some(placed) = self.meshes.first() {
                        alone.each(|k| {
                            let (o, d) = rays.ray(c * CHUNK + k);
                            out[k] = placed.mesh.count_hits(o, d, rays.t_min, rays.t_max);
                        });
                    }
                    Ok(())
                })
        })?;
        Ok(counts)
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
        rays: &Rays,
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
    fn span_misses(&self, rays: &Rays, first: usize, n: usize) -> bool {
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
    /// [`PACKET`]).
    fn nearest_group(&self, rays: &Rays, first: usize, out: &mut [Nearest], scale: f64) {
        let n = out.len();
        let world: [(DVec3, DVec3); PACKET] = gather(rays, first, n);
        let coherent = coherent(&world[..n], scale);
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
        rays: &Rays,
        chunk: usize,
        first: usize,
        out: &mut [bool],
        scale: f64,
        alone: &mut ByAxes,
    ) {
        let n = out.len();
        let world: [(DVec3, DVec3); PACKET] = gather(rays, chunk + first, n);
        let coherent = coherent(&world[..n], scale);
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
    /// [`STREAM`], which is [`PACKET`]): coherent ones as a packet,
    /// incoherent ones through a large mesh in a stream, otherwise ray by
    /// ray. Every hit is counted, so the any-hit traversals serve (run to
    /// their ends), which sort no children.
    ///
    /// As in `blocked_group`, the rays start at `chunk + first`, and those
    /// of a scene of one mesh without a transform to be traced alone are
    /// left in `alone`.
    fn count_group(
        &self,
        rays: &Rays,
        chunk: usize,
        first: usize,
        out: &mut [u32],
        scale: f64,
        alone: &mut ByAxes,
    ) {
        let n = out.len();
        let world: [(DVec3, DVec3); STREAM] = gather(rays, chunk + first, n);
        let coherent = coherent(&world[..n], scale);
        // As in `nearest_group`.
        let skip_box = self.meshes.len() == 1;
        for placed in &self.meshes {
            let (reach, live) =
                reach_into::<STREAM>(placed, &world[..n], rays.t_min, skip_box, |_| {
                    Some(rays.t_max)
                });
            if live == 0 {
                continue;
            }
            let moved: [(DVec3, DVec3); STREAM];
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

    /// Calls `trace` with each ray left, a permutation after another.
    fn each(&self, mut trace: impl FnMut(usize)) {
        for (rays, &count) in self.rays.iter().zip(&self.count) {
            rays[..count].iter().for_each(|&k| trace(usize::from(k)));
        }
    }
}

/// Rays `first..first + n` of `rays` (n ≥ 1), lanes past the last
/// repeating it. A loop: `array::from_fn`'s closure stayed a call per ray,
/// its result passed through memory.
#[inline(always)]
fn gather<const N: usize>(rays: &Rays, first: usize, n: usize) -> [(DVec3, DVec3); N] {
    let mut world = [(DVec3::ZERO, DVec3::ZERO); N];
    for (k, ray) in world.iter_mut().enumerate() {
        *ray = rays.ray(first + k.min(n - 1));
    }
    world
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
fn coherent(rays: &[(DVec3, DVec3)], scale: f64) -> bool {
    let Some(&(o0, d0)) = rays.first() else {
        return false;
    };
    // cos θ > 0.99 as cos θ > 0 and cos² θ > 0.99², without a root or a
    // division per ray (a camera's groups all ask it).
    let (near, d0_squared) = ((0.02 * scale).powi(2), d0.length_squared());
    rays.len() >= 3
        && rays.iter().all(|&(o, d)| {
            let cos = d.dot(d0);
            cos > 0.0
                && cos * cos > 0.9801 * d.length_squared() * d0_squared
                && (o - o0).length_squared() <= near
        })
}
