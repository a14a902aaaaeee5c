//! RayScene (prism::query) against references: brute force over every
//! triangle with the same watertight test, the renderer's own hits, the
//! watertightness test of pbrt-v4 (rays from inside perturbed closed meshes
//! never escape), and `contains` against an exact crossing count made of
//! Shewchuk's exact orient3d.

// The torus's vertices: any sin/cos will do (no bits are compared across
// machines).
#![allow(clippy::disallowed_methods)]

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use glam::{DAffine3, DMat4, DVec3};
use prism::accel::{Aggregate, Primitive, Shape};
use prism::geometry::nearest::{NearestOnTriangle, nearest_on_triangle};
use prism::geometry::triangle::{WatertightRay, triangle_hit};
use prism::geometry::{Mesh, MeshData, MeshInstance};
use prism::math::{Ray, Transform};
use prism::query::{Coordinates, QueryError, QueryOptions, RayScene, Rays};
use prism::scene::LoadOptions;
use prism::scene::models::load_model;
use prism::scene::resources::Resources;

/// splitmix64: a seeded stream of uniform numbers.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    fn f(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.f()
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
    /// A uniform direction.
    fn direction(&mut self) -> DVec3 {
        loop {
            let v = DVec3::new(
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
            );
            let l = v.length_squared();
            if l > 1e-6 && l <= 1.0 {
                return v / l.sqrt();
            }
        }
    }
}

/// Vertices and faces as flat arrays.
#[derive(Clone)]
struct Soup {
    vertices: Vec<f64>,
    faces: Vec<u32>,
}

impl Soup {
    fn vertex(&self, i: u32) -> DVec3 {
        DVec3::from_slice(&self.vertices[3 * i as usize..])
    }
    fn triangles(&self) -> Vec<[DVec3; 3]> {
        self.faces
            .chunks_exact(3)
            .map(|f| [self.vertex(f[0]), self.vertex(f[1]), self.vertex(f[2])])
            .collect()
    }
    fn data(&self) -> MeshData {
        MeshData {
            positions: self
                .vertices
                .chunks_exact(3)
                .map(DVec3::from_slice)
                .collect(),
            triangles: self
                .faces
                .chunks_exact(3)
                .map(|f| [f[0], f[1], f[2]])
                .collect(),
            ..MeshData::default()
        }
    }
}

/// `n` random triangles in the box [-1, 1]³.
fn random_soup(rng: &mut Rng, n: usize) -> Soup {
    let mut vertices = Vec::new();
    for _ in 0..n {
        let centre = DVec3::new(
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
        );
        for _ in 0..3 {
            vertices.extend((centre + 0.3 * rng.direction()).to_array());
        }
    }
    Soup {
        vertices,
        faces: (0..3 * n as u32).collect(),
    }
}

/// An icosphere of `levels` subdivisions, each vertex's radius drawn from
/// [1 - jitter, 1 + jitter]: closed and consistently wound.
fn icosphere(levels: u32, jitter: f64, rng: &mut Rng) -> Soup {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut points: Vec<DVec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|p| DVec3::from_array(*p).normalize())
    .collect();
    let mut faces: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut middle = std::collections::HashMap::new();
        let mut mid = |a: u32, b: u32, points: &mut Vec<DVec3>| {
            *middle.entry((a.min(b), a.max(b))).or_insert_with(|| {
                points.push(((points[a as usize] + points[b as usize]) / 2.0).normalize());
                points.len() as u32 - 1
            })
        };
        let mut next = Vec::new();
        for [a, b, c] in faces {
            let (ab, bc, ca) = (
                mid(a, b, &mut points),
                mid(b, c, &mut points),
                mid(c, a, &mut points),
            );
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        faces = next;
    }
    let vertices = points
        .iter()
        .flat_map(|p| (*p * rng.range(1.0 - jitter, 1.0 + jitter)).to_array())
        .collect();
    Soup {
        vertices,
        faces: faces.into_iter().flatten().collect(),
    }
}

/// A torus (radii 1 and 0.4) of `n` × `m` quads, each vertex moved by up
/// to `jitter` in a random direction.
fn torus(n: u32, m: u32, jitter: f64, rng: &mut Rng) -> Soup {
    let mut vertices = Vec::new();
    for i in 0..n {
        for j in 0..m {
            let (u, v) = (
                std::f64::consts::TAU * i as f64 / n as f64,
                std::f64::consts::TAU * j as f64 / m as f64,
            );
            let p = DVec3::new(
                (1.0 + 0.4 * v.cos()) * u.cos(),
                (1.0 + 0.4 * v.cos()) * u.sin(),
                0.4 * v.sin(),
            );
            vertices.extend((p + jitter * rng.f() * rng.direction()).to_array());
        }
    }
    let id = |i: u32, j: u32| (i % n) * m + (j % m);
    let mut faces = Vec::new();
    for i in 0..n {
        for j in 0..m {
            faces.extend([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            faces.extend([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    Soup { vertices, faces }
}

fn rays(origins: &[f64], directions: &[f64]) -> Rays<'static> {
    // Leaked: tests only, so that the batches outlive the calls.
    let o: &'static [f64] = Vec::leak(origins.to_vec());
    let d: &'static [f64] = Vec::leak(directions.to_vec());
    Rays::new(o, d, 0.0, f64::INFINITY).unwrap()
}

fn options(threads: usize) -> QueryOptions<'static> {
    QueryOptions {
        threads: Some(threads),
        cancel: None,
    }
}

/// Every hit of a ray against every triangle of the meshes, brute force:
/// (t, mesh, triangle, barycentric).
fn brute_hits(
    meshes: &[(Soup, Option<Transform>)],
    o: DVec3,
    d: DVec3,
    t_min: f64,
    t_max: f64,
) -> Vec<(f64, u32, u32, DVec3)> {
    let mut out = Vec::new();
    for (id, (soup, transform)) in meshes.iter().enumerate() {
        let (lo, ld) = match transform {
            None => (o, d),
            Some(t) => t.ray_to_object(&Ray {
                origin: o,
                direction: d,
            }),
        };
        let ray = WatertightRay::new(lo, ld);
        for (i, [a, b, c]) in soup.triangles().into_iter().enumerate() {
            if let Some(h) = triangle_hit(&ray, a, b, c, t_min, t_max) {
                out.push((h.t, id as u32, i as u32, h.barycentric));
            }
        }
    }
    out.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)).then(x.2.cmp(&y.2)));
    out
}

fn two_soups(rng: &mut Rng) -> (RayScene, Vec<(Soup, Option<Transform>)>) {
    let a = random_soup(rng, 300);
    let b = random_soup(rng, 200);
    let m = DMat4::from_scale_rotation_translation(
        DVec3::new(1.5, 0.7, 1.1),
        glam::DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 0.7),
        DVec3::new(0.3, -0.2, 0.4),
    );
    let mut scene = RayScene::new();
    assert_eq!(scene.add_mesh(&a.vertices, &a.faces, None).unwrap(), 0);
    assert_eq!(scene.add_mesh(&b.vertices, &b.faces, Some(m)).unwrap(), 1);
    let t = Transform::from_affine(DAffine3::from_mat4(m)).unwrap();
    (scene, vec![(a, None), (b, Some(t))])
}

/// Incoherent rays (random origins and directions) and coherent ones (a
/// pinhole camera's), interleaved in groups so both paths are taken.
fn mixed_rays(rng: &mut Rng, n: usize) -> (Vec<f64>, Vec<f64>) {
    let (mut o, mut d) = (Vec::new(), Vec::new());
    let eye = DVec3::new(0.2, -3.0, 0.5);
    for k in 0..n {
        if (k / 64) % 2 == 0 {
            o.extend(
                DVec3::new(
                    rng.range(-2.0, 2.0),
                    rng.range(-2.0, 2.0),
                    rng.range(-2.0, 2.0),
                )
                .to_array(),
            );
            d.extend((rng.direction() * rng.range(0.5, 2.0)).to_array());
        } else {
            let (x, y) = ((k % 8) as f64 / 8.0 - 0.5, ((k / 8) % 8) as f64 / 8.0 - 0.5);
            o.extend(eye.to_array());
            d.extend(
                DVec3::new(
                    x * 0.1 + rng.range(-0.3, 0.3),
                    1.0,
                    y * 0.1 + rng.range(-0.3, 0.3),
                )
                .to_array(),
            );
        }
    }
    (o, d)
}

#[test]
fn every_query_equals_brute_force() {
    let mut rng = Rng(1);
    let (scene, meshes) = two_soups(&mut rng);
    let (o, d) = mixed_rays(&mut rng, 2048);
    for (t_min, t_max) in [(0.0, f64::INFINITY), (0.5, 3.0)] {
        let batch = Rays::new(&o, &d, t_min, t_max).unwrap();
        let hits = scene.intersect(&batch, &options(2)).unwrap();
        let occluded = scene.occluded(&batch, &options(2)).unwrap();
        let counts = scene.count_intersections(&batch, &options(2)).unwrap();
        let all = scene.all_intersections(&batch, &options(2)).unwrap();
        let mut hit_rays = 0;
        for k in 0..batch.len() {
            let (ro, rd) = batch.ray(k);
            let brute = brute_hits(&meshes, ro, rd, t_min, t_max);
            // Nearest: the first of the sorted list (ties: lowest mesh, then triangle).
            match brute.first() {
                None => {
                    assert_eq!((hits.mesh_id[k], hits.triangle_id[k]), (-1, -1), "ray {k}");
                    assert_eq!(hits.t[k], f64::INFINITY);
                }
                Some(&(t, mesh, tri, bary)) => {
                    hit_rays += 1;
                    assert_eq!(hits.t[k].to_bits(), t.to_bits(), "ray {k}");
                    assert_eq!(
                        (hits.mesh_id[k], hits.triangle_id[k]),
                        (mesh as i64, tri as i64),
                        "ray {k}"
                    );
                    assert_eq!(
                        (hits.u[k].to_bits(), hits.v[k].to_bits()),
                        (bary.y.to_bits(), bary.z.to_bits())
                    );
                    let (soup, transform) = &meshes[mesh as usize];
                    let [a, b, c] = soup.triangles()[tri as usize];
                    let n = (b - a).cross(c - a).normalize_or_zero();
                    let n = transform.map_or(n, |t| t.normal(n));
                    assert_eq!(&hits.normal[3 * k..3 * k + 3], &n.to_array());
                }
            }
            assert_eq!(occluded[k], !brute.is_empty(), "ray {k}");
            assert_eq!(counts[k] as usize, brute.len(), "ray {k}");
            let (s, e) = (all.offsets[k] as usize, all.offsets[k + 1] as usize);
            assert_eq!(e - s, brute.len());
            for (j, &(t, mesh, tri, bary)) in brute.iter().enumerate() {
                assert_eq!(all.t[s + j].to_bits(), t.to_bits());
                assert_eq!(
                    (all.mesh_id[s + j], all.triangle_id[s + j]),
                    (mesh as i64, tri as i64)
                );
                assert_eq!((all.u[s + j], all.v[s + j]), (bary.y, bary.z));
            }
        }
        assert!(
            hit_rays > 500,
            "only {hit_rays} rays hit: the test tests little"
        );
        assert_eq!(*all.offsets.last().unwrap() as usize, all.t.len());
    }
}

/// A pinhole camera's rows over untransformed meshes, most of them
/// beside the meshes (`RayScene` tests runs of rays against the meshes'
/// trees at once, as spans): every query still equals brute force, and
/// the test checks that many runs of 64 are ones a span rules out (and so
/// are the shorter runs the queries test within them: a part of a span
/// lets through no more).
#[test]
fn camera_rows_beside_the_meshes_equal_brute_force() {
    let mut rng = Rng(12);
    let soup = random_soup(&mut rng, 200);
    let ball = icosphere(2, 0.1, &mut rng);
    // Four runs of 64 a row; no run holds directions of both signs on an
    // axis (those are not tested by spans). Rows a little further apart
    // than pixels along them: traced in tiles of 4 × 2.
    let (width, height, run) = (256, 64, 64);
    let eye = DVec3::new(0.3, -7.0, 0.2);
    let (mut o, mut d) = (Vec::new(), Vec::new());
    for row in 0..height {
        for column in 0..width {
            let x = (column as f64 + 0.5) / width as f64 * 2.0 - 1.0;
            let y = (row as f64 + 0.5) / height as f64 * 2.0 - 1.0;
            o.extend(eye.to_array());
            d.extend(DVec3::new(x * 0.9, 1.0, y * 0.7).to_array());
        }
    }
    // Runs the spans rule out, found with the same public test.
    let mesh = Mesh::new(soup.data()).unwrap();
    let runs_ruled_out = o
        .chunks(3 * run)
        .zip(d.chunks(3 * run))
        .filter(|(o, d)| {
            let fold = |v: &[f64], f: fn(DVec3, DVec3) -> DVec3| {
                v.chunks_exact(3).map(DVec3::from_slice).reduce(f).unwrap()
            };
            let span = prism::accel::NodePacket::spanning(
                fold(o, DVec3::min),
                fold(o, DVec3::max),
                fold(d, DVec3::min),
                fold(d, DVec3::max),
            );
            span.is_some_and(|span| !mesh.span_may_meet(&span, f64::INFINITY))
        })
        .count();
    assert!(
        runs_ruled_out >= 10,
        "{runs_ruled_out} of {height} rows ruled out"
    );
    let mut two = RayScene::new();
    two.add_mesh(&soup.vertices, &soup.faces, None).unwrap();
    two.add_mesh(&ball.vertices, &ball.faces, None).unwrap();
    let mut one = RayScene::new();
    one.add_mesh(&soup.vertices, &soup.faces, None).unwrap();
    for (scene, meshes) in [
        (&one, vec![(soup.clone(), None)]),
        (&two, vec![(soup.clone(), None), (ball.clone(), None)]),
    ] {
        for (t_min, t_max) in [(0.0, f64::INFINITY), (6.5, 7.5)] {
            let batch = Rays::new(&o, &d, t_min, t_max).unwrap();
            for threads in [1, 2] {
                let hits = scene.intersect(&batch, &options(threads)).unwrap();
                let occluded = scene.occluded(&batch, &options(threads)).unwrap();
                let counts = scene
                    .count_intersections(&batch, &options(threads))
                    .unwrap();
                let mut hit_rays = 0;
                for k in 0..batch.len() {
                    let (ro, rd) = batch.ray(k);
                    let brute = brute_hits(&meshes, ro, rd, t_min, t_max);
                    let expected = brute.first().map_or((f64::INFINITY, -1, -1), |h| {
                        (h.0, i64::from(h.1), i64::from(h.2))
                    });
                    assert_eq!(
                        (hits.t[k].to_bits(), hits.mesh_id[k], hits.triangle_id[k]),
                        (expected.0.to_bits(), expected.1, expected.2),
                        "ray {k}"
                    );
                    assert_eq!(occluded[k], !brute.is_empty(), "ray {k}");
                    assert_eq!(counts[k] as usize, brute.len(), "ray {k}");
                    hit_rays += usize::from(!brute.is_empty());
                }
                assert!(hit_rays > 100, "{hit_rays}");
            }
        }
    }
}

#[test]
fn hits_equal_the_renderers_bit_for_bit() {
    let mut rng = Rng(2);
    let soup = icosphere(3, 0.1, &mut rng);
    let m = DMat4::from_scale_rotation_translation(
        DVec3::new(1.0, 2.0, 0.5),
        glam::DQuat::from_rotation_y(0.4),
        DVec3::new(0.1, 0.2, -0.3),
    );
    for transform in [None, Some(m)] {
        let mut scene = RayScene::new();
        scene
            .add_mesh(&soup.vertices, &soup.faces, transform)
            .unwrap();
        let instance = MeshInstance {
            mesh: Arc::new(Mesh::new(soup.data()).unwrap()),
            transform: transform.map(|m| Transform::from_affine(DAffine3::from_mat4(m)).unwrap()),
            materials: Arc::from(vec![0u32]),
        };
        let aggregate = Aggregate::new(vec![Primitive {
            shape: Shape::Mesh(Box::new(instance)),
            material: 0,
        }]);
        // A camera's unit-length rays, row by row (packets), and random ones.
        let (mut o, mut d) = (Vec::new(), Vec::new());
        let eye = DVec3::new(0.3, 0.2, 4.0);
        for y in 0..48 {
            for x in 0..48 {
                let dir =
                    DVec3::new(x as f64 / 48.0 - 0.5, y as f64 / 48.0 - 0.5, -1.0).normalize();
                o.extend(eye.to_array());
                d.extend(dir.to_array());
            }
        }
        for _ in 0..2000 {
            o.extend((rng.direction() * 0.3).to_array());
            d.extend(rng.direction().to_array());
        }
        let batch = rays(&o, &d);
        let hits = scene.intersect(&batch, &options(2)).unwrap();
        let mut seen = 0;
        for k in 0..batch.len() {
            let (origin, direction) = batch.ray(k);
            let ray = Ray { origin, direction };
            let renderer = aggregate.closest_hit(&ray, f64::INFINITY);
            match renderer {
                None => assert_eq!(hits.triangle_id[k], -1),
                Some(h) => {
                    seen += 1;
                    assert_eq!(hits.t[k].to_bits(), h.t.to_bits(), "ray {k}");
                    assert_eq!(
                        &hits.normal[3 * k..3 * k + 3],
                        &h.normal.to_array(),
                        "ray {k}"
                    );
                }
            }
        }
        assert!(seen > 2000, "{seen}");
    }
}

/// Incoherent rays through a mesh beyond the cache are traced in an order
/// of the query's own (by direction octant and origin cell) and their
/// answers put back: every answer is the one the same rays get in batches
/// too small to be reordered, bit for bit, on any thread count, and the
/// nearest hits are the renderer's.
#[test]
fn rays_traced_in_the_querys_own_order_answer_as_given() {
    let mut rng = Rng(9);
    // 262,144 triangles: more than the 8 MB the order is kept for.
    let big = torus(512, 256, 0.002, &mut rng);
    let small = icosphere(2, 0.1, &mut rng);
    let m = DMat4::from_scale_rotation_translation(
        DVec3::splat(0.3),
        glam::DQuat::from_rotation_x(0.5),
        DVec3::new(0.2, 0.1, 0.0),
    );
    let mut scene = RayScene::new();
    scene.add_mesh(&big.vertices, &big.faces, None).unwrap();
    assert!(scene.memory_bytes() > 12 << 20, "{}", scene.memory_bytes());
    scene
        .add_mesh(&small.vertices, &small.faces, Some(m))
        .unwrap();
    let n = 40_000;
    let (mut o, mut d) = (Vec::new(), Vec::new());
    for _ in 0..n {
        o.extend(
            DVec3::new(
                rng.range(-1.5, 1.5),
                rng.range(-1.5, 1.5),
                rng.range(-0.5, 0.5),
            )
            .to_array(),
        );
        d.extend(rng.direction().to_array());
    }
    let whole = Rays::new(&o, &d, 0.0, f64::INFINITY).unwrap();
    let sorted = (
        scene.intersect(&whole, &options(1)).unwrap(),
        scene.occluded(&whole, &options(1)).unwrap(),
        scene.count_intersections(&whole, &options(1)).unwrap(),
    );
    assert!(
        sorted
            == (
                scene.intersect(&whole, &options(2)).unwrap(),
                scene.occluded(&whole, &options(2)).unwrap(),
                scene.count_intersections(&whole, &options(2)).unwrap(),
            )
    );
    // Batches of 5,000 rays are traced as given.
    let part = 5000;
    let mut hit = 0;
    for first in (0..n).step_by(part) {
        let batch = Rays::new(
            &o[3 * first..3 * (first + part)],
            &d[3 * first..3 * (first + part)],
            0.0,
            f64::INFINITY,
        )
        .unwrap();
        let hits = scene.intersect(&batch, &options(2)).unwrap();
        let occluded = scene.occluded(&batch, &options(2)).unwrap();
        let counts = scene.count_intersections(&batch, &options(2)).unwrap();
        for k in 0..part {
            let i = first + k;
            assert_eq!(hits.t[k].to_bits(), sorted.0.t[i].to_bits(), "ray {i}");
            assert_eq!(hits.mesh_id[k], sorted.0.mesh_id[i], "ray {i}");
            assert_eq!(hits.triangle_id[k], sorted.0.triangle_id[i], "ray {i}");
            assert_eq!(hits.u[k].to_bits(), sorted.0.u[i].to_bits(), "ray {i}");
            assert_eq!(hits.v[k].to_bits(), sorted.0.v[i].to_bits(), "ray {i}");
            assert_eq!(
                hits.normal[3 * k..3 * k + 3],
                sorted.0.normal[3 * i..3 * i + 3],
                "ray {i}"
            );
            assert_eq!(occluded[k], sorted.1[i], "ray {i}");
            assert_eq!(counts[k], sorted.2[i], "ray {i}");
            hit += usize::from(hits.mesh_id[k] >= 0);
        }
    }
    assert!(hit > n / 4 && hit < n, "{hit} of {n} rays hit");
    assert!(sorted.0.mesh_id.contains(&1), "no ray hit the small mesh");
    // The nearest hits against the big mesh alone, by the renderer's own
    // search, ray by ray.
    let mesh = Mesh::new(big.data()).unwrap();
    for i in (0..n).step_by(7) {
        let (origin, direction) = whole.ray(i);
        if sorted.0.mesh_id[i] == 1 {
            continue;
        }
        match mesh.intersect(origin, direction, 0.0, f64::INFINITY) {
            None => assert_eq!(sorted.0.triangle_id[i], -1, "ray {i}"),
            Some(h) => {
                assert_eq!(sorted.0.t[i].to_bits(), h.t.to_bits(), "ray {i}");
                assert_eq!(sorted.0.triangle_id[i], i64::from(h.triangle), "ray {i}");
            }
        }
    }
}

/// The Stanford bunny (3,674 triangles, closed: every edge on two
/// triangles), tests/data/bunny.ply read by Prism's own PLY reader; each
/// vertex moved by up to `jitter` along each axis.
fn bunny(jitter: f64, rng: &mut Rng) -> Soup {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/bunny.ply");
    let mut res = Resources::new(path.parent().unwrap(), &LoadOptions::default());
    let model = load_model(&path, &mut res).unwrap_or_else(|e| panic!("{e}"));
    let [mesh] = &model.meshes[..] else {
        panic!("one mesh expected in {}", path.display());
    };
    Soup {
        vertices: mesh
            .positions
            .iter()
            .flat_map(|p| p.to_array())
            .map(|x| x + jitter * rng.range(-1.0, 1.0))
            .collect(),
        faces: mesh.triangles.iter().flatten().copied().collect(),
    }
}

/// pbrt-v4's watertightness test: from random points inside randomly
/// perturbed closed meshes (icospheres, tori, the bunny), rays in random
/// directions and aimed at vertices and at points on edges must all hit,
/// and `contains` must hold every origin.
#[test]
fn no_ray_escapes_a_closed_mesh() {
    let mut rng = Rng(3);
    let mut total = 0;
    for round in 0..7 {
        let (soup, points): (Soup, Vec<DVec3>) = if round == 6 {
            // Inside the bunny: points of its box the exact crossing count
            // puts inside.
            let soup = bunny(0.02, &mut rng);
            let triangles = soup.triangles();
            let (lo, hi) = triangles.iter().flatten().fold(
                (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
                |(lo, hi), &p| (lo.min(p), hi.max(p)),
            );
            let mut points = Vec::new();
            while points.len() < 200 {
                let p = DVec3::new(
                    rng.range(lo.x, hi.x),
                    rng.range(lo.y, hi.y),
                    rng.range(lo.z, hi.z),
                );
                if exact_inside(&triangles, p, &mut rng) {
                    points.push(p);
                }
            }
            (soup, points)
        } else if round % 2 == 0 {
            let soup = icosphere(2 + round / 2, 0.1, &mut rng);
            let points = (0..400)
                .map(|_| rng.direction() * rng.range(0.0, 0.5))
                .collect();
            (soup, points)
        } else {
            let soup = torus(24 + 8 * round, 12 + 4 * round, 0.02, &mut rng);
            let points = (0..400)
                .map(|_| {
                    let u = rng.range(0.0, std::f64::consts::TAU);
                    DVec3::new(u.cos(), u.sin(), 0.0) + rng.direction() * rng.range(0.0, 0.15)
                })
                .collect();
            (soup, points)
        };
        let mut scene = RayScene::new();
        scene.add_mesh(&soup.vertices, &soup.faces, None).unwrap();
        assert_eq!(scene.is_closed(0), Some(true));
        let triangles = soup.triangles();
        let (mut o, mut d) = (Vec::new(), Vec::new());
        for &p in &points {
            for j in 0..16 {
                let [a, b, c] = triangles[rng.below(triangles.len())];
                let target = match j % 4 {
                    0 => p + rng.direction(),
                    1 => a,
                    2 => a + (b - a) * rng.f(),
                    _ => (b + c) * 0.5,
                };
                o.extend(p.to_array());
                d.extend((target - p).to_array());
            }
        }
        let batch = rays(&o, &d);
        for threads in [1, 2] {
            let hits = scene.intersect(&batch, &options(threads)).unwrap();
            let escaped = hits.triangle_id.iter().filter(|&&t| t < 0).count();
            assert_eq!(
                escaped,
                0,
                "round {round}: {escaped} of {} rays escaped",
                batch.len()
            );
            let blocked = scene.occluded(&batch, &options(threads)).unwrap();
            assert!(
                blocked.iter().all(|&b| b),
                "round {round}: an any-hit ray escaped"
            );
            let counts = scene
                .count_intersections(&batch, &options(threads))
                .unwrap();
            assert!(counts.iter().all(|&c| c >= 1));
        }
        let points: Vec<f64> = points.iter().flat_map(|p| p.to_array()).collect();
        let held = scene.contains(&points, &options(2)).unwrap();
        assert!(
            held.iter().all(|&h| h),
            "round {round}: a point inside was called outside"
        );
        // Beyond every mesh's box (the bunny's reaches about 5 from the
        // origin).
        let outside: Vec<f64> = (0..200)
            .flat_map(|_| (rng.direction() * 20.0).to_array())
            .collect();
        assert!(
            scene
                .contains(&outside, &options(2))
                .unwrap()
                .iter()
                .all(|&h| !h)
        );
        total += batch.len();
    }
    assert!(total >= 6 * 6400 + 3200);
}

/// Shewchuk's exact orientation of d against the plane of a, b, c.
fn orient(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> f64 {
    let p = |v: DVec3| robust::Coord3D {
        x: v.x,
        y: v.y,
        z: v.z,
    };
    robust::orient3d(p(a), p(b), p(c), p(d))
}

/// Inside or outside, exactly: the parity of the triangles the segment
/// from `p` to a far point crosses, every sign from exact predicates; a
/// segment through an edge or vertex (some sign zero) is set aside for
/// another.
fn exact_inside(triangles: &[[DVec3; 3]], p: DVec3, rng: &mut Rng) -> bool {
    'attempt: for _ in 0..64 {
        let q = p + rng.direction() * 100.0;
        let mut odd = false;
        for &[a, b, c] in triangles {
            let (sp, sq) = (orient(a, b, c, p), orient(a, b, c, q));
            // In the triangle's plane the segment meets it at p alone: no
            // crossing, p being off the surface.
            if sp == 0.0 {
                continue;
            }
            if sq == 0.0 {
                continue 'attempt;
            }
            if (sp > 0.0) == (sq > 0.0) {
                continue;
            }
            let e = [orient(p, q, a, b), orient(p, q, b, c), orient(p, q, c, a)];
            if e.contains(&0.0) {
                continue 'attempt;
            }
            if e.iter().all(|&x| x > 0.0) || e.iter().all(|&x| x < 0.0) {
                odd = !odd;
            }
        }
        return odd;
    }
    panic!("no segment from {p} avoided every edge");
}

/// Points 1e-12 from the surface (off faces, edges and vertices, in
/// random directions) against the exact reference.
#[test]
fn contains_is_exact_a_trillionth_from_the_surface() {
    let mut rng = Rng(4);
    for round in 0..2 {
        let soup = if round == 0 {
            icosphere(2, 0.1, &mut rng)
        } else {
            torus(24, 12, 0.02, &mut rng)
        };
        let mut scene = RayScene::new();
        scene.add_mesh(&soup.vertices, &soup.faces, None).unwrap();
        let triangles = soup.triangles();
        let mut points = Vec::new();
        for k in 0..1500 {
            let [a, b, c] = triangles[rng.below(triangles.len())];
            let q = match k % 3 {
                0 => {
                    let (u, v) = (rng.f(), rng.f());
                    let (u, v) = if u + v > 1.0 {
                        (1.0 - u, 1.0 - v)
                    } else {
                        (u, v)
                    };
                    a + (b - a) * u + (c - a) * v
                }
                1 => a + (b - a) * rng.f(),
                _ => c,
            };
            let n = (b - a).cross(c - a).normalize();
            // Along the normal either way, or any way.
            let off = match k % 4 {
                0 => n,
                1 => -n,
                _ => rng.direction(),
            };
            points.extend((q + off * 1e-12).to_array());
        }
        let got = scene.contains(&points, &options(2)).unwrap();
        let (mut inside, mut wrong) = (0, 0);
        for (k, &g) in got.iter().enumerate() {
            let p = DVec3::from_slice(&points[3 * k..]);
            let exact = exact_inside(&triangles, p, &mut rng);
            inside += usize::from(exact);
            wrong += usize::from(exact != g);
        }
        assert_eq!(
            wrong,
            0,
            "round {round}: {wrong} of {} points misjudged",
            got.len()
        );
        assert!(
            inside > 300 && inside < 1200,
            "round {round}: {inside} inside: too one-sided"
        );
    }
}

/// A grid mesh's edges lie in the coordinate planes; the cube's vertices
/// and edges are met exactly by axis-aligned rays: each query still
/// answers as brute force does, and contains as the exact reference.
#[test]
fn axis_aligned_rays_through_edges_and_vertices() {
    let mut rng = Rng(5);
    // A closed box of 2 × 2 quads per face (vertices on a grid of halves).
    let cube = icosphere(0, 0.0, &mut rng); // replaced below by the grid box
    let _ = cube;
    let mut vertices = Vec::new();
    let mut index = std::collections::HashMap::new();
    let mut faces = Vec::new();
    let mut id = |p: [i32; 3], vertices: &mut Vec<f64>| {
        *index.entry(p).or_insert_with(|| {
            vertices.extend(p.map(|c| c as f64 / 2.0));
            (vertices.len() / 3 - 1) as u32
        })
    };
    for axis in 0..3 {
        for side in [0, 2] {
            for i in 0..2 {
                for j in 0..2 {
                    let corner = |di: i32, dj: i32| {
                        let mut p = [0; 3];
                        p[axis] = side;
                        p[(axis + 1) % 3] = i + di;
                        p[(axis + 2) % 3] = j + dj;
                        p
                    };
                    let q = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)];
                    let q: Vec<u32> = q.iter().map(|&p| id(p, &mut vertices)).collect();
                    // Outward: counter-clockwise seen from outside.
                    let tris = if side == 2 {
                        [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]
                    } else {
                        [[q[0], q[2], q[1]], [q[0], q[3], q[2]]]
                    };
                    faces.extend(tris.into_iter().flatten());
                }
            }
        }
    }
    let soup = Soup { vertices, faces };
    let mut scene = RayScene::new();
    scene.add_mesh(&soup.vertices, &soup.faces, None).unwrap();
    assert_eq!(scene.is_closed(0), Some(true));
    let (mut o, mut d) = (Vec::new(), Vec::new());
    for x in 0..=4 {
        for y in 0..=4 {
            for (dir, from) in [
                (DVec3::Z, -1.0),
                (DVec3::X, -1.0),
                (DVec3::new(1.0, 1.0, 1.0), -1.0),
            ] {
                let p = DVec3::new(x as f64 / 4.0, y as f64 / 4.0, 0.0);
                let origin = if dir == DVec3::Z {
                    p + DVec3::Z * from
                } else if dir == DVec3::X {
                    DVec3::new(from, p.x, p.y)
                } else {
                    p - dir * 2.0
                };
                o.extend(origin.to_array());
                d.extend(dir.to_array());
            }
        }
    }
    let batch = rays(&o, &d);
    let hits = scene.intersect(&batch, &options(1)).unwrap();
    let counts = scene.count_intersections(&batch, &options(1)).unwrap();
    let meshes = [(soup.clone(), None)];
    for (k, &count) in counts.iter().enumerate() {
        let (ro, rd) = batch.ray(k);
        let brute = brute_hits(&meshes, ro, rd, 0.0, f64::INFINITY);
        assert_eq!(count as usize, brute.len());
        assert_eq!(
            hits.triangle_id[k],
            brute.first().map_or(-1, |b| b.2 as i64)
        );
    }
    // Points on the grid's lines, a trillionth in or out, and exactly on it.
    let triangles = soup.triangles();
    let mut points = Vec::new();
    for x in 0..=4 {
        for y in 0..=4 {
            for off in [1e-12, -1e-12] {
                points.extend([x as f64 / 4.0, y as f64 / 4.0, off]);
                points.extend([off + 1.0, x as f64 / 4.0, y as f64 / 4.0]);
            }
        }
    }
    let got = scene.contains(&points, &options(1)).unwrap();
    for (k, &g) in got.iter().enumerate() {
        let p = DVec3::from_slice(&points[3 * k..]);
        let expect = p.cmpgt(DVec3::ZERO).all() && p.cmplt(DVec3::ONE).all();
        if p.cmpgt(DVec3::ZERO).all() && p.cmplt(DVec3::ONE).all()
            || !p.cmpge(DVec3::ZERO).all()
            || !p.cmple(DVec3::ONE).all()
        {
            assert_eq!(g, exact_inside(&triangles, p, &mut rng), "{p}");
            assert_eq!(g, expect, "{p}");
        } else {
            // On the surface: a closed solid holds its boundary.
            assert!(g, "{p} on the surface");
        }
    }
}

#[test]
fn answers_do_not_depend_on_threads() {
    let mut rng = Rng(6);
    let (scene, _) = two_soups(&mut rng);
    let (o, d) = mixed_rays(&mut rng, 5000);
    let batch = Rays::new(&o, &d, 0.0, f64::INFINITY).unwrap();
    let first = (
        scene.intersect(&batch, &options(1)).unwrap(),
        scene.occluded(&batch, &options(1)).unwrap(),
        scene.count_intersections(&batch, &options(1)).unwrap(),
        scene.all_intersections(&batch, &options(1)).unwrap(),
    );
    for threads in [2, 3, 7] {
        let again = (
            scene.intersect(&batch, &options(threads)).unwrap(),
            scene.occluded(&batch, &options(threads)).unwrap(),
            scene
                .count_intersections(&batch, &options(threads))
                .unwrap(),
            scene.all_intersections(&batch, &options(threads)).unwrap(),
        );
        // Bits, NaN-free: PartialEq on the f64s is bitwise here.
        assert!(first == again, "{threads} threads differ");
    }
    let sphere = icosphere(3, 0.1, &mut rng);
    let mut closed = RayScene::new();
    closed
        .add_mesh(&sphere.vertices, &sphere.faces, None)
        .unwrap();
    let points: Vec<f64> = (0..3000)
        .flat_map(|_| (rng.direction() * rng.range(0.8, 1.2)).to_array())
        .collect();
    let one = closed.contains(&points, &options(1)).unwrap();
    assert_eq!(one, closed.contains(&points, &options(3)).unwrap());
    assert_eq!(
        one,
        closed.contains(&points, &QueryOptions::default()).unwrap()
    );
}

/// Rays given in single precision are read in place and answer as their
/// values widened to double precision do, bit for bit, on every path: as
/// given (packets, streams, alone), a camera's rows in tiles, scattered
/// rays sorted through a mesh beyond the cache; checked eagerly or by the
/// query, with the same errors.
#[test]
fn single_precision_rays_answer_as_their_doubles() {
    let mut rng = Rng(14);
    let (mut scene, _) = two_soups(&mut rng);
    // 262,144 triangles: beyond the 8 MB at which scattered rays are
    // sorted.
    let big = torus(512, 256, 0.002, &mut rng);
    let before = scene.memory_bytes();
    scene.add_mesh(&big.vertices, &big.faces, None).unwrap();
    assert!(scene.memory_bytes() - before > 12 << 20);
    let (mixed_o, mixed_d) = mixed_rays(&mut rng, 6000);
    let (width, height) = (128, 48);
    let (mut camera_o, mut camera_d) = (Vec::new(), Vec::new());
    for k in 0..width * height {
        let (x, y) = ((k % width) as f64, (k / width) as f64);
        camera_o.extend([0.1, -4.0, 0.2]);
        camera_d.extend([(x - 64.0) / 40.0, 1.5, (y - 24.0) / 40.0]);
    }
    let (mut scattered_o, mut scattered_d) = (Vec::new(), Vec::new());
    for _ in 0..20_000 {
        scattered_o.extend([
            rng.range(-1.5, 1.5),
            rng.range(-1.5, 1.5),
            rng.range(-0.5, 0.5),
        ]);
        scattered_d.extend(rng.direction().to_array());
    }
    for (o, d) in [
        (mixed_o, mixed_d),
        (camera_o, camera_d),
        (scattered_o, scattered_d),
    ] {
        let (o32, d32): (Vec<f32>, Vec<f32>) = (
            o.iter().map(|&x| x as f32).collect(),
            d.iter().map(|&x| x as f32).collect(),
        );
        let (o64, d64): (Vec<f64>, Vec<f64>) = (
            o32.iter().map(|&x| f64::from(x)).collect(),
            d32.iter().map(|&x| f64::from(x)).collect(),
        );
        let single = [
            Rays::from_coordinates(o32[..].into(), d32[..].into(), 0.0, f64::INFINITY).unwrap(),
            Rays::deferred_from_coordinates(o32[..].into(), d32[..].into(), 0.0, f64::INFINITY)
                .unwrap(),
            // Mixed: origins in double, directions in single precision.
            Rays::from_coordinates(o64[..].into(), d32[..].into(), 0.0, f64::INFINITY).unwrap(),
        ];
        let double = Rays::new(&o64, &d64, 0.0, f64::INFINITY).unwrap();
        for threads in [1, 2] {
            let expected = (
                scene.intersect(&double, &options(threads)).unwrap(),
                scene.occluded(&double, &options(threads)).unwrap(),
                scene
                    .count_intersections(&double, &options(threads))
                    .unwrap(),
                scene.all_intersections(&double, &options(threads)).unwrap(),
            );
            assert!(expected.1.iter().any(|&b| b) && !expected.1.iter().all(|&b| b));
            for rays in &single {
                assert_eq!(rays.ray(7), double.ray(7));
                let got = (
                    scene.intersect(rays, &options(threads)).unwrap(),
                    scene.occluded(rays, &options(threads)).unwrap(),
                    scene.count_intersections(rays, &options(threads)).unwrap(),
                    scene.all_intersections(rays, &options(threads)).unwrap(),
                );
                assert!(got == expected, "{} rays, {threads} threads", o.len() / 3);
            }
        }
    }
    // Bad values: the errors of their doubles.
    let o32 = [0.0f32, 0.0, -5.0, 0.1, 0.1, -5.0, 0.2, 0.2, -5.0];
    for (row, value) in [(1, f32::NAN), (2, f32::INFINITY)] {
        let mut d32 = [0.0f32, 0.0, 1.0].repeat(3);
        d32[3 * row + 1] = value;
        let d64: Vec<f64> = d32.iter().map(|&x| f64::from(x)).collect();
        let o64: Vec<f64> = o32.iter().map(|&x| f64::from(x)).collect();
        let eager = Rays::new(&o64, &d64, 0.0, f64::INFINITY).unwrap_err();
        let single: Coordinates = d32[..].into();
        let err = Rays::from_coordinates(o32[..].into(), single, 0.0, f64::INFINITY).unwrap_err();
        assert_eq!(err, eager);
        let deferred =
            Rays::deferred_from_coordinates(o32[..].into(), single, 0.0, f64::INFINITY).unwrap();
        assert_eq!(scene.intersect(&deferred, &options(1)).unwrap_err(), eager);
    }
    let zero = [0.0f32, 0.0, 1.0, 0.0, 0.0, 0.0];
    let err = Rays::from_coordinates(o32[..6].into(), zero[..].into(), 0.0, 1.0).unwrap_err();
    assert_eq!(
        err.to_string(),
        "directions: row 1 is zero (every component below 1e-30)"
    );
    // Beyond ±1e30, which single precision can hold.
    let far = [0.0f32, 0.0, 2e30];
    let err = Rays::from_coordinates(far[..].into(), o32[..3].into(), 0.0, 1.0).unwrap_err();
    assert!(
        err.to_string().starts_with("origins: row 0 holds 2"),
        "{err}"
    );
}

#[test]
fn bad_arguments_name_themselves() {
    let v = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    let mut scene = RayScene::new();
    let argument = |e: QueryError| match e {
        QueryError::Invalid { argument, .. } => argument,
        other => panic!("{other}"),
    };
    assert_eq!(
        argument(scene.add_mesh(&v[..8], &[0, 1, 2], None).unwrap_err()),
        "vertices"
    );
    assert_eq!(
        argument(scene.add_mesh(&[] as &[f64], &[0, 1, 2], None).unwrap_err()),
        "vertices"
    );
    assert_eq!(
        argument(
            scene
                .add_mesh(&[f64::NAN; 9], &[0, 1, 2], None)
                .unwrap_err()
        ),
        "vertices"
    );
    assert_eq!(
        argument(scene.add_mesh(&v, &[0, 1, 3], None).unwrap_err()),
        "faces"
    );
    assert_eq!(
        argument(scene.add_mesh(&v, &[], None).unwrap_err()),
        "faces"
    );
    assert_eq!(
        argument(scene.add_mesh(&v, &[0, 1], None).unwrap_err()),
        "faces"
    );
    assert_eq!(
        argument(
            scene
                .add_mesh(&v, &[0, 1, 2], Some(DMat4::ZERO))
                .unwrap_err()
        ),
        "transform"
    );
    let mut projective = DMat4::IDENTITY;
    projective.x_axis.w = 1.0;
    assert_eq!(
        argument(
            scene
                .add_mesh(&v, &[0, 1, 2], Some(projective))
                .unwrap_err()
        ),
        "transform"
    );
    assert_eq!(scene.add_mesh(&v, &[0, 1, 2], None).unwrap(), 0);
    let o = [0.0, 0.0, 1.0];
    assert_eq!(
        argument(Rays::new(&[], &[], 0.0, 1.0).unwrap_err()),
        "origins"
    );
    assert_eq!(
        argument(Rays::new(&o[..2], &o[..2], 0.0, 1.0).unwrap_err()),
        "origins"
    );
    assert_eq!(
        argument(Rays::new(&o, &[0.0; 6], 0.0, 1.0).unwrap_err()),
        "directions"
    );
    assert_eq!(
        argument(Rays::new(&o, &[0.0; 3], 0.0, 1.0).unwrap_err()),
        "directions"
    );
    assert_eq!(
        argument(Rays::new(&[f64::INFINITY, 0.0, 0.0], &o, 0.0, 1.0).unwrap_err()),
        "origins"
    );
    assert_eq!(
        argument(Rays::new(&o, &[f64::NAN, 0.0, 1.0], 0.0, 1.0).unwrap_err()),
        "directions"
    );
    assert_eq!(
        argument(Rays::new(&o, &o, f64::NAN, 1.0).unwrap_err()),
        "tmin"
    );
    assert_eq!(
        argument(Rays::new(&o, &o, 0.0, f64::NAN).unwrap_err()),
        "tmax"
    );
    assert_eq!(argument(Rays::new(&o, &o, 2.0, 1.0).unwrap_err()), "tmax");
    assert_eq!(argument(Rays::new(&o, &o, -1.0, 1.0).unwrap_err()), "tmin");
    let batch = Rays::new(&o, &[0.0, 0.0, -1.0], 0.0, f64::INFINITY).unwrap();
    for threads in [0, 100_000] {
        let e = scene.intersect(&batch, &options(threads)).unwrap_err();
        assert_eq!(argument(e), "threads");
    }
    assert_eq!(
        argument(scene.contains(&[0.0; 4], &options(1)).unwrap_err()),
        "points"
    );
    // One triangle has no inside.
    assert_eq!(
        scene.contains(&o, &options(1)).unwrap_err(),
        QueryError::NotClosed { mesh: 0 }
    );
    for bad in [
        &[0.0; 4][..],
        &[],
        &[0.0, f64::NAN, 0.0],
        &[f64::INFINITY, 0.0, 0.0],
    ] {
        assert_eq!(
            argument(scene.closest_point(bad, &options(1)).unwrap_err()),
            "points"
        );
    }
    assert_eq!(
        argument(scene.closest_point(&o, &options(0)).unwrap_err()),
        "threads"
    );
    let hits = scene.intersect(&batch, &options(1)).unwrap();
    assert_eq!((hits.t[0], hits.triangle_id[0]), (1.0, 0));
}

/// A deferred batch's coordinates are checked by the query, on its workers,
/// with the error `Rays::new` gives (the first bad row; origins, then
/// directions, then a zero direction), and its answers are the same.
#[test]
fn a_deferred_batch_is_checked_by_the_query_as_rays_new_checks_it() {
    let mut scene = RayScene::new();
    let v = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    scene.add_mesh(&v, &[0, 1, 2], None).unwrap();
    let n = 5000;
    let o: Vec<f64> = (0..n).flat_map(|_| [0.1, 0.1, 1.0]).collect();
    let d: Vec<f64> = (0..n).flat_map(|_| [0.0, 0.0, -1.0]).collect();
    let good = Rays::deferred(&o, &d, 0.0, f64::INFINITY).unwrap();
    let checked = Rays::new(&o, &d, 0.0, f64::INFINITY).unwrap();
    for threads in [1, 2, 3] {
        assert_eq!(
            scene.intersect(&good, &options(threads)).unwrap(),
            scene.intersect(&checked, &options(threads)).unwrap()
        );
    }
    let (mut o2, mut d2) = (o.clone(), d.clone());
    o2[3 * 4000 + 1] = f64::NAN;
    o2[3 * 4500] = f64::INFINITY;
    d2[3 * 10..3 * 11].fill(0.0);
    d2[3 * 3000 + 2] = 1e31;
    for (o, d, t_min) in [
        (&o2, &d2, 0.0),
        (&o, &d2, 0.0),
        (&o, &d2, -1.0),
        (&o2, &d, 0.0),
    ] {
        let want = Rays::new(o, d, t_min, 1.0).unwrap_err();
        let batch = match Rays::deferred(o, d, t_min, 1.0) {
            Ok(batch) => batch,
            Err(e) => {
                assert_eq!(e, want);
                continue;
            }
        };
        for threads in [1, 2] {
            let options = options(threads);
            assert_eq!(scene.intersect(&batch, &options).unwrap_err(), want);
            assert_eq!(scene.occluded(&batch, &options).unwrap_err(), want);
            assert_eq!(
                scene.count_intersections(&batch, &options).unwrap_err(),
                want
            );
            assert_eq!(scene.all_intersections(&batch, &options).unwrap_err(), want);
        }
    }
}

#[test]
fn a_raised_cancel_flag_stops_a_query() {
    let mut rng = Rng(7);
    let (scene, _) = two_soups(&mut rng);
    let (o, d) = mixed_rays(&mut rng, 4096);
    let batch = Rays::new(&o, &d, 0.0, f64::INFINITY).unwrap();
    let flag = AtomicBool::new(true);
    let cancel = QueryOptions {
        threads: Some(2),
        cancel: Some(&flag),
    };
    assert_eq!(
        scene.intersect(&batch, &cancel).unwrap_err(),
        QueryError::Cancelled
    );
    assert_eq!(
        scene.occluded(&batch, &cancel).unwrap_err(),
        QueryError::Cancelled
    );
    assert_eq!(
        scene.count_intersections(&batch, &cancel).unwrap_err(),
        QueryError::Cancelled
    );
    assert_eq!(
        scene.all_intersections(&batch, &cancel).unwrap_err(),
        QueryError::Cancelled
    );
    assert_eq!(
        scene.closest_point(&o, &cancel).unwrap_err(),
        QueryError::Cancelled
    );
}

/// The nearest surface point by brute force: every triangle of every mesh
/// (corners placed in world space), the first mesh, then the first
/// triangle, of those equally near.
fn brute_nearest(
    meshes: &[(Soup, Option<Transform>)],
    p: DVec3,
) -> (usize, usize, NearestOnTriangle) {
    let mut best: Option<(usize, usize, NearestOnTriangle)> = None;
    for (id, (soup, transform)) in meshes.iter().enumerate() {
        for (i, corners) in soup.triangles().into_iter().enumerate() {
            let corners = match transform {
                None => corners,
                Some(t) => corners.map(|c| t.to_world.transform_point3(c)),
            };
            let near = nearest_on_triangle(p, corners);
            if best.is_none_or(|(_, _, b)| near.distance_squared < b.distance_squared) {
                best = Some((id, i, near));
            }
        }
    }
    best.unwrap()
}

/// Points near the meshes, far from them, on their triangles (so at
/// distance 0, where several triangles of a shared corner tie) and on a
/// fine grid (ties between parallel faces): the query's answers equal
/// brute force's bit for bit, on one thread and two.
#[test]
fn closest_point_equals_brute_force() {
    let mut rng = Rng(21);
    let (scene, meshes) = two_soups(&mut rng);
    let mut points = Vec::new();
    for k in 0..3000 {
        let p = match k % 4 {
            0 => DVec3::new(
                rng.range(-2.0, 2.0),
                rng.range(-2.0, 2.0),
                rng.range(-2.0, 2.0),
            ),
            1 => rng.direction() * rng.range(5.0, 50.0),
            2 => {
                // A corner or a point on a triangle of the first mesh.
                let t = meshes[0].0.triangles()[rng.below(300)];
                let (u, v) = (rng.f(), rng.f());
                let (u, v) = if u + v > 1.0 {
                    (1.0 - u, 1.0 - v)
                } else {
                    (u, v)
                };
                if k % 8 == 2 {
                    t[0]
                } else {
                    t[0] + (t[1] - t[0]) * u + (t[2] - t[0]) * v
                }
            }
            _ => DVec3::new((k % 7) as f64, (k % 5) as f64, (k % 3) as f64) * 0.25 - 0.5,
        };
        points.extend(p.to_array());
    }
    let one = scene.closest_point(&points, &options(1)).unwrap();
    let two = scene.closest_point(&points, &options(2)).unwrap();
    assert_eq!(one, two);
    for (k, p) in points.chunks_exact(3).enumerate() {
        let (id, triangle, near) = brute_nearest(&meshes, DVec3::from_slice(p));
        assert_eq!(
            (one.mesh_id[k], one.triangle_id[k]),
            (id as i64, triangle as i64),
            "point {k} {p:?}"
        );
        assert_eq!(one.distance[k], near.distance_squared.sqrt());
        assert_eq!(&one.point[3 * k..3 * k + 3], &near.point.to_array());
        assert_eq!((one.u[k], one.v[k]), (near.u, near.v));
        // The normal as `intersect` gives it: the object-space facet
        // normal, through the transform's normal matrix.
        let (soup, transform) = &meshes[id];
        let [a, b, c] = soup.triangles()[triangle];
        let n = (b - a).cross(c - a).normalize_or_zero();
        let n = match transform {
            None => n,
            Some(t) => (t.normal_to_world * n).normalize_or_zero(),
        };
        assert_eq!(&one.normal[3 * k..3 * k + 3], &n.to_array(), "point {k}");
    }
    // A point on a triangle is at distance 0.
    assert!(one.distance.iter().skip(2).step_by(8).all(|&d| d < 1e-15));
}

/// A unit cube's faces, seen from outside and inside: distances by hand.
#[test]
fn closest_point_of_a_cube_by_hand() {
    let vertices: Vec<f64> = (0..8)
        .flat_map(|i| [(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64])
        .collect();
    let faces = [
        0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6,
        1, 3, 5, 3, 7, 5,
    ];
    let mut scene = RayScene::new();
    scene.add_mesh(&vertices, &faces, None).unwrap();
    // Inside, nearest the x = 0 face; beyond the corner (1, 1, 1); over
    // the edge x = 1, y = 0; straight above the top face; the single-
    // precision form of the first.
    let points = [0.2, 0.5, 0.4, 2.0, 3.0, 1.5, 1.5, -2.0, 0.5, 0.25, 0.5, 4.0];
    let near = scene.closest_point(&points, &options(1)).unwrap();
    let expect = [
        ([0.0, 0.5, 0.4], 0.2),
        ([1.0, 1.0, 1.0], (1.0f64 + 4.0 + 0.25).sqrt()),
        ([1.0, 0.0, 0.5], (0.25f64 + 4.0).sqrt()),
        ([0.25, 0.5, 1.0], 3.0),
    ];
    for (k, (point, distance)) in expect.into_iter().enumerate() {
        assert_eq!(&near.point[3 * k..3 * k + 3], &point, "point {k}");
        assert!((near.distance[k] - distance).abs() < 1e-15, "point {k}");
        let [a, b, c] = [0, 1, 2].map(|i| faces[3 * near.triangle_id[k] as usize + i] as usize);
        let corner = |i: usize| DVec3::from_slice(&vertices[3 * i..]);
        let (u, v) = (near.u[k], near.v[k]);
        let q = corner(a) * (1.0 - u - v) + corner(b) * u + corner(c) * v;
        assert!(
            (q - DVec3::from_slice(&point)).length() < 1e-15,
            "point {k}"
        );
        let n = (corner(b) - corner(a)).cross(corner(c) - corner(a));
        assert_eq!(&near.normal[3 * k..3 * k + 3], &n.to_array(), "point {k}");
    }
    // The faces are wound outwards: the x = 0 face's and the top's.
    assert_eq!(&near.normal[..3], &[-1.0, 0.0, 0.0]);
    assert_eq!(&near.normal[9..], &[0.0, 0.0, 1.0]);
    let single: Vec<f32> = points.iter().map(|&x| x as f32).collect();
    let widened: Vec<f64> = single.iter().map(|&x| f64::from(x)).collect();
    assert_eq!(
        scene.closest_point(&single, &options(1)).unwrap(),
        scene.closest_point(&widened, &options(1)).unwrap()
    );
    // A scene with no mesh has no nearest point.
    let empty = RayScene::new()
        .closest_point(&points[..3], &options(1))
        .unwrap();
    assert_eq!((empty.mesh_id[0], empty.distance[0]), (-1, f64::INFINITY));
    assert!(empty.point[0].is_nan());
    assert_eq!(empty.normal, [0.0; 3]);
}

#[test]
fn from_file_reads_what_a_scene_reads() {
    let mut rng = Rng(8);
    let mut soup = icosphere(1, 0.1, &mut rng);
    // The OBJ reader (tobj) reads single precision, as the renderer does.
    soup.vertices
        .iter_mut()
        .for_each(|v| *v = f64::from(*v as f32));
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ball.obj");
    let mut text = String::new();
    for v in soup.vertices.chunks_exact(3) {
        text += &format!("v {:?} {:?} {:?}\n", v[0], v[1], v[2]);
    }
    for f in soup.faces.chunks_exact(3) {
        text += &format!("f {} {} {}\n", f[0] + 1, f[1] + 1, f[2] + 1);
    }
    std::fs::write(&path, text).unwrap();
    let from_file = RayScene::from_file(&path, &prism::scene::LoadOptions::default()).unwrap();
    let mut direct = RayScene::new();
    direct.add_mesh(&soup.vertices, &soup.faces, None).unwrap();
    assert_eq!(from_file.triangle_count(), soup.faces.len() / 3);
    assert!(from_file.memory_bytes() > 0);
    let (o, d) = mixed_rays(&mut rng, 512);
    let batch = Rays::new(&o, &d, 0.0, f64::INFINITY).unwrap();
    let (a, b) = (
        from_file.intersect(&batch, &options(1)).unwrap(),
        direct.intersect(&batch, &options(1)).unwrap(),
    );
    for k in 0..batch.len() {
        assert_eq!(
            (a.t[k], a.triangle_id[k], a.u[k], a.v[k]),
            (b.t[k], b.triangle_id[k], b.u[k], b.v[k]),
            "ray {k}"
        );
    }
    assert_eq!(a, b);
    let missing = RayScene::from_file(&dir.path().join("none.obj"), &Default::default());
    assert!(matches!(missing, Err(QueryError::Load(_))));
    let unknown = RayScene::from_file(&dir.path().join("x.stl"), &Default::default());
    assert!(matches!(unknown, Err(QueryError::Load(_))));
}

/// A mesh too big for the cache goes through streams for incoherent rays
/// (and packets for coherent ones): each answer is still the single ray's,
/// and brute force's.
#[test]
fn big_meshes_take_streams_with_the_same_answers() {
    let mut rng = Rng(9);
    let n = 320u32;
    let mut vertices = Vec::new();
    for i in 0..n {
        for j in 0..n {
            let (x, z) = (
                i as f64 / n as f64 * 2.0 - 1.0,
                j as f64 / n as f64 * 2.0 - 1.0,
            );
            vertices.extend([x, 0.05 * rng.range(-1.0, 1.0), z]);
        }
    }
    let mut faces = Vec::new();
    for i in 0..n - 1 {
        for j in 0..n - 1 {
            let a = i * n + j;
            faces.extend([a, a + n, a + 1, a + 1, a + n, a + n + 1]);
        }
    }
    let soup = Soup { vertices, faces };
    let mut scene = RayScene::new();
    scene.add_mesh(&soup.vertices, &soup.faces, None).unwrap();
    assert!(
        scene.memory_bytes() > 8 << 20,
        "{} bytes: no streams",
        scene.memory_bytes()
    );
    let mesh = Mesh::new(soup.data()).unwrap();
    let (o, d) = mixed_rays(&mut rng, 4096);
    let batch = rays(&o, &d);
    let hits = scene.intersect(&batch, &options(2)).unwrap();
    let blocked = scene.occluded(&batch, &options(2)).unwrap();
    let counts = scene.count_intersections(&batch, &options(2)).unwrap();
    let mut seen = 0;
    for (k, &blocked) in blocked.iter().enumerate() {
        let (ro, rd) = batch.ray(k);
        let single = mesh.intersect(ro, rd, 0.0, f64::INFINITY);
        let mut count = 0;
        mesh.each_hit(ro, rd, 0.0, f64::INFINITY, |_, _| count += 1);
        assert_eq!(counts[k], count, "ray {k}");
        assert_eq!(
            hits.t[k].to_bits(),
            single.map_or(f64::INFINITY, |h| h.t).to_bits(),
            "ray {k}"
        );
        assert_eq!(
            hits.triangle_id[k],
            single.map_or(-1, |h| i64::from(h.triangle))
        );
        assert_eq!(blocked, single.is_some());
        seen += usize::from(single.is_some());
        if k % 64 == 0 {
            let brute = brute_hits(&[(soup.clone(), None)], ro, rd, 0.0, f64::INFINITY);
            assert_eq!(
                hits.triangle_id[k],
                brute.first().map_or(-1, |b| i64::from(b.2))
            );
            assert_eq!(counts[k] as usize, brute.len(), "ray {k}");
        }
    }
    assert!(seen > 1000, "{seen}");
}
