//! Ray-query throughput of Prism's mesh BVH, for `bench/meshes.py`, which
//! measures Embree on the same rays in the same run.
//!
//! Usage: cargo run --release --example meshbench -- MODEL OUT_DIR [INCOHERENT_RAYS]
//! Times the load and the build, then (a) 1024×1024 primary camera rays
//! (closest hit), (b) incoherent rays (random origins in the bounding box,
//! random directions; closest hit), (c) shadow rays from the primary hits
//! to a point light (any hit), each single-threaded and on all threads
//! (best of 3); then (a) and (c) again in packets of eight (camera rays in
//! 4×2 tiles, shadow rays of eight neighbouring hits: the `packets` object),
//! each packet answer first checked against the ray's own. Writes the rays
//! for Embree to OUT_DIR (f32: origin, direction, t_max per ray) with the
//! triangles, and prints one JSON line.

use std::io::Write;
use std::path::Path;
use std::time::Instant;

use glam::DVec3;
use prism::accel::PACKET;
use prism::geometry::Mesh;
use prism::geometry::mesh::MeshHit;
use prism::math::Frame;
use prism::math::rng::PixelRng;
use prism::scene::models::load_model;
use prism::scene::resources::{LoadOptions, Resources};
use rayon::prelude::*;

struct Rays {
    origins: Vec<DVec3>,
    directions: Vec<DVec3>,
    t_max: Vec<f64>,
}

impl Rays {
    fn write(&self, path: &Path) -> std::io::Result<()> {
        let mut f = std::io::BufWriter::new(std::fs::File::create(path)?);
        for i in 0..self.origins.len() {
            for v in [self.origins[i].to_array(), self.directions[i].to_array()].concat() {
                f.write_all(&(v as f32).to_le_bytes())?;
            }
            f.write_all(&(self.t_max[i].min(f32::MAX as f64) as f32).to_le_bytes())?;
        }
        f.flush()
    }
}

/// Best of 3 wall times of `run`, and its result.
/// Rays per parallel task of the streamed incoherent query.
const STREAM_PART: usize = 1024;

fn best_of_3<T>(mut run: impl FnMut() -> T) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..3 {
        let start = Instant::now();
        let r = run();
        best = best.min(start.elapsed().as_secs_f64());
        out = Some(r);
    }
    (best, out.expect("ran"))
}

fn peak_rss_mb() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok())
        })
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    anyhow::ensure!(
        args.len() >= 3,
        "usage: meshbench MODEL OUT_DIR [INCOHERENT_RAYS]"
    );
    let out = Path::new(&args[2]);
    let incoherent_count: usize = args.get(3).map_or(Ok(1 << 20), |s| s.parse())?;

    let start = Instant::now();
    let model_path = Path::new(&args[1]);
    let mut resources = Resources::new(
        model_path.parent().unwrap_or(Path::new(".")),
        &LoadOptions::default(),
    );
    let model = load_model(model_path, &mut resources).map_err(|e| anyhow::anyhow!("{e}"))?;
    let load_s = start.elapsed().as_secs_f64();
    anyhow::ensure!(
        model.meshes.len() == 1,
        "meshbench takes single-mesh models (OBJ, PLY)"
    );
    let triangles_in = model.meshes[0].clone();
    let start = Instant::now();
    let mesh = Mesh::new(triangles_in.clone())?;
    let build_s = start.elapsed().as_secs_f64();

    // (a) primary rays: a pinhole camera 40° wide looking at the model.
    let bounds = mesh.bounds();
    let center = bounds.centroid();
    let radius = 0.5 * bounds.diagonal();
    let eye = center + DVec3::new(0.3, 0.4, 1.0).normalize() * radius * 2.6;
    let frame = Frame::from_z((center - eye).normalize());
    let side = 1024usize;
    let half = prism::math::transcendental::tan(20f64.to_radians());
    let mut primary = Rays {
        origins: vec![],
        directions: vec![],
        t_max: vec![],
    };
    for y in 0..side {
        for x in 0..side {
            let sx = (2.0 * (x as f64 + 0.5) / side as f64 - 1.0) * half;
            let sy = (1.0 - 2.0 * (y as f64 + 0.5) / side as f64) * half;
            primary.origins.push(eye);
            primary
                .directions
                .push(frame.to_world(DVec3::new(sx, sy, 1.0)).normalize());
            primary.t_max.push(f64::INFINITY);
        }
    }
    // (b) incoherent rays.
    let mut rng = PixelRng::new(2026, 0, 0);
    let mut incoherent = Rays {
        origins: vec![],
        directions: vec![],
        t_max: vec![],
    };
    let extent = bounds.max - bounds.min;
    while incoherent.origins.len() < incoherent_count {
        let d = DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 2.0 - 1.0;
        if d.length_squared() > 1.0 || d.length_squared() < 1e-6 {
            continue;
        }
        incoherent
            .origins
            .push(bounds.min + extent * DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()));
        incoherent.directions.push(d.normalize());
        incoherent.t_max.push(f64::INFINITY);
    }
    // (c) shadow rays from the primary hits towards a light above the model.
    let light = center + DVec3::new(-0.5, 1.0, 0.6).normalize() * radius * 3.0;
    let mut shadow = Rays {
        origins: vec![],
        directions: vec![],
        t_max: vec![],
    };
    for i in 0..primary.origins.len() {
        if let Some(h) = mesh.intersect(
            primary.origins[i],
            primary.directions[i],
            0.0,
            f64::INFINITY,
        ) {
            let p = primary.origins[i] + h.t * primary.directions[i];
            let to_light = light - p;
            let n = if h.normal.dot(to_light) > 0.0 {
                h.normal
            } else {
                -h.normal
            };
            let o = p + n * 1e-6 * radius;
            shadow.origins.push(o);
            shadow.directions.push((light - o).normalize());
            shadow.t_max.push((light - o).length());
        }
    }

    let closest_1 = |r: &Rays| {
        (0..r.origins.len())
            .filter(|&i| {
                mesh.intersect(r.origins[i], r.directions[i], 0.0, r.t_max[i])
                    .is_some()
            })
            .count()
    };
    let closest_n = |r: &Rays| {
        (0..r.origins.len())
            .into_par_iter()
            .filter(|&i| {
                mesh.intersect(r.origins[i], r.directions[i], 0.0, r.t_max[i])
                    .is_some()
            })
            .count()
    };
    let any_1 = |r: &Rays| {
        (0..r.origins.len())
            .filter(|&i| mesh.any_hit(r.origins[i], r.directions[i], 0.0, r.t_max[i]))
            .count()
    };
    let any_n = |r: &Rays| {
        (0..r.origins.len())
            .into_par_iter()
            .filter(|&i| mesh.any_hit(r.origins[i], r.directions[i], 0.0, r.t_max[i]))
            .count()
    };
    // The same queries in packets of eight rays: the camera rays of a tile
    // of 4×2 pixels, the shadow rays of eight consecutive hits.
    let mut tiled = Rays {
        origins: vec![],
        directions: vec![],
        t_max: vec![],
    };
    for ty in (0..side).step_by(2) {
        for tx in (0..side).step_by(4) {
            for y in ty..(ty + 2).min(side) {
                for x in tx..(tx + 4).min(side) {
                    let i = y * side + x;
                    tiled.origins.push(primary.origins[i]);
                    tiled.directions.push(primary.directions[i]);
                    tiled.t_max.push(primary.t_max[i]);
                }
            }
        }
    }
    let closest_packets = |r: &Rays, chunk: std::ops::Range<usize>| {
        let mut rays = [(DVec3::ZERO, DVec3::ZERO); PACKET];
        for (ray, i) in rays.iter_mut().zip(chunk.clone()) {
            *ray = (r.origins[i], r.directions[i]);
        }
        let rays = &rays[..chunk.len()];
        let mut hits = [None; PACKET];
        mesh.intersect_packet(rays, 0.0, &r.t_max[chunk], &mut hits[..rays.len()]);
        hits
    };
    let any_packets = |r: &Rays, chunk: std::ops::Range<usize>| {
        let mut rays = [(DVec3::ZERO, DVec3::ZERO); PACKET];
        for (ray, i) in rays.iter_mut().zip(chunk.clone()) {
            *ray = (r.origins[i], r.directions[i]);
        }
        let rays = &rays[..chunk.len()];
        mesh.any_hit_packet(rays, 0.0, &r.t_max[chunk])
    };
    let chunks = |r: &Rays| {
        let n = r.origins.len();
        (0..n.div_ceil(PACKET)).map(move |c| c * PACKET..n.min((c + 1) * PACKET))
    };
    let par_chunks = |r: &Rays| {
        let n = r.origins.len();
        (0..n.div_ceil(PACKET))
            .into_par_iter()
            .map(move |c| c * PACKET..n.min((c + 1) * PACKET))
    };
    let closest_packet_1 = |r: &Rays| {
        chunks(r)
            .map(|c| closest_packets(r, c).iter().flatten().count())
            .sum::<usize>()
    };
    let closest_packet_n = |r: &Rays| {
        par_chunks(r)
            .map(|c| closest_packets(r, c).iter().flatten().count())
            .sum::<usize>()
    };
    let any_packet_1 = |r: &Rays| {
        chunks(r)
            .map(|c| any_packets(r, c).count_ones() as usize)
            .sum::<usize>()
    };
    let any_packet_n = |r: &Rays| {
        par_chunks(r)
            .map(|c| any_packets(r, c).count_ones() as usize)
            .sum::<usize>()
    };
    // Each packet answer must be, to the bit, the ray's answer alone.
    for r in [&tiled, &incoherent] {
        for c in chunks(r) {
            let together = closest_packets(r, c.clone());
            for (k, i) in c.enumerate() {
                let alone = mesh.intersect(r.origins[i], r.directions[i], 0.0, r.t_max[i]);
                anyhow::ensure!(
                    together[k] == alone,
                    "ray {i}: the packet's hit differs from the ray's own"
                );
            }
        }
    }
    for c in chunks(&shadow) {
        let together = any_packets(&shadow, c.clone());
        for (k, i) in c.enumerate() {
            let alone = mesh.any_hit(
                shadow.origins[i],
                shadow.directions[i],
                0.0,
                shadow.t_max[i],
            );
            anyhow::ensure!(
                (together >> k & 1 == 1) == alone,
                "shadow ray {i}: the packet's answer differs from the ray's own"
            );
        }
    }

    // Incoherent rays traced in turns, STREAM at a time (see
    // Mesh::intersect_stream); each answer checked against the ray's own.
    let pairs: Vec<(DVec3, DVec3)> = incoherent
        .origins
        .iter()
        .zip(&incoherent.directions)
        .map(|(&o, &d)| (o, d))
        .collect();
    let stream_part = |range: std::ops::Range<usize>, hits: &mut Vec<Option<MeshHit>>| {
        hits.clear();
        hits.resize(range.len(), None);
        mesh.intersect_stream(&pairs[range.clone()], 0.0, &incoherent.t_max[range], hits);
        hits.iter().flatten().count()
    };
    // In parts of STREAM_PART rays with one buffer for their hits (one
    // buffer for all the rays would be 100 MB to fault in).
    let part = |c: usize| c * STREAM_PART..pairs.len().min((c + 1) * STREAM_PART);
    let parts = pairs.len().div_ceil(STREAM_PART);
    let stream_1 = || {
        let mut hits = Vec::new();
        (0..parts)
            .map(|c| stream_part(part(c), &mut hits))
            .sum::<usize>()
    };
    let stream_n = || {
        (0..parts)
            .into_par_iter()
            .map_init(Vec::new, |hits, c| stream_part(part(c), hits))
            .sum::<usize>()
    };
    {
        let mut streamed = vec![None; pairs.len()];
        mesh.intersect_stream(&pairs, 0.0, &incoherent.t_max, &mut streamed);
        for (i, &(o, d)) in pairs.iter().enumerate() {
            let alone = mesh.intersect(o, d, 0.0, incoherent.t_max[i]);
            anyhow::ensure!(
                streamed[i] == alone,
                "ray {i}: the stream's hit differs from the ray's own"
            );
        }
    }

    let (p1, primary_hits) = best_of_3(|| closest_1(&primary));
    let (pn, _) = best_of_3(|| closest_n(&primary));
    let (i1, incoherent_hits) = best_of_3(|| closest_1(&incoherent));
    let (i_n, _) = best_of_3(|| closest_n(&incoherent));
    let (s1, shadow_hits) = best_of_3(|| any_1(&shadow));
    let (sn, _) = best_of_3(|| any_n(&shadow));

    let (pp1, _) = best_of_3(|| closest_packet_1(&tiled));
    let (ppn, _) = best_of_3(|| closest_packet_n(&tiled));
    let (sp1, _) = best_of_3(|| any_packet_1(&shadow));
    let (spn, _) = best_of_3(|| any_packet_n(&shadow));

    let (st1, _) = best_of_3(stream_1);
    let (stn, _) = best_of_3(stream_n);

    let obvhs = obvhs_rates(&triangles_in, &primary, &shadow);

    primary.write(&out.join("primary.f32"))?;
    incoherent.write(&out.join("incoherent.f32"))?;
    shadow.write(&out.join("shadow.f32"))?;
    let mut f = std::io::BufWriter::new(std::fs::File::create(out.join("triangles.f32"))?);
    for t in &triangles_in.triangles {
        for &i in t {
            for c in triangles_in.positions[i as usize].to_array() {
                f.write_all(&(c as f32).to_le_bytes())?;
            }
        }
    }
    f.flush()?;
    let rate = |n: usize, s: f64| n as f64 / s / 1e6;
    println!(
        "{{\"triangles\": {}, \"load_s\": {load_s}, \"build_s\": {build_s}, \"mesh_mb\": {}, \"peak_rss_mb\": {}, \
         \"threads\": {}, \
         \"primary\": {{\"rays\": {}, \"hits\": {primary_hits}, \"mrays_1\": {}, \"mrays_n\": {}}}, \
         \"incoherent\": {{\"rays\": {}, \"hits\": {incoherent_hits}, \"mrays_1\": {}, \"mrays_n\": {}}}, \
         \"shadow\": {{\"rays\": {}, \"hits\": {shadow_hits}, \"mrays_1\": {}, \"mrays_n\": {}}}, \
         \"packets\": {{\"primary_mrays_1\": {}, \"primary_mrays_n\": {}, \"shadow_mrays_1\": {}, \"shadow_mrays_n\": {}}}, \
         \"streams\": {{\"incoherent_mrays_1\": {}, \"incoherent_mrays_n\": {}}}, \
         \"obvhs\": {{\"build_s\": {}, \"primary_mrays_1\": {}, \"shadow_mrays_1\": {}}}}}",
        mesh.triangle_count(),
        mesh.memory_bytes() as f64 / 1e6,
        peak_rss_mb(),
        rayon::current_num_threads(),
        primary.origins.len(),
        rate(primary.origins.len(), p1),
        rate(primary.origins.len(), pn),
        incoherent.origins.len(),
        rate(incoherent.origins.len(), i1),
        rate(incoherent.origins.len(), i_n),
        shadow.origins.len(),
        rate(shadow.origins.len(), s1),
        rate(shadow.origins.len(), sn),
        rate(primary.origins.len(), pp1),
        rate(primary.origins.len(), ppn),
        rate(shadow.origins.len(), sp1),
        rate(shadow.origins.len(), spn),
        rate(incoherent.origins.len(), st1),
        rate(incoherent.origins.len(), stn),
        obvhs.0,
        obvhs.1,
        obvhs.2,
    );
    Ok(())
}

/// The same primary and shadow rays through obvhs's compressed wide BVH8
/// (a candidate replacement for Prism's own BVH): build seconds, then
/// single-threaded Mrays/s for primary (closest) and shadow (any) rays.
fn obvhs_rates(mesh: &prism::geometry::MeshData, primary: &Rays, shadow: &Rays) -> (f64, f64, f64) {
    use glam034::Vec3A;
    use obvhs::ray::{Ray, RayHit};
    let v = |p: DVec3| Vec3A::new(p.x as f32, p.y as f32, p.z as f32);
    let tris: Vec<obvhs::triangle::Triangle> = mesh
        .triangles
        .iter()
        .map(|t| obvhs::triangle::Triangle {
            v0: v(mesh.positions[t[0] as usize]),
            v1: v(mesh.positions[t[1] as usize]),
            v2: v(mesh.positions[t[2] as usize]),
        })
        .collect();
    let start = Instant::now();
    let bvh = obvhs::cwbvh::builder::build_cwbvh_from_tris(
        &tris,
        obvhs::BvhBuildParams::medium_build(),
        &mut std::time::Duration::default(),
    );
    let build_s = start.elapsed().as_secs_f64();
    let (p, _) = best_of_3(|| {
        (0..primary.origins.len())
            .filter(|&i| {
                let ray = Ray::new_inf(v(primary.origins[i]), v(primary.directions[i]));
                let mut hit = RayHit::none();
                bvh.ray_traverse(ray, &mut hit, |r, id| {
                    tris[bvh.primitive_indices[id] as usize].intersect(r)
                })
            })
            .count()
    });
    let (s, _) = best_of_3(|| {
        (0..shadow.origins.len())
            .filter(|&i| {
                let ray = Ray::new(
                    v(shadow.origins[i]),
                    v(shadow.directions[i]),
                    0.0,
                    shadow.t_max[i] as f32,
                );
                !bvh.ray_traverse_miss(ray, |r, id| {
                    tris[bvh.primitive_indices[id] as usize].intersect(r)
                })
            })
            .count()
    });
    (
        build_s,
        primary.origins.len() as f64 / p / 1e6,
        shadow.origins.len() as f64 / s / 1e6,
    )
}
