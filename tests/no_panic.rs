//! Whatever a user writes, loading a scene returns a scene or errors; it
//! never panics, and what loads renders. Random edits of a valid scene, checked with proptest.

use proptest::prelude::*;

const SCENE: &str = include_str!("../scenes/nested-glass.toml");

/// Tokens that tend to produce interesting mistakes.
const TOKENS: &[&str] = &[
    "nan",
    "inf",
    "-inf",
    "-1",
    "0",
    "1e308",
    "\"x\"",
    "[",
    "]",
    "{",
    "}",
    "=",
    ",",
    "\n",
    "[[objects]]",
    "[lights.z]",
    "type = \"sphere\"",
    "radius",
    "vertices = []",
    "transform = [{}]",
    "[1, 2]",
    "1.5",
    "true",
];

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, .. ProptestConfig::default() })]

    #[test]
    fn edited_scenes_never_panic(edits in prop::collection::vec((0usize..SCENE.len(), 0usize..TOKENS.len(), 0usize..20), 1..6)) {
        let mut text = SCENE.to_string();
        for (at, token, cut) in edits {
            let at = (at % (text.len() + 1)).min(text.len());
            let at = (0..=at).rev().find(|&i| text.is_char_boundary(i)).unwrap_or(0);
            let end = (at + cut).min(text.len());
            let end = (end..=text.len()).find(|&i| text.is_char_boundary(i)).unwrap_or(text.len());
            text.replace_range(at..end, TOKENS[token]);
        }
        match prism::Scene::from_toml(&text, "fuzz.toml") {
            Err(e) => {
                let message = e.to_string();
                prop_assert!(message.starts_with("fuzz.toml:"), "{}", message);
            }
            // What loads also renders.
            Ok(scene) => {
                let settings = prism::RenderSettings { width: 4, height: 3, spp: 1, threads: Some(1), ..scene.settings };
                prism::render(&scene, &settings, &()).unwrap();
            }
        }
    }
}

/// Random edits of the example model files: loading gives a model or an
/// error, never a panic.
fn mutate(bytes: &[u8], edits: &[(usize, u8, usize)]) -> Vec<u8> {
    let mut b = bytes.to_vec();
    for &(at, byte, cut) in edits {
        let at = at % (b.len() + 1);
        let end = (at + cut % 8).min(b.len());
        b.splice(at..end, [byte]);
    }
    b
}

fn load_mutated(name: &str, edits: &[(usize, u8, usize)]) {
    let dir = tempfile::tempdir().unwrap();
    let models = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/models");
    for f in ["pyramid.bin", "tile.png", "tile.mtl", "crystal.mtl"] {
        std::fs::copy(models.join(f), dir.path().join(f)).unwrap();
    }
    let original = std::fs::read(models.join(name)).unwrap();
    std::fs::write(dir.path().join(name), mutate(&original, edits)).unwrap();
    let mut resources =
        prism::scene::resources::Resources::new(dir.path(), &prism::scene::LoadOptions::default());
    let _ = prism::scene::models::load_model(&dir.path().join(name), &mut resources);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 150, .. ProptestConfig::default() })]

    #[test]
    fn edited_models_never_panic(
        edits in prop::collection::vec((0usize..40_000, any::<u8>(), 0usize..8), 1..8),
        which in 0usize..4,
    ) {
        let name = ["crystal.obj", "tile.obj", "icosphere.ply", "pyramids.gltf"][which];
        load_mutated(name, &edits);
    }
}
