//! Whitted's adaptive anti-aliasing (`[render] adaptive`): corner and
//! centre samples shared by neighbouring pixels and tiles, the same bits in
//! any region split and on any thread count, a flat picture costing exactly
//! its lattice, fewer rays than uniform sampling for the same error on an
//! edge-heavy scene, and its keys checked.

use glam::DVec3;
use prism::render::{Region, render_region};
use prism::settings::Adaptive;
use prism::{RenderSettings, Scene, render};

fn scene(toml: &str) -> Scene {
    Scene::from_toml(toml, "test").unwrap_or_else(|e| panic!("{e}"))
}

fn edges() -> Scene {
    let text = include_str!("../bench/edges.toml");
    scene(text)
}

fn adaptive(threshold: f64, depth: u32, jitter: bool) -> Option<Adaptive> {
    Some(Adaptive {
        threshold,
        depth,
        jitter,
    })
}

#[test]
fn any_region_split_and_thread_count_gives_the_whole_renders_bits() {
    let s = edges();
    for jitter in [false, true] {
        let settings = RenderSettings {
            width: 80,
            height: 50,
            adaptive: adaptive(0.05, 2, jitter),
            threads: Some(2),
            ..s.settings
        };
        let whole = render(&s, &settings, &()).unwrap().film;
        let one = render(
            &s,
            &RenderSettings {
                threads: Some(1),
                ..settings
            },
            &(),
        )
        .unwrap();
        assert_eq!(whole.pixels(), one.film.pixels());
        // Uneven cuts, so that tiles of the parts lie elsewhere than the
        // whole render's.
        for (x0, x1, y0, y1) in [
            (0, 37, 0, 23),
            (37, 80, 0, 23),
            (0, 37, 23, 50),
            (37, 80, 23, 50),
        ] {
            let region = Region { x0, x1, y0, y1 };
            let part = render_region(&s, &settings, region, &()).unwrap().film;
            for y in y0..y1 {
                for x in x0..x1 {
                    assert_eq!(
                        part.pixels()[((y - y0) * (x1 - x0) + (x - x0)) as usize],
                        whole.pixels()[(y * 80 + x) as usize],
                        "jitter {jitter}: pixel {x},{y}"
                    );
                }
            }
        }
    }
}

#[test]
fn a_flat_picture_costs_its_corners_and_centres_once() {
    // Nothing but the background: no square is cut, every corner is traced
    // once per tile it belongs to (tiles of 16 × 16 keep their own), and
    // every pixel's centre once.
    let s = scene(
        "[render]\nbackground = [0.2, 0.3, 0.4]\n[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n",
    );
    let (w, h) = (40u64, 20u64);
    let settings = RenderSettings {
        width: w as u32,
        height: h as u32,
        adaptive: adaptive(0.0, 3, false),
        ..s.settings
    };
    let out = render(&s, &settings, &()).unwrap();
    assert!(
        out.film
            .pixels()
            .iter()
            .all(|p| *p == DVec3::new(0.2, 0.3, 0.4))
    );
    let mut expected = 0;
    for tx in (0..w).step_by(16) {
        for ty in (0..h).step_by(16) {
            let (tw, th) = ((w - tx).min(16), (h - ty).min(16));
            expected += (tw + 1) * (th + 1) + tw * th;
        }
    }
    assert_eq!(out.stats.camera, expected);
}

#[test]
fn on_edges_it_beats_uniform_sampling_with_fewer_rays() {
    let s = edges();
    let base = RenderSettings {
        width: 160,
        height: 100,
        ..s.settings
    };
    let reference = render(
        &s,
        &RenderSettings {
            spp: 256,
            seed: 99,
            ..base
        },
        &(),
    )
    .unwrap()
    .film;
    let uniform = render(&s, &RenderSettings { spp: 8, ..base }, &()).unwrap();
    let adapted = render(
        &s,
        &RenderSettings {
            adaptive: adaptive(0.2, 1, false),
            ..base
        },
        &(),
    )
    .unwrap();
    let (eu, ea) = (uniform.film.rmse(&reference), adapted.film.rmse(&reference));
    let rays = |o: &prism::RenderOutput| o.stats.camera + o.stats.shadow + o.stats.reflection;
    eprintln!(
        "uniform 8 spp: rmse {eu:.4}, {} rays; adaptive 0.2/1: rmse {ea:.4}, {} rays",
        rays(&uniform),
        rays(&adapted)
    );
    assert!(ea < eu, "{ea} against {eu}");
    assert!(4 * rays(&adapted) < 3 * rays(&uniform));
    // Deeper cuts and a lower threshold bring it closer to the reference.
    let finer = render(
        &s,
        &RenderSettings {
            adaptive: adaptive(0.05, 3, false),
            ..base
        },
        &(),
    )
    .unwrap();
    assert!(finer.film.rmse(&reference) < 0.7 * ea);
}

#[test]
fn adaptive_keys_are_checked() {
    let err = |render: &str| {
        Scene::from_toml(
            &format!("[render]\n{render}\n[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n"),
            "test",
        )
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default()
    };
    assert!(err("adaptive = { depth = 9 }").contains("adaptive.depth"));
    assert!(err("adaptive = { threshold = -1 }").contains("adaptive.threshold"));
    assert!(err("adaptive = { thresold = 0.1 }").contains("thresold"));
    let ok =
        scene("[render]\nadaptive = {}\n[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n");
    // POV-Ray's defaults: +A0.3, +R3.
    assert_eq!(ok.settings.adaptive, adaptive(0.3, 3, false));
    assert!(ok.settings.pixel_key().contains("adaptive=0.3/3"));
}

/// The feelers of a ray tree.
fn feelers(node: &prism::render::explain::RayNode) -> usize {
    let own: usize = node.lights.iter().map(|l| l.feelers).sum();
    own + [&node.reflected, &node.refracted]
        .into_iter()
        .flatten()
        .map(|n| feelers(n))
        .sum::<usize>()
}

#[test]
fn explain_and_debug_views_trace_the_adaptive_samples() {
    use prism::render::aov::{Aov, render_aov};
    use prism::render::explain::explain;
    let s = edges();
    let settings = RenderSettings {
        width: 40,
        height: 25,
        adaptive: adaptive(0.05, 2, true),
        threads: Some(2),
        ..s.settings
    };
    let film = render(&s, &settings, &()).unwrap().film;
    let region = Region::full(settings.width, settings.height);
    let feeler_view = render_aov(&s, &settings, region, Aov::Feelers, &())
        .unwrap()
        .film;
    let mut counts = Vec::new();
    for y in 0..settings.height {
        for x in 0..settings.width {
            // The pixel worked out alone is the render's, to the bit.
            let first = explain(&s, &settings, x, y, 0).unwrap();
            assert_eq!(first.pixel_radiance, film.get(x, y).to_array(), "{x},{y}");
            let n = first.samples as usize;
            // Corners and centre at least; at most every point of the
            // pixel's lattice (spacing 1/8 at depth 2: 9 × 9).
            assert!((5..=81).contains(&n), "{n}");
            counts.push(n);
            if n > 5 && counts.iter().filter(|&&c| c > 5).count() <= 3 {
                // Every sample can be explained, and no more; their
                // feelers are the debug view's count.
                let trees: Vec<_> = (0..n)
                    .map(|k| explain(&s, &settings, x, y, k).unwrap())
                    .collect();
                let total: usize = trees.iter().map(|e| feelers(&e.tree)).sum();
                assert_eq!(feeler_view.get(x, y).x, total as f64, "{x},{y}");
                let past = explain(&s, &settings, x, y, n).unwrap_err();
                assert!(past.contains("adaptive"), "{past}");
            }
        }
    }
    assert!(counts.contains(&5), "no flat pixel");
    assert!(counts.iter().any(|&n| n > 5), "no pixel was subdivided");
}
