//! `prism explain`: the recorded ray tree is the render's own computation
//! (its radiance is the rendered pixel, bit for bit), its terms add up at
//! every node, and what it reports (hits, indices, total internal
//! reflection, stops) matches the scene.

use std::process::Command;

use glam::DVec3;
use prism::render::explain::{RayNode, explain};
use prism::{RenderSettings, Scene, render};

fn whitted() -> Scene {
    Scene::load(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenes/whitted.toml"
    )))
    .unwrap()
}

fn small(scene: &Scene, spp: u32) -> RenderSettings {
    RenderSettings {
        width: 64,
        height: 48,
        spp,
        threads: Some(2),
        ..scene.settings
    }
}

/// Relative agreement of the terms with the ray's colour.
fn adds_up(node: &RayNode) -> bool {
    let (sum, radiance) = (node.sum_of_terms(), DVec3::from_array(node.radiance));
    (sum - radiance).abs().max_element() <= 1e-9 * radiance.abs().max_element().max(1e-300)
}

#[test]
fn the_tree_is_the_rendered_pixel_and_its_terms_add_up() {
    let scene = whitted();
    for spp in [1, 4] {
        let settings = small(&scene, spp);
        let film = render(&scene, &settings, &()).unwrap().film;
        let mut nodes = 0;
        for y in (0..48).step_by(3) {
            for x in (0..64).step_by(3) {
                let e = explain(&scene, &settings, x, y, 0).unwrap();
                // The pixel over all samples, bit for bit.
                assert_eq!(
                    DVec3::from_array(e.pixel_radiance),
                    film.get(x, y),
                    "{x},{y}"
                );
                if spp == 1 {
                    assert_eq!(DVec3::from_array(e.radiance), film.get(x, y));
                }
                assert_eq!(e.radiance, e.tree.radiance);
                for n in e.tree.nodes() {
                    assert!(
                        adds_up(n),
                        "{x},{y}: {:?} vs {:?}",
                        n.sum_of_terms(),
                        n.radiance
                    );
                    nodes += 1;
                }
            }
        }
        assert!(nodes > 400, "{nodes} nodes");
    }
}

#[test]
fn hits_indices_and_stops_are_reported() {
    let scene = whitted();
    let settings = small(&scene, 1);
    let mut seen_glass = false;
    let mut seen_miss = false;
    for y in 0..48 {
        for x in 0..64 {
            let e = explain(&scene, &settings, x, y, 0).unwrap();
            for n in e.tree.nodes() {
                match &n.hit {
                    None => {
                        seen_miss = true;
                        assert_eq!(n.stopped, ["miss: the background"]);
                        assert_eq!(DVec3::from_array(n.radiance), scene.background);
                    }
                    Some(h) if h.object == "glass ball" => {
                        seen_glass = true;
                        assert_eq!(h.material, "glass");
                        // Air and glass on either side, by direction.
                        let (a, b) = (h.eta_incoming.unwrap(), h.eta_beyond.unwrap());
                        assert_eq!(if h.entering { (a, b) } else { (b, a) }, (1.0, 1.5));
                        // No total internal reflection in a sphere: a ray
                        // refracted in meets the far side at its entry angle.
                        assert!(!n.total_internal_reflection);
                    }
                    Some(_) => {}
                }
                // A child's weight is its parent's times kr or kt.
                for (child, k) in [(&n.reflected, n.kr), (&n.refracted, n.kt)] {
                    if let Some(c) = child {
                        let expected = DVec3::from_array(n.weight) * DVec3::from_array(k);
                        assert_eq!(DVec3::from_array(c.weight), expected);
                        assert_eq!(c.depth, n.depth + 1);
                    }
                }
            }
        }
    }
    assert!(
        seen_glass && seen_miss,
        "glass {seen_glass} miss {seen_miss}"
    );
    // Bad requests are refused with a reason.
    assert!(
        explain(&scene, &settings, 64, 0, 0)
            .unwrap_err()
            .contains("outside")
    );
    assert!(
        explain(&scene, &settings, 0, 0, 1)
            .unwrap_err()
            .contains("1 samples")
    );
}

#[test]
fn the_command_prints_the_same_tree_as_json() {
    let scene_path = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/whitted.toml");
    let out = Command::new(env!("CARGO_BIN_EXE_prism"))
        .args([
            "explain", scene_path, "--pixel", "20,30", "--json", "--width", "64", "--height", "48",
            "--spp", "1",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let scene = whitted();
    let e = explain(&scene, &small(&scene, 1), 20, 30, 0).unwrap();
    let radiance: Vec<f64> = json["radiance"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    // JSON prints the shortest decimal that round-trips; serde_json's
    // default parser reads it back to within an ulp or so.
    for (a, b) in radiance.iter().zip(e.radiance) {
        assert!((a - b).abs() <= 4.0 * f64::EPSILON * b.abs(), "{a} vs {b}");
    }
    assert_eq!(json["tree"]["kind"], "camera");
    // Text form: names the hit and the formula's terms.
    let out = Command::new(env!("CARGO_BIN_EXE_prism"))
        .args([
            "explain", scene_path, "--pixel", "20,30", "--width", "64", "--height", "48",
        ])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("camera ray") && text.contains("ka*Od*Ia"),
        "{text}"
    );
    let bad = Command::new(env!("CARGO_BIN_EXE_prism"))
        .args(["explain", scene_path, "--pixel", "9999,0"])
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(2));
}

/// Inside a glass ball of radius 10, 8 from its centre, looking along the
/// wall: rays meet it at sin i ≈ 0.8 > 1/1.5, beyond the critical angle,
/// so all of kr + kt is reflected; rays aimed at the centre refract out.
#[test]
fn total_internal_reflection_is_reported() {
    let scene = Scene::from_toml(
        r#"
[render]
width = 16
height = 16
spp = 1
max_depth = 3
[camera]
position = [8, 0, 0]
look_at = [8, 0, 1]
fov = 20
[materials.glass]
ka = 0
kd = 0
ks = 0
kr = 0.1
kt = 0.9
ior = 1.5
[lights.l]
type = "point"
position = [0, 0, 0]
[[objects]]
type = "sphere"
name = "ball"
material = "glass"
radius = 10
"#,
        "tir.toml",
    )
    .unwrap();
    let e = explain(&scene, &scene.settings, 8, 8, 0).unwrap();
    let n = &e.tree;
    let h = n.hit.as_ref().unwrap();
    assert!(!h.entering && h.eta_incoming == Some(1.5) && h.eta_beyond == Some(1.0));
    assert!(n.total_internal_reflection);
    assert_eq!((n.kr, n.kt), ([1.0; 3], [0.0; 3]));
    assert!(n.refracted.is_none() && n.reflected.is_some());
    assert!(adds_up(n));
}

/// The lecture's steps reach the command's JSON under the notes' names
/// (the values are checked against the render in tests/lecture.rs), and
/// its text names them too.
#[test]
fn the_command_lists_the_lectures_steps() {
    let run = |scene: &str, pixel: &str, json: bool| {
        let path = format!("{}/../scenes/{scene}", env!("CARGO_MANIFEST_DIR"));
        let mut args = vec!["explain", &path, "--pixel", pixel];
        if json {
            args.push("--json");
        }
        let out = Command::new(env!("CARGO_BIN_EXE_prism"))
            .args(&args)
            .output()
            .unwrap();
        assert!(out.status.success());
        String::from_utf8(out.stdout).unwrap()
    };
    // Inside the concave star: its polygon test, odd.
    let json: serde_json::Value = serde_json::from_str(&run("star.toml", "330,140", true)).unwrap();
    let test = &json["tree"]["intersection"];
    assert_eq!(test["object"], "standing star");
    assert_eq!(test["plane"]["verdict"], "front face");
    assert_eq!(test["polygon"]["principal_axis"], "z");
    assert_eq!(test["polygon"]["parity"], "odd");
    assert_eq!(test["polygon"]["edges"].as_array().unwrap().len(), 10);
    let crossings = test["polygon"]["crossings"].as_u64().unwrap();
    assert_eq!(crossings % 2, 1);
    let text = run("star.toml", "330,140", false);
    assert!(
        text.contains("principal axis z") && text.contains(&format!("crossings {crossings} (odd)")),
        "{text}"
    );
    // The glass ball: its quadratic, and at the bubble, TIR.
    let json: serde_json::Value =
        serde_json::from_str(&run("nested-glass.toml", "210,140", true)).unwrap();
    let ball = &json["tree"]["intersection"]["sphere"];
    assert!(ball["discriminant"].as_f64().unwrap() > 0.0);
    assert_eq!(ball["taken"], "t0");
    let bubble = &json["tree"]["refracted"];
    let snell = &bubble["refraction"];
    assert_eq!(bubble["hit"]["object"], "air bubble");
    assert_eq!(snell["total_internal_reflection"], true);
    assert!((snell["critical_angle"].as_f64().unwrap() - 41.81).abs() < 0.01);
    assert!((snell["theta_i"].as_f64().unwrap() - 59.5).abs() < 0.05);
    let text = run("nested-glass.toml", "210,140", false);
    assert!(
        text.contains("critical angle 41.8") && text.contains("total internal reflection"),
        "{text}"
    );
}
