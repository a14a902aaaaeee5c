//! The exports Blender 3.4.1 wrote (tests/data/blender/, made by
//! scripts/test-blender.sh --update-data), loaded as scenes: the probes'
//! centre pixel against Cycles' values in tests/data/blender/README.md,
//! within 5 %. No Blender is needed.

use std::path::Path;

use prism::{RenderSettings, Scene, render};

/// The centre pixel of a 9 × 9, 1 spp render (its ray through the image
/// centre, straight down onto the plane) of tests/data/blender/NAME.
fn centre(name: &str) -> f64 {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/blender")
        .join(name);
    let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
    let settings = RenderSettings {
        width: 9,
        height: 9,
        spp: 1,
        threads: Some(1),
        ..scene.settings
    };
    let c = render(&scene, &settings, &()).unwrap().film.get(4, 4);
    // A grey plane under a white light: the three channels agree.
    assert!(
        (c.x - c.y).abs() < 1e-9 && (c.x - c.z).abs() < 1e-9,
        "{name}: {c:?}"
    );
    c.x
}

fn matches_cycles(name: &str, cycles: f64) {
    let got = centre(name);
    assert!(
        (got / cycles - 1.0).abs() < 0.05,
        "{name}: Prism {got} vs Cycles' {cycles}"
    );
}

#[test]
fn blenders_point_light_export_gives_what_cycles_gives() {
    matches_cycles("probe_point.glb", 0.1265);
}

#[test]
fn blenders_spot_light_export_gives_what_cycles_gives() {
    matches_cycles("probe_spot.glb", 0.1264);
}

#[test]
fn blenders_sun_export_gives_what_cycles_gives() {
    matches_cycles("probe_sun.glb", 0.2546);
}
