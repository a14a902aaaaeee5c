//! The thin lens (`aperture`, `focus_distance`, `focus_on`): a small
//! emitter off the plane in focus blurs to the thin lens's circle of
//! confusion, the plane in focus images as the pinhole does, aperture 0
//! is the pinhole to the bit, and a lens keeps the same bits on any thread
//! count, region and per pixel.
//!
//! The circle of confusion in Prism's film. A perspective camera's film
//! point at (u, v) pixels from the image centre aims along
//! forward + (u, v)/f, f = (h/2) / tan(fov/2) the focal length in pixels
//! (vertical fov). The lens ray from lens point a (a vector in the lens
//! plane, |a| ≤ A) through that film point's point on the plane in focus
//! (depth F) is, at depth d, at a·(1 − d/F) + d·(u, v)/f. It meets a point
//! q at depth d where (u, v) = f·q/d + f·a·(1/F − 1/d): the pinhole image
//! f·q/d moved by f·a·(1/F − 1/d). Over the lens disk the point spreads
//! uniformly over a disc of radius
//!
//!   c = f·A·|1/d − 1/F| = A·|d − F|/d · (f/F) pixels,
//!
//! the thin-lens circle of confusion A·|d − F|/d on the plane in focus
//! times that plane's scale in the image, f/F pixels per world unit.
//! Orthographic (a lens in front of each film point, pbrt's way): the ray
//! at depth d is at a·(1 − d/F) + film point, so c = A·|d − F|/F · k with
//! k = h / view_height pixels per world unit.

#![allow(clippy::disallowed_methods)] // the test's own tan, for the focal length

use glam::DVec2;
use prism::camera::ThinLens;
use prism::math::sampling::concentric_disk;
use prism::render::{Region, render_pixel, render_region};
use prism::shading::whitted::{Whitted, WhittedSettings};
use prism::{RenderSettings, Scene, render};

fn scene(toml: &str) -> Scene {
    Scene::from_toml(toml, "t.toml").unwrap_or_else(|e| panic!("{e}"))
}

fn film(scene: &Scene, threads: usize) -> prism::render::Film {
    let settings = RenderSettings {
        threads: Some(threads),
        ..scene.settings
    };
    render(scene, &settings, &()).unwrap().film
}

/// An emitting disc of radius `r` facing the camera at depth `d` on the
/// axis, on black, seen by `camera` (keys of `[camera]` besides position
/// and look_at) on a 96 × 96 film.
fn glowing_disc(camera: &str, d: f64, r: f64) -> String {
    format!(
        r#"
        [render]
        width = 96
        height = 96
        spp = 144
        ambient = [0, 0, 0]
        max_depth = 1
        [camera]
        position = [0, 0, 0]
        look_at = [0, 0, -1]
        {camera}
        [materials.glow]
        emission = [1, 1, 1]
        ka = 0
        kd = 0
        [[objects]]
        type = "disc"
        center = [0, 0, {z}]
        normal = [0, 0, 1]
        radius = {r}
        material = "glow"
        "#,
        z = -d
    )
}

/// The squared radius of the blur disc, from the second moment of a
/// picture of [`glowing_disc`] about the image centre; `s` is the disc's
/// own (pinhole) image radius in pixels.
///
/// The picture is the pinhole image (a disc of radius s) spread by the
/// lens's uniform disc of radius c and averaged over each pixel; as a
/// distribution its second moment is s²/2 + c²/2 + 1/6 (the last from
/// the pixel's area, read at pixel centres), so c² = 2·(M₂/M₀ − 1/6) − s².
fn blur_squared_from_moment(film: &prism::render::Film, s: f64) -> f64 {
    let (mut m0, mut m2) = (0.0, 0.0);
    for (r, v) in radii_and_values(film) {
        m0 += v;
        m2 += v * r * r;
    }
    // The emitter's whole light arrives: M₀ is the pinhole image's area.
    let area = std::f64::consts::PI * s * s;
    assert!((m0 / area - 1.0).abs() < 0.01, "M0 {m0} vs {area}");
    2.0 * (m2 / m0 - 1.0 / 6.0) - s * s
}

/// The blur disc's radius from its area at half the plateau: where c > s
/// the middle is a plateau of (s/c)², and the brightness falls through
/// half of it at r ≈ c. `near` is the radius within which to read the
/// plateau.
fn blur_from_half_plateau(film: &prism::render::Film, near: f64) -> f64 {
    let all = radii_and_values(film);
    let inner: Vec<f64> = all.iter().filter(|(r, _)| *r < near).map(|p| p.1).collect();
    let plateau = inner.iter().sum::<f64>() / inner.len() as f64;
    let above = all.iter().filter(|(_, v)| *v > plateau / 2.0).count();
    (above as f64 / std::f64::consts::PI).sqrt()
}

/// Each pixel's distance from the image centre (at the pixel's centre)
/// and its red value.
fn radii_and_values(film: &prism::render::Film) -> Vec<(f64, f64)> {
    let centre = DVec2::new(f64::from(film.width()), f64::from(film.height())) / 2.0;
    (0..film.height())
        .flat_map(|y| (0..film.width()).map(move |x| (x, y)))
        .map(|(x, y)| {
            let at = DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5);
            ((at - centre).length(), film.get(x, y).x)
        })
        .collect()
}

/// Renders a glowing disc through a lens and checks both measured blur
/// radii against `c`, within a pixel.
fn check_blur(camera: &str, d: f64, r: f64, s: f64, c: f64) {
    let picture = film(&scene(&glowing_disc(camera, d, r)), 2);
    let moment = blur_squared_from_moment(&picture, s).sqrt();
    let half = blur_from_half_plateau(&picture, c - s - 1.5);
    eprintln!(
        "c = {c:.3} px (s = {s:.3}): second moment {moment:.3} ({:+.3}), half plateau {half:.3} ({:+.3})",
        moment - c,
        half - c
    );
    assert!((moment - c).abs() < 1.0, "{moment} vs {c}");
    assert!((half - c).abs() < 1.0, "{half} vs {c}");
}

#[test]
fn a_small_emitter_off_the_plane_in_focus_blurs_to_the_circle_of_confusion() {
    let f = 48.0 / 20f64.to_radians().tan();
    // Nearer than the plane in focus, and beyond it.
    for (d, focus, r, aperture) in [(4.0, 10.0, 0.12, 0.5), (12.0, 4.0, 0.3, 0.5)] {
        let camera = format!("fov = 40\naperture = {aperture}\nfocus_distance = {focus}");
        let s = f * r / d;
        let c = f * aperture * (1.0 / d - 1.0 / focus).abs();
        check_blur(&camera, d, r, s, c);
    }
    // focus_on sets the same plane by a point's depth (off the axis).
    let camera = "fov = 40\naperture = 0.5\nfocus_on = [3, -2, -10]";
    let c = f * 0.5 * (1.0 / 4.0 - 1.0 / 10.0);
    check_blur(camera, 4.0, 0.12, f * 0.12 / 4.0, c);
    // Orthographic: 24 pixels per world unit.
    let camera = "type = \"orthographic\"\nview_height = 4\naperture = 0.5\nfocus_distance = 5";
    check_blur(
        camera,
        10.0,
        0.15,
        24.0 * 0.15,
        24.0 * 0.5 * (10.0 - 5.0) / 5.0,
    );
}

#[test]
fn without_aperture_the_emitter_is_sharp() {
    // The same disc through a pinhole: its own image, radius s, no blur.
    let f = 48.0 / 20f64.to_radians().tan();
    let s = f * 0.12 / 4.0;
    let picture = film(&scene(&glowing_disc("fov = 40", 4.0, 0.12)), 2);
    let c2 = blur_squared_from_moment(&picture, s);
    // (c² is read within about ±0.1 px²: the pixel-area term 1/6 holds
    // exactly only for pictures much larger than a pixel.)
    assert!(c2.abs() < 0.25, "{c2}");
}

/// A checkered wall facing the camera at depth 6, lit by a point light:
/// the only geometry, all of it at one depth.
fn wall(lens: &str, spp: u32) -> Scene {
    scene(&format!(
        r#"
        [render]
        width = 80
        height = 60
        spp = {spp}
        ambient = [0.1, 0.1, 0.1]
        [camera]
        position = [0.3, 0.2, 0]
        look_at = [0.3, 0.2, -6]
        fov = 50
        {lens}
        [materials.wall]
        color = [0.9, 0.9, 0.9]
        checker = {{ color = [0.1, 0.3, 0.8], size = 0.37 }}
        [lights.lamp]
        type = "point"
        position = [2, 3, -1]
        [[objects]]
        type = "plane"
        normal = [0, 0, 1]
        distance = -6
        material = "wall"
        "#
    ))
}

#[test]
fn the_plane_in_focus_images_as_the_pinhole_does() {
    let lens = "aperture = 0.4\nfocus_distance = 6";
    // One sample, through the pixel centre: every lens ray meets the wall
    // where the pinhole ray does, up to rounding (1e-15 of the distance):
    // the same colour to within 1e-9 in every pixel.
    let (sharp, blurred) = (film(&wall("", 1), 2), film(&wall(lens, 1), 2));
    let worst = sharp
        .pixels()
        .iter()
        .zip(blurred.pixels())
        .map(|(a, b)| (*a - *b).abs().max_element())
        .fold(0.0, f64::max);
    eprintln!("one sample: largest difference {worst:e}");
    assert!(worst < 1e-9, "{worst}");
    // Sixteen samples: the lens draws its points from the pixel's stream
    // too, so the film points differ from the pinhole's and the checker's
    // edges are sampled at other places: pixels on an edge differ by the
    // sampling of their area (up to a quarter), the rest not at all, and
    // the differences cancel on average (signed mean below 0.002; unsigned
    // below 0.02).
    let (sharp, blurred) = (film(&wall("", 16), 2), film(&wall(lens, 16), 2));
    let diffs: Vec<f64> = sharp
        .pixels()
        .iter()
        .zip(blurred.pixels())
        .map(|(a, b)| (*a - *b).abs().max_element())
        .collect();
    let mean = diffs.iter().sum::<f64>() / diffs.len() as f64;
    let worst = diffs.iter().copied().fold(0.0, f64::max);
    let signed = sharp
        .pixels()
        .iter()
        .zip(blurred.pixels())
        .map(|(a, b)| (*b - *a).x)
        .sum::<f64>()
        / diffs.len() as f64;
    eprintln!(
        "sixteen samples: mean difference {mean:e}, largest {worst:e}, mean signed {signed:e}"
    );
    assert!(
        signed.abs() < 0.002 && mean < 0.02 && worst < 0.25,
        "{signed} {mean} {worst}"
    );
}

#[test]
fn aperture_zero_is_the_pinhole_to_the_bit() {
    let text = prism::scene::DEFAULT_SCENE;
    let with_keys = text.replacen(
        "[camera]\n",
        "[camera]\naperture = 0\nfocus_distance = 3\n",
        1,
    );
    assert_ne!(text, with_keys);
    let (mut plain, mut zero) = (scene(text), scene(&with_keys));
    assert_eq!(zero.camera.lens, None);
    assert_eq!(plain.camera, zero.camera);
    for s in [&mut plain, &mut zero] {
        (s.settings.width, s.settings.height, s.settings.spp) = (64, 48, 4);
    }
    assert_eq!(film(&plain, 2), film(&zero, 2));
}

#[test]
fn a_lens_gives_the_same_bits_on_any_thread_count_in_any_region_and_alone() {
    // Meshes (packets of camera rays through a mesh's tree), a glass cube,
    // sphere-light feelers: the camera rays now start apart on the lens.
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/models.toml");
    let mut s = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    s.camera.lens = Some(ThinLens {
        radius: 0.15,
        focus_distance: 6.0,
    });
    (s.settings.width, s.settings.height, s.settings.spp) = (64, 40, 4);
    let one = film(&s, 1);
    let two = film(&s, 2);
    assert_eq!(one, two);
    let pinhole = {
        let mut p = s.clone();
        p.camera.lens = None;
        film(&p, 2)
    };
    assert_ne!(one, pinhole, "the lens changes the picture");
    // A region renders its pixels as the whole frame does (a farm's parts
    // merge into the whole render).
    let region = Region::crop(13, 50, 7, 33, 64, 40).unwrap();
    let part = render_region(&s, &s.settings, region, &()).unwrap().film;
    for y in region.y0..region.y1 {
        for x in region.x0..region.x1 {
            assert_eq!(part.get(x, y), one.get(x, y), "pixel {x},{y}");
        }
    }
    // Each pixel alone (one ray at a time) as in the render's packets of
    // eight camera rays from eight lens points.
    let tracer = Whitted::new(
        &s,
        WhittedSettings {
            max_depth: s.settings.max_depth,
            min_weight: s.settings.min_weight,
        },
    );
    let mut stats = Default::default();
    for (x, y) in (0..40).flat_map(|y| (0..64).map(move |x| (x, y))) {
        let alone = render_pixel(&s, &tracer, &s.settings, x, y, &mut stats);
        assert_eq!(alone, one.get(x, y), "pixel {x},{y}");
    }
}

#[test]
fn each_pixel_uses_every_lens_stratum_once_in_its_own_order() {
    let mut s = wall("aperture = 0.4\nfocus_distance = 6", 64);
    s.settings.spp = 64;
    let lens_points = |x: u32, y: u32| -> Vec<DVec2> {
        (0..64)
            .map(|k| {
                let e = prism::render::explain::explain(&s, &s.settings, x, y, k).unwrap();
                DVec2::from_array(e.lens_point.expect("a lens point")) / 0.4
            })
            .collect()
    };
    let a = lens_points(10, 20);
    let b = lens_points(11, 20);
    assert_ne!(a, b, "pixels pair film and lens strata differently");
    for points in [&a, &b] {
        // One point in each of the 64 pieces the concentric map makes of
        // the 8 × 8 strata: each piece's area is π/64 and the points are
        // spread as a stratified sample's (mean r² = 1/2, mean point 0,
        // both far closer than 64 independent points would come).
        assert!(points.iter().all(|p| p.length() <= 1.0 + 1e-12));
        let r2 = points.iter().map(|p| p.length_squared()).sum::<f64>() / 64.0;
        let mean = points.iter().sum::<DVec2>() / 64.0;
        assert!(
            (r2 - 0.5).abs() < 0.02 && mean.length() < 0.03,
            "{r2} {mean}"
        );
        let mut cells = [0u32; 64];
        for p in points {
            // Back to the square: which 8 × 8 stratum the point came from.
            let cell = (0..64)
                .find(|&i| {
                    let corner = DVec2::new((i % 8) as f64, (i / 8) as f64) / 8.0;
                    let u = inverse_concentric(*p);
                    (u - corner).cmpge(DVec2::ZERO).all()
                        && (u - corner).cmplt(DVec2::splat(0.125 + 1e-12)).all()
                })
                .unwrap();
            cells[cell] += 1;
        }
        assert!(cells.iter().all(|&n| n == 1), "{cells:?}");
    }
    // A pinhole reports none.
    let e = prism::render::explain::explain(&wall("", 4), &wall("", 4).settings, 3, 3, 0).unwrap();
    assert_eq!(e.lens_point, None);
}

/// The inverse of Shirley and Chiu's concentric map, for telling which
/// stratum of the square a lens point came from.
fn inverse_concentric(p: DVec2) -> DVec2 {
    let r = p.length();
    if r == 0.0 {
        return DVec2::splat(0.5);
    }
    let phi = p.y.atan2(p.x);
    let quarter = std::f64::consts::FRAC_PI_4;
    // Which wedge: right, top, bottom, left (the map's radius is a.x or
    // a.y, negative on the left and bottom, turning the point by π).
    let pi = std::f64::consts::PI;
    let a = if phi.abs() <= quarter {
        DVec2::new(r, r * phi / quarter)
    } else if phi > quarter && phi < 3.0 * quarter {
        DVec2::new(r * (2.0 - phi / quarter), r)
    } else if phi < -quarter && phi > -3.0 * quarter {
        DVec2::new(r * (2.0 + phi / quarter), -r)
    } else {
        let theta = if phi > 0.0 { phi - pi } else { phi + pi };
        DVec2::new(-r, -r * theta / quarter)
    };
    (a + DVec2::ONE) / 2.0
}

#[test]
fn the_inverse_concentric_map_inverts_it() {
    let mut rng = prism::math::rng::PixelRng::new(3, 2, 1);
    for _ in 0..10_000 {
        let u = DVec2::new(rng.uniform(), rng.uniform());
        let back = inverse_concentric(concentric_disk(u));
        assert!((back - u).length() < 1e-9, "{u} -> {back}");
    }
}

#[test]
fn bad_lens_keys_are_refused_with_their_place() {
    let refused = |camera: &str, expected: &str| {
        let text = format!(
            "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n{camera}\n\
             [materials.m]\n[[objects]]\ntype = \"sphere\"\nmaterial = \"m\"\n"
        );
        let e = Scene::from_toml(&text, "t.toml").unwrap_err().to_string();
        assert!(e.contains(expected), "{camera}: {e}");
        assert!(e.starts_with("t.toml:4:"), "{camera}: {e}");
    };
    refused("aperture = -0.1", "`aperture` must be 0 or between");
    refused("aperture = nan", "`aperture` must be a finite number");
    refused("aperture = inf", "`aperture` must be a finite number");
    refused("focus_distance = 0", "`focus_distance` must be between");
    refused("focus_distance = -2", "`focus_distance` must be between");
    refused(
        "focus_on = [0, 0, 9]",
        "`focus_on` must lie in front of the camera",
    );
    refused(
        "focus_on = [3, 0, 5]",
        "`focus_on` must lie in front of the camera",
    );
    refused(
        "focus_on = [0, 0, 1]\nfocus_distance = 2",
        "give `focus_distance` or `focus_on`, not both",
    );
    refused("apperture = 0.1", "unknown field `apperture`");
}

#[test]
fn the_lens_focuses_on_look_at_unless_told_otherwise() {
    let lens = |camera: &str| {
        let text = format!(
            "[camera]\nposition = [1, 2, 3]\nlook_at = [1, 2, -5]\n{camera}\n\
             [materials.m]\n[[objects]]\ntype = \"sphere\"\nmaterial = \"m\"\n"
        );
        scene(&text).camera.lens
    };
    let at = |focus_distance| {
        Some(ThinLens {
            radius: 0.25,
            focus_distance,
        })
    };
    assert_eq!(lens(""), None);
    assert_eq!(lens("aperture = 0.25"), at(8.0));
    assert_eq!(lens("aperture = 0.25\nfocus_distance = 3.5"), at(3.5));
    // focus_on: the point's depth along the view, wherever it is across.
    assert_eq!(lens("aperture = 0.25\nfocus_on = [4, -1, -1]"), at(4.0));
    assert_eq!(lens("aperture = 0\nfocus_on = [4, -1, -1]"), None);
}

#[test]
fn a_dict_scene_carries_the_lens_keys() {
    use prism::scene::dict::{DictScene, Value};
    let v3 = |a: f64, b: f64, c: f64| {
        Value::Array(vec![Value::Float(a), Value::Float(b), Value::Float(c)])
    };
    let build = |focus: (&str, Value)| {
        let mut d = DictScene::new();
        d.section(
            "camera",
            Value::Table(vec![
                ("position".into(), v3(0.0, 0.0, 5.0)),
                ("look_at".into(), v3(0.0, 0.0, 0.0)),
                ("aperture".into(), Value::Float(0.1)),
                (focus.0.into(), focus.1),
            ]),
        );
        d.section(
            "materials",
            Value::Table(vec![("m".into(), Value::Table(vec![]))]),
        );
        d.object(Value::Table(vec![
            ("type".into(), Value::String("sphere".into())),
            ("material".into(), Value::String("m".into())),
        ]));
        d.finish(std::path::Path::new("."), &Default::default())
    };
    let built = build(("focus_on", v3(0.0, 3.0, 1.0))).unwrap();
    assert_eq!(
        built.camera.lens,
        Some(ThinLens {
            radius: 0.1,
            focus_distance: 4.0
        })
    );
    let problems = build(("focus_distance", Value::Integer(-1))).unwrap_err();
    assert_eq!(problems.len(), 1, "{problems:?}");
    assert_eq!(problems[0].key_path, "camera.focus_distance");
}
