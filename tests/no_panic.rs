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
