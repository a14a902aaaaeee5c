//! Constructive solid geometry and the solids' inside intervals against
//! oracles: The Ray Tracer Challenge's cube and cylinder tables, a thick
//! lens against the lensmaker's formula, a glass merge without inner
//! surfaces, an air bubble in a block, CSG of closed meshes against the
//! same CSG of their analytic twins, and the scene format's refusals.

#![allow(clippy::disallowed_methods)] // references computed with the platform's functions

use glam::DVec3;
use prism::accel::Shape;
use prism::geometry::ShapeHit;
use prism::math::Ray;
use prism::math::rng::PixelRng;
use prism::shading::optics::refract;
use prism::{Scene, SceneError};

const HEAD: &str = r#"
[camera]
position = [0, 0, -10]
look_at = [0, 0, 0]
[materials.glass]
color = [1, 1, 1]
kt = 0.9
ior = 1.5
[materials.red]
color = [1, 0, 0]
"#;

fn scene_in(dir: &std::path::Path, objects: &str) -> Result<Scene, SceneError> {
    Scene::from_toml_in(&format!("{HEAD}{objects}"), "test.toml", dir)
}

fn scene(objects: &str) -> Scene {
    scene_in(std::path::Path::new("."), objects).unwrap_or_else(|e| panic!("{e}"))
}

fn shape(scene: &Scene) -> &Shape {
    &scene.aggregate.primitives()[0].shape
}

/// Every surface `shape` meets along `ray` from t > 0 on, in order.
fn surfaces(shape: &Shape, ray: &Ray) -> Vec<ShapeHit> {
    let mut out: Vec<ShapeHit> = Vec::new();
    let mut from = 0.0;
    while let Some(h) = shape.intersect(ray, from, f64::INFINITY) {
        from = h.t;
        out.push(h);
        assert!(out.len() < 100);
    }
    out
}

fn inside_ends(shape: &Shape, origin: DVec3, direction: DVec3) -> Vec<f64> {
    let ray = Ray { origin, direction };
    shape
        .inside(&ray)
        .unwrap()
        .iter()
        .flat_map(|i| [i.enter.t, i.exit.t])
        .collect()
}

#[test]
fn the_ray_tracer_challenges_cube_table() {
    let s = scene(
        "[[objects]]\ntype = \"box\"\ncorner1 = [-1, -1, -1]\ncorner2 = [1, 1, 1]\nmaterial = \"red\"",
    );
    let cube = shape(&s);
    // "A ray intersects a cube": origin, direction, t1, t2.
    for (o, d, t1, t2) in [
        ([5.0, 0.5, 0.0], [-1.0, 0.0, 0.0], 4.0, 6.0),
        ([-5.0, 0.5, 0.0], [1.0, 0.0, 0.0], 4.0, 6.0),
        ([0.5, 5.0, 0.0], [0.0, -1.0, 0.0], 4.0, 6.0),
        ([0.5, -5.0, 0.0], [0.0, 1.0, 0.0], 4.0, 6.0),
        ([0.5, 0.0, 5.0], [0.0, 0.0, -1.0], 4.0, 6.0),
        ([0.5, 0.0, -5.0], [0.0, 0.0, 1.0], 4.0, 6.0),
        ([0.0, 0.5, 0.0], [0.0, 0.0, 1.0], -1.0, 1.0),
    ] {
        let ends = inside_ends(cube, DVec3::from(o), DVec3::from(d));
        assert_eq!(ends, [t1, t2], "{o:?} {d:?}");
    }
    // "A ray misses a cube".
    for (o, d) in [
        ([-2.0, 0.0, 0.0], [0.2673, 0.5345, 0.8018]),
        ([0.0, -2.0, 0.0], [0.8018, 0.2673, 0.5345]),
        ([0.0, 0.0, -2.0], [0.5345, 0.8018, 0.2673]),
        ([2.0, 0.0, 2.0], [0.0, 0.0, -1.0]),
        ([0.0, 2.0, 2.0], [0.0, -1.0, 0.0]),
        ([2.0, 2.0, 0.0], [-1.0, 0.0, 0.0]),
    ] {
        assert!(inside_ends(cube, DVec3::from(o), DVec3::from(d)).is_empty());
    }
    // "The normal on the surface of a cube" (the corner rows are ties).
    for (p, n) in [
        ([1.0, 0.5, -0.8], [1.0, 0.0, 0.0]),
        ([-1.0, -0.2, 0.9], [-1.0, 0.0, 0.0]),
        ([-0.4, 1.0, -0.1], [0.0, 1.0, 0.0]),
        ([0.3, -1.0, -0.7], [0.0, -1.0, 0.0]),
        ([-0.6, 0.3, 1.0], [0.0, 0.0, 1.0]),
        ([0.4, 0.4, -1.0], [0.0, 0.0, -1.0]),
    ] {
        // A ray from outside straight at the point along −n.
        let n = DVec3::from(n);
        let ray = Ray::new(DVec3::from(p) + 3.0 * n, -n);
        let h = cube.intersect(&ray, 0.0, f64::INFINITY).unwrap();
        assert_eq!(h.normal, n);
        assert!((h.t - 3.0).abs() < 1e-12);
    }
}

#[test]
fn the_ray_tracer_challenges_capped_cylinder_table() {
    // Its cylinder: radius 1 around y, from y = 1 to y = 2, closed.
    let s = scene(
        "[[objects]]\ntype = \"cylinder\"\nbase = [0, 1, 0]\ncap = [0, 2, 0]\nradius = 1\nmaterial = \"red\"",
    );
    let cylinder = shape(&s);
    // "Intersecting the caps of a closed cylinder": 2 crossings each.
    for (o, d) in [
        ([0.0, 3.0, 0.0], [0.0, -1.0, 0.0]),
        ([0.0, 3.0, -2.0], [0.0, -1.0, 2.0]),
        ([0.0, 4.0, -2.0], [0.0, -1.0, 1.0]),
        ([0.0, 0.0, -2.0], [0.0, 1.0, 2.0]),
        ([0.0, -1.0, -2.0], [0.0, 1.0, 1.0]),
    ] {
        let ray = Ray::new(DVec3::from(o), DVec3::from(d));
        assert_eq!(surfaces(cylinder, &ray).len(), 2, "{o:?} {d:?}");
    }
    // "Intersecting a constrained cylinder", the rows off its end planes
    // (the book's ends are open intervals; a closed solid includes them).
    for (o, d, count) in [
        ([0.0, 1.5, 0.0], [0.1, 1.0, 0.0], 0),
        ([0.0, 3.0, -5.0], [0.0, 0.0, 1.0], 0),
        ([0.0, 0.0, -5.0], [0.0, 0.0, 1.0], 0),
        ([0.0, 1.5, -2.0], [0.0, 0.0, 1.0], 2),
    ] {
        let ray = Ray::new(DVec3::from(o), DVec3::from(d));
        // (0, 1.5, 0) lies inside: the one crossing ahead is the exit.
        let expected = if o == [0.0, 1.5, 0.0] { 1 } else { count };
        assert_eq!(surfaces(cylinder, &ray).len(), expected, "{o:?} {d:?}");
    }
    // Its normals: the side at (1, 1.5, 0) is +x; a cap centre is ±y.
    let h = cylinder
        .intersect(&Ray::new(DVec3::new(3.0, 1.5, 0.0), -DVec3::X), 0.0, 1e9)
        .unwrap();
    assert!((h.normal - DVec3::X).length() < 1e-12 && (h.t - 2.0).abs() < 1e-12);
    let h = cylinder
        .intersect(&Ray::new(DVec3::new(0.5, 5.0, 0.0), -DVec3::Y), 0.0, 1e9)
        .unwrap();
    assert!((h.normal - DVec3::Y).length() < 1e-12 && (h.t - 3.0).abs() < 1e-12);
}

#[test]
fn a_cone_to_a_tip_is_entered_through_its_side_and_left_through_its_base() {
    // Base radius 1 at z = 0, tip at z = 2: the radius at z is 1 − z/2.
    let s = scene(
        "[[objects]]\ntype = \"cone\"\nbase = [0, 0, 0]\ncap = [0, 0, 2]\nbase_radius = 1\ncap_radius = 0\nmaterial = \"red\"",
    );
    let cone = shape(&s);
    // Along x at z = 1 (radius 0.5): inside from x = −0.5 to 0.5.
    let ends = inside_ends(cone, DVec3::new(-3.0, 0.0, 1.0), DVec3::X);
    assert!((ends[0] - 2.5).abs() < 1e-12 && (ends[1] - 3.5).abs() < 1e-12);
    // Up the axis: in through the base at z = 0, out at the tip z = 2.
    let ends = inside_ends(cone, DVec3::new(0.0, 0.0, -1.0), DVec3::Z);
    assert_eq!(ends, [1.0, 3.0]);
    // Straight down beside the axis at x = 0.3: in through the side where
    // the radius is 0.3 (z = 1.4), out through the base.
    let hits = surfaces(cone, &Ray::new(DVec3::new(0.3, 0.0, 3.0), -DVec3::Z));
    assert_eq!(hits.len(), 2);
    let side = DVec3::new(1.0, 0.0, 0.5).normalize();
    assert!((hits[0].t - 1.6).abs() < 1e-12 && (hits[0].normal - side).length() < 1e-12);
    assert!((hits[1].t - 3.0).abs() < 1e-12 && hits[1].normal == -DVec3::Z);
    assert!(hits[0].front_face && !hits[1].front_face);
}

/// The lensmaker's thick-lens formula for a biconvex lens of two spheres
/// of radius `r` at thickness `d`, index `n`: the back focal distance from
/// the back vertex.
fn back_focal_length(r: f64, d: f64, n: f64) -> f64 {
    let (r1, r2) = (r, -r);
    let power = (n - 1.0) * (1.0 / r1 - 1.0 / r2 + (n - 1.0) * d / (n * r1 * r2));
    let f = 1.0 / power;
    f * (1.0 - (n - 1.0) * d / (n * r1))
}

#[test]
fn a_lens_cut_from_two_spheres_focuses_at_the_lensmakers_distance() {
    // Spheres of radius 3 with centres 5.4 apart: thickness 0.6, the
    // vertices at z = ∓0.3, the axis along z.
    let s = scene(
        r#"
        [[objects]]
        type = "intersection"
        material = "glass"
        [[objects.children]]
        type = "sphere"
        center = [0, 0, 2.7]
        radius = 3
        [[objects.children]]
        type = "sphere"
        center = [0, 0, -2.7]
        radius = 3
        "#,
    );
    let lens = shape(&s);
    let (r, d, n) = (3.0, 0.6, 1.5);
    let expected = 0.5 * d + back_focal_length(r, d, n);
    for h in [1e-4, -2e-4, 3e-4] {
        // A paraxial ray parallel to the axis, at height h in x.
        let ray = Ray::new(DVec3::new(h, 0.0, -10.0), DVec3::Z);
        let a = lens.intersect(&ray, 0.0, f64::INFINITY).unwrap();
        assert!(a.front_face);
        let inside = Ray {
            origin: ray.at(a.t),
            direction: refract(ray.direction, a.normal, 1.0 / n).unwrap(),
        };
        let b = lens.intersect(&inside, 1e-9, f64::INFINITY).unwrap();
        assert!(!b.front_face, "the second surface is left, not entered");
        let out = Ray {
            origin: inside.at(b.t),
            direction: refract(inside.direction, -b.normal, n).unwrap(),
        };
        // Where it crosses the axis (x = 0).
        let focus = out.at(-out.origin.x / out.direction.x).z;
        let error = (focus - expected).abs() / expected;
        assert!(
            error < 1e-6,
            "h = {h}: focus {focus}, formula {expected}, {error:e}"
        );
    }
}

#[test]
fn a_glass_merge_has_no_inner_surface_and_a_union_keeps_them() {
    let two = |op: &str| {
        format!(
            "[[objects]]\ntype = \"{op}\"\nmaterial = \"glass\"\n\
             [[objects.children]]\ntype = \"sphere\"\ncenter = [-0.5, 0, 0]\n\
             [[objects.children]]\ntype = \"sphere\"\ncenter = [0.5, 0, 0]\n"
        )
    };
    let ray = Ray::new(DVec3::new(-5.0, 0.0, 0.0), DVec3::X);
    let merged = scene(&two("merge"));
    assert_eq!(merged.aggregate.primitives().len(), 1);
    let hits = surfaces(shape(&merged), &ray);
    let ts: Vec<f64> = hits.iter().map(|h| h.t).collect();
    assert_eq!(ts, [3.5, 6.5]);
    assert!(hits[0].front_face && !hits[1].front_face);
    // A union places both spheres: all four surfaces, as POV-Ray's union.
    let union = scene(&two("union"));
    assert_eq!(union.aggregate.primitives().len(), 2);
    let mut ts = Vec::new();
    let mut from = 0.0;
    while let Some(h) = union
        .aggregate
        .closest_hit(&Ray::new(ray.at(from + 1e-9), ray.direction), f64::INFINITY)
    {
        from += 1e-9 + h.t;
        ts.push(from);
    }
    let want = [3.5, 4.5, 5.5, 6.5];
    assert!(
        ts.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-6),
        "{ts:?}"
    );
}

#[test]
fn a_bubble_cut_from_a_block_is_entered_as_air() {
    let s = scene(
        r#"
        [[objects]]
        type = "difference"
        material = "glass"
        [[objects.children]]
        type = "box"
        corner1 = [-1, -1, -1]
        corner2 = [1, 1, 1]
        [[objects.children]]
        type = "sphere"
        radius = 0.5
        "#,
    );
    let hits = surfaces(shape(&s), &Ray::new(DVec3::new(0.0, 0.0, -5.0), DVec3::Z));
    let seen: Vec<(f64, bool, f64)> = hits
        .iter()
        .map(|h| (h.t, h.front_face, h.normal.z))
        .collect();
    // Into the glass, out into the bubble, into the glass, out.
    assert_eq!(
        seen,
        [
            (4.0, true, -1.0),
            (4.5, false, 1.0),
            (5.5, true, -1.0),
            (6.0, false, 1.0)
        ]
    );
}

#[test]
fn inverse_and_half_spaces_cut_as_povray_says() {
    // A sphere cut by the plane y = 0.5: the inside is y < 0.5.
    let s = scene(
        r#"
        [[objects]]
        type = "intersection"
        material = "red"
        [[objects.children]]
        type = "sphere"
        [[objects.children]]
        type = "plane"
        normal = [0, 1, 0]
        distance = 0.5
        "#,
    );
    let cap = shape(&s);
    let down = surfaces(cap, &Ray::new(DVec3::new(0.0, 5.0, 0.0), -DVec3::Y));
    assert_eq!(down.iter().map(|h| h.t).collect::<Vec<_>>(), [4.5, 6.0]);
    assert_eq!(down[0].normal, DVec3::Y);
    // Its bounds are the sphere's (the plane is unbounded).
    assert_eq!(cap.bounds().unwrap().max, DVec3::ONE);
    // `inverse` on the plane keeps the other side: y > 0.5.
    let s = scene(
        r#"
        [[objects]]
        type = "intersection"
        material = "red"
        [[objects.children]]
        type = "sphere"
        [[objects.children]]
        type = "plane"
        normal = [0, 1, 0]
        distance = 0.5
        inverse = true
        "#,
    );
    let down = surfaces(shape(&s), &Ray::new(DVec3::new(0.0, 5.0, 0.0), -DVec3::Y));
    assert_eq!(down.iter().map(|h| h.t).collect::<Vec<_>>(), [4.0, 4.5]);
    assert_eq!(
        down[1].normal,
        -DVec3::Y,
        "the cut faces down, out of the cap"
    );
}

#[test]
fn transform_and_material_are_handed_down_to_children_without_their_own() {
    let s = scene(
        r#"
        [[objects]]
        type = "difference"
        material = "red"
        transform = [{ scale = 2 }, { translate = [10, 0, 0] }]
        [[objects.children]]
        type = "sphere"
        [[objects.children]]
        type = "sphere"
        center = [0, 0, -1]
        radius = 0.5
        material = "glass"
        "#,
    );
    let d = shape(&s);
    // The ball (radius 2 at x = 10) less a bite at its front (z = −2).
    let hits = surfaces(d, &Ray::new(DVec3::new(10.0, 0.0, -10.0), DVec3::Z));
    let ts: Vec<f64> = hits.iter().map(|h| h.t).collect();
    assert_eq!(ts, [9.0, 12.0]);
    let (red, glass) = (1, 0); // materials in name order: glass, red
    assert_eq!(
        hits[0].material,
        Some(glass),
        "the bite's surface is the glass child's"
    );
    assert_eq!(hits[1].material, Some(red));
}

fn write_obj(dir: &std::path::Path, name: &str, vertices: &[DVec3], faces: &[[usize; 3]]) {
    let mut text = String::new();
    for v in vertices {
        text += &format!("v {} {} {}\n", v.x, v.y, v.z);
    }
    for f in faces {
        text += &format!("f {} {} {}\n", f[0] + 1, f[1] + 1, f[2] + 1);
    }
    std::fs::write(dir.join(name), text).unwrap();
}

/// An axis-aligned box as 12 outward-wound triangles.
fn box_obj(dir: &std::path::Path, name: &str, lo: DVec3, hi: DVec3) {
    let v: Vec<DVec3> = (0..8)
        .map(|i| {
            DVec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            )
        })
        .collect();
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let faces: Vec<[usize; 3]> = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    write_obj(dir, name, &v, &faces);
}

/// A UV sphere of radius 1 (`rings` × `segments`), outward-wound.
fn sphere_obj(dir: &std::path::Path, name: &str, rings: usize, segments: usize) {
    let mut v = vec![DVec3::Y, -DVec3::Y];
    for i in 1..rings {
        let theta = std::f64::consts::PI * i as f64 / rings as f64;
        for j in 0..segments {
            let phi = std::f64::consts::TAU * j as f64 / segments as f64;
            v.push(DVec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            ));
        }
    }
    let at = |i: usize, j: usize| 2 + (i - 1) * segments + j % segments;
    let mut f = Vec::new();
    for j in 0..segments {
        f.push([0, at(1, j + 1), at(1, j)]);
        f.push([1, at(rings - 1, j), at(rings - 1, j + 1)]);
        for i in 1..rings - 1 {
            f.push([at(i, j), at(i, j + 1), at(i + 1, j + 1)]);
            f.push([at(i, j), at(i + 1, j + 1), at(i + 1, j)]);
        }
    }
    write_obj(dir, name, &v, &f);
}

#[test]
fn csg_of_closed_meshes_matches_the_same_csg_of_their_analytic_twins() {
    let dir = tempfile::tempdir().unwrap();
    box_obj(dir.path(), "big.obj", DVec3::splat(-1.0), DVec3::splat(1.0));
    box_obj(
        dir.path(),
        "bite.obj",
        DVec3::new(0.0, 0.0, -1.5),
        DVec3::splat(1.5),
    );
    sphere_obj(dir.path(), "ball.obj", 96, 192);
    let make = |first: &str, second: &str| {
        scene_in(
            dir.path(),
            &format!(
                "[[objects]]\ntype = \"difference\"\nmaterial = \"red\"\n\
                 [[objects.children]]\n{first}\n[[objects.children]]\n{second}\n"
            ),
        )
        .unwrap_or_else(|e| panic!("{e}"))
    };
    let mesh = |f: &str| format!("type = \"mesh\"\nfile = \"{f}\"\nmaterial = \"red\"");
    let bite = "type = \"box\"\ncorner1 = [0, 0, -1.5]\ncorner2 = [1.5, 1.5, 1.5]";
    // A box less a corner: the meshes are exact, so the hits agree to
    // rounding on every ray.
    let (meshes, twins) = (
        make(&mesh("big.obj"), &mesh("bite.obj")),
        make(
            "type = \"box\"\ncorner1 = [-1, -1, -1]\ncorner2 = [1, 1, 1]",
            bite,
        ),
    );
    // A ball less the same corner: the mesh ball lies within a facet's
    // sagitta of the sphere.
    let (ball_mesh, ball) = (
        make(&mesh("ball.obj"), &mesh("bite.obj")),
        make("type = \"sphere\"", bite),
    );
    let mut rng = PixelRng::new(3, 1, 4);
    let (mut compared, mut on_the_cut) = (0, 0);
    for _ in 0..3000 {
        let dir = DVec3::new(
            rng.uniform() - 0.5,
            rng.uniform() - 0.5,
            rng.uniform() - 0.5,
        )
        .normalize();
        let target = DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 2.0 - 1.0;
        let ray = Ray::new(target - 5.0 * dir, dir);
        let (a, b) = (
            shape(&meshes).intersect(&ray, 0.0, 1e9),
            shape(&twins).intersect(&ray, 0.0, 1e9),
        );
        match (a, b) {
            (Some(a), Some(b)) => {
                assert!((a.t - b.t).abs() < 1e-9, "{ray:?}: {} vs {}", a.t, b.t);
                assert!((a.normal - b.normal).length() < 1e-9);
                assert_eq!(a.front_face, b.front_face);
            }
            (None, None) => {}
            (a, b) => panic!("{ray:?}: mesh {a:?}, box {b:?}"),
        }
        let (a, b) = (
            shape(&ball_mesh).intersect(&ray, 0.0, 1e9),
            shape(&ball).intersect(&ray, 0.0, 1e9),
        );
        // Away from the tessellation: rays that meet the sphere well
        // inside its outline (or the cut, which both have exactly).
        let Some(b) = b else { continue };
        let p = ray.at(b.t);
        let grazing = b.normal.dot(ray.direction).abs() < 0.2;
        // The rim where the cut meets the ball, and the cut's inner edge.
        let rim = (p.length() - 1.0).abs() < 0.03 && (p.x.abs() < 0.05 || p.y.abs() < 0.05);
        let near_edge = rim || (p.x.abs() < 0.02 && p.y.abs() < 0.02);
        if grazing || near_edge {
            continue;
        }
        let a = a.unwrap_or_else(|| panic!("{ray:?}: the mesh ball missed"));
        compared += 1;
        let on_cut = p.length() < 0.999;
        if on_cut {
            on_the_cut += 1;
            assert!((a.t - b.t).abs() < 1e-9, "on the cut: {} vs {}", a.t, b.t);
        } else {
            // A facet lies within (a² + b²)/8 ≈ 2.7e-4 of the sphere (its
            // angular sides a, b = π/96); along the ray that is / |n·d|.
            let bound = 3e-4 / b.normal.dot(ray.direction).abs();
            assert!((a.t - b.t).abs() < bound, "{} vs {}", a.t, b.t);
        }
        assert_eq!(a.front_face, b.front_face);
    }
    assert!(compared > 500 && on_the_cut > 50, "{compared} {on_the_cut}");
}

fn refused(objects: &str) -> String {
    match scene_in(std::path::Path::new("."), objects) {
        Ok(_) => panic!("accepted:\n{objects}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn parts_without_an_inside_and_misplaced_keys_are_refused_with_their_place() {
    let polygon = refused(
        "[[objects]]\ntype = \"difference\"\nmaterial = \"red\"\n\
         [[objects.children]]\ntype = \"sphere\"\n\
         [[objects.children]]\ntype = \"polygon\"\nvertices = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]\n",
    );
    assert!(
        polygon.contains("objects[0].children[1]") && polygon.contains("a polygon has no inside"),
        "{polygon}"
    );
    assert!(polygon.contains("test.toml:"), "{polygon}");
    let open = refused(
        "[[objects]]\ntype = \"merge\"\nmaterial = \"red\"\n\
         [[objects.children]]\ntype = \"cylinder\"\nbase = [0, 0, 0]\ncap = [0, 1, 0]\nopen = true\n",
    );
    assert!(open.contains("an open cylinder has no inside"), "{open}");
    let lone = refused("[[objects]]\ntype = \"sphere\"\nmaterial = \"red\"\ninverse = true\n");
    assert!(lone.contains("`inverse` applies to a part"), "{lone}");
    let empty = refused("[[objects]]\ntype = \"intersection\"\nmaterial = \"red\"\n");
    assert!(empty.contains("needs `children`"), "{empty}");
    let foreign = refused(
        "[[objects]]\ntype = \"sphere\"\nmaterial = \"red\"\n[[objects.children]]\ntype = \"sphere\"\n",
    );
    assert!(
        foreign.contains("`children` does not apply to a sphere"),
        "{foreign}"
    );
    let no_material =
        refused("[[objects]]\ntype = \"intersection\"\n[[objects.children]]\ntype = \"sphere\"\n");
    assert!(no_material.contains("needs `material`"), "{no_material}");
}

#[test]
fn an_open_mesh_in_csg_is_refused_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    write_obj(
        dir.path(),
        "sheet.obj",
        &[DVec3::ZERO, DVec3::X, DVec3::Y],
        &[[0, 1, 2]],
    );
    let e = scene_in(
        dir.path(),
        "[[objects]]\ntype = \"intersection\"\nmaterial = \"red\"\n\
         [[objects.children]]\ntype = \"sphere\"\n\
         [[objects.children]]\nname = \"sheet\"\ntype = \"mesh\"\nfile = \"sheet.obj\"\n",
    )
    .err()
    .unwrap()
    .to_string();
    assert!(
        e.contains("object `sheet`") && e.contains("not closed"),
        "{e}"
    );
}

#[test]
fn csg_nested_past_the_limit_is_an_error_not_a_stack_overflow() {
    let nest = |depth: usize| {
        let mut text = String::new();
        let mut header = "objects".to_string();
        for _ in 0..depth {
            text += &format!("[[{header}]]\ntype = \"intersection\"\nmaterial = \"red\"\n");
            header += ".children";
        }
        text + &format!("[[{header}]]\ntype = \"sphere\"\n")
    };
    // At the limit it builds, and a ray finds the sphere at the bottom.
    let s = scene(&nest(prism::limits::MAX_CSG_DEPTH));
    let h = shape(&s).intersect(&Ray::new(DVec3::new(0.0, 0.0, -5.0), DVec3::Z), 0.0, 1e9);
    assert_eq!(h.map(|h| h.t), Some(4.0));
    for depth in [prism::limits::MAX_CSG_DEPTH + 1, 500] {
        let e = refused(&nest(depth));
        assert!(e.contains("deep"), "{e}");
        assert!(
            e.lines().count() < 10,
            "one message, not one per level: {e}"
        );
    }
    // Inline tables nested deep stop at the TOML reader, with a message.
    let levels = 100_000;
    let inline = "{ type = \"merge\", material = \"red\", children = [".repeat(levels)
        + "{ type = \"sphere\" }"
        + &"] }".repeat(levels);
    let e = Scene::from_toml(&format!("objects = [{inline}]\n{HEAD}"), "deep.toml")
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("nested too deep"), "{}", &e[..e.len().min(300)]);
}

#[test]
fn a_merge_of_many_children_is_found_through_their_boxes() {
    // 40,000 small spheres in a merge: each ray tests the few it passes.
    let mut text = String::from("[[objects]]\ntype = \"merge\"\nmaterial = \"red\"\n");
    for i in 0..40_000 {
        let (x, y) = ((i % 200) as f64 * 0.1 - 10.0, (i / 200) as f64 * 0.1 - 10.0);
        text += &format!(
            "[[objects.children]]\ntype = \"sphere\"\ncenter = [{x}, {y}, 0]\nradius = 0.04\n"
        );
    }
    let s = scene(&text);
    let merged = shape(&s);
    let h = merged
        .intersect(&Ray::new(DVec3::new(0.0, 0.0, -5.0), DVec3::Z), 0.0, 1e9)
        .unwrap();
    assert!((h.t - 4.96).abs() < 1e-12);
    assert!(
        merged
            .intersect(&Ray::new(DVec3::new(0.05, 0.05, -5.0), DVec3::Z), 0.0, 1e9)
            .is_none()
    );
}

#[test]
fn refraction_follows_the_csg_boundary_whatever_paints_a_part() {
    // A glass block less a ball painted with a water material: the ball's
    // surface is the block's boundary, so the medium behind it is air (the
    // block's outside), not water. Down the axis: 1 → 1.5 → 1 → 1.5 → 1.
    let toml = r#"
        [render]
        width = 101
        height = 101
        spp = 1
        max_depth = 8
        min_weight = 0
        [camera]
        type = "orthographic"
        position = [0, 0, -10]
        look_at = [0, 0, 0]
        view_height = 4
        [materials.glass]
        color = [1, 1, 1]
        kt = 0.9
        ior = 1.5
        [materials.water]
        color = [0.5, 0.7, 1]
        kt = 0.9
        ior = 1.33
        [[objects]]
        type = "difference"
        material = "glass"
        [[objects.children]]
        type = "box"
        corner1 = [-1, -1, -1]
        corner2 = [1, 1, 1]
        [[objects.children]]
        type = "sphere"
        radius = 0.5
        material = "water"
    "#;
    let s = Scene::from_toml(toml, "test").unwrap();
    let e = prism::render::explain::explain(&s, &s.settings, 50, 50, 0).unwrap();
    let mut etas = Vec::new();
    let mut materials = Vec::new();
    let mut node = Some(&e.tree);
    while let Some(n) = node {
        if let Some(h) = &n.hit {
            etas.push((h.eta_incoming.unwrap(), h.eta_beyond.unwrap()));
            materials.push(h.material.clone());
        }
        node = n.refracted.as_deref();
    }
    assert_eq!(etas, [(1.0, 1.5), (1.5, 1.0), (1.0, 1.5), (1.5, 1.0)]);
    assert_eq!(materials, ["glass", "water", "water", "glass"]);
}

#[test]
fn a_csg_scene_renders_the_same_bits_on_any_thread_count() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/csg.toml");
    let text = std::fs::read_to_string(path).unwrap();
    let s = Scene::from_toml_in(&text, path, std::path::Path::new("scenes")).unwrap();
    let film = |threads: usize| {
        let settings = prism::RenderSettings {
            width: 96,
            height: 54,
            spp: 2,
            threads: Some(threads),
            ..s.settings
        };
        prism::render(&s, &settings, &()).unwrap().film
    };
    let one = film(1);
    assert!(one.pixels().iter().any(|p| p.x > 0.1), "it drew something");
    assert_eq!(one, film(3));
}

#[test]
fn a_ray_through_a_shared_edge_of_a_mesh_crosses_it_once() {
    // Tetrahedra with tilted faces; rays along +z through points of their
    // edge ab (x = 2y, exact in the projection), where two triangles each
    // report the crossing (their t equal to within rounding): counted once,
    // the ray goes in and out; counted twice, the parity would flip.
    let dir = tempfile::tempdir().unwrap();
    let mut rng = PixelRng::new(8, 8, 8);
    for m in 0..12 {
        let mut z = || (rng.uniform() * 4.0 - 2.0) as f32 as f64;
        let v = [
            DVec3::new(0.0, 0.0, z()),
            DVec3::new(2.0, 1.0, z()),
            DVec3::new(2.0, -1.0, z() - 3.0),
            DVec3::new(-0.5, 1.5, z() + 3.0),
        ];
        let centre = (v[0] + v[1] + v[2] + v[3]) / 4.0;
        let faces: Vec<[usize; 3]> = [[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]]
            .into_iter()
            .map(|[a, b, c]| {
                // Wound to face away from the centre.
                let n = (v[b] - v[a]).cross(v[c] - v[a]);
                if n.dot(v[a] - centre) > 0.0 {
                    [a, b, c]
                } else {
                    [a, c, b]
                }
            })
            .collect();
        let name = format!("tetra{m}.obj");
        write_obj(dir.path(), &name, &v, &faces);
        let s = scene_in(
            dir.path(),
            &format!(
                "[[objects]]\ntype = \"intersection\"\nmaterial = \"red\"\n\
                 [[objects.children]]\ntype = \"mesh\"\nfile = \"{name}\"\n\
                 [[objects.children]]\ntype = \"sphere\"\nradius = 100\n"
            ),
        )
        .unwrap_or_else(|e| panic!("{e}"));
        let tetra = shape(&s);
        for k in 1..200 {
            let y = k as f64 / 200.0;
            let ray = Ray::new(DVec3::new(2.0 * y, y, -10.0), DVec3::Z);
            let hits = surfaces(tetra, &ray);
            // In and out: one crossing at the edge, one through a far face.
            let zs: Vec<f64> = hits.iter().map(|h| ray.at(h.t).z).collect();
            assert_eq!(hits.len(), 2, "tetrahedron {m}, y = {y}: {zs:?}");
            let edge_z = v[0].z + (v[1].z - v[0].z) * y;
            assert!(
                zs.iter().any(|z| (z - edge_z).abs() < 1e-6),
                "tetrahedron {m}, y = {y}: edge at z = {edge_z}, hits at {zs:?}"
            );
        }
    }
}
