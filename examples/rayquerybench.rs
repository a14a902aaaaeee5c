//! CPU time of `RayScene`'s queries on the rays of `bench/rayqueries.py`,
//! without Python (nearest hits written into arrays kept from round to
//! round, as the Python methods write them): for profiling and for
//! comparing two builds in alternation (each answer's hash is printed, so
//! two builds can be seen to give the same bits).
//!
//! Usage: cargo run --release --example rayquerybench -- DIR [ROUNDS] [FILTER]
//! DIR holds `MESH.v` (f64 x, y, z per vertex), `MESH.f` (u32 a, b, c per
//! triangle), `MESH.KIND.o` and `MESH.KIND.d` (f64 origins, directions)
//! for MESH in bunny, bunny940k, terrain and KIND in coherent, incoherent, as
//! `bench/rayqueries.py --dump DIR` writes them. FILTER keeps the rows whose
//! name contains it. Prints one line per row: the name, the CPU seconds of
//! each round (the rays' check, as `RayScene`'s Python methods make it,
//! and the query), the wall seconds of each round, and the answer's hash.

use std::collections::hash_map::DefaultHasher;
use std::hash::{Hash, Hasher};
use std::path::Path;
use std::time::Instant;

use prism::query::{Hits, QueryOptions, RayScene, Rays};

fn read_f64(path: &Path) -> Vec<f64> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    bytes
        .chunks_exact(8)
        .map(|b| f64::from_le_bytes(b.try_into().unwrap()))
        .collect()
}

fn read_u32(path: &Path) -> Vec<u32> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    bytes
        .chunks_exact(4)
        .map(|b| u32::from_le_bytes(b.try_into().unwrap()))
        .collect()
}

/// CPU time of the whole process so far, in seconds.
fn cpu_seconds() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes the timespec it is given.
    unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

/// One row's line: its name, the CPU and wall seconds of each round, and
/// the answer's hash.
fn print_row(name: &str, times: &[f64], walls: &[f64], hash: u64) {
    let show = |v: &[f64]| {
        v.iter()
            .map(|t| format!("{t:.4}"))
            .collect::<Vec<_>>()
            .join(" ")
    };
    println!(
        "{name}: cpu {} wall {} hash {hash:016x}",
        show(times),
        show(walls)
    );
}

/// The batch as `RayScene`'s Python methods make it (its coordinates
/// checked by the query).
fn batch<'a>(o: &'a [f64], d: &'a [f64]) -> Rays<'a> {
    Rays::deferred(o, d, 0.0, f64::INFINITY).unwrap()
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let dir = Path::new(args.get(1).map(String::as_str).unwrap_or("target/rq"));
    let rounds: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(3);
    let filter = args.get(3).cloned().unwrap_or_default();
    for mesh in ["bunny", "bunny940k", "terrain"] {
        // A filter no row of this mesh matches skips its load.
        let matches = ["coherent", "incoherent"].iter().any(|kind| {
            ["nearest", "any", "count"].iter().any(|query| {
                [1, 2]
                    .iter()
                    .any(|t| format!("{mesh} {kind} {query} {t}t").contains(&filter))
            })
        }) || point_rows(mesh)
            .iter()
            .any(|(name, ..)| name.contains(&filter));
        if !matches {
            continue;
        }
        let v = read_f64(&dir.join(format!("{mesh}.v")));
        let f = read_u32(&dir.join(format!("{mesh}.f")));
        let mut scene = RayScene::new();
        scene.add_mesh(&v, &f, None).unwrap();
        for kind in ["coherent", "incoherent"] {
            let o = read_f64(&dir.join(format!("{mesh}.{kind}.o")));
            let d = read_f64(&dir.join(format!("{mesh}.{kind}.d")));
            let start = cpu_seconds();
            Rays::new(&o, &d, 0.0, f64::INFINITY).unwrap();
            if filter.is_empty() || "check".contains(&filter) {
                println!("{mesh} {kind} check: {:.4}", cpu_seconds() - start);
            }
            if kind == "incoherent" {
                closest_point_rows(&scene, mesh, &v, rounds, &filter);
            }
            for query in ["nearest", "any", "count"] {
                for threads in [1, 2] {
                    let name = format!("{mesh} {kind} {query} {threads}t");
                    if !name.contains(&filter) {
                        continue;
                    }
                    let options = QueryOptions {
                        threads: Some(threads),
                        cancel: None,
                    };
                    let mut times = Vec::new();
                    let mut walls = Vec::new();
                    let mut hash = 0;
                    // Written (so faulted in) before the first round.
                    let n = o.len() / 3;
                    let mut kept = Hits {
                        t: vec![1.0; n],
                        mesh_id: vec![1; n],
                        triangle_id: vec![1; n],
                        u: vec![1.0; n],
                        v: vec![1.0; n],
                        normal: vec![1.0; 3 * n],
                    };
                    for _ in 0..rounds {
                        let start = cpu_seconds();
                        let wall = Instant::now();
                        let rays = batch(&o, &d);
                        let mut h = DefaultHasher::new();
                        match query {
                            "nearest" => {
                                // Into arrays kept from round to round, as
                                // Python's `RayScene.intersect` writes them.
                                scene
                                    .intersect_into(&rays, kept.as_mut(), &options)
                                    .unwrap();
                                times.push(cpu_seconds() - start);
                                let hits = &kept;
                                walls.push(wall.elapsed().as_secs_f64());
                                for x in [&hits.t, &hits.u, &hits.v, &hits.normal] {
                                    x.iter().for_each(|x| x.to_bits().hash(&mut h));
                                }
                                hits.mesh_id.hash(&mut h);
                                hits.triangle_id.hash(&mut h);
                            }
                            "any" => {
                                let b = scene.occluded(&rays, &options).unwrap();
                                times.push(cpu_seconds() - start);
                                walls.push(wall.elapsed().as_secs_f64());
                                b.hash(&mut h);
                            }
                            _ => {
                                let c = scene.count_intersections(&rays, &options).unwrap();
                                times.push(cpu_seconds() - start);
                                walls.push(wall.elapsed().as_secs_f64());
                                c.hash(&mut h);
                            }
                        }
                        hash = h.finish();
                    }
                    print_row(&name, &times, &walls, hash);
                }
            }
        }
    }
}

/// The closest-point rows of `mesh`: name, point kind, threads.
fn point_rows(mesh: &str) -> Vec<(String, &'static str, usize)> {
    let mut rows = Vec::new();
    for kind in ["scattered", "near"] {
        for threads in [1, 2] {
            rows.push((
                format!("{mesh} {kind} closest point {threads}t"),
                kind,
                threads,
            ));
        }
    }
    rows
}

/// Closest points of 20,000 points: uniform in the mesh's box
/// (`scattered`), or a vertex moved by up to 1 % of the box's diagonal
/// (`near`), as `bench/rayqueries.py` makes them (other draws).
fn closest_point_rows(scene: &RayScene, mesh: &str, v: &[f64], rounds: usize, filter: &str) {
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut uniform = || {
        state = prism::math::rng::splitmix64(state);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in v.chunks_exact(3) {
        for i in 0..3 {
            lo[i] = lo[i].min(p[i]);
            hi[i] = hi[i].max(p[i]);
        }
    }
    let size = (0..3).map(|i| (hi[i] - lo[i]).powi(2)).sum::<f64>().sqrt();
    let n = 20_000;
    let mut scattered = Vec::with_capacity(3 * n);
    let mut near = Vec::with_capacity(3 * n);
    for _ in 0..n {
        for i in 0..3 {
            scattered.push(lo[i] + (hi[i] - lo[i]) * uniform());
        }
        let k = ((uniform() * (v.len() / 3) as f64) as usize).min(v.len() / 3 - 1);
        for i in 0..3 {
            near.push(v[3 * k + i] + (uniform() * 0.02 - 0.01) * size / 3f64.sqrt());
        }
    }
    for (name, kind, threads) in point_rows(mesh) {
        if !name.contains(filter) {
            continue;
        }
        let points = if kind == "near" { &near } else { &scattered };
        let options = QueryOptions {
            threads: Some(threads),
            cancel: None,
        };
        let (mut times, mut walls, mut hash) = (Vec::new(), Vec::new(), 0);
        for _ in 0..rounds {
            let start = cpu_seconds();
            let wall = Instant::now();
            let near = scene.closest_point(points.as_slice(), &options).unwrap();
            times.push(cpu_seconds() - start);
            walls.push(wall.elapsed().as_secs_f64());
            let mut h = DefaultHasher::new();
            for x in [&near.point, &near.distance, &near.u, &near.v, &near.normal] {
                x.iter().for_each(|x| x.to_bits().hash(&mut h));
            }
            near.mesh_id.hash(&mut h);
            near.triangle_id.hash(&mut h);
            hash = h.finish();
        }
        print_row(&name, &times, &walls, hash);
    }
}
