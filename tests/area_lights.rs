//! Area lights (rectangles and disks) against their oracles: the
//! irradiance of a uniform Lambertian polygon (Lambert's closed form, a sum
//! over the edges) and of a disk on its axis; an error that falls at least
//! as 1/√N with no bias; the penumbra of a straight edge as wide as
//! similar triangles make it; one- and two-sided emission.
//!
//! A white diffuse floor (kd = 1, Od = 1, no ambient, no highlight) shows
//! L·E: the radiance times the irradiance the light gives each point.

#![allow(clippy::disallowed_methods)] // references computed with the platform's functions

use glam::DVec3;
use prism::math::Ray;
use prism::{RenderSettings, Scene, render};

fn scene(toml: &str) -> Scene {
    Scene::from_toml(toml, "test").unwrap_or_else(|e| panic!("{e}"))
}

/// The floor z = 0 seen from straight above by an orthographic camera
/// `view` wide around (cx, cy), `pixels` square, one sample per pixel (each
/// pixel draws its own random numbers: a pixel is one estimate).
fn floor_scene(light: &str, cx: f64, cy: f64, view: f64, pixels: u32) -> String {
    format!(
        r#"
        [render]
        width = {pixels}
        height = {pixels}
        spp = 1
        ambient = [0, 0, 0]
        [camera]
        type = "orthographic"
        position = [{cx}, {cy}, 10]
        look_at = [{cx}, {cy}, 0]
        view_height = {view}
        [materials.white]
        color = [1, 1, 1]
        ka = 0
        kd = 1
        ks = 0
        [lights.area]
        {light}
        [[objects]]
        type = "plane"
        material = "white"
        normal = [0, 0, 1]
        distance = 0
        "#
    )
}

/// Each pixel's value (green channel) and the floor point at its centre.
fn pixels_and_points(s: &Scene) -> Vec<(f64, DVec3)> {
    let settings = RenderSettings {
        threads: Some(2),
        ..s.settings
    };
    let film = render(s, &settings, &()).unwrap().film;
    let (w, h) = (film.width(), film.height());
    let mut out = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let ray: Ray = s.camera.ray(f64::from(x) + 0.5, f64::from(y) + 0.5, w, h);
            let t = -ray.origin.z / ray.direction.z;
            let value = film.pixels()[(y * w + x) as usize].y;
            out.push((value, ray.origin + t * ray.direction));
        }
    }
    out
}

/// Lambert's irradiance at `x` (normal `n`) from a uniform Lambertian
/// polygon of radiance `radiance` wholly above x's horizon:
/// E = L/2 · |Σ Θᵢ (n · Γᵢ)|, Θᵢ the angle the edge i, i+1 subtends at x and
/// Γᵢ the unit normal of the plane through x and the edge.
fn lambert_polygon(x: DVec3, n: DVec3, corners: &[DVec3], radiance: f64) -> f64 {
    let mut sum = 0.0;
    for i in 0..corners.len() {
        let (a, b) = (corners[i] - x, corners[(i + 1) % corners.len()] - x);
        let cross = a.cross(b);
        let angle = cross.length().atan2(a.dot(b));
        sum += angle * n.dot(cross.normalize());
    }
    0.5 * radiance * sum.abs()
}

/// A tilted, off-centre 1.6 × 0.9 rectangle 2 above the floor, emitting
/// downwards, of radiance 3.
const RECT_CENTER: DVec3 = DVec3::new(0.4, -0.3, 2.0);
const RECT_EDGE_U: DVec3 = DVec3::new(1.6, 0.0, 0.3);
const RECT_EDGE_V: DVec3 = DVec3::new(0.0, -0.9, 0.0);

fn rectangle(samples: u32) -> String {
    let (c, u, v) = (RECT_CENTER, RECT_EDGE_U, RECT_EDGE_V);
    format!(
        "type = \"rectangle\"\nposition = [{}, {}, {}]\nedge_u = [{}, {}, {}]\nedge_v = [{}, {}, {}]\ncolor = [1, 1, 1]\nintensity = 3\nsamples = {samples}",
        c.x, c.y, c.z, u.x, u.y, u.z, v.x, v.y, v.z
    )
}

fn rectangle_corners() -> [DVec3; 4] {
    let (c, u, v) = (RECT_CENTER, 0.5 * RECT_EDGE_U, 0.5 * RECT_EDGE_V);
    [c - u - v, c + u - v, c + u + v, c - u + v]
}

/// Over 4,096 pixels (independent estimates) around (0.9, 0.2): the mean
/// relative error (bias) and the RMS relative error of one estimate.
fn rectangle_errors(samples: u32) -> (f64, f64) {
    let s = scene(&floor_scene(&rectangle(samples), 0.9, 0.2, 0.01, 64));
    let corners = rectangle_corners();
    let (mut sum, mut sum2, mut n) = (0.0, 0.0, 0.0);
    for (value, point) in pixels_and_points(&s) {
        let reference = lambert_polygon(point, DVec3::Z, &corners, 3.0);
        let e = value / reference - 1.0;
        sum += e;
        sum2 += e * e;
        n += 1.0;
    }
    (sum / n, (sum2 / n).sqrt())
}

#[test]
fn a_rectangle_gives_lamberts_irradiance_without_bias_and_its_error_falls_as_one_over_root_n() {
    let mut rms_before: Option<(u32, f64)> = None;
    for samples in [4, 16, 64, 256] {
        let (bias, rms) = rectangle_errors(samples);
        eprintln!("rectangle, {samples} feelers: bias {bias:+.2e}, rms {rms:.2e}");
        // Unbiased at every count: the mean of 4,096 estimates lies within
        // four standard errors of Lambert's value.
        let standard_error = rms / 64.0;
        assert!(
            bias.abs() < 4.0 * standard_error + 1e-4,
            "{samples} samples: bias {bias:e}, rms {rms:e}"
        );
        if samples >= 256 {
            assert!(bias.abs() < 0.005, "{samples}: {bias}");
        }
        // Stratified: four times the feelers at least halve the error.
        if let Some((before, rms0)) = rms_before {
            assert!(
                rms <= 1.05 * rms0 * (f64::from(before) / f64::from(samples)).sqrt(),
                "{before} → {samples} samples: rms {rms0:e} → {rms:e}"
            );
        }
        rms_before = Some((samples, rms));
    }
}

#[test]
fn a_disk_gives_lamberts_irradiance_on_its_axis() {
    // Radius 0.8 at height 1.5 over (−0.2, 0.5), facing down, radiance 2:
    // E = L·π·r²/(r² + h²).
    let light = "type = \"disk\"\nposition = [-0.2, 0.5, 1.5]\nnormal = [0, 0, -1]\nradius = 0.8\ncolor = [1, 1, 1]\nintensity = 2\nsamples = 256";
    let s = scene(&floor_scene(light, -0.2, 0.5, 0.001, 32));
    let (r2, h2) = (0.8f64 * 0.8, 1.5f64 * 1.5);
    let reference = 2.0 * std::f64::consts::PI * r2 / (r2 + h2);
    let values = pixels_and_points(&s);
    let mean = values.iter().map(|(v, _)| v).sum::<f64>() / values.len() as f64;
    eprintln!("disk on its axis: {:+.2e}", mean / reference - 1.0);
    assert!(
        (mean / reference - 1.0).abs() < 0.005,
        "{mean} against {reference}"
    );
    // A tilted disk off its axis, against the closed form of a polygon of
    // 720 sides inscribed in it (within 2e-5 of the disk's irradiance).
    let (c, n) = (
        DVec3::new(0.3, 0.1, 1.2),
        DVec3::new(0.3, -0.2, -1.0).normalize(),
    );
    let light = format!(
        "type = \"disk\"\nposition = [{}, {}, {}]\nnormal = [{}, {}, {}]\nradius = 0.5\ncolor = [1, 1, 1]\nintensity = 1\nsamples = 400",
        c.x, c.y, c.z, n.x, n.y, n.z
    );
    let s = scene(&floor_scene(&light, -0.5, 0.6, 0.001, 32));
    let frame = prism::math::Frame::from_z(n);
    let polygon: Vec<DVec3> = (0..720)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / 720.0;
            c + 0.5 * (a.cos() * frame.x + a.sin() * frame.y)
        })
        .collect();
    let values = pixels_and_points(&s);
    let (mut mean, mut reference) = (0.0, 0.0);
    for (v, p) in &values {
        mean += v;
        reference += lambert_polygon(*p, DVec3::Z, &polygon, 1.0);
    }
    eprintln!("tilted disk off its axis: {:+.2e}", mean / reference - 1.0);
    assert!(
        (mean / reference - 1.0).abs() < 0.005,
        "{mean} against {reference}"
    );
}

#[test]
fn a_one_sided_light_is_dark_behind_and_a_two_sided_one_is_not() {
    // The rectangle emits downwards (edge_u × edge_v points to −z); flipped
    // upwards, the floor below sees its back.
    let up = rectangle(64).replace("edge_v = [0, -0.9, 0]", "edge_v = [0, 0.9, 0]");
    let s = scene(&floor_scene(&up, 0.9, 0.2, 0.01, 16));
    let settings = RenderSettings {
        threads: Some(1),
        ..s.settings
    };
    let output = render(&s, &settings, &()).unwrap();
    assert!(output.film.pixels().iter().all(|p| *p == DVec3::ZERO));
    // No feelers go to a light whose back a point sees.
    assert_eq!(output.stats.shadow, 0);
    // Two-sided: the same light as the one facing down.
    let both = format!("{up}\ntwo_sided = true");
    let (two, down) = (
        pixels_and_points(&scene(&floor_scene(&both, 0.9, 0.2, 0.01, 16))),
        pixels_and_points(&scene(&floor_scene(&rectangle(64), 0.9, 0.2, 0.01, 16))),
    );
    let mean = |v: &[(f64, DVec3)]| v.iter().map(|(x, _)| x).sum::<f64>() / v.len() as f64;
    assert!((mean(&two) / mean(&down) - 1.0).abs() < 0.01);
}

#[test]
fn the_penumbra_of_a_straight_edge_is_as_wide_as_similar_triangles_make_it() {
    // A light 2 wide (x from −1 to 1) at height H = 4, a large opaque
    // square at height h = 1 covering x < 0: the floor is in full shadow
    // for x < −(w/2)·h/(H − h) and fully lit beyond +(w/2)·h/(H − h), and
    // in between the share of the light it sees grows linearly.
    let s = scene(
        r#"
        [camera]
        position = [0, 0, 10]
        look_at = [0, 0, 0]
        [materials.black]
        [lights.area]
        type = "rectangle"
        position = [0, 0, 4]
        edge_u = [2, 0, 0]
        edge_v = [0, -0.5, 0]
        samples = 1024
        [[objects]]
        type = "polygon"
        material = "black"
        vertices = [[-50, -50, 1], [0, -50, 1], [0, 50, 1], [-50, 50, 1]]
        "#,
    );
    let light = s.lights[0];
    let (w, height, blocker) = (2.0, 4.0, 1.0);
    let edge = 0.5 * w * blocker / (height - blocker);
    let mut rng = prism::math::rng::PixelRng::new(1, 2, 3);
    let mut worst: f64 = 0.0;
    for k in 0..=60 {
        let x = -0.6 + 1.2 * f64::from(k) / 60.0;
        let point = DVec3::new(x, 0.0, 0.0);
        let sampler = light.sampler(point);
        let mut seen = 0u32;
        for i in 0..sampler.count() {
            let sample = sampler.sample(i, &mut rng);
            let feeler = Ray::new(point, sample.direction);
            if !s.aggregate.any_hit(&feeler, sample.distance) {
                seen += 1;
            }
        }
        let share = f64::from(seen) / sampler.count() as f64;
        // The share of the light's width in view, from similar triangles:
        // the feeler to the light's x = l crosses the blocker's height at
        // x + (l − x)·h/H, blocked where that is negative.
        let expected = ((x + edge) / (2.0 * edge)).clamp(0.0, 1.0);
        // 32 × 32 strata: the share is exact to one column (1/32).
        worst = worst.max((share - expected).abs());
        assert!(
            (share - expected).abs() <= 1.0 / 32.0 + 1e-9,
            "x = {x}: {share} against {expected}"
        );
        if x < -edge - 1e-9 {
            assert_eq!(seen, 0, "umbra at {x}");
        }
        if x > edge + 1e-9 {
            assert_eq!(seen as usize, sampler.count(), "full light at {x}");
        }
    }
    eprintln!(
        "penumbra: worst |share - similar triangles'| = {worst:.4} (one column of strata: 0.0313)"
    );
}

const CAMERA: &str = "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n";

#[test]
fn area_light_keys_are_checked() {
    let err = |light: &str| {
        Scene::from_toml(&format!("{CAMERA}[lights.a]\n{light}"), "test")
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default()
    };
    let m = err("type = \"rectangle\"\nposition = [0, 1, 0]\nedge_u = [1, 0, 0]");
    assert!(m.contains("needs `edge_v`"), "{m}");
    let m =
        err("type = \"rectangle\"\nposition = [0, 1, 0]\nedge_u = [1, 0, 0]\nedge_v = [2, 0, 0]");
    assert!(m.contains("span no area"), "{m}");
    let m = err("type = \"disk\"\nposition = [0, 1, 0]\nradius = 1");
    assert!(m.contains("needs `normal`"), "{m}");
    let m = err("type = \"disk\"\nposition = [0, 1, 0]\nnormal = [0, -1, 0]\nradius = -1");
    assert!(m.contains("radius"), "{m}");
    let m = err(
        "type = \"disk\"\nposition = [0, 1, 0]\nnormal = [0, -1, 0]\nfalloff = \"inverse_square\"",
    );
    assert!(m.contains("`falloff` does not apply"), "{m}");
    let m = err("type = \"point\"\nposition = [0, 1, 0]\ntwo_sided = true");
    assert!(m.contains("`two_sided` does not apply"), "{m}");
    // The power of a light of radiance L and area A is π·A·L.
    let s = scene(&format!(
        "{CAMERA}[lights.a]\ntype = \"disk\"\nposition = [0, 1, 0]\nnormal = [0, -1, 0]\nradius = 0.5"
    ));
    let area = s.lights[0].shape.area();
    assert!((area - std::f64::consts::PI * 0.25).abs() < 1e-15);
}

#[test]
fn area_lights_render_the_same_bits_on_one_and_two_threads() {
    let text = floor_scene(&rectangle(16), 0.5, 0.0, 3.0, 48).replace(
        "[[objects]]",
        "[[objects]]\ntype = \"sphere\"\nmaterial = \"white\"\ncenter = [0.5, 0, 0.6]\nradius = 0.4\n[[objects]]",
    );
    let s = scene(&text);
    let one = render(
        &s,
        &RenderSettings {
            threads: Some(1),
            ..s.settings
        },
        &(),
    )
    .unwrap();
    let two = render(
        &s,
        &RenderSettings {
            threads: Some(2),
            ..s.settings
        },
        &(),
    )
    .unwrap();
    assert_eq!(one.film.pixels(), two.film.pixels());
    // The sphere's shadow is there: some pixels darker than the open floor.
    assert!(
        one.film
            .pixels()
            .iter()
            .any(|p| p.y < 0.5 * two.film.pixels()[0].y)
    );
}

#[test]
fn explain_lists_each_feelers_point_on_the_area_light() {
    // 100 feelers to the tilted rectangle: the first 64 listed, each on
    // the light (in its plane, within its edges), the rest counted.
    let s = scene(&floor_scene(&rectangle(100), 0.9, 0.2, 0.5, 8));
    let e = prism::render::explain::explain(&s, &s.settings, 4, 4, 0).unwrap();
    let terms = &e.tree.lights[0];
    assert_eq!(terms.feelers, 100);
    assert_eq!(terms.feeler_points.len(), 64);
    assert_eq!(terms.feeler_points_left_out, 36);
    let normal = RECT_EDGE_U.cross(RECT_EDGE_V).normalize();
    for f in &terms.feeler_points {
        let p = DVec3::from(f.on_light.expect("a point on the light")) - RECT_CENTER;
        assert!(p.dot(normal).abs() < 1e-12, "{p}");
        let (u, v) = (
            p.dot(RECT_EDGE_U) / RECT_EDGE_U.length_squared(),
            p.dot(RECT_EDGE_V) / RECT_EDGE_V.length_squared(),
        );
        assert!(u.abs() <= 0.5 + 1e-12 && v.abs() <= 0.5 + 1e-12, "{u} {v}");
        assert!(f.weight > 0.0 && f.visibility == [1.0; 3]);
    }
}
