//! Debug views agree with the ray trees `explain` records and with the
//! render's own counts: first-hit normal, distance and ids, tree depth,
//! feelers per pixel (summing to the render's shadow-ray count).

use std::process::Command;

use glam::DVec3;
use prism::render::Region;
use prism::render::aov::{Aov, render_aov};
use prism::render::explain::explain;
use prism::{RenderSettings, Scene, render};

fn scene() -> Scene {
    Scene::load(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenes/whitted.toml"
    )))
    .unwrap()
}

#[test]
fn views_match_the_explained_ray_trees() {
    let scene = scene();
    let settings = RenderSettings {
        width: 48,
        height: 36,
        spp: 1,
        ..scene.settings
    };
    let full = Region::full(48, 36);
    let view = |aov| render_aov(&scene, &settings, full, aov, &()).unwrap().film;
    let (normal, depth, object, material, bounces, feelers) = (
        view(Aov::Normal),
        view(Aov::Depth),
        view(Aov::Object),
        view(Aov::Material),
        view(Aov::Bounces),
        view(Aov::Feelers),
    );
    let mut hits = 0;
    for y in 0..36 {
        for x in 0..48 {
            let e = explain(&scene, &settings, x, y, 0).unwrap();
            let nodes = e.tree.nodes();
            let tree_feelers: usize = nodes
                .iter()
                .flat_map(|n| &n.lights)
                .map(|l| l.feelers)
                .sum();
            assert_eq!(feelers.get(x, y), DVec3::splat(tree_feelers as f64));
            match &e.tree.hit {
                None => {
                    assert_eq!(object.get(x, y), DVec3::splat(-1.0));
                    assert_eq!(material.get(x, y), DVec3::splat(-1.0));
                    assert_eq!(depth.get(x, y).x, f64::INFINITY);
                    assert_eq!(bounces.get(x, y), DVec3::ZERO);
                }
                Some(h) => {
                    hits += 1;
                    assert_eq!(depth.get(x, y), DVec3::splat(h.distance));
                    assert_eq!(object.get(x, y), DVec3::splat(f64::from(h.primitive)));
                    // Renormalised after averaging: equal to rounding.
                    assert!((normal.get(x, y) - DVec3::from_array(h.normal)).length() < 1e-14);
                    assert!((normal.get(x, y).length() - 1.0).abs() < 1e-12);
                    let deepest = nodes.iter().map(|n| n.depth).max().unwrap();
                    assert_eq!(bounces.get(x, y), DVec3::splat(f64::from(deepest)));
                    let m = scene
                        .names
                        .materials
                        .iter()
                        .position(|n| *n == h.material)
                        .unwrap();
                    assert_eq!(material.get(x, y), DVec3::splat(m as f64));
                    if h.material == "floor" {
                        assert!((normal.get(x, y) - DVec3::Y).length() < 1e-12);
                    }
                }
            }
        }
    }
    assert!(hits > 500 && hits < 48 * 36, "{hits} hits");
    // With several samples, the feelers still add up to the render's count.
    let settings = RenderSettings { spp: 4, ..settings };
    let total: f64 = render_aov(&scene, &settings, full, Aov::Feelers, &())
        .unwrap()
        .film
        .pixels()
        .iter()
        .map(|p| p.x)
        .sum();
    assert_eq!(
        total as u64,
        render(&scene, &settings, &()).unwrap().stats.shadow
    );
}

#[test]
fn every_view_writes_exr_and_a_false_colour_png() {
    let dir = tempfile::tempdir().unwrap();
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/whitted.toml");
    for name in [
        "normal", "depth", "object", "material", "bounces", "feelers", "time",
    ] {
        for ext in ["exr", "png"] {
            let out = dir.path().join(format!("{name}.{ext}"));
            let o = Command::new(env!("CARGO_BIN_EXE_prism"))
                .args([
                    "render", scene, "--width", "40", "--height", "30", "-q", "--aov", name, "-o",
                ])
                .arg(&out)
                .output()
                .unwrap();
            assert!(
                o.status.success(),
                "{name}.{ext}: {}",
                String::from_utf8_lossy(&o.stderr)
            );
        }
        let png = image::open(dir.path().join(format!("{name}.png")))
            .unwrap()
            .to_rgb8();
        let distinct: std::collections::HashSet<_> = png.pixels().map(|p| p.0).collect();
        assert!(
            distinct.len() >= 3,
            "{name}: a readable picture has several colours"
        );
    }
    // The raw EXR depth is a distance, not a colour.
    let depth = image::open(dir.path().join("depth.exr"))
        .unwrap()
        .to_rgb32f();
    assert!(depth.pixels().any(|p| p.0[0] > 2.0));
}
