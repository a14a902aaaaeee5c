//! Glossy reflection and translucency (a material's `roughness`) against
//! its oracles: under a uniform sky a glossy mirror returns kr times the
//! sky and a rough glass ball vanishes (white furnace: the lobe moves
//! light, it neither makes nor loses any, total internal reflection
//! included); the picture converges to the sharp mirror's as the lobe
//! narrows; the same bits on every thread count.

use glam::DVec3;
use prism::render::Film;
use prism::{RenderSettings, Scene, render};

fn scene(toml: &str) -> Scene {
    Scene::from_toml(toml, "test").unwrap_or_else(|e| panic!("{e}"))
}

fn film(s: &Scene, threads: usize) -> (Film, prism::RayStats) {
    let settings = RenderSettings {
        threads: Some(threads),
        ..s.settings
    };
    let out = render(s, &settings, &()).unwrap();
    (out.film, out.stats)
}

const SKY: DVec3 = DVec3::new(0.6, 0.7, 0.8);

/// A ball of `material` (TOML keys) under a uniform sky, nothing else.
fn furnace(material: &str, max_depth: u32) -> Scene {
    scene(&format!(
        r#"
        [render]
        width = 40
        height = 40
        spp = 1
        max_depth = {max_depth}
        background = [{}, {}, {}]
        ambient = [0, 0, 0]
        [camera]
        position = [0, 0, 4]
        look_at = [0, 0, 0]
        fov = 40
        [materials.ball]
        ka = 0
        kd = 0
        ks = 0
        {material}
        [[objects]]
        type = "sphere"
        material = "ball"
        radius = 1
        "#,
        SKY.x, SKY.y, SKY.z
    ))
}

#[test]
fn a_glossy_mirror_under_a_uniform_sky_returns_kr_times_the_sky() {
    for roughness in [0.1, 0.5, 1.0] {
        let s = furnace(
            &format!("kr = 0.7\nroughness = {roughness}\nsamples = 9"),
            8,
        );
        let (film, stats) = film(&s, 2);
        let on_ball = film.pixels().iter().filter(|p| **p != SKY).count();
        let worst = film
            .pixels()
            .iter()
            .filter(|p| **p != SKY)
            .map(|p| (*p - 0.7 * SKY).abs().max_element())
            .fold(0.0, f64::max);
        eprintln!("white furnace, roughness {roughness}: worst |pixel - kr L| = {worst:.1e}");
        for p in film.pixels() {
            if *p != SKY {
                assert!(
                    (*p - 0.7 * SKY).abs().max_element() < 1e-12,
                    "{roughness}: {p}"
                );
            }
        }
        // The ball is there, and each of its pixels sent nine rays.
        assert!(on_ball > 300, "{on_ball}");
        assert_eq!(stats.reflection, 9 * on_ball as u64);
    }
}

#[test]
fn a_rough_glass_ball_under_a_uniform_sky_vanishes() {
    // kt = 1, kr = 0: every path is one chain of rays (refracted, or
    // reflected where a facet totally reflects) that ends in the sky.
    // A path can stay trapped by total internal reflection for long; a
    // path cut at the depth limit returns nothing. At the limit of 256 no
    // path of this picture is cut.
    let s = furnace("kt = 1\nior = 1.5\nroughness = 0.6\nsamples = 4", 256);
    let (film, stats) = film(&s, 2);
    let worst = film
        .pixels()
        .iter()
        .map(|p| (*p - SKY).abs().max_element())
        .fold(0.0, f64::max);
    eprintln!("rough glass ball in the furnace: worst |pixel - L| = {worst:.1e}");
    for p in film.pixels() {
        assert!((*p - SKY).abs().max_element() < 1e-12, "{p}");
    }
    // At 64 a few are (one in four rays of a pixel gives 3/4 of the sky),
    // and nothing is ever brighter than the sky.
    let (cut, _) = self::film(
        &furnace("kt = 1\nior = 1.5\nroughness = 0.6\nsamples = 4", 64),
        2,
    );
    let dimmer = cut.pixels().iter().filter(|p| **p != SKY).count();
    assert!(dimmer <= 4, "{dimmer}");
    assert!(cut.pixels().iter().all(|p| p.cmple(SKY + 1e-12).all()));
    assert!(stats.refraction > 1000);
    // Inside the glass some facets reflect all: those rays are traced too.
    assert!(stats.reflection > 0, "{stats:?}");
}

/// A mirror ball over a checkered floor under a point light.
fn mirror(roughness: f64) -> Scene {
    scene(&format!(
        r#"
        [render]
        width = 64
        height = 48
        spp = 1
        [camera]
        position = [0, 1.5, 5]
        look_at = [0, 0.8, 0]
        fov = 40
        [materials.floor]
        color = [0.9, 0.9, 0.9]
        checker = {{ color = [0.1, 0.1, 0.4], size = 0.5 }}
        [materials.mirror]
        ka = 0
        kd = 0.1
        kr = 0.8
        roughness = {roughness}
        samples = 64
        [lights.sun]
        type = "point"
        position = [3, 6, 4]
        [[objects]]
        type = "plane"
        material = "floor"
        normal = [0, 1, 0]
        distance = 0
        [[objects]]
        type = "sphere"
        material = "mirror"
        center = [0, 1, 0]
        radius = 1
        "#
    ))
}

fn rms(a: &Film, b: &Film) -> f64 {
    let n = a.pixels().len() as f64;
    let sum: f64 = a
        .pixels()
        .iter()
        .zip(b.pixels())
        .map(|(x, y)| (*x - *y).length_squared())
        .sum();
    (sum / n).sqrt()
}

#[test]
fn the_picture_converges_to_the_sharp_mirrors_as_the_lobe_narrows() {
    let sharp = film(&mirror(0.0), 2).0;
    let mut before = f64::INFINITY;
    let mut first = None;
    for roughness in [0.4, 0.2, 0.1, 0.05, 0.025, 0.0125] {
        let d = rms(&film(&mirror(roughness), 2).0, &sharp);
        eprintln!("roughness {roughness}: rms {d:.4} from the sharp mirror");
        assert!(d < before, "roughness {roughness}: {d} after {before}");
        before = d;
        first.get_or_insert(d);
    }
    // At r = 0.0125 (α = 1.6e-4) the difference is a small part of r = 0.4's.
    assert!(before < 0.1 * first.unwrap(), "{before}");
}

#[test]
fn glossy_renders_the_same_bits_on_one_and_two_threads() {
    let s = mirror(0.3);
    assert_eq!(film(&s, 1).0.pixels(), film(&s, 2).0.pixels());
}

#[test]
fn roughness_outside_zero_to_one_is_refused() {
    let e = Scene::from_toml(
        "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n[materials.m]\nroughness = 1.5",
        "test",
    )
    .err()
    .map(|e| e.to_string())
    .unwrap_or_default();
    assert!(e.contains("roughness"), "{e}");
}
