//! Rays for equal error: Whitted's adaptive anti-aliasing against uniform
//! stratified sampling, for `bench/adaptive.py`.
//!
//! Usage: cargo run --release --example adaptive_rmse -- SCENE WIDTH HEIGHT
//! Renders SCENE at WIDTH×HEIGHT with 1,024 stratified samples per pixel
//! (the reference), then uniformly at 1, 2, 4, … 64 spp and adaptively at
//! depths 1 to 3 and thresholds 0.4 to 0.0125, and prints one JSON line per
//! render: its kind, setting, RMSE against the reference (linear radiance,
//! all channels) and the rays it traced (camera rays and all rays).

use prism::settings::Adaptive;
use prism::{RayStats, RenderSettings, Scene, render};

fn total(s: &RayStats) -> u64 {
    s.camera + s.reflection + s.refraction + s.shadow
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let [_, path, width, height] = &args[..] else {
        eprintln!("usage: adaptive_rmse SCENE WIDTH HEIGHT");
        std::process::exit(2);
    };
    let scene = Scene::load(std::path::Path::new(path)).unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(2)
    });
    let base = RenderSettings {
        width: width.parse().expect("width"),
        height: height.parse().expect("height"),
        adaptive: None,
        ..scene.settings
    };
    let run = |settings: RenderSettings| render(&scene, &settings, &()).expect("render");
    let reference = run(RenderSettings {
        spp: 1024,
        seed: 12345,
        ..base
    })
    .film;
    let print = |kind: &str, setting: String, out: prism::RenderOutput| {
        println!(
            "{{\"kind\": \"{kind}\", \"setting\": \"{setting}\", \"rmse\": {:.6e}, \"camera_rays\": {}, \"rays\": {}}}",
            out.film.rmse(&reference),
            out.stats.camera,
            total(&out.stats)
        );
    };
    for spp in [1, 2, 4, 8, 16, 32, 64] {
        print(
            "uniform",
            format!("{spp} spp"),
            run(RenderSettings { spp, ..base }),
        );
    }
    for jitter in [false, true] {
        for depth in [1, 2, 3] {
            for threshold in [0.4, 0.2, 0.1, 0.05, 0.025, 0.0125] {
                let adaptive = Adaptive {
                    threshold,
                    depth,
                    jitter,
                };
                let out = run(RenderSettings {
                    adaptive: Some(adaptive),
                    ..base
                });
                let jittered = if jitter { " jitter" } else { "" };
                print(
                    "adaptive",
                    format!("threshold {threshold} depth {depth}{jittered}"),
                    out,
                );
            }
        }
    }
}
