//! The lecture worked on pixels (`render::explain`'s steps): what the
//! steps record is what the render decided, and the notes' own examples
//! come out as the notes say.

use std::path::Path;

use glam::DVec3;
use prism::render::explain::{Explanation, IntersectionSteps, RayNode, explain};
use prism::{RenderSettings, Scene};

fn scene(name: &str) -> Scene {
    Scene::load(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenes")
            .join(name),
    )
    .unwrap()
}

fn at(scene: &Scene, x: u32, y: u32) -> Explanation {
    explain(scene, &scene.settings, x, y, 0).unwrap()
}

/// Checks one test's steps against its own answer: a polygon is hit
/// exactly when its crossing count is odd and its plane is ahead, a sphere
/// at the root it says it took; returns whether it was a polygon's.
fn steps_agree(s: &IntersectionSteps) -> bool {
    if let Some(p) = &s.plane {
        assert_eq!(p.verdict == "parallel", p.t.is_none());
        if let Some(t) = p.t {
            assert_eq!(p.verdict == "back face", p.n_dot_d > 0.0, "{s:?}");
            if s.t.is_some() {
                assert_eq!(s.t, Some(t), "the hit is the plane's t");
            }
        }
    }
    if let Some(poly) = &s.polygon {
        assert_eq!(poly.inside, s.t.is_some(), "parity is the verdict: {s:?}");
        assert_eq!(poly.parity == "odd", poly.inside);
        let crossing = poly.edges.iter().filter(|e| e.crosses).count();
        assert_eq!(crossing, poly.crossings);
        for e in &poly.edges {
            let (z1, z2) = (e.from[1], e.to[1]);
            match e.case {
                "both z positive" => assert!(z1 > 0.0 && z2 > 0.0),
                "both z negative" => assert!(z1 <= 0.0 && z2 <= 0.0),
                "both x negative" => assert!(e.from[0] < 0.0 && e.to[0] < 0.0),
                "x_int" => {
                    let x = e.x_int.unwrap();
                    assert_eq!(e.crosses, x > 0.0);
                    // On the segment, between its ends' x.
                    let (lo, hi) = (e.from[0].min(e.to[0]), e.from[0].max(e.to[0]));
                    assert!(x >= lo - 1e-9 && x <= hi + 1e-9, "{e:?}");
                }
                other => panic!("unknown case {other}"),
            }
        }
        return true;
    }
    if let Some(tri) = &s.triangle {
        // The watertight test's verdict is the mesh's hit: the signs agree,
        // t is the hit's, the barycentrics are the edge functions over det.
        assert_ne!(tri.signs, "mixed");
        assert_eq!(tri.t, s.t, "{tri:?}");
        let [u, v, w] = tri.edge_functions;
        let det = tri.det.unwrap();
        assert_eq!(det, u + v + w);
        let b = tri.barycentric.unwrap();
        for (got, want) in b.iter().zip([u / det, v / det, w / det]) {
            assert!((got - want).abs() <= 1e-12, "{tri:?}");
        }
        assert!((b.iter().sum::<f64>() - 1.0).abs() < 1e-9);
    }
    if let Some(q) = &s.sphere {
        let d = q.b * q.b - 4.0 * q.a * q.c;
        assert!(
            (d - q.discriminant).abs() <= 1e-6 * (q.b * q.b).max(1.0),
            "{q:?}"
        );
        assert_eq!(q.roots.is_none(), q.discriminant < 0.0);
        match (q.roots, q.taken, s.t) {
            (Some([t0, _]), Some("t0"), Some(t)) => assert_eq!(t, t0),
            (Some([_, t1]), Some("t1"), Some(t)) => assert_eq!(t, t1),
            (_, None, None) => {}
            other => panic!("root taken and hit disagree: {other:?}"),
        }
    }
    false
}

/// Every node of every listed pixel: the hit's test says it hit at the
/// hit's distance, and every rejected object's test says it missed or hit
/// no nearer.
fn check_pixels(scene: &Scene, pixels: impl Iterator<Item = (u32, u32)>) -> (usize, usize) {
    let (mut polygons, mut rejected_polygons, mut triangles) = (0, 0, 0);
    for (x, y) in pixels {
        let e = at(scene, x, y);
        for n in e.tree.nodes() {
            match (&n.hit, &n.intersection) {
                (Some(h), Some(s)) => {
                    assert_eq!(s.primitive, h.primitive);
                    assert_eq!(s.t, Some(h.distance), "{x},{y}: recorded t is the hit's");
                    assert_eq!(s.verdict, "hit: the nearest");
                    assert_eq!(s.shape == "mesh", s.triangle.is_some());
                    triangles += usize::from(s.triangle.is_some());
                    polygons += usize::from(steps_agree(s));
                }
                (None, None) => assert_eq!(n.stopped, ["miss: the background"]),
                other => panic!("{x},{y}: hit and steps disagree: {other:?}"),
            }
            let total = scene.aggregate.primitives().len();
            assert_eq!(
                n.rejected.len() + n.rejected_left_out + usize::from(n.hit.is_some()),
                total
            );
            for r in &n.rejected {
                if let (Some(t), Some(h)) = (r.t, &n.hit) {
                    assert!(t >= h.distance, "{x},{y}: {r:?} nearer than the hit");
                }
                assert!(n.hit.is_some() || r.t.is_none());
                rejected_polygons += usize::from(steps_agree(r));
            }
        }
    }
    (polygons, rejected_polygons + triangles)
}

fn small(scene: &Scene) -> Scene {
    Scene {
        settings: RenderSettings {
            width: 64,
            height: 40,
            spp: 1,
            ..scene.settings
        },
        ..scene.clone()
    }
}

#[test]
fn recorded_steps_are_the_renders_decisions() {
    for name in [
        "star.toml",
        "nested-glass.toml",
        "whitted.toml",
        "models.toml",
    ] {
        let s = small(&scene(name));
        let grid = (0..40)
            .step_by(3)
            .flat_map(|y| (0..64).step_by(3).map(move |x| (x, y)));
        // Polygons hit; polygons rejected plus mesh triangles hit.
        let (polygons, others) = check_pixels(&s, grid);
        if name != "whitted.toml" {
            assert!(others > 10, "{name}: {others}");
        }
        if name == "star.toml" || name == "nested-glass.toml" {
            assert!(polygons > 10, "{name}: {polygons}");
        }
    }
}

/// The notes' question: n = [0.2, 0.96, 0.3], what is the principal axis,
/// what plane do we project onto? A square with that normal, hit head on.
#[test]
fn the_notes_principal_axis_example() {
    let n = DVec3::new(0.2, 0.96, 0.3).normalize();
    let a = n.cross(DVec3::X).normalize();
    let b = n.cross(a);
    let c = DVec3::new(0.0, 1.0, 0.0);
    let v: Vec<String> = [a + b, b - a, -a - b, a - b]
        .iter()
        .map(|p| {
            let p = c + *p;
            format!("[{}, {}, {}]", p.x, p.y, p.z)
        })
        .collect();
    let eye = c + 5.0 * n;
    let toml = format!(
        r#"
[render]
width = 9
height = 9
spp = 1
[camera]
position = [{}, {}, {}]
look_at = [0, 1, 0]
fov = 20
[materials.m]
kd = 1
[lights.l]
type = "point"
position = [0, 10, 0]
[[objects]]
type = "polygon"
name = "tilted"
material = "m"
vertices = [{}]
"#,
        eye.x,
        eye.y,
        eye.z,
        v.join(", ")
    );
    let scene = Scene::from_toml(&toml, "tilted.toml").unwrap();
    let e = at(&scene, 4, 4);
    let s = e.tree.intersection.as_ref().expect("the centre hits");
    let plane = s.plane.as_ref().unwrap();
    for (got, want) in plane.normal.iter().zip(n.to_array()) {
        assert!((got - want).abs() < 1e-9);
    }
    assert_eq!(plane.verdict, "front face");
    let poly = s.polygon.as_ref().unwrap();
    assert_eq!(poly.principal_axis, "y");
    assert_eq!(poly.projected_onto, "zx");
    assert_eq!((poly.x_axis, poly.z_axis), ("z", "x"));
    // A convex outline around the point: one crossing, odd, inside.
    assert_eq!((poly.crossings, poly.parity, poly.inside), (1, "odd", true));
    assert_eq!(poly.translated_polygon.len(), 4);
    // The scene docs/teaching.md starts with: the same question, clicked.
    let e = at(&scene_file("principal-axis.toml"), 320, 170);
    let s = e.tree.intersection.unwrap();
    assert_eq!(s.object, "tilted pentagon");
    let poly = s.polygon.unwrap();
    assert_eq!((poly.principal_axis, poly.projected_onto), ("y", "zx"));
    assert_eq!(poly.parity, "odd");
}

fn scene_file(name: &str) -> Scene {
    scene(name)
}

/// The concave star: a click inside a point of the star is an odd count;
/// a click in the notch between two points, inside the star's outline's
/// hull, is even, and the ray goes on to the floor.
#[test]
fn the_star_inside_and_outside() {
    let scene = scene("star.toml");
    let star = |n: &RayNode| {
        n.intersection
            .iter()
            .chain(&n.rejected)
            .find(|s| s.object == "standing star")
            .cloned()
    };
    let inside = at(&scene, INSIDE.0, INSIDE.1);
    let s = star(&inside.tree).unwrap();
    assert_eq!(s.verdict, "hit: the nearest");
    let p = s.polygon.unwrap();
    assert_eq!((p.principal_axis, p.parity, p.inside), ("z", "odd", true));
    assert_eq!(p.edges.len(), 10);

    let outside = at(&scene, NOTCH.0, NOTCH.1);
    assert_ne!(outside.tree.hit.as_ref().unwrap().object, "standing star");
    let s = star(&outside.tree).expect("the star is among the nearest rejected");
    let p = s.polygon.unwrap();
    assert_eq!((p.parity, p.inside), ("even", false));
    assert!(
        p.crossings >= 2,
        "a notch: the test ray leaves and re-enters"
    );
    assert!(s.verdict.starts_with("outside the polygon"));
}

/// The star's centre, world (0, 1.9, −1).
const INSIDE: (u32, u32) = (330, 140);
/// Between its two lower points, world (−0.3, 0.9, −1): the test ray
/// along +x crosses the right-hand point's two edges.
const NOTCH: (u32, u32) = (314, 192);

/// The glass ball of nested-glass.toml: a ray refracted into the glass
/// meets the air bubble at 59.5°, past the 41.8° critical angle of glass to
/// air, and is totally reflected.
#[test]
#[allow(clippy::disallowed_methods)] // Snell's law checked with the platform's sin
fn total_internal_reflection_at_the_bubble() {
    let scene = scene("nested-glass.toml");
    let e = at(&scene, GLASS.0, GLASS.1);
    assert_eq!(e.tree.hit.as_ref().unwrap().object, "glass ball");
    let tir = e
        .tree
        .nodes()
        .into_iter()
        .find(|n| {
            n.refraction
                .as_ref()
                .is_some_and(|r| r.total_internal_reflection)
        })
        .expect("a ray totally reflected");
    assert_eq!(tir.hit.as_ref().unwrap().object, "air bubble");
    assert!(tir.total_internal_reflection);
    let r = tir.refraction.as_ref().unwrap();
    assert_eq!((r.eta_i, r.eta_t), (1.5, 1.0));
    assert!((r.critical_angle.unwrap() - 41.81).abs() < 0.01, "{r:?}");
    assert!((r.theta_i - 59.5).abs() < 0.05, "{r:?}");
    assert!(r.radicand < 0.0 && r.t.is_none() && r.theta_t.is_none());
    // Everything went to the reflected ray: R = I − 2N(I·N), traced.
    let refl = tir.reflection.as_ref().unwrap();
    let traced = tir.reflected.as_ref().unwrap();
    for k in 0..3 {
        assert!((refl.r[k] - traced.direction[k]).abs() < 1e-12);
    }
    // The ray that got there was refracted into the glass by Snell's law:
    // sin θt = η sin θi, and its T is the refracted child's direction.
    let entry = &e.tree;
    let r = entry.refraction.as_ref().unwrap();
    assert!(!r.total_internal_reflection && r.critical_angle.is_none());
    let (si, st) = (
        r.theta_i.to_radians().sin(),
        r.theta_t.unwrap().to_radians().sin(),
    );
    assert!((st - r.eta * si).abs() < 1e-9);
    let t = DVec3::from_array(r.t.unwrap()).normalize();
    let child = DVec3::from_array(entry.refracted.as_ref().unwrap().direction);
    assert!((t - child).length() < 1e-12);
    // T = w + ηu, the notes' construction.
    let built = DVec3::from_array(r.w.unwrap()) + r.eta * DVec3::from_array(r.u);
    assert!((built - DVec3::from_array(r.t.unwrap())).length() < 1e-12);
}

/// Found by a scan of the picture for a ray of the glass ball meeting the
/// bubble at 59.5°.
const GLASS: (u32, u32) = (210, 140);

/// Shadow feelers name what blocked them: a blocked feeler has a blocker
/// short of the light, a clear one none (opaque shadows: visibility 0 or 1).
#[test]
fn feelers_name_their_blockers() {
    let (mut blocked, mut clear) = (0, 0);
    // models.toml: smooth meshes, whose feelers start off the facet.
    for name in ["star.toml", "models.toml"] {
        let scene = small(&scene(name));
        feelers_of(&scene, &mut blocked, &mut clear);
    }
    assert!(blocked > 10 && clear > 10, "{blocked} {clear}");
}

fn feelers_of(scene: &Scene, blocked: &mut usize, clear: &mut usize) {
    for y in (0..40).step_by(2) {
        for x in (0..64).step_by(2) {
            for n in at(scene, x, y).tree.nodes() {
                for l in &n.lights {
                    for f in &l.feeler_points {
                        let hidden = f.visibility == [0.0; 3];
                        assert_eq!(hidden, f.blocked_by.is_some(), "{x},{y}: {f:?}");
                        *blocked += usize::from(hidden);
                        *clear += usize::from(!hidden);
                    }
                }
            }
        }
    }
}
