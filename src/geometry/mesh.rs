//! Triangle meshes: shared vertex data, watertight triangle tests, a BVH
//! over the triangles, smooth (interpolated) or flat normals, texture
//! coordinates and per-triangle materials.

use glam::{DAffine3, DVec2, DVec3};
use thiserror::Error;

use super::Aabb;
use super::nearest::{NearestOnTriangle, nearest_on_triangle};
use super::terminator::terminator_offset;
use super::triangle::{
    TriangleHit, WatertightLanes, WatertightRay, triangle_hit, triangle_hit_as, triangle_hit_at,
    triangle_hit_dispatched, triangle_hit_lanes,
};
use crate::accel::bvh::{AnyTest, Bvh, ClosestTest, Fetch};
use crate::accel::packet::{PacketAnyTest, PacketClosestTest};
use crate::accel::simd::{self, Kernel};
use crate::accel::{NodePacket, NodeRay, PACKET};
use crate::huge_pages;

/// What a loader hands over to build a mesh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshData {
    /// Vertex positions.
    pub positions: Vec<DVec3>,
    /// Per-vertex normals (empty: flat shading).
    pub normals: Vec<DVec3>,
    /// Per-vertex texture coordinates (empty: none).
    pub uvs: Vec<DVec2>,
    /// Vertex indices of each triangle, counter-clockwise seen from the front.
    pub triangles: Vec<[u32; 3]>,
    /// Per-triangle material slot (empty: all slot 0).
    pub materials: Vec<u32>,
    /// Per-vertex colours (glTF COLOR_0), multiplied into the surface
    /// colour (empty: none).
    pub colors: Vec<DVec3>,
}

/// Why mesh data is unusable.
#[derive(Debug, Error, PartialEq)]
pub enum MeshError {
    /// No triangles.
    #[error("the mesh has no triangles")]
    Empty,
    /// A triangle refers past the vertex list.
    #[error("triangle {triangle} refers to vertex {index}, but there are only {count} vertices")]
    IndexOutOfRange {
        /// The triangle.
        triangle: usize,
        /// The bad index.
        index: u32,
        /// Number of vertices.
        count: usize,
    },
    /// A position, normal or texture coordinate is NaN or infinite.
    #[error("{what} {index} is not finite")]
    NotFinite {
        /// "vertex", "normal" or "texture coordinate".
        what: &'static str,
        /// Its index.
        index: usize,
    },
    /// Normal or texture coordinate count differs from the vertex count.
    #[error("{what}: {got} given for {expected} vertices")]
    CountMismatch {
        /// "normals" or "texture coordinates".
        what: &'static str,
        /// How many there are.
        got: usize,
        /// How many vertices.
        expected: usize,
    },
    /// More than 2³² − 1 of something.
    #[error("the mesh is too large")]
    TooLarge,
}

/// A triangle mesh with its BVH, in object space.
#[derive(Clone, Debug, PartialEq)]
pub struct Mesh {
    positions: Vec<DVec3>,
    normals: Vec<DVec3>,
    uvs: Vec<DVec2>,
    colors: Vec<DVec3>,
    /// Triangles in BVH leaf order.
    triangles: Vec<[u32; 3]>,
    /// Material slot per triangle (BVH order; empty: slot 0).
    materials: Vec<u32>,
    bvh: Bvh,
}

/// A ray-mesh hit with the surface at it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshHit {
    /// Ray parameter.
    pub t: f64,
    /// Unit geometric normal (right-hand rule of the vertex order).
    pub normal: DVec3,
    /// Unit shading normal: interpolated vertex normals, or `normal`.
    pub shading_normal: DVec3,
    /// Interpolated texture coordinates (zero without any).
    pub uv: DVec2,
    /// Interpolated vertex colour (white without any).
    pub color: DVec3,
    /// Material slot of the triangle.
    pub material: u32,
    /// The triangle's index in the [`MeshData`] the mesh was built from.
    pub triangle: u32,
    /// Barycentric weights of the triangle's corners a, b, c (sum 1).
    pub barycentric: DVec3,
    /// Where shadow feelers start, relative to the hit: Hanika's lift off
    /// the facet on smooth-shaded triangles (see
    /// [`terminator`](super::terminator)), zero on flat ones.
    pub feeler_offset: DVec3,
}

/// A ray-mesh hit without the shading fields (uv, colour, shading normal,
/// feeler offset): what a ray query returns. Each field is, to the bit,
/// the [`MeshHit`]'s of the same ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FacetHit {
    /// Ray parameter.
    pub t: f64,
    /// The triangle's index in the [`MeshData`] the mesh was built from.
    pub triangle: u32,
    /// Barycentric weights of the triangle's corners a, b, c (sum 1).
    pub barycentric: DVec3,
    /// Unit geometric normal (right-hand rule of the vertex order).
    pub normal: DVec3,
}

impl Mesh {
    /// Checks `data` and builds the BVH.
    pub fn new(data: MeshData) -> Result<Mesh, MeshError> {
        let MeshData {
            positions,
            normals,
            uvs,
            triangles,
            materials,
            colors,
        } = data;
        if triangles.is_empty() {
            return Err(MeshError::Empty);
        }
        if positions.len() > u32::MAX as usize || triangles.len() > u32::MAX as usize {
            return Err(MeshError::TooLarge);
        }
        for (what, values) in [
            ("vertex", &positions),
            ("normal", &normals),
            ("vertex colour", &colors),
        ] {
            if let Some(index) = values.iter().position(|v| !v.is_finite()) {
                return Err(MeshError::NotFinite { what, index });
            }
        }
        if let Some(index) = uvs.iter().position(|v| !v.is_finite()) {
            return Err(MeshError::NotFinite {
                what: "texture coordinate",
                index,
            });
        }
        for (what, got) in [
            ("normals", normals.len()),
            ("texture coordinates", uvs.len()),
            ("vertex colours", colors.len()),
        ] {
            if got != 0 && got != positions.len() {
                return Err(MeshError::CountMismatch {
                    what,
                    got,
                    expected: positions.len(),
                });
            }
        }
        for (triangle, t) in triangles.iter().enumerate() {
            if let Some(&index) = t.iter().find(|&&i| i as usize >= positions.len()) {
                return Err(MeshError::IndexOutOfRange {
                    triangle,
                    index,
                    count: positions.len(),
                });
            }
        }
        let bvh = Bvh::build(
            triangles
                .iter()
                .map(|t| Aabb::from_points(t.iter().map(|&i| positions[i as usize]))),
        );
        // Store triangles in leaf order, so leaves index them directly.
        let mut ordered: Vec<[u32; 3]> =
            huge_pages::collect(bvh.order().iter().map(|&i| triangles[i as usize]));
        drop(triangles);
        let (positions, normals, uvs, colors) =
            renumber_vertices(&mut ordered, positions, normals, uvs, colors);
        let materials = if materials.is_empty() {
            materials
        } else {
            bvh.order()
                .iter()
                .map(|&i| materials.get(i as usize).copied().unwrap_or(0))
                .collect()
        };
        Ok(Mesh {
            positions,
            normals,
            uvs,
            colors,
            triangles: ordered,
            materials,
            bvh,
        })
    }

    /// Whether the mesh is a closed, consistently oriented surface (every
    /// edge shared by exactly two triangles that run it in opposite
    /// directions, vertices taken as equal where their positions are, so
    /// seams of split normals or texture coordinates do not open it):
    /// what crossing parity needs to tell inside from outside.
    pub fn is_closed(&self) -> bool {
        use std::collections::HashMap;
        let mut welded: HashMap<[u64; 3], u32> = HashMap::new();
        let ids: Vec<u32> = self
            .positions
            .iter()
            .map(|p| {
                let next = welded.len() as u32;
                // + 0.0 makes −0.0 and 0.0 one position.
                *welded
                    .entry((*p + DVec3::ZERO).to_array().map(f64::to_bits))
                    .or_insert(next)
            })
            .collect();
        // Each undirected edge: +1 for a <, −1 for a > direction, and a count.
        let mut edges: HashMap<(u32, u32), (i32, u32)> = HashMap::new();
        for t in &self.triangles {
            let v = t.map(|i| ids[i as usize]);
            for (a, b) in [(v[0], v[1]), (v[1], v[2]), (v[2], v[0])] {
                if a == b {
                    continue;
                }
                let e = edges.entry((a.min(b), a.max(b))).or_default();
                e.0 += if a < b { 1 } else { -1 };
                e.1 += 1;
            }
        }
        !edges.is_empty() && edges.values().all(|&(dir, count)| count == 2 && dir == 0)
    }

    /// Where the whole line `origin + t·direction` is inside the (closed)
    /// mesh, as (enter, exit) hits in ascending order: the Jordan curve
    /// theorem's crossing parity along the line. Every triangle the line
    /// meets is found (t from −∞ to +∞); hits at the same t (the line
    /// through a shared edge or vertex) are one crossing when the
    /// triangles all face the same way along the line, and none when they
    /// do not (the line grazes a fold). Ties are ordered by the mesh's own
    /// order, so the answer is the same however the tree is visited.
    pub fn inside(&self, origin: DVec3, direction: DVec3) -> Vec<(MeshHit, MeshHit)> {
        let ray = WatertightRay::new(origin, direction);
        let mut hits: Vec<(f64, usize, TriangleHit)> = Vec::new();
        self.bvh.visit(
            |b| super::cuboid::slab_interval(origin, direction, b.min, b.max).is_some(),
            |position| {
                let [a, b, c] = self.corners(position);
                if let Some(h) = triangle_hit(&ray, a, b, c, f64::NEG_INFINITY, f64::INFINITY) {
                    hits.push((h.t, position, h));
                }
                true
            },
        );
        hits.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
        let facing = |position: usize| {
            let [a, b, c] = self.corners(position);
            (b - a).cross(c - a).dot(direction)
        };
        let mut out = Vec::new();
        let mut entered: Option<MeshHit> = None;
        let mut i = 0;
        // On an edge or vertex (a barycentric weight exactly 0) the triangles
        // sharing it each compute t from their own weights: equal to within
        // rounding, not always to the bit.
        let on_edge = |h: &TriangleHit| h.barycentric.min_element() == 0.0;
        while i < hits.len() {
            let t = hits[i].0;
            let close = 1e-12 * t.abs().max(1.0);
            let end = i + hits[i..]
                .iter()
                .take_while(|h| {
                    h.0 == t || (on_edge(&hits[i].2) && on_edge(&h.2) && h.0 - t <= close)
                })
                .count();
            let group = &hits[i..end];
            let crossing =
                group.iter().all(|h| facing(h.1) > 0.0) || group.iter().all(|h| facing(h.1) < 0.0);
            if crossing {
                let (_, position, h) = hits[i];
                let surface = self.surface(position, h.barycentric, h.t, direction);
                match entered.take() {
                    None => entered = Some(surface),
                    Some(enter) => out.push((enter, surface)),
                }
            }
            i = end;
        }
        out
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Bounds in object space.
    pub fn bounds(&self) -> Aabb {
        self.bvh.bounds()
    }

    /// Whether some ray `span` stands for (see
    /// [`NodePacket::spanning`]) may hit a triangle before `t_max`; false
    /// only where every such ray's search finds nothing at the root.
    pub fn span_may_meet(&self, span: &NodePacket, t_max: f64) -> bool {
        self.bvh.span_may_meet(span, t_max)
    }

    /// Approximate heap memory in bytes.
    pub fn memory_bytes(&self) -> usize {
        self.positions.len() * 24
            + self.normals.len() * 24
            + self.uvs.len() * 16
            + self.colors.len() * 24
            + self.triangles.len() * 12
            + self.materials.len() * 4
            + self.bvh.memory_bytes()
    }

    /// Calls `visit` with the index (in the [`MeshData`]) and corners of
    /// each triangle in every leaf whose box `keep` accepts, descending
    /// only into boxes it accepts: for queries that want every crossing
    /// rather than the nearest or any (counting hits, inside tests).
    pub fn visit_triangles(
        &self,
        keep: impl Fn(&Aabb) -> bool,
        mut visit: impl FnMut(u32, [DVec3; 3]),
    ) {
        let order = self.bvh.order();
        self.bvh.visit(keep, |position| {
            visit(order[position], self.corners(position));
            true
        });
    }

    /// The point of the mesh nearest `p`, placed by `to_world` (object to
    /// world; `None`: as it is), where its squared distance in world space
    /// is at most `reach`: the triangle's index (in the [`MeshData`]), its
    /// nearest point (in world space) and the triangle's unit geometric
    /// normal (in object space; zero for a degenerate triangle). Of
    /// triangles equally near, the first in the mesh's own order, whatever
    /// order the tree gives them in. `stack` is the traversal's, reused
    /// between calls.
    pub fn nearest_point(
        &self,
        p: DVec3,
        reach: f64,
        to_world: Option<&DAffine3>,
        stack: &mut Vec<(f64, u32, u16)>,
    ) -> Option<(u32, NearestOnTriangle, DVec3)> {
        let order = self.bvh.order();
        // Index, leaf position and nearest point of the triangle kept.
        let mut best: Option<(u32, usize, NearestOnTriangle)> = None;
        // Each box's bound is taken down by more than the rounding of a
        // nearest point computed in it (its coordinates within the mesh's
        // bounds) and of its distance, so that the bound never exceeds what
        // a triangle inside gives.
        let bounds = match to_world {
            None => self.bounds(),
            Some(m) => world_box(&self.bounds(), m),
        };
        let slack = p.abs().max(bounds.min.abs()).max(bounds.max.abs()) * (64.0 * f64::EPSILON);
        self.bvh.nearest_items(
            stack,
            reach,
            |b| {
                let b = match to_world {
                    None => *b,
                    Some(m) => world_box(b, m),
                };
                let d = (b.min - p - slack).max(p - b.max - slack).max(DVec3::ZERO);
                d.length_squared() * (1.0 - 8.0 * f64::EPSILON)
            },
            |position, reach| {
                let corners = self.corners(position);
                let corners = match to_world {
                    None => corners,
                    Some(m) => corners.map(|c| m.transform_point3(c)),
                };
                let near = nearest_on_triangle(p, corners);
                let index = order[position];
                let better = match best {
                    _ if near.distance_squared > reach => false,
                    None => true,
                    Some((held, _, h)) => {
                        near.distance_squared < h.distance_squared
                            || (near.distance_squared == h.distance_squared && index < held)
                    }
                };
                if better {
                    best = Some((index, position, near));
                    near.distance_squared
                } else {
                    reach
                }
            },
        );
        best.map(|(index, position, near)| (index, near, facet_normal(self.corners(position))))
    }

    /// Calls `each` with the index (in the [`MeshData`]) and hit of every
    /// triangle hit with t in (t_min, t_max), t_min ≥ 0, in no particular
    /// order: the any-hit traversal (no child sorted by distance, the
    /// reach fixed) run to its end, each triangle tested as
    /// [`intersect`](Self::intersect) tests it. Compiled once per axis
    /// permutation, as [`any_hit`](Self::any_hit) is.
    pub fn each_hit(
        &self,
        origin: DVec3,
        direction: DVec3,
        t_min: f64,
        t_max: f64,
        mut each: impl FnMut(u32, TriangleHit),
    ) {
        let kernel = simd::kernel();
        let ray = WatertightRay::new(origin, direction);
        let node_ray = NodeRay::new(origin, direction);
        let each = &mut each;
        match ray.permutation() {
            0 => self.each_as::<0>(kernel, ray, &node_ray, t_min, t_max, each),
            1 => self.each_as::<1>(kernel, ray, &node_ray, t_min, t_max, each),
            2 => self.each_as::<2>(kernel, ray, &node_ray, t_min, t_max, each),
            3 => self.each_as::<3>(kernel, ray, &node_ray, t_min, t_max, each),
            4 => self.each_as::<4>(kernel, ray, &node_ray, t_min, t_max, each),
            _ => self.each_as::<5>(kernel, ray, &node_ray, t_min, t_max, each),
        }
    }

    /// How many triangles the ray hits with t in (t_min, t_max): what
    /// [`each_hit`](Self::each_hit) reports, counted.
    pub fn count_hits(&self, origin: DVec3, direction: DVec3, t_min: f64, t_max: f64) -> u32 {
        let mut count = 0u32;
        self.each_hit(origin, direction, t_min, t_max, |_, _| {
            count = count.saturating_add(1);
        });
        count
    }

    /// [`each_hit`](Self::each_hit) for a ray of axis permutation `P`.
    #[inline(always)]
    fn each_as<const P: u8>(
        &self,
        kernel: Kernel,
        ray: WatertightRay,
        node_ray: &NodeRay,
        t_min: f64,
        t_max: f64,
        each: &mut impl FnMut(u32, TriangleHit),
    ) {
        let leaf = EveryTriangle::<_, P> {
            mesh: self,
            ray,
            t_min,
            t_max,
            each,
        };
        self.bvh.any_on(kernel, node_ray, t_max, leaf);
    }

    /// [`count_hits`](Self::count_hits) for each of up to [`PACKET`] rays
    /// (`rays[k]` is origin and direction, `t_max[k]` its limit), traced
    /// together as [`any_hit_packet`](Self::any_hit_packet) traces them,
    /// to the end: `counts[k]` is added to.
    ///
    /// # Panics
    /// If there are more than [`PACKET`] rays, or `t_max` or `counts` is
    /// not as long as `rays`.
    pub fn count_hits_packet(
        &self,
        rays: &[(DVec3, DVec3)],
        t_min: f64,
        t_max: &[f64],
        counts: &mut [u32],
    ) {
        assert!(rays.len() <= PACKET && t_max.len() == rays.len() && counts.len() == rays.len());
        let Some(packet) = NodePacket::new(rays) else {
            for ((count, &(o, d)), &t) in counts.iter_mut().zip(rays).zip(t_max) {
                *count = count.saturating_add(self.count_hits(o, d, t_min, t));
            }
            return;
        };
        let limits = padded(t_max);
        let mut leaf = CountingPacket {
            mesh: self,
            rays: LeafRays::new(rays),
            t_min,
            t_max: limits,
            counts: [0; PACKET],
        };
        self.bvh
            .any_packet_on(simd::kernel(), &packet, &limits, &mut leaf);
        for (count, &n) in counts.iter_mut().zip(&leaf.counts) {
            *count = count.saturating_add(n);
        }
    }

    /// How many triangles each of `rays` hits with t in (t_min, t_max\[k\])
    /// (what [`each_hit`](Self::each_hit) reports for it, counted), traced
    /// [`STREAM`] at a time in turns as
    /// [`any_hit_stream`](Self::any_hit_stream) traces them, to the end:
    /// for incoherent rays through a mesh larger than the cache.
    /// `counts[k]` is added to.
    ///
    /// # Panics
    /// If `t_max` or `counts` is not as long as `rays`.
    pub fn count_hits_stream(
        &self,
        rays: &[(DVec3, DVec3)],
        t_min: f64,
        t_max: &[f64],
        counts: &mut [u32],
    ) {
        assert!(t_max.len() == rays.len() && counts.len() == rays.len());
        let kernel = simd::kernel();
        for ((rays, t_max), counts) in rays
            .chunks(STREAM)
            .zip(t_max.chunks(STREAM))
            .zip(counts.chunks_mut(STREAM))
        {
            let ray = |k: usize| rays[k.min(rays.len() - 1)];
            let mut limits = [f64::NEG_INFINITY; STREAM];
            limits[..t_max.len()].copy_from_slice(t_max);
            let limits = limits;
            let mut tests: [CountingTriangles; STREAM] =
                std::array::from_fn(|k| CountingTriangles {
                    mesh: self,
                    ray: WatertightRay::new(ray(k).0, ray(k).1),
                    t_min,
                    t_max: limits[k],
                    count: 0,
                });
            let node_rays = std::array::from_fn(|k| NodeRay::new(ray(k).0, ray(k).1));
            self.bvh
                .any_stream_on(kernel, &node_rays, rays.len(), &limits, &mut tests);
            for (count, test) in counts.iter_mut().zip(&tests) {
                *count = count.saturating_add(test.count);
            }
        }
    }

    /// The corners of the triangle at leaf position `triangle`, where they
    /// lie (see `triangle_hit_at`).
    #[inline(always)]
    fn corner_refs(&self, triangle: usize) -> [&DVec3; 3] {
        self.triangles[triangle].map(|i| &self.positions[i as usize])
    }

    #[inline(always)]
    fn corners(&self, triangle: usize) -> [DVec3; 3] {
        let [a, b, c] = self.triangles[triangle];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// The nearest hit of `origin + t·direction` (direction need not be
    /// unit) with t in (t_min, t_max); of triangles hit at the same t, the
    /// one first in the mesh's own order, whatever order the tree visits
    /// them in.
    pub fn intersect(
        &self,
        origin: DVec3,
        direction: DVec3,
        t_min: f64,
        t_max: f64,
    ) -> Option<MeshHit> {
        self.intersect_on(simd::kernel(), origin, direction, t_min, t_max)
    }

    /// [`intersect`](Self::intersect) on a given SIMD kernel.
    #[inline]
    pub(crate) fn intersect_on(
        &self,
        kernel: Kernel,
        origin: DVec3,
        direction: DVec3,
        t_min: f64,
        t_max: f64,
    ) -> Option<MeshHit> {
        let mut leaf = ClosestTriangle::<ANY_AXES>::new(self, origin, direction, t_min);
        self.bvh
            .closest_on(kernel, &NodeRay::new(origin, direction), t_max, &mut leaf);
        let (triangle, h) = leaf.best?;
        Some(self.surface(triangle, h.barycentric, h.t, direction))
    }

    /// [`intersect`](Self::intersect) without the shading fields: what a
    /// ray query needs, each field the same bits.
    pub fn intersect_facet(
        &self,
        origin: DVec3,
        direction: DVec3,
        t_min: f64,
        t_max: f64,
    ) -> Option<FacetHit> {
        self.closest_on(simd::kernel(), origin, direction, t_min, t_max, |p, h| {
            self.facet(p, h)
        })
    }

    /// The closest-hit search of `intersect`, its hit (leaf position and
    /// triangle hit) made into an answer by `finish`.
    #[inline(always)]
    fn closest_on<H>(
        &self,
        kernel: Kernel,
        origin: DVec3,
        direction: DVec3,
        t_min: f64,
        t_max: f64,
        finish: impl FnOnce(usize, TriangleHit) -> H,
    ) -> Option<H> {
        let mut leaf = ClosestTriangle::<ANY_AXES>::new(self, origin, direction, t_min);
        self.bvh
            .closest_on(kernel, &NodeRay::new(origin, direction), t_max, &mut leaf);
        let (triangle, h) = leaf.best?;
        Some(finish(triangle, h))
    }

    /// [`intersect`](Self::intersect) for each of `rays` (origin and
    /// direction; `t_max[k]` ray k's limit, `hits[k]` its answer), traced
    /// [`STREAM`] at a time in turns, so that one ray's cache misses wait
    /// while the others take their steps. For incoherent rays through a
    /// mesh larger than the cache (on a cache-resident one, the turns cost
    /// more than they hide). Each answer is, to the bit, what `intersect`
    /// gives that ray alone.
    ///
    /// # Panics
    /// If `t_max` or `hits` is not as long as `rays`.
    pub fn intersect_stream(
        &self,
        rays: &[(DVec3, DVec3)],
        t_min: f64,
        t_max: &[f64],
        hits: &mut [Option<MeshHit>],
    ) {
        self.intersect_stream_on(simd::kernel(), rays, t_min, t_max, hits);
    }

    /// [`intersect_stream`](Self::intersect_stream) on a given kernel.
    pub(crate) fn intersect_stream_on(
        &self,
        kernel: Kernel,
        rays: &[(DVec3, DVec3)],
        t_min: f64,
        t_max: &[f64],
        hits: &mut [Option<MeshHit>],
    ) {
        // Not through `closest_stream_on`: the renderer's path kept as it
        // was compiled (through it, 1-2 % slower renders of the bunny).
        assert!(t_max.len() == rays.len() && hits.len() == rays.len());
        for ((rays, t_max), hits) in rays
            .chunks(STREAM)
            .zip(t_max.chunks(STREAM))
            .zip(hits.chunks_mut(STREAM))
        {
            let ray = |k: usize| rays[k.min(rays.len() - 1)];
            let mut tests: [ClosestTriangle; STREAM] = std::array::from_fn(|k| {
                ClosestTriangle::<ANY_AXES>::new(self, ray(k).0, ray(k).1, t_min)
            });
            let node_rays = std::array::from_fn(|k| NodeRay::new(ray(k).0, ray(k).1));
            let mut limits = [f64::NEG_INFINITY; STREAM];
            limits[..t_max.len()].copy_from_slice(t_max);
            self.bvh
                .closest_stream_on(kernel, &node_rays, rays.len(), &mut limits, &mut tests);
            for (k, (hit, test)) in hits.iter_mut().zip(&tests).enumerate() {
                *hit = test
                    .best
                    .map(|(triangle, h)| self.surface(triangle, h.barycentric, h.t, ray(k).1));
            }
        }
    }

    /// [`intersect_stream`](Self::intersect_stream) without the shading
    /// fields (see [`intersect_facet`](Self::intersect_facet)).
    pub fn intersect_facet_stream(
        &self,
        rays: &[(DVec3, DVec3)],
        t_min: f64,
        t_max: &[f64],
        hits: &mut [Option<FacetHit>],
    ) {
        self.closest_stream_on(simd::kernel(), rays, t_min, t_max, hits, |p, h, _| {
            self.facet(p, h)
        });
    }

    /// The streamed closest-hit search of `intersect_stream`, each hit
    /// (leaf position, triangle hit, the ray's direction) made into an
    /// answer by `finish`.
    #[inline(always)]
    fn closest_stream_on<H>(
        &self,
        kernel: Kernel,
        rays: &[(DVec3, DVec3)],
        t_min: f64,
        t_max: &[f64],
        hits: &mut [Option<H>],
        finish: impl Fn(usize, TriangleHit, DVec3) -> H,
    ) {
        assert!(t_max.len() == rays.len() && hits.len() == rays.len());
        for ((rays, t_max), hits) in rays
            .chunks(STREAM)
            .zip(t_max.chunks(STREAM))
            .zip(hits.chunks_mut(STREAM))
        {
            let ray = |k: usize| rays[k.min(rays.len() - 1)];
            let mut tests: [ClosestTriangle; STREAM] = std::array::from_fn(|k| {
                ClosestTriangle::<ANY_AXES>::new(self, ray(k).0, ray(k).1, t_min)
            });
            let node_rays = std::array::from_fn(|k| NodeRay::new(ray(k).0, ray(k).1));
            let mut limits = [f64::NEG_INFINITY; STREAM];
            limits[..t_max.len()].copy_from_slice(t_max);
            self.bvh
                .closest_stream_on(kernel, &node_rays, rays.len(), &mut limits, &mut tests);
            for (k, (hit, test)) in hits.iter_mut().zip(&tests).enumerate() {
                *hit = test.best.map(|(triangle, h)| finish(triangle, h, ray(k).1));
            }
        }
    }

    /// Whether any triangle is hit with t in (t_min, t_max).
    pub fn any_hit(&self, origin: DVec3, direction: DVec3, t_min: f64, t_max: f64) -> bool {
        self.any_hit_on(simd::kernel(), origin, direction, t_min, t_max)
    }

    /// [`any_hit`](Self::any_hit) on a given SIMD kernel.
    ///
    /// The traversal is compiled once per axis permutation of the
    /// watertight test, and the ray's picks one: each leaf test then reads
    /// the coordinates it needs directly. Not inlined: six traversals (the
    /// SSE2 and scalar ones inlined) make it too big to copy into callers.
    #[inline(never)]
    pub(crate) fn any_hit_on(
        &self,
        kernel: Kernel,
        origin: DVec3,
        direction: DVec3,
        t_min: f64,
        t_max: f64,
    ) -> bool {
        let ray = WatertightRay::new(origin, direction);
        let node_ray = NodeRay::new(origin, direction);
        match ray.permutation() {
            0 => self.any_as::<0>(kernel, ray, &node_ray, t_min, t_max),
            1 => self.any_as::<1>(kernel, ray, &node_ray, t_min, t_max),
            2 => self.any_as::<2>(kernel, ray, &node_ray, t_min, t_max),
            3 => self.any_as::<3>(kernel, ray, &node_ray, t_min, t_max),
            4 => self.any_as::<4>(kernel, ray, &node_ray, t_min, t_max),
            _ => self.any_as::<5>(kernel, ray, &node_ray, t_min, t_max),
        }
    }

    /// [`any_hit_on`](Self::any_hit_on) for a ray of axis permutation `P`.
    #[inline(always)]
    fn any_as<const P: u8>(
        &self,
        kernel: Kernel,
        ray: WatertightRay,
        node_ray: &NodeRay,
        t_min: f64,
        t_max: f64,
    ) -> bool {
        let leaf = BlockingTriangle::<P> {
            mesh: self,
            ray,
            t_min,
            t_max,
        };
        self.bvh.any_on(kernel, node_ray, t_max, leaf)
    }

    /// [`any_hit`](Self::any_hit) for each of `rays` (origin and
    /// direction; `t_max[k]` ray k's limit), traced [`STREAM`] at a time in
    /// turns as [`intersect_stream`](Self::intersect_stream) traces them:
    /// for incoherent rays through a mesh larger than the cache. Bit k of
    /// the answer is set when ray k is blocked, as `any_hit` answers it
    /// alone.
    ///
    /// # Panics
    /// If there are more than 32 rays, or `t_max` is not as long as `rays`.
    pub fn any_hit_stream(&self, rays: &[(DVec3, DVec3)], t_min: f64, t_max: &[f64]) -> u32 {
        self.any_hit_stream_on(simd::kernel(), rays, t_min, t_max)
    }

    /// [`any_hit_stream`](Self::any_hit_stream) on a given kernel.
    pub(crate) fn any_hit_stream_on(
        &self,
        kernel: Kernel,
        rays: &[(DVec3, DVec3)],
        t_min: f64,
        t_max: &[f64],
    ) -> u32 {
        assert!(rays.len() <= 32 && t_max.len() == rays.len());
        let mut blocked = 0;
        for (c, (rays, t_max)) in rays.chunks(STREAM).zip(t_max.chunks(STREAM)).enumerate() {
            let ray = |k: usize| rays[k.min(rays.len() - 1)];
            let mut limits = [f64::NEG_INFINITY; STREAM];
            limits[..t_max.len()].copy_from_slice(t_max);
            let mut tests: [BlockingRay; STREAM] = std::array::from_fn(|k| BlockingRay {
                mesh: self,
                ray: WatertightRay::new(ray(k).0, ray(k).1),
                t_min,
                t_max: limits[k],
            });
            let node_rays = std::array::from_fn(|k| NodeRay::new(ray(k).0, ray(k).1));
            let mask = self
                .bvh
                .any_stream_on(kernel, &node_rays, rays.len(), &limits, &mut tests);
            blocked |= mask << (c * STREAM);
        }
        blocked
    }

    /// [`intersect`](Self::intersect) for each of up to [`PACKET`] rays
    /// (`rays[k]` is origin and direction, `t_max[k]` its limit, `hits[k]`
    /// its answer), traced together: coherent rays (neighbouring camera
    /// rays, feelers from one point) share their node visits. Each answer is, to the bit, what
    /// `intersect` gives that ray alone.
    ///
    /// # Panics
    /// If there are more than [`PACKET`] rays, or `t_max` or `hits` is not
    /// as long as `rays`.
    pub fn intersect_packet(
        &self,
        rays: &[(DVec3, DVec3)],
        t_min: f64,
        t_max: &[f64],
        hits: &mut [Option<MeshHit>],
    ) {
        self.intersect_packet_on(simd::kernel(), rays, t_min, t_max, hits);
    }

    /// [`intersect_packet`](Self::intersect_packet) on a given SIMD kernel.
    pub(crate) fn intersect_packet_on(
        &self,
        kernel: Kernel,
        rays: &[(DVec3, DVec3)],
        t_min: f64,
        t_max: &[f64],
        hits: &mut [Option<MeshHit>],
    ) {
        // Not through `closest_packet_on`, as `intersect_stream_on`.
        assert!(rays.len() <= PACKET && t_max.len() == rays.len() && hits.len() == rays.len());
        let Some(packet) = NodePacket::new(rays) else {
            for ((hit, &(o, d)), &t) in hits.iter_mut().zip(rays).zip(t_max) {
                *hit = self.intersect_on(kernel, o, d, t_min, t);
            }
            return;
        };
        let mut limits = padded(t_max);
        let mut leaf = ClosestTriangles {
            mesh: self,
            rays: LeafRays::new(rays),
            t_min,
            best: [None; PACKET],
            reach: limits,
        };
        self.bvh
            .closest_packet_on(kernel, &packet, &mut limits, &mut leaf);
        for ((hit, best), ray) in hits.iter_mut().zip(&leaf.best).zip(rays) {
            *hit = best.map(|(triangle, h)| self.surface(triangle, h.barycentric, h.t, ray.1));
        }
    }

    /// [`intersect_packet`](Self::intersect_packet) without the shading
    /// fields (see [`intersect_facet`](Self::intersect_facet)).
    pub fn intersect_facet_packet(
        &self,
        rays: &[(DVec3, DVec3)],
        t_min: f64,
        t_max: &[f64],
        hits: &mut [Option<FacetHit>],
    ) {
        self.closest_packet_on(simd::kernel(), rays, t_min, t_max, hits, |p, h, _| {
            self.facet(p, h)
        });
    }

    /// The packet search of `intersect_packet`, each hit (leaf position,
    /// triangle hit, the ray's direction) made into an answer by `finish`.
    #[inline(always)]
    fn closest_packet_on<H>(
        &self,
        kernel: Kernel,
        rays: &[(DVec3, DVec3)],
        t_min: f64,
        t_max: &[f64],
        hits: &mut [Option<H>],
        finish: impl Fn(usize, TriangleHit, DVec3) -> H,
    ) {
        assert!(rays.len() <= PACKET && t_max.len() == rays.len() && hits.len() == rays.len());
        let Some(packet) = NodePacket::new(rays) else {
            for ((hit, &(o, d)), &t) in hits.iter_mut().zip(rays).zip(t_max) {
                *hit = self.closest_on(kernel, o, d, t_min, t, |p, h| finish(p, h, d));
            }
            return;
        };
        let mut limits = padded(t_max);
        let mut leaf = ClosestTriangles {
            mesh: self,
            rays: LeafRays::new(rays),
            t_min,
            best: [None; PACKET],
            reach: limits,
        };
        self.bvh
            .closest_packet_on(kernel, &packet, &mut limits, &mut leaf);
        for ((hit, best), ray) in hits.iter_mut().zip(&leaf.best).zip(rays) {
            *hit = best.map(|(triangle, h)| finish(triangle, h, ray.1));
        }
    }

    /// [`any_hit`](Self::any_hit) for each of up to [`PACKET`] rays, traced
    /// together (see [`intersect_packet`](Self::intersect_packet)): bit k of
    /// the answer is set when ray k is blocked.
    ///
    /// # Panics
    /// If there are more than [`PACKET`] rays, or `t_max` is not as long
    /// as `rays`.
    pub fn any_hit_packet(&self, rays: &[(DVec3, DVec3)], t_min: f64, t_max: &[f64]) -> u32 {
        self.any_hit_packet_on(simd::kernel(), rays, t_min, t_max)
    }

    /// [`any_hit_packet`](Self::any_hit_packet) on a given SIMD kernel.
    pub(crate) fn any_hit_packet_on(
        &self,
        kernel: Kernel,
        rays: &[(DVec3, DVec3)],
        t_min: f64,
        t_max: &[f64],
    ) -> u32 {
        assert!(rays.len() <= PACKET && t_max.len() == rays.len());
        let Some(packet) = NodePacket::new(rays) else {
            return rays
                .iter()
                .zip(t_max)
                .enumerate()
                .fold(0, |mask, (k, (&(o, d), &t))| {
                    mask | u32::from(self.any_hit_on(kernel, o, d, t_min, t)) << k
                });
        };
        let limits = padded(t_max);
        let leaf = BlockingTriangles {
            mesh: self,
            rays: LeafRays::new(rays),
            t_min,
            t_max: limits,
        };
        self.bvh.any_packet_on(kernel, &packet, &limits, leaf)
    }

    /// The surface at the point of weights `bary` on `triangle`, hit by a
    /// ray along `direction`.
    fn surface(&self, triangle: usize, bary: DVec3, t: f64, direction: DVec3) -> MeshHit {
        let [ia, ib, ic] = self.triangles[triangle].map(|i| i as usize);
        let [a, b, c] = self.corners(triangle);
        let normal = facet_normal([a, b, c]);
        let interpolate3 = |v: &[DVec3]| bary.x * v[ia] + bary.y * v[ib] + bary.z * v[ic];
        let (shading_normal, feeler_offset) = if self.normals.is_empty() {
            (normal, DVec3::ZERO)
        } else {
            let shading_normal = interpolate3(&self.normals)
                .try_normalize()
                .unwrap_or(normal);
            // The vertex normals on the side the ray sees.
            let seen = if direction.dot(normal) < 0.0 {
                1.0
            } else {
                -1.0
            };
            let normals = [ia, ib, ic].map(|i| seen * self.normals[i].normalize_or_zero());
            let offset = terminator_offset([a, b, c], normals, bary);
            (shading_normal, offset)
        };
        let uv = if self.uvs.is_empty() {
            DVec2::ZERO
        } else {
            bary.x * self.uvs[ia] + bary.y * self.uvs[ib] + bary.z * self.uvs[ic]
        };
        let color = if self.colors.is_empty() {
            DVec3::ONE
        } else {
            interpolate3(&self.colors)
        };
        MeshHit {
            t,
            normal,
            shading_normal,
            uv,
            color,
            material: self.materials.get(triangle).copied().unwrap_or(0),
            triangle: self.bvh.order()[triangle],
            barycentric: bary,
            feeler_offset,
        }
    }

    /// The hit `h` of the triangle at leaf position `triangle` as a
    /// [`FacetHit`]: [`surface`](Self::surface)'s fields that need no
    /// shading data.
    #[inline(always)]
    fn facet(&self, triangle: usize, h: TriangleHit) -> FacetHit {
        FacetHit {
            t: h.t,
            triangle: self.bvh.order()[triangle],
            barycentric: h.barycentric,
            normal: facet_normal(self.corners(triangle)),
        }
    }
}

/// A world-space box holding object-space box `b` placed by `m`: the
/// centre mapped and the half extents through |M|, widened by more than
/// the rounding of either.
fn world_box(b: &Aabb, m: &DAffine3) -> Aabb {
    let centre = (b.min + b.max) * 0.5;
    let half = (b.max - b.min) * 0.5;
    let abs = glam::DMat3::from_cols(
        m.matrix3.x_axis.abs(),
        m.matrix3.y_axis.abs(),
        m.matrix3.z_axis.abs(),
    );
    let c = m.transform_point3(centre);
    let rounding = (abs * (centre.abs() + half) + m.translation.abs()) * (16.0 * f64::EPSILON);
    let h = abs * half + rounding + DVec3::splat(f64::MIN_POSITIVE);
    Aabb {
        min: c - h,
        max: c + h,
    }
}

/// The unit geometric normal of triangle (a, b, c): (b − a) × (c − a),
/// normalised (zero for a degenerate triangle).
#[inline(always)]
fn facet_normal([a, b, c]: [DVec3; 3]) -> DVec3 {
    (b - a).cross(c - a).normalize_or_zero()
}

/// A packet's limits, lanes past the last ray at −∞ (no ray there).
#[inline(always)]
fn padded(t_max: &[f64]) -> [f64; PACKET] {
    let mut limits = [f64::NEG_INFINITY; PACKET];
    limits[..t_max.len()].copy_from_slice(t_max);
    limits
}

/// A packet's rays prepared for the watertight test when a leaf is first
/// reached: a packet that meets no leaf (most of a camera's rays that miss)
/// never pays for it.
struct LeafRays<'r> {
    source: &'r [(DVec3, DVec3)],
    prepared: Option<([WatertightRay; PACKET], Option<WatertightLanes>)>,
}

impl<'r> LeafRays<'r> {
    fn new(source: &'r [(DVec3, DVec3)]) -> Self {
        LeafRays {
            source,
            prepared: None,
        }
    }

    /// The rays one by one (lanes past the last repeat ray 0), and all of
    /// them as lanes where they share the watertight test's axes.
    #[inline(always)]
    fn get(&mut self) -> &([WatertightRay; PACKET], Option<WatertightLanes>) {
        let source = self.source;
        self.prepared.get_or_insert_with(|| {
            let mut rays = [WatertightRay::new(source[0].0, source[0].1); PACKET];
            for (prepared, &(o, d)) in rays.iter_mut().zip(source).skip(1) {
                *prepared = WatertightRay::new(o, d);
            }
            (rays, WatertightLanes::new(&rays))
        })
    }
}

/// The closest-hit leaf test: the watertight test, keeping the nearest hit
/// and, of hits at the same t, the triangle first in the mesh's own order.
struct ClosestTriangle<'a, const P: u8 = ANY_AXES> {
    mesh: &'a Mesh,
    ray: WatertightRay,
    t_min: f64,
    /// Leaf position and hit of the triangle kept so far.
    best: Option<(usize, TriangleHit)>,
    /// Where to look for hits once one is held (see `closer_triangle`).
    reach: f64,
}

impl<'a, const P: u8> ClosestTriangle<'a, P> {
    /// The test of `mesh` for the ray `origin + t·direction`, with t above
    /// `t_min`, no hit held yet.
    #[inline(always)]
    fn new(mesh: &'a Mesh, origin: DVec3, direction: DVec3, t_min: f64) -> Self {
        ClosestTriangle {
            mesh,
            ray: WatertightRay::new(origin, direction),
            t_min,
            best: None,
            // Read only once a hit is held, which sets it.
            reach: f64::INFINITY,
        }
    }
}

impl<const P: u8> ClosestTest for ClosestTriangle<'_, P> {
    #[inline(always)]
    fn test(&mut self, position: usize, t_max: f64) -> Option<f64> {
        closer_triangle::<P>(
            self.mesh,
            &self.ray,
            self.t_min,
            (&mut self.best, &mut self.reach),
            position,
            t_max,
        )
    }

    #[inline(always)]
    fn prefetch(&self, position: usize, count: usize, what: Fetch) {
        prefetch_triangles(self.mesh, position, count, what);
    }
}

/// Asks the cache for what testing the `count` triangles from leaf
/// position `position` reads (see `ClosestTest::prefetch`).
#[inline(always)]
fn prefetch_triangles(mesh: &Mesh, position: usize, count: usize, what: Fetch) {
    let triangles = &mesh.triangles[position..position + count];
    match what {
        // At most four triangles of 12 bytes: one or two lines.
        Fetch::Items => {
            simd::prefetch(&triangles[0]);
            simd::prefetch(&triangles[count - 1]);
        }
        Fetch::Data => {
            for &i in triangles.iter().flatten() {
                simd::prefetch(&mesh.positions[i as usize]);
            }
        }
    }
}

impl<const P: u8> ClosestTest for &mut ClosestTriangle<'_, P> {
    #[inline(always)]
    fn test(&mut self, position: usize, t_max: f64) -> Option<f64> {
        (**self).test(position, t_max)
    }
}

/// Rays traced in turns by [`Mesh::intersect_stream`] and the other
/// streams: on the 1M-triangle terrain eight hid more misses than four
/// (2.6 against 2.1–2.2 Mrays/s), and sixteen more than eight (the ray
/// queries' scattered rays through the 940k-triangle bunny and the
/// terrain, 1–6 % less time; 24 gained nothing more).
pub const STREAM: usize = 16;

/// The fewest rays a triangle is tested against in eight lanes at once;
/// fewer are tested one by one (eight lanes cost about three rays' tests).
const LANES_FROM: u32 = 3;

/// The closest-hit leaf test of a packet: [`ClosestTriangle`]'s, ray by
/// ray, or all rays at once where they share the watertight test's axes.
struct ClosestTriangles<'a> {
    mesh: &'a Mesh,
    rays: LeafRays<'a>,
    t_min: f64,
    best: [Option<(usize, TriangleHit)>; PACKET],
    /// Where the lanes look for hits: `t_max`, or just past it once a hit
    /// is held (a hit at the same t is looked for too).
    reach: [f64; PACKET],
}

impl PacketClosestTest for &mut ClosestTriangles<'_> {
    #[inline(always)]
    fn test(&mut self, rays: u32, position: usize, t_max: &mut [f64; PACKET]) -> u32 {
        let mut closer = 0;
        let (one_by_one, lanes) = self.rays.get();
        let Some(lanes) = lanes.as_ref().filter(|_| rays.count_ones() >= LANES_FROM) else {
            let mut scan = rays;
            while scan != 0 {
                let k = scan.trailing_zeros() as usize;
                scan &= scan - 1;
                let held = (&mut self.best[k], &mut self.reach[k]);
                if let Some(t) = closer_triangle::<ANY_AXES>(
                    self.mesh,
                    &one_by_one[k],
                    self.t_min,
                    held,
                    position,
                    t_max[k],
                ) {
                    t_max[k] = t;
                    closer |= 1 << k;
                }
            }
            return closer;
        };
        // What `closer_triangle` does, with the triangle test for all lanes
        // at once.
        let [a, b, c] = self.mesh.corners(position);
        let hits = triangle_hit_lanes(lanes, rays, a, b, c, self.t_min, &self.reach);
        let order = self.mesh.bvh.order();
        let mut scan = hits.mask;
        while scan != 0 {
            let k = scan.trailing_zeros() as usize;
            scan &= scan - 1;
            let h = hits.hit(k);
            let best = &mut self.best[k];
            if best.is_some_and(|(held, bh)| h.t == bh.t && order[held] < order[position]) {
                continue;
            }
            *best = Some((position, h));
            t_max[k] = h.t;
            self.reach[k] = h.t.next_up();
            closer |= 1 << k;
        }
        closer
    }
}

/// The leaf tests' permutation parameter for a ray of any permutation
/// (its axes read at run time); 0 to 5 name one (see
/// `WatertightRay::permutation`).
const ANY_AXES: u8 = u8::MAX;

/// Tests the triangle at leaf position `position` (with the ray's axes
/// those of permutation `P`, or its own for `ANY_AXES`); keeps it in `best` when
/// it is nearer than the hit held there, or as near and first in the
/// mesh's own order, and then returns its distance.
#[inline(always)]
fn closer_triangle<const P: u8>(
    mesh: &Mesh,
    ray: &WatertightRay,
    t_min: f64,
    (best, reach): (&mut Option<(usize, TriangleHit)>, &mut f64),
    position: usize,
    t_max: f64,
) -> Option<f64> {
    let corners = mesh.corner_refs(position);
    // Once a hit is held, one at the same t is looked for too: `reach`,
    // just past it, kept from when it was found (the searches pass the
    // held hit's t as `t_max`).
    let limit = match best {
        Some((_, held)) => {
            debug_assert!(held.t == t_max && *reach == t_max.next_up());
            *reach
        }
        None => t_max,
    };
    let h = if P == ANY_AXES {
        triangle_hit_at(ray, corners, t_min, limit)
    } else {
        triangle_hit_as::<P>(ray, corners, t_min, limit)
    }?;
    let order = mesh.bvh.order();
    if best.is_some_and(|(held, bh)| h.t == bh.t && order[held] < order[position]) {
        return None;
    }
    *best = Some((position, h));
    *reach = h.t.next_up();
    Some(h.t)
}

/// The any-hit leaf test.
struct BlockingTriangle<'a, const P: u8> {
    mesh: &'a Mesh,
    ray: WatertightRay,
    t_min: f64,
    t_max: f64,
}

impl<const P: u8> AnyTest for BlockingTriangle<'_, P> {
    #[inline(always)]
    fn test(&mut self, position: usize) -> bool {
        let corners = self.mesh.corner_refs(position);
        triangle_hit_as::<P>(&self.ray, corners, self.t_min, self.t_max).is_some()
    }
}

/// The leaf test of `each_hit` for a ray of axis permutation `P`: every
/// triangle hit within (t_min, t_max) reported to `each`; never blocks, so
/// the any-hit traversal runs to its end.
struct EveryTriangle<'a, F, const P: u8> {
    mesh: &'a Mesh,
    ray: WatertightRay,
    t_min: f64,
    t_max: f64,
    each: &'a mut F,
}

impl<F: FnMut(u32, TriangleHit), const P: u8> AnyTest for EveryTriangle<'_, F, P> {
    #[inline(always)]
    fn test(&mut self, position: usize) -> bool {
        let corners = self.mesh.corner_refs(position);
        if let Some(h) = triangle_hit_as::<P>(&self.ray, corners, self.t_min, self.t_max) {
            (self.each)(self.mesh.bvh.order()[position], h);
        }
        false
    }
}

/// The counting leaf test of one ray of a stream: each triangle hit within
/// the fixed (t_min, t_max) counted, as `each_hit` reports it; never
/// blocks.
struct CountingTriangles<'a> {
    mesh: &'a Mesh,
    ray: WatertightRay,
    t_min: f64,
    t_max: f64,
    count: u32,
}

impl AnyTest for CountingTriangles<'_> {
    #[inline(always)]
    fn test(&mut self, position: usize) -> bool {
        let [a, b, c] = self.mesh.corners(position);
        if triangle_hit_dispatched(&self.ray, a, b, c, self.t_min, self.t_max).is_some() {
            self.count = self.count.saturating_add(1);
        }
        false
    }

    #[inline(always)]
    fn prefetch(&self, position: usize, count: usize, what: Fetch) {
        prefetch_triangles(self.mesh, position, count, what);
    }
}

/// The any-hit leaf test of one ray of a stream: [`BlockingTriangle`]'s,
/// the ray's permutation picked per test (the rays of a stream differ).
struct BlockingRay<'a> {
    mesh: &'a Mesh,
    ray: WatertightRay,
    t_min: f64,
    t_max: f64,
}

impl AnyTest for BlockingRay<'_> {
    #[inline(always)]
    fn test(&mut self, position: usize) -> bool {
        let [a, b, c] = self.mesh.corners(position);
        triangle_hit_dispatched(&self.ray, a, b, c, self.t_min, self.t_max).is_some()
    }

    #[inline(always)]
    fn prefetch(&self, position: usize, count: usize, what: Fetch) {
        prefetch_triangles(self.mesh, position, count, what);
    }
}

/// The any-hit leaf test of a packet: [`BlockingTriangle`]'s, ray by ray,
/// or all rays at once where they share the watertight test's axes.
struct BlockingTriangles<'a> {
    mesh: &'a Mesh,
    rays: LeafRays<'a>,
    t_min: f64,
    t_max: [f64; PACKET],
}

impl PacketAnyTest for BlockingTriangles<'_> {
    #[inline(always)]
    fn test(&mut self, rays: u32, position: usize) -> u32 {
        let [a, b, c] = self.mesh.corners(position);
        let (one_by_one, lanes) = self.rays.get();
        if let Some(lanes) = lanes.as_ref().filter(|_| rays.count_ones() >= LANES_FROM) {
            return triangle_hit_lanes(lanes, rays, a, b, c, self.t_min, &self.t_max).mask;
        }
        let mut blocked = 0;
        let mut scan = rays;
        while scan != 0 {
            let k = scan.trailing_zeros() as usize;
            scan &= scan - 1;
            let hit = triangle_hit_dispatched(&one_by_one[k], a, b, c, self.t_min, self.t_max[k]);
            blocked |= u32::from(hit.is_some()) << k;
        }
        blocked
    }
}

/// The counting leaf test of a packet: each triangle hit counted per ray,
/// tested as [`BlockingTriangles`] tests it; never blocks.
struct CountingPacket<'a> {
    mesh: &'a Mesh,
    rays: LeafRays<'a>,
    t_min: f64,
    t_max: [f64; PACKET],
    counts: [u32; PACKET],
}

impl PacketAnyTest for &mut CountingPacket<'_> {
    #[inline(always)]
    fn test(&mut self, rays: u32, position: usize) -> u32 {
        let [a, b, c] = self.mesh.corners(position);
        let (one_by_one, lanes) = self.rays.get();
        let mut hit = 0;
        if let Some(lanes) = lanes.as_ref().filter(|_| rays.count_ones() >= LANES_FROM) {
            hit = triangle_hit_lanes(lanes, rays, a, b, c, self.t_min, &self.t_max).mask;
        } else {
            let mut scan = rays;
            while scan != 0 {
                let k = scan.trailing_zeros() as usize;
                scan &= scan - 1;
                let h = triangle_hit_dispatched(&one_by_one[k], a, b, c, self.t_min, self.t_max[k]);
                hit |= u32::from(h.is_some()) << k;
            }
        }
        while hit != 0 {
            let k = hit.trailing_zeros() as usize;
            hit &= hit - 1;
            self.counts[k] = self.counts[k].saturating_add(1);
        }
        0
    }
}

/// Numbers the vertices in the order the leaf-ordered `triangles` first
/// use them, and reorders the per-vertex data to match: a leaf's vertices,
/// and its neighbours', then share cache lines instead of lying a grid row
/// or a file apart (on the 1M terrain most triangle tests waited for their
/// vertices). Vertices no triangle uses are dropped. The values are
/// untouched, so every hit is the same.
fn renumber_vertices(
    triangles: &mut [[u32; 3]],
    positions: Vec<DVec3>,
    normals: Vec<DVec3>,
    uvs: Vec<DVec2>,
    colors: Vec<DVec3>,
) -> (Vec<DVec3>, Vec<DVec3>, Vec<DVec2>, Vec<DVec3>) {
    const UNSEEN: u32 = u32::MAX;
    let mut new_number = vec![UNSEEN; positions.len()];
    let mut old_number = Vec::with_capacity(positions.len());
    for index in triangles.iter_mut().flatten() {
        let slot = &mut new_number[*index as usize];
        if *slot == UNSEEN {
            *slot = old_number.len() as u32;
            old_number.push(*index);
        }
        *index = *slot;
    }
    drop(new_number);
    fn gather<T: Copy>(values: Vec<T>, old_number: &[u32]) -> Vec<T> {
        if values.is_empty() {
            return values;
        }
        huge_pages::collect(old_number.iter().map(|&i| values[i as usize]))
    }
    (
        gather(positions, &old_number),
        gather(normals, &old_number),
        gather(uvs, &old_number),
        gather(colors, &old_number),
    )
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A unit cube from (0,0,0) to (1,1,1), 12 triangles, outward winding.
    pub fn cube() -> MeshData {
        let positions = (0..8)
            .map(|i| DVec3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64))
            .collect();
        let quads = [
            [0, 2, 3, 1],
            [4, 5, 7, 6], // z = 0, z = 1
            [0, 1, 5, 4],
            [2, 6, 7, 3], // y = 0, y = 1
            [0, 4, 6, 2],
            [1, 3, 7, 5], // x = 0, x = 1
        ];
        let triangles = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        MeshData {
            positions,
            triangles,
            ..Default::default()
        }
    }

    #[test]
    fn cube_hits_have_outward_normals_and_distances() {
        let m = Mesh::new(cube()).unwrap();
        assert_eq!(m.triangle_count(), 12);
        let h = m
            .intersect(DVec3::new(0.3, 0.6, 5.0), -DVec3::Z, 0.0, f64::INFINITY)
            .unwrap();
        assert!((h.t - 4.0).abs() < 1e-12);
        assert!((h.normal - DVec3::Z).length() < 1e-12, "{}", h.normal);
        // From inside, the far wall.
        let h = m
            .intersect(DVec3::splat(0.5), DVec3::X, 0.0, f64::INFINITY)
            .unwrap();
        assert!((h.t - 0.5).abs() < 1e-12 && (h.normal - DVec3::X).length() < 1e-12);
        assert!(m.any_hit(DVec3::splat(0.5), DVec3::X, 0.0, 0.6));
        assert!(!m.any_hit(DVec3::splat(0.5), DVec3::X, 0.0, 0.4));
        // Along the cube's diagonal edge between two triangles of a face.
        let h = m
            .intersect(DVec3::new(0.5, 0.5, -3.0), DVec3::Z, 0.0, f64::INFINITY)
            .unwrap();
        assert!((h.t - 3.0).abs() < 1e-12);
    }

    #[test]
    fn smooth_normals_and_uvs_interpolate() {
        let data = MeshData {
            positions: vec![DVec3::ZERO, DVec3::X, DVec3::Y],
            normals: vec![DVec3::Z, DVec3::Z, DVec3::new(0.0, 1.0, 1.0)],
            uvs: vec![DVec2::ZERO, DVec2::X, DVec2::Y],
            triangles: vec![[0, 1, 2]],
            materials: vec![3],
            colors: vec![DVec3::X, DVec3::Y, DVec3::Z],
        };
        let m = Mesh::new(data).unwrap();
        let h = m
            .intersect(DVec3::new(0.25, 0.5, 1.0), -DVec3::Z, 0.0, f64::INFINITY)
            .unwrap();
        assert!((h.uv - DVec2::new(0.25, 0.5)).length() < 1e-12);
        // Barycentric (0.25, 0.25, 0.5) of red, green, blue.
        assert!(
            (h.color - DVec3::new(0.25, 0.25, 0.5)).length() < 1e-12,
            "{}",
            h.color
        );
        let expected = (0.5 * DVec3::Z + 0.5 * DVec3::new(0.0, 1.0, 1.0)).normalize();
        assert!((h.shading_normal - expected).length() < 1e-12);
        assert_eq!(h.normal, DVec3::Z);
        assert_eq!(h.material, 3);
    }

    #[test]
    fn bad_data_is_refused() {
        let mut d = cube();
        d.triangles[5] = [0, 1, 8];
        assert_eq!(
            Mesh::new(d),
            Err(MeshError::IndexOutOfRange {
                triangle: 5,
                index: 8,
                count: 8
            })
        );
        let mut d = cube();
        d.positions[2].y = f64::NAN;
        assert_eq!(
            Mesh::new(d),
            Err(MeshError::NotFinite {
                what: "vertex",
                index: 2
            })
        );
        let mut d = cube();
        d.normals = vec![DVec3::Z; 3];
        assert!(matches!(Mesh::new(d), Err(MeshError::CountMismatch { .. })));
        assert_eq!(Mesh::new(MeshData::default()), Err(MeshError::Empty));
    }

    /// A bumpy n×n grid over [0, n]², heights from a seeded generator.
    pub(crate) fn bumpy_grid(n: u32, seed: u64) -> MeshData {
        let mut rng = crate::math::rng::PixelRng::new(seed, 0, 0);
        let positions = (0..(n + 1) * (n + 1))
            .map(|i| {
                DVec3::new(
                    (i % (n + 1)) as f64,
                    0.3 * rng.uniform(),
                    (i / (n + 1)) as f64,
                )
            })
            .collect();
        let triangles = (0..n * n)
            .flat_map(|q| {
                let a = q / n * (n + 1) + q % n;
                [[a, a + n + 1, a + 1], [a + 1, a + n + 1, a + n + 2]]
            })
            .collect();
        MeshData {
            positions,
            triangles,
            ..Default::default()
        }
    }

    fn kernels() -> Vec<Kernel> {
        crate::accel::SimdPath::ALL
            .iter()
            .filter_map(|p| p.kernel())
            .collect()
    }

    #[test]
    fn every_simd_path_gives_the_same_hits() {
        let data = bumpy_grid(24, 3);
        let mesh = Mesh::new(data.clone()).unwrap();
        let mut rng = crate::math::rng::PixelRng::new(11, 0, 0);
        let mut hits = 0;
        for i in 0..20_000 {
            // Aim at a vertex, a point of an edge, or anywhere.
            let t = data.triangles[(rng.uniform() * data.triangles.len() as f64) as usize];
            let [a, b, c] = t.map(|k| data.positions[k as usize]);
            let target = match i % 4 {
                0 => a,
                1 => a + (b - a) * 0.5,
                2 => b + (c - b) * rng.uniform(),
                _ => DVec3::new(rng.uniform() * 24.0, 0.15, rng.uniform() * 24.0),
            };
            let origin = DVec3::new(
                rng.uniform() * 40.0 - 8.0,
                0.5 + rng.uniform() * 10.0,
                rng.uniform() * 40.0 - 8.0,
            );
            let direction = target - origin;
            let t_max = if i % 3 == 0 { 0.999 } else { f64::INFINITY };
            let kernels = kernels();
            let first = mesh.intersect_on(kernels[0], origin, direction, 0.0, t_max);
            let any = mesh.any_hit_on(kernels[0], origin, direction, 0.0, t_max);
            assert_eq!(first.is_some(), any);
            hits += usize::from(any);
            for &k in &kernels[1..] {
                let other = mesh.intersect_on(k, origin, direction, 0.0, t_max);
                assert_eq!(
                    first.map(|h| h.t.to_bits()),
                    other.map(|h| h.t.to_bits()),
                    "{k:?}"
                );
                assert_eq!(first, other, "{k:?}");
                assert_eq!(
                    any,
                    mesh.any_hit_on(k, origin, direction, 0.0, t_max),
                    "{k:?}"
                );
            }
        }
        assert!(hits > 10_000, "{hits}");
    }

    /// Bit-for-bit equality of two answers, the distance by its bits.
    fn same_hit(a: Option<MeshHit>, b: Option<MeshHit>) -> bool {
        a.map(|h| h.t.to_bits()) == b.map(|h| h.t.to_bits()) && a == b
    }

    #[test]
    fn packets_answer_each_ray_as_it_is_answered_alone() {
        // Packets of every kind the traversal treats apart: rays from one
        // origin (a camera's tile, a point's feelers), from eight origins
        // (shadow rays of neighbouring hits), of unlike signs (traced one
        // by one), of unlike dominant axes (leaf tests one by one), short
        // ones, and limits that end before the surface; rays aimed at
        // vertices, edges and anywhere, on every SIMD path.
        // Twice: over a bumpy grid, and through a soup of crossing
        // triangles, where a ray's leaves overlap along it (a hit found in
        // one leaf must bound the next).
        let mut rng = crate::math::rng::PixelRng::new(29, 0, 0);
        let soup = crossing_soup(&mut rng);
        for data in [bumpy_grid(24, 7), soup] {
            packets_answer_as_alone(&data, &mut rng);
        }
    }

    /// 1,500 triangles of size 3 crossing one another over a 24 × 3 × 24
    /// slab: a ray's leaves overlap along it.
    fn crossing_soup(rng: &mut crate::math::rng::PixelRng) -> MeshData {
        let mut soup = MeshData::default();
        for i in 0..1_500u32 {
            let center = DVec3::new(
                rng.uniform() * 24.0,
                rng.uniform() * 3.0,
                rng.uniform() * 24.0,
            );
            for _ in 0..3 {
                let corner = DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 2.0 - 1.0;
                soup.positions.push(center + corner * 1.5);
            }
            soup.triangles.push([3 * i, 3 * i + 1, 3 * i + 2]);
        }
        soup
    }

    #[test]
    fn streams_answer_each_ray_as_it_is_answered_alone() {
        // Incoherent rays (random origins over and inside the meshes,
        // aimed at vertices, edges and anywhere, some with limits that end
        // early), traced in turns, a last group shorter than STREAM, on
        // every SIMD path; over a bumpy grid and through a crossing soup.
        let mut rng = crate::math::rng::PixelRng::new(31, 0, 0);
        let soup = crossing_soup(&mut rng);
        for data in [bumpy_grid(24, 7), soup] {
            let mesh = Mesh::new(data.clone()).unwrap();
            let (mut rays, mut t_max) = (Vec::new(), Vec::new());
            for i in 0..2_003 {
                let t = data.triangles[(rng.uniform() * data.triangles.len() as f64) as usize];
                let [a, b, c] = t.map(|k| data.positions[k as usize]);
                let target = match i % 4 {
                    0 => a,
                    1 => a + (b - a) * 0.5,
                    2 => b + (c - b) * rng.uniform(),
                    _ => DVec3::new(rng.uniform() * 24.0, rng.uniform(), rng.uniform() * 24.0),
                };
                let origin = DVec3::new(
                    rng.uniform() * 40.0 - 8.0,
                    rng.uniform() * 8.0 - 2.0,
                    rng.uniform() * 40.0 - 8.0,
                );
                rays.push((origin, target - origin));
                t_max.push(if i % 7 == 0 { 0.999 } else { f64::INFINITY });
            }
            let mut hits_seen = 0;
            for kernel in kernels() {
                let mut streamed = vec![None; rays.len()];
                mesh.intersect_stream_on(kernel, &rays, 0.0, &t_max, &mut streamed);
                for (k, &(o, d)) in rays.iter().enumerate() {
                    let alone = mesh.intersect_on(kernel, o, d, 0.0, t_max[k]);
                    assert!(same_hit(streamed[k], alone), "ray {k}, {kernel:?}");
                    hits_seen += usize::from(alone.is_some());
                }
                // Any hit: in groups of up to 32 (a last one shorter).
                for (g, (rays, t_max)) in rays.chunks(32).zip(t_max.chunks(32)).enumerate() {
                    let mask = mesh.any_hit_stream_on(kernel, rays, 0.0, t_max);
                    for (k, &(o, d)) in rays.iter().enumerate() {
                        let alone = mesh.any_hit_on(kernel, o, d, 0.0, t_max[k]);
                        assert_eq!(
                            mask & (1 << k) != 0,
                            alone,
                            "ray {}, {kernel:?}",
                            32 * g + k
                        );
                    }
                }
            }
            assert!(hits_seen > 1_000, "{hits_seen}");
            // The query's forms on this CPU's kernel: facet hits and
            // counts, streamed, against the renderer's hit and brute force.
            let mut facets = vec![None; rays.len()];
            mesh.intersect_facet_stream(&rays, 0.0, &t_max, &mut facets);
            let mut counts = vec![0; rays.len()];
            for ((rays, t_max), counts) in rays
                .chunks(STREAM)
                .zip(t_max.chunks(STREAM))
                .zip(counts.chunks_mut(STREAM))
            {
                mesh.count_hits_stream(rays, 0.0, t_max, counts);
            }
            for (k, &(o, d)) in rays.iter().enumerate() {
                assert_facet_and_count(&mesh, &data, (o, d), t_max[k], facets[k], counts[k]);
            }
        }
    }

    /// `facet` and `count`, found for ray `(o, d)` up to `t_max` by a
    /// packet or stream, are the renderer's hit's fields and the number of
    /// triangles brute force hits, as `intersect_facet` and `count_hits`
    /// give them for the ray alone.
    fn assert_facet_and_count(
        mesh: &Mesh,
        data: &MeshData,
        (o, d): (DVec3, DVec3),
        t_max: f64,
        facet: Option<FacetHit>,
        count: u32,
    ) {
        let expected = mesh.intersect(o, d, 0.0, t_max).map(|h| FacetHit {
            t: h.t,
            triangle: h.triangle,
            barycentric: h.barycentric,
            normal: h.normal,
        });
        let bits = |h: Option<FacetHit>| {
            h.map(|h| {
                let [x, y, z] = h.barycentric.to_array().map(f64::to_bits);
                let [nx, ny, nz] = h.normal.to_array().map(f64::to_bits);
                (h.t.to_bits(), h.triangle, [x, y, z, nx, ny, nz])
            })
        };
        assert_eq!(bits(facet), bits(expected), "ray {o} {d}");
        assert_eq!(bits(mesh.intersect_facet(o, d, 0.0, t_max)), bits(expected));
        let ray = WatertightRay::new(o, d);
        let brute = data
            .triangles
            .iter()
            .filter(|t| {
                let [a, b, c] = t.map(|i| data.positions[i as usize]);
                triangle_hit(&ray, a, b, c, 0.0, t_max).is_some()
            })
            .count();
        assert_eq!(count as usize, brute, "ray {o} {d}");
        assert_eq!(mesh.count_hits(o, d, 0.0, t_max) as usize, brute);
    }

    fn packets_answer_as_alone(data: &MeshData, rng: &mut crate::math::rng::PixelRng) {
        let mesh = Mesh::new(data.clone()).unwrap();
        let (mut hits, mut blocked, mut rays_seen) = (0, 0, 0);
        for i in 0..3_000 {
            let len = if i % 5 == 0 { 1 + i % PACKET } else { PACKET };
            let shared = DVec3::new(
                rng.uniform() * 40.0 - 8.0,
                0.5 + rng.uniform() * 10.0,
                rng.uniform() * 40.0 - 8.0,
            );
            let spread = [0.0, 1e-3, 0.3, 30.0][i % 4];
            let center = DVec3::new(rng.uniform() * 24.0, 0.15, rng.uniform() * 24.0);
            let mut rays = Vec::new();
            let mut t_max = Vec::new();
            for k in 0..len {
                let t = data.triangles[(rng.uniform() * data.triangles.len() as f64) as usize];
                let [a, b, c] = t.map(|k| data.positions[k as usize]);
                let target = match (i + k) % 4 {
                    0 => a,
                    1 => a + (b - a) * 0.5,
                    2 => b + (c - b) * rng.uniform(),
                    _ => {
                        center + DVec3::new(rng.uniform() - 0.5, 0.0, rng.uniform() - 0.5) * spread
                    }
                };
                let origin = if i % 3 == 0 {
                    shared
                } else {
                    shared + DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * spread
                };
                rays.push((origin, target - origin));
                t_max.push(if (i + k) % 7 == 0 {
                    0.999
                } else {
                    f64::INFINITY
                });
            }
            rays_seen += len;
            for kernel in kernels() {
                let mut together = [None; PACKET];
                mesh.intersect_packet_on(kernel, &rays, 0.0, &t_max, &mut together[..len]);
                let blocking = mesh.any_hit_packet_on(kernel, &rays, 0.0, &t_max);
                assert_eq!(blocking >> len, 0);
                for (k, &(o, d)) in rays.iter().enumerate() {
                    let alone = mesh.intersect_on(kernel, o, d, 0.0, t_max[k]);
                    assert!(
                        same_hit(together[k], alone),
                        "packet {i}, ray {k}, {kernel:?}"
                    );
                    let any = mesh.any_hit_on(kernel, o, d, 0.0, t_max[k]);
                    assert_eq!(
                        blocking >> k & 1 == 1,
                        any,
                        "packet {i}, ray {k}, {kernel:?}"
                    );
                    hits += usize::from(alone.is_some());
                    blocked += usize::from(any);
                }
            }
            let mut facets = [None; PACKET];
            mesh.intersect_facet_packet(&rays, 0.0, &t_max, &mut facets[..len]);
            let mut counts = [0; PACKET];
            mesh.count_hits_packet(&rays, 0.0, &t_max, &mut counts[..len]);
            for (k, &ray) in rays.iter().enumerate() {
                assert_facet_and_count(&mesh, data, ray, t_max[k], facets[k], counts[k]);
            }
        }
        // Most rays hit, and the limits leave some short.
        let total = rays_seen * kernels().len();
        assert!(hits > total / 2 && hits < total, "{hits} of {total}");
        assert_eq!(hits, blocked);
    }

    #[test]
    fn packets_keep_the_tie_break() {
        // The duplicate triangle of the test below, hit by a packet of rays
        // around its centre: each gets the lower index, as alone.
        let mut data = bumpy_grid(8, 5);
        let copy = data.triangles[77];
        data.materials = vec![0; data.triangles.len()];
        data.triangles.insert(0, copy);
        data.materials.insert(0, 1);
        let mesh = Mesh::new(data.clone()).unwrap();
        let [a, b, c] = copy.map(|k| data.positions[k as usize]);
        let target = (a + b + c) / 3.0;
        let origin = target + DVec3::new(0.3, 5.0, -0.2);
        let rays: Vec<_> = (0..PACKET)
            .map(|k| (origin, target + (b - a) * (k as f64 * 0.01) - origin))
            .collect();
        for kernel in kernels() {
            let mut hits = [None; PACKET];
            mesh.intersect_packet_on(kernel, &rays, 0.0, &[f64::INFINITY; PACKET], &mut hits);
            assert!(hits.iter().all(|h| h.unwrap().material == 1), "{kernel:?}");
        }
    }

    #[test]
    fn ties_go_to_the_lowest_triangle_index() {
        // A duplicate of one grid triangle with another material, once
        // before the grid and once after it: the same t exactly, so the
        // lower index must win whatever order the tree visits them in.
        let grid = bumpy_grid(8, 5);
        let original = 77;
        for duplicate_first in [false, true] {
            let mut data = grid.clone();
            let copy = data.triangles[original];
            data.materials = vec![0; data.triangles.len()];
            let original_index = if duplicate_first {
                data.triangles.insert(0, copy);
                data.materials.insert(0, 1);
                original + 1
            } else {
                data.triangles.push(copy);
                data.materials.push(1);
                original
            };
            let mesh = Mesh::new(data.clone()).unwrap();
            let [a, b, c] = copy.map(|k| data.positions[k as usize]);
            let target = (a + b + c) / 3.0;
            let origin = target + DVec3::new(0.3, 5.0, -0.2);
            let lowest = if duplicate_first { 0 } else { original_index };
            for k in kernels() {
                let h = mesh
                    .intersect_on(k, origin, target - origin, 0.0, f64::INFINITY)
                    .unwrap();
                assert_eq!(
                    h.material, data.materials[lowest],
                    "{k:?}, first {duplicate_first}"
                );
            }
        }
    }
}
