//! Closest-hit throughput of Prism's aggregate on one scene's camera rays,
//! for `bench/raycast.py`, which times Embree on the same rays.
//!
//! Usage: cargo run --release --example raycast -- SCENE WIDTH HEIGHT OUT_DIR
//! Writes OUT_DIR/rays.f32 (origin, direction per ray) and
//! OUT_DIR/triangles.f32 (the scene's polygons, fan-triangulated: convex
//! polygons only), and prints one JSON line: rays, hits, best seconds.

use std::io::Write;
use std::path::Path;
use std::time::Instant;

use prism::Scene;
use prism::accel::Shape;
use prism::math::Ray;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    anyhow::ensure!(args.len() == 5, "usage: raycast SCENE WIDTH HEIGHT OUT_DIR");
    let scene = Scene::load(Path::new(&args[1]))?;
    let (width, height): (u32, u32) = (args[2].parse()?, args[3].parse()?);
    let out = Path::new(&args[4]);

    let rays: Vec<Ray> = (0..height)
        .flat_map(|y| (0..width).map(move |x| (x, y)))
        .map(|(x, y)| {
            scene
                .camera
                .ray(f64::from(x) + 0.5, f64::from(y) + 0.5, width, height)
        })
        .collect();

    let mut best = f64::INFINITY;
    let mut hits = 0;
    for _ in 0..5 {
        let start = Instant::now();
        hits = rays
            .iter()
            .filter(|r| {
                std::hint::black_box(scene.aggregate.closest_hit(r, f64::INFINITY)).is_some()
            })
            .count();
        best = best.min(start.elapsed().as_secs_f64());
    }

    let mut ray_file = std::io::BufWriter::new(std::fs::File::create(out.join("rays.f32"))?);
    for r in &rays {
        for v in [r.origin.to_array(), r.direction.to_array()].concat() {
            ray_file.write_all(&(v as f32).to_le_bytes())?;
        }
    }
    ray_file.flush()?;
    let mut tri_file = std::io::BufWriter::new(std::fs::File::create(out.join("triangles.f32"))?);
    for p in scene.aggregate.primitives() {
        let Shape::Polygon(poly) = &p.shape else {
            anyhow::bail!("raycast compares polygon scenes only");
        };
        let v = poly.vertices();
        for i in 1..v.len() - 1 {
            for corner in [v[0], v[i], v[i + 1]] {
                for c in corner.to_array() {
                    tri_file.write_all(&(c as f32).to_le_bytes())?;
                }
            }
        }
    }
    tri_file.flush()?;
    println!(
        "{{\"rays\": {}, \"hits\": {hits}, \"seconds\": {best}, \"primitives\": {}}}",
        rays.len(),
        scene.aggregate.primitives().len()
    );
    Ok(())
}
