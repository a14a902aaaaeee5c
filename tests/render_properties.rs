//! Renders checked by properties a physicist would check: silhouette
//! areas, shadows without or with penumbra (against a brute-force
//! reference), pixels computed by hand, the ray tree through glass, the
//! total-internal-reflection disk, energy in a white furnace, invisibility
//! of index-matched glass, symmetry, and determinism across thread counts.

#![allow(clippy::disallowed_methods)] // references computed with the platform's functions

use glam::DVec3;
use prism::render::{Film, render_pixel};
use prism::shading::whitted::{Whitted, WhittedSettings};
use prism::{RenderSettings, Scene, render};

fn scene(toml: &str) -> Scene {
    Scene::from_toml(toml, "test").unwrap_or_else(|e| panic!("{e}"))
}

fn film(scene: &Scene, threads: usize) -> Film {
    let settings = RenderSettings {
        threads: Some(threads),
        ..scene.settings
    };
    render(scene, &settings, &()).unwrap().film
}

/// A unit-radius object seen from above by an orthographic camera 4 units
/// wide, lit only by ambient light: white on black.
fn silhouette_scene(object: &str) -> String {
    format!(
        r#"
        [render]
        width = 200
        height = 200
        spp = 1
        ambient = [1, 1, 1]
        [camera]
        type = "orthographic"
        position = [0, 0, 10]
        look_at = [0, 0, 0]
        view_height = 4
        [materials.white]
        ka = 1
        kd = 0
        [[objects]]
        material = "white"
        {object}
        "#
    )
}

fn covered_area(film: &Film, world_width: f64) -> f64 {
    let pixel = world_width / f64::from(film.width());
    let lit = film.pixels().iter().filter(|p| p.x > 0.5).count();
    lit as f64 * pixel * pixel
}

#[test]
fn sphere_silhouette_has_area_pi_r_squared() {
    let s = scene(&silhouette_scene("type = \"sphere\"\nradius = 1"));
    let area = covered_area(&film(&s, 2), 4.0);
    let expected = std::f64::consts::PI;
    assert!((area - expected).abs() / expected < 0.005, "area {area}");
}

/// Boxes, cylinders, cones and discs seen from above cover the areas
/// geometry gives them: a turned box its rectangle, a cylinder lying
/// down 2r·h, a cone lying down its triangle r·h plus nothing of its base
/// (seen edge-on), a tilted ring π(R² − h²)·cos θ, an open cylinder seen
/// down its axis only its wall (zero area in orthographic view: a circle),
/// a torus its annulus 4πRr along its axis and its stadium edge-on.
#[test]
fn solids_cover_the_areas_geometry_gives_them() {
    let pi = std::f64::consts::PI;
    let cos30 = 3f64.sqrt() / 2.0;
    for (object, expected, tolerance) in [
        (
            "type = \"box\"\ncorner1 = [-1.2, -0.5, -1]\ncorner2 = [0.8, 0.5, 0.3]\n\
             transform = [{ rotate = { axis = [0, 0, 1], degrees = 25 } }]",
            2.0,
            0.01,
        ),
        (
            "type = \"cylinder\"\nbase = [-1.5, 0.2, 0]\ncap = [1.0, 0.2, 0]\nradius = 0.6",
            2.0 * 0.6 * 2.5,
            0.01,
        ),
        (
            "type = \"cone\"\nbase = [-1, 0, 0]\ncap = [1, 0, 0]\nbase_radius = 1\ncap_radius = 0",
            1.0 * 2.0,
            0.01,
        ),
        (
            "type = \"cone\"\nbase = [-1, 0, 0]\ncap = [1, 0, 0]\nbase_radius = 1\ncap_radius = 0.5",
            (1.0 + 0.5) * 2.0,
            0.01,
        ),
        (
            "type = \"disc\"\nnormal = [0, 0.5, 0.8660254037844386]\nradius = 1.5\nhole_radius = 0.5",
            pi * (1.5 * 1.5 - 0.25) * cos30,
            0.01,
        ),
        (
            // Seen along its axis: the annulus from R − r to R + r, 4πRr.
            "type = \"torus\"\nmajor_radius = 1.2\nminor_radius = 0.4\n\
             transform = [{ rotate = { axis = [1, 0, 0], degrees = 90 } }]",
            4.0 * pi * 1.2 * 0.4,
            0.01,
        ),
        (
            // Seen edge-on: two discs of radius r and the band between
            // them, 2(R + r)·2r less the corners the round ends leave out.
            "type = \"torus\"\nmajor_radius = 1.2\nminor_radius = 0.4",
            2.0 * 1.6 * 0.8 - (4.0 - pi) * 0.4 * 0.4,
            0.01,
        ),
    ] {
        let s = scene(&silhouette_scene(object));
        let area = covered_area(&film(&s, 2), 4.0);
        assert!(
            (area - expected).abs() / expected < tolerance,
            "{object}: area {area}, expected {expected}"
        );
    }
    // Down the axis of an open cylinder: only the wall's edge, and the
    // ring between its radii when capped.
    let open = "type = \"cylinder\"\nbase = [0, 0, -1]\ncap = [0, 0, 1]\nradius = 1\nopen = true";
    let area = covered_area(&film(&scene(&silhouette_scene(open)), 2), 4.0);
    assert!(area < 0.05, "an open tube seen down its axis: {area}");
    let capped = open.replace("open = true", "open = false");
    let area = covered_area(&film(&scene(&silhouette_scene(&capped)), 2), 4.0);
    assert!((area - pi).abs() / pi < 0.005, "its cap: {area}");
}

/// CSG seen from above covers what its set operation leaves: a lens cut
/// from two spheres its rim circle πa² (a² = R² − c², c the centres'
/// distance from the middle), a slab less a cylinder through it the square
/// less the hole, a cube rounded by a sphere (the die) the square within
/// the circle.
#[test]
fn csg_covers_the_areas_its_set_operation_leaves() {
    let pi = std::f64::consts::PI;
    // ∫ √(1 − x²) dx from 0.6 to 0.8, for the die's corners.
    let half_disc = |x: f64| 0.5 * (x * (1.0 - x * x).sqrt() + x.asin());
    for (object, expected) in [
        (
            "type = \"intersection\"\n[[objects.children]]\ntype = \"sphere\"\ncenter = [0, 0, 1.2]\n\
             radius = 1.5\n[[objects.children]]\ntype = \"sphere\"\ncenter = [0, 0, -1.2]\nradius = 1.5",
            pi * (1.5 * 1.5 - 1.2 * 1.2),
        ),
        (
            "type = \"difference\"\n[[objects.children]]\ntype = \"box\"\ncorner1 = [-1, -1, -0.5]\n\
             corner2 = [1, 1, 0.5]\n[[objects.children]]\ntype = \"cylinder\"\nbase = [0.2, 0, -1]\n\
             cap = [0.2, 0, 1]\nradius = 0.5",
            4.0 - pi * 0.25,
        ),
        (
            "type = \"intersection\"\n[[objects.children]]\ntype = \"box\"\n\
             corner1 = [-0.8, -0.8, -0.8]\ncorner2 = [0.8, 0.8, 0.8]\n\
             [[objects.children]]\ntype = \"sphere\"",
            4.0 * (0.6 * 0.8 + half_disc(0.8) - half_disc(0.6)),
        ),
    ] {
        let s = scene(&silhouette_scene(object));
        let area = covered_area(&film(&s, 2), 4.0);
        assert!(
            (area - expected).abs() / expected < 0.01,
            "{object}: area {area}, expected {expected}"
        );
    }
}

#[test]
fn non_uniformly_scaled_sphere_is_an_ellipse_of_area_pi_a_b() {
    let s = scene(&silhouette_scene(
        "type = \"sphere\"\nradius = 1\ntransform = [{ scale = [1.8, 0.6, 1] }, { rotate = { axis = [0, 0, 1], degrees = 30 } }]",
    ));
    let area = covered_area(&film(&s, 2), 4.0);
    let expected = std::f64::consts::PI * 1.8 * 0.6;
    assert!((area - expected).abs() / expected < 0.01, "area {area}");
}

#[test]
fn concave_polygon_covers_its_shoelace_area() {
    // A five-pointed star with inner radius 0.6 and outer radius 1.5.
    let mut vertices = Vec::new();
    for i in 0..10 {
        let r = if i % 2 == 0 { 1.5 } else { 0.6 };
        let a = std::f64::consts::FRAC_PI_2 + i as f64 * std::f64::consts::PI / 5.0;
        vertices.push([r * a.cos(), r * a.sin(), 0.0]);
    }
    let shoelace: f64 = (0..10)
        .map(|i| {
            let (a, b) = (vertices[i], vertices[(i + 1) % 10]);
            0.5 * (a[0] * b[1] - b[0] * a[1])
        })
        .sum();
    let list: Vec<String> = vertices
        .iter()
        .map(|v| format!("[{}, {}, {}]", v[0], v[1], v[2]))
        .collect();
    let s = scene(&silhouette_scene(&format!(
        "type = \"polygon\"\nvertices = [{}]",
        list.join(", ")
    )));
    let area = covered_area(&film(&s, 2), 4.0);
    assert!(
        (area - shoelace).abs() / shoelace < 0.01,
        "area {area}, shoelace {shoelace}"
    );
}

const STRIP_PIXELS: u32 = 161;
/// World width of the floor strip the shadow tests look at.
const STRIP_WIDTH: f64 = 8.0;

/// A ball of radius 0.5 at height 2 over a floor, the floor seen from
/// straight above as a strip one pixel tall through the shadow's centre,
/// lit by `light` (a light table's body). `ball` is the ball's material
/// table body, or `None` for no ball.
fn shadow_scene(light: &str, ball: Option<&str>) -> Scene {
    let ball = match ball {
        Some(m) => format!(
            "[materials.ball]\n{m}\n[[objects]]\ntype = \"sphere\"\nmaterial = \"ball\"\ncenter = [0, 2, 0]\nradius = 0.5\n"
        ),
        None => String::new(),
    };
    scene(&format!(
        r#"
        [render]
        width = {STRIP_PIXELS}
        height = 1
        spp = 1
        ambient = [0.1, 0.1, 0.1]
        [camera]
        type = "orthographic"
        position = [0, 1, 0]
        look_at = [0, 0, 0]
        up = [0, 0, -1]
        view_height = {}
        [materials.white]
        ka = 1
        kd = 0.8
        [lights.lamp]
        {light}
        [[objects]]
        type = "plane"
        material = "white"
        normal = [0, 1, 0]
        distance = 0
        {ball}
        "#,
        STRIP_WIDTH / f64::from(STRIP_PIXELS)
    ))
}

/// The fraction of the light each floor pixel sees, left to right:
/// (I − ambient) / (I_unblocked − ambient), which cancels the N·L and
/// distance terms and leaves the visibility.
fn visibility_profile(light: &str, ball: &str) -> Vec<f64> {
    let shadowed = film(&shadow_scene(light, Some(ball)), 2);
    let open = film(&shadow_scene(light, None), 2);
    shadowed
        .pixels()
        .iter()
        .zip(open.pixels())
        .map(|(s, o)| (s.x - 0.1) / (o.x - 0.1))
        .collect()
}

fn profile(light: &str) -> Vec<f64> {
    visibility_profile(light, "kd = 0.8")
}

#[test]
fn point_light_shadow_has_no_penumbra() {
    let v = profile("type = \"point\"\nposition = [0, 6, 0]");
    assert!(
        v.iter().all(|&x| x == 0.0 || (x - 1.0).abs() < 1e-12),
        "{v:?}"
    );
    // The shadow cone is tangent to the ball: half-angle asin(0.5/4), so
    // the umbra on the floor 6 below the light is 2·6·tan(asin(1/8)) wide.
    let umbra =
        v.iter().filter(|&&x| x == 0.0).count() as f64 * STRIP_WIDTH / f64::from(STRIP_PIXELS);
    let expected = 12.0 * (0.125f64).asin().tan();
    assert!(
        (umbra - expected).abs() < 2.0 * STRIP_WIDTH / f64::from(STRIP_PIXELS),
        "umbra {umbra}, expected {expected}"
    );
}

fn sphere_light(radius: f64) -> String {
    format!("type = \"sphere\"\nposition = [0, 6, 0]\nradius = {radius}\nsamples = 64")
}

/// Pixels whose visibility is strictly between umbra and lit.
fn penumbra_width(v: &[f64]) -> usize {
    v.iter().filter(|&&x| x > 1e-9 && x < 1.0 - 1e-9).count()
}

#[test]
fn sphere_light_penumbra_lies_between_umbra_and_lit_and_is_monotone() {
    let v = profile(&sphere_light(0.3));
    let centre = v.len() / 2;
    assert_eq!(v[centre], 0.0, "umbra under the ball");
    assert_eq!(v[0], 1.0, "fully lit far away");
    assert!(v.iter().all(|&x| (0.0..=1.0 + 1e-12).contains(&x)));
    assert!(penumbra_width(&v) >= 6, "a penumbra exists: {v:?}");
    // From the centre outwards the visible fraction never decreases (beyond
    // the noise of 64 stratified samples).
    for side in [1i64, -1] {
        let mut prev = 0.0;
        for k in 0..=centre as i64 {
            let x = v[(centre as i64 + side * k) as usize];
            assert!(x >= prev - 0.03, "not monotone at offset {k}: {v:?}");
            prev = prev.max(x);
        }
    }
}

#[test]
fn penumbra_widens_with_light_radius() {
    let widths: Vec<usize> = [0.1, 0.3, 0.6]
        .iter()
        .map(|&r| penumbra_width(&profile(&sphere_light(r))))
        .collect();
    assert!(widths[0] < widths[1] && widths[1] < widths[2], "{widths:?}");
    // A radius-0 sphere light is a point light.
    assert_eq!(penumbra_width(&profile(&sphere_light(0.0))), 0);
}

#[test]
fn index_matched_glass_is_invisible() {
    let base = r#"
        [render]
        width = 48
        height = 32
        spp = 1
        background = [0.2, 0.3, 0.4]
        [camera]
        position = [0, 1, 6]
        look_at = [0, 0.5, 0]
        [materials.floor]
        color = [1, 1, 0]
        checker = { color = [1, 0, 0], size = 0.5 }
        [materials.clear]
        ka = 0
        kd = 0
        kt = 1
        ior = 1
        [lights.l]
        type = "directional"
        direction = [0.3, -1, -0.2]
        [[objects]]
        type = "plane"
        material = "floor"
        normal = [0, 1, 0]
        "#;
    let glass =
        "[[objects]]\ntype = \"sphere\"\nmaterial = \"clear\"\ncenter = [0, 1, 0]\nradius = 0.9\n";
    let without = film(&scene(base), 2);
    let mut with = scene(&format!("{base}{glass}"));
    // Classic shadows: the glass would block the light; let it through.
    with.transparent_shadows = true;
    let with = film(&with, 2);
    for (a, b) in without.pixels().iter().zip(with.pixels()) {
        assert!((*a - *b).abs().max_element() < 1e-6, "{a} vs {b}");
    }
}

#[test]
fn classic_shadows_are_cast_by_glass_too() {
    let light = "type = \"point\"\nposition = [0, 6, 0]";
    let glass = "ka = 0\nkd = 0\nkt = 0.9\nior = 1.5";
    // By default every object blocks light, transparent ones included.
    let v = visibility_profile(light, glass);
    assert_eq!(v[v.len() / 2], 0.0);
    // Opted in, the glass passes kt at each of its two surfaces.
    let mut shadowed = shadow_scene(light, Some(glass));
    shadowed.transparent_shadows = true;
    let open = film(&shadow_scene(light, None), 2);
    let through = film(&shadowed, 2);
    let centre = STRIP_PIXELS / 2;
    let fraction = (through.get(centre, 0).x - 0.1) / (open.get(centre, 0).x - 0.1);
    assert!((fraction - 0.81).abs() < 1e-9, "{fraction}");
}

#[test]
fn symmetric_scene_renders_symmetric() {
    let s = scene(
        r#"
        [render]
        width = 40
        height = 30
        spp = 1
        [camera]
        position = [0, 2, 6]
        look_at = [0, 1, 0]
        [materials.m]
        ks = 0.5
        kr = 0.3
        [lights.l]
        type = "point"
        position = [0, 5, 5]
        [[objects]]
        type = "sphere"
        material = "m"
        center = [0, 1, 0]
        [[objects]]
        type = "plane"
        material = "m"
        normal = [0, 1, 0]
        "#,
    );
    let f = film(&s, 2);
    for y in 0..30 {
        for x in 0..20 {
            let (a, b) = (f.get(x, y), f.get(39 - x, y));
            assert!((a - b).abs().max_element() < 1e-9, "({x}, {y}): {a} vs {b}");
        }
    }
}

#[test]
fn image_is_bit_identical_for_any_thread_count_and_per_pixel() {
    let mut s = Scene::demo();
    s.settings.width = 64;
    s.settings.height = 48;
    s.settings.spp = 4;
    s.lights[0].shape = prism::lights::LightShape::Sphere {
        center: DVec3::new(4.0, 9.0, 7.0),
        radius: 1.0,
        samples: 9,
    };
    let one = film(&s, 1);
    let two = film(&s, 2);
    let three = film(&s, 3);
    assert_eq!(one, two);
    assert_eq!(one, three);
    // Any pixel rendered on its own gives the same bits: regions of the
    // image can be rendered apart and merged (and the render's camera rays,
    // traced in packets of neighbouring pixels, are each traced as alone).
    let settings = s.settings;
    let tracer = Whitted::new(
        &s,
        WhittedSettings {
            max_depth: settings.max_depth,
            min_weight: settings.min_weight,
        },
    );
    let mut stats = Default::default();
    for (x, y) in (0..48).flat_map(|y| (0..64).map(move |x| (x, y))) {
        assert_eq!(
            render_pixel(&s, &tracer, &settings, x, y, &mut stats),
            one.get(x, y)
        );
    }
}

/// Brute-force reference for the visible fraction of a sphere light (centre
/// `light`, radius `radius`) from floor point `x` past a ball (`ball`,
/// `ball_radius`): a fine grid on the plane through the light's centre,
/// perpendicular to the axis, each grid point weighted by the solid angle it
/// subtends from `x` (cos θ / r²), kept when its direction meets the light.
/// Independent of the renderer's cone sampling.
fn reference_visibility(x: DVec3, light: DVec3, radius: f64, ball: DVec3, ball_radius: f64) -> f64 {
    use prism::geometry::sphere::sphere_roots;
    let axis = (light - x).normalize();
    let frame = prism::math::Frame::from_z(axis);
    let distance = (light - x).length();
    let half = radius * distance / (distance * distance - radius * radius).sqrt() * 1.01;
    let n = 300;
    let (mut total, mut seen) = (0.0, 0.0);
    for i in 0..n {
        for j in 0..n {
            let a = (2.0 * (i as f64 + 0.5) / n as f64 - 1.0) * half;
            let b = (2.0 * (j as f64 + 0.5) / n as f64 - 1.0) * half;
            let p = light + a * frame.x + b * frame.y;
            let d = p - x;
            let r = d.length();
            let dir = d / r;
            let Some((t_light, _)) = sphere_roots(x, dir, light, radius) else {
                continue;
            };
            let weight = dir.dot(axis) / (r * r);
            total += weight;
            let blocked = sphere_roots(x, dir, ball, ball_radius)
                .is_some_and(|(t0, _)| t0 > 0.0 && t0 < t_light);
            if !blocked {
                seen += weight;
            }
        }
    }
    seen / total
}

#[test]
fn penumbra_matches_a_brute_force_reference() {
    let light = "type = \"sphere\"\nposition = [0, 6, 0]\nradius = 0.5\nsamples = 256";
    let v = profile(light);
    let pixel = STRIP_WIDTH / f64::from(STRIP_PIXELS);
    let mut worst = 0.0f64;
    for (i, &measured) in v.iter().enumerate().step_by(4) {
        // The strip's pixel centres, from the left (−x) edge.
        let x = DVec3::new((i as f64 + 0.5) * pixel - STRIP_WIDTH / 2.0, 0.0, 0.0);
        let expected = reference_visibility(
            x,
            DVec3::new(0.0, 6.0, 0.0),
            0.5,
            DVec3::new(0.0, 2.0, 0.0),
            0.5,
        );
        worst = worst.max((measured - expected).abs());
    }
    // 256 stratified samples: the error is a few percent at most.
    assert!(worst < 0.03, "worst difference {worst}");
}

#[test]
fn lit_pixel_equals_the_whitted_formula_by_hand() {
    // Orthographic view straight down on a floor; a point light straight
    // above at height 4 with inverse-square falloff. At the centre pixel
    // N = L = V = +y, so N·L = 1 and R·V = 1:
    // I = ka·Od·Ia + Il/d²·(kd·Od + ks).
    let s = scene(
        r#"
        [render]
        width = 3
        height = 3
        spp = 1
        ambient = [0.2, 0.4, 0.6]
        [camera]
        type = "orthographic"
        position = [0, 5, 0]
        look_at = [0, 0, 0]
        up = [0, 0, -1]
        view_height = 0.3
        [materials.m]
        color = [1, 0.5, 0.25]
        ka = 0.3
        kd = 0.6
        ks = 0.25
        shininess = 7
        [lights.l]
        type = "point"
        position = [0, 4, 0]
        color = [1, 0.8, 0.6]
        intensity = 8
        falloff = "inverse_square"
        [[objects]]
        type = "plane"
        material = "m"
        normal = [0, 1, 0]
        "#,
    );
    let od = DVec3::new(1.0, 0.5, 0.25);
    let il = DVec3::new(1.0, 0.8, 0.6) * 8.0 / 16.0;
    let expected = 0.3 * od * DVec3::new(0.2, 0.4, 0.6) + il * (0.6 * od + DVec3::splat(0.25));
    let got = film(&s, 1).get(1, 1);
    assert!(
        (got - expected).abs().max_element() < 1e-12,
        "{got} vs {expected}"
    );
}

#[test]
fn glass_ball_seen_along_its_axis_passes_kt_squared() {
    // Straight through the centre both interfaces are at normal incidence:
    // no bending, the ray leaves along the axis and sees the background,
    // weighted by kt on entering and kt on leaving; kr adds the mirror
    // image of the (black) camera side.
    let s = scene(
        r#"
        [render]
        width = 1
        height = 1
        spp = 1
        background = [0.5, 1, 0.25]
        ambient = [0, 0, 0]
        min_weight = 0
        [camera]
        position = [0, 0, 5]
        look_at = [0, 0, 0]
        fov = 1
        [materials.glass]
        ka = 0
        kd = 0
        kr = 0.1
        kt = 0.8
        ior = 1.5
        [[objects]]
        type = "sphere"
        material = "glass"
        "#,
    );
    let got = film(&s, 1).get(0, 0);
    // The whole ray tree by hand (min_weight = 0, so only max_depth = 8
    // cuts it): the camera ray (depth 1) reflects kr·b off the outer
    // surface and sends kt inside. A ray inside at depth d < 8 meets the
    // surface head-on again: kt leaves to the background, kr goes back in
    // at depth d + 1; at depth 8 only the (zero) local terms count.
    let b = DVec3::new(0.5, 1.0, 0.25);
    let mut inner = DVec3::ZERO;
    for _depth in (2..8).rev() {
        inner = 0.8 * b + 0.1 * inner;
    }
    let expected = 0.1 * b + 0.8 * inner;
    assert!(
        (got - expected).abs().max_element() < 1e-9,
        "{got} vs {expected}"
    );
    // Without kr it is exactly kt²·background.
    let mut s = s;
    s.materials[0].kr = glam::DVec3::ZERO;
    let got = film(&s, 1).get(0, 0);
    assert!((got - 0.64 * b).abs().max_element() < 1e-12, "{got}");
}

#[test]
fn total_internal_reflection_disk_has_radius_r_over_n() {
    // An orthographic camera inside a unit glass ball (n = 1.5) looking
    // along −z: a ray at distance r from the axis meets the surface at
    // sin θ = r, and leaves only if r < 1/n; beyond, it is totally
    // reflected and stays trapped (same angle at every bounce), so it
    // ends black. The bright disk must have area π/n².
    let s = scene(
        r#"
        [render]
        width = 301
        height = 301
        spp = 1
        background = [1, 1, 1]
        ambient = [0, 0, 0]
        [camera]
        type = "orthographic"
        position = [0, 0, 0]
        look_at = [0, 0, -1]
        view_height = 2
        [materials.glass]
        ka = 0
        kd = 0
        kt = 1
        ior = 1.5
        [[objects]]
        type = "sphere"
        material = "glass"
        "#,
    );
    let f = film(&s, 2);
    let pixel = 2.0 / 301.0;
    let mut bright = 0;
    for y in 0..301 {
        for x in 0..301 {
            let (u, v) = (
                (x as f64 + 0.5) * pixel - 1.0,
                (y as f64 + 0.5) * pixel - 1.0,
            );
            if u * u + v * v < 1.0 && f.get(x, y).x > 0.5 {
                bright += 1;
            }
        }
    }
    let area = bright as f64 * pixel * pixel;
    let expected = std::f64::consts::PI / 2.25;
    assert!(
        (area - expected).abs() / expected < 0.01,
        "area {area}, expected {expected}"
    );
}

#[test]
fn adaptive_depth_skips_only_rays_of_negligible_weight() {
    // A ball between two parallel mirrors: a long ray tree.
    let toml = |min_weight: f64| {
        format!(
            r#"
            [render]
            width = 16
            height = 12
            spp = 1
            max_depth = 30
            min_weight = {min_weight}
            background = [1, 1, 1]
            [camera]
            position = [0, 0, 0]
            look_at = [0, 0, -1]
            [materials.mirror]
            kd = 0.1
            kr = 0.8
            [lights.l]
            type = "point"
            position = [0, 3, 0]
            [[objects]]
            type = "plane"
            material = "mirror"
            normal = [0, 0, 1]
            distance = -3
            [[objects]]
            type = "plane"
            material = "mirror"
            normal = [0, 0, 1]
            distance = 3
            [[objects]]
            type = "sphere"
            material = "mirror"
            center = [0, -1, -1.5]
            radius = 0.5
            "#
        )
    };
    let run = |min_weight: f64| {
        let s = scene(&toml(min_weight));
        render(
            &s,
            &RenderSettings {
                threads: Some(2),
                ..s.settings
            },
            &(),
        )
        .unwrap()
    };
    let (full, adaptive) = (run(0.0), run(0.01));
    // Between the mirrors the weight is 0.8ᵏ after k bounces: below 0.01
    // from k = 21 on, so about 20 of the 29 reflections per pixel remain.
    assert!(
        adaptive.stats.reflection * 4 < full.stats.reflection * 3,
        "{:?} vs {:?}",
        adaptive.stats,
        full.stats
    );
    // A dropped ray has weight < 0.01, and no ray here can carry more than
    // (local ≤ 0.01 ambient + 0.1 diffuse) / (1 − 0.8) = 0.55.
    for (a, b) in adaptive.film.pixels().iter().zip(full.film.pixels()) {
        assert!((*a - *b).abs().max_element() < 0.01 * 0.55, "{a} vs {b}");
        assert!(
            a.max_element() <= b.max_element() + 1e-12,
            "dropping rays only removes light"
        );
    }
}

#[test]
fn lossless_glass_vanishes_in_a_white_furnace() {
    // A ball that only reflects and transmits (kr + kt = 1, no local
    // terms) under a uniform white sky: every path ends in the sky, so
    // every pixel is 1 — whatever the split, classic or Fresnel. A ray
    // entering a sphere can never be totally reflected inside (its inner
    // angle equals its refraction angle), so no energy is trapped; only the
    // weight still bouncing inside at max_depth is lost, which near the
    // silhouette, where Fresnel reflectance nears 1, is up to ~1e-5.
    for fresnel in ["off", "exact", "schlick"] {
        let s = scene(&format!(
            r#"
            [render]
            width = 24
            height = 24
            spp = 1
            max_depth = 64
            min_weight = 0
            background = [1, 1, 1]
            ambient = [0, 0, 0]
            [camera]
            position = [0, 0, 4]
            look_at = [0, 0, 0]
            fov = 35
            [materials.glass]
            ka = 0
            kd = 0
            kr = 0.3
            kt = 0.7
            ior = 1.5
            fresnel = "{fresnel}"
            [[objects]]
            type = "sphere"
            material = "glass"
            "#
        ));
        let lost = if fresnel == "off" { 1e-12 } else { 1e-4 };
        for p in film(&s, 2).pixels() {
            assert!(
                p.max_element() <= 1.0 + 1e-12,
                "{fresnel}: energy created: {p}"
            );
            assert!(p.min_element() >= 1.0 - lost, "{fresnel}: energy lost: {p}");
        }
    }
}

/// The one pixel of an orthographic view straight down on a floor of
/// `material`, with no ambient light, a white background, `render` lines
/// added to `[render]` and `more` (lights, objects) to the scene.
fn floor_pixel(material: &str, render: &str, more: &str) -> DVec3 {
    let s = scene(&format!(
        r#"
        [render]
        width = 1
        height = 1
        spp = 1
        ambient = [0, 0, 0]
        background = [1, 1, 1]
        {render}
        [camera]
        type = "orthographic"
        position = [0, 1, 0]
        look_at = [0, 0, 0]
        up = [0, 0, -1]
        view_height = 0.1
        [materials.floor]
        {material}
        [[objects]]
        type = "plane"
        material = "floor"
        normal = [0, 1, 0]
        {more}
        "#
    ));
    film(&s, 1).get(0, 0)
}

#[test]
fn a_coloured_kr_tints_the_reflection_and_a_number_stays_grey() {
    // A black mirror seen straight on reflects the white background back,
    // each channel weighted by its kr.
    let gold = floor_pixel("kd = 0\nka = 0\nkr = [1.0, 0.766, 0.336]", "", "");
    assert_eq!(gold, DVec3::new(1.0, 0.766, 0.336));
    let grey = floor_pixel("kd = 0\nka = 0\nkr = 0.5", "", "");
    assert_eq!(grey, DVec3::splat(0.5));
    // The same as a triple of equal numbers, bit for bit.
    assert_eq!(
        floor_pixel("kd = 0\nka = 0\nkr = [0.5, 0.5, 0.5]", "", ""),
        grey
    );
}

#[test]
fn coloured_kt_filters_transparent_shadows_by_channel() {
    // A white floor lit from straight above through a pane that passes
    // only red (kt = [0.9, 0, 0]): with transparent shadows the light
    // reaching the floor below is the unblocked light times kt, channel by
    // channel; with classic shadows the pane blocks everything.
    let lit = |pane: bool, transparent: bool| {
        let pane = if pane {
            "[materials.red_glass]\nkd = 0\nka = 0\nkt = [0.9, 0, 0]\nior = 1\n\
             [[objects]]\ntype = \"plane\"\nmaterial = \"red_glass\"\nnormal = [0, 1, 0]\ndistance = 2\n"
        } else {
            ""
        };
        floor_pixel(
            "kd = 1\nka = 0",
            &format!("transparent_shadows = {transparent}"),
            &format!("[lights.l]\ntype = \"point\"\nposition = [0, 4, 0]\n{pane}"),
        )
    };
    let open = lit(false, true);
    assert!(open.min_element() > 0.0);
    let filtered = lit(true, true);
    assert!(
        (filtered - open * DVec3::new(0.9, 0.0, 0.0))
            .abs()
            .max_element()
            < 1e-12,
        "{filtered} vs {open}"
    );
    assert_eq!(lit(true, false), DVec3::ZERO);
}
