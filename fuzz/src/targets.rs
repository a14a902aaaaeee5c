//! Fuzz targets: each takes arbitrary bytes as the contents of one kind of
//! user file and goes through the library's public API as `prism render`
//! would: load the scene (and the model or texture it names) and, if it
//! loads, render a few pixels, which must all be finite and non-negative.
//! A panic, an abort (out of memory under the fuzzer's limit) or a
//! non-finite pixel is a finding.
//!
//! Shared by the AFL harnesses (fuzz/src/bin, built by fuzz/run.sh) and by
//! tests/fuzz_corpus.rs, which replays the saved corpus in `cargo test`.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use prism::{RenderSettings, Scene, render};

/// Every target, by the name of its corpus folder (fuzz/corpus/NAME).
pub const TARGETS: &[&str] = &["scene", "obj", "ply", "gltf", "glb", "image"];

/// Image formats the `image` target writes, chosen by the input's first byte.
const IMAGE_FORMATS: &[&str] = &["png", "jpg", "exr", "hdr", "ppm"];

/// Separates an OBJ from its MTL in the `obj` target's input.
const MTL_SEPARATOR: &[u8] = b"\0MTL\0";

/// A scene around one model file: a camera and a light in case the model
/// brings none.
const MODEL_SCENE: &str = "[camera]\nposition = [0, 1, 5]\nlook_at = [0, 0, 0]\n\
    [lights.l]\ntype = \"point\"\nposition = [2, 4, 5]\n\
    [[objects]]\ntype = \"mesh\"\nfile = \"MODEL\"\n";

/// Runs `target` on `data`.
pub fn run(target: &str, data: &[u8]) {
    match target {
        "scene" => {
            if let Ok(text) = std::str::from_utf8(data) {
                load_and_render(text);
            }
        }
        "obj" => {
            let (obj, mtl) = match find(data, MTL_SEPARATOR) {
                Some(at) => (&data[..at], &data[at + MTL_SEPARATOR.len()..]),
                None => (data, &[][..]),
            };
            write("m.mtl", mtl);
            model("m.obj", obj);
        }
        "ply" => model("m.ply", data),
        "gltf" => model("m.gltf", data),
        "glb" => model("m.glb", data),
        "image" => {
            let Some((&first, image)) = data.split_first() else {
                return;
            };
            let name = format!("t.{}", IMAGE_FORMATS[first as usize % IMAGE_FORMATS.len()]);
            write(&name, image);
            load_and_render(&format!(
                "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n\
                 [materials.m]\ntexture = \"{name}\"\n\
                 [lights.l]\ntype = \"point\"\nposition = [2, 4, 5]\n\
                 [[objects]]\ntype = \"sphere\"\nmaterial = \"m\"\n"
            ));
        }
        other => panic!("unknown fuzz target `{other}`; known: {TARGETS:?}"),
    }
}

/// A folder of this process's own where the target's files are written
/// (the scene may read only below it).
fn folder() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| tempfile::tempdir().expect("a temporary folder"))
        .path()
}

fn write(name: &str, data: &[u8]) -> PathBuf {
    let path = folder().join(name);
    std::fs::write(&path, data).expect("the fuzz folder is writable");
    path
}

fn model(name: &str, data: &[u8]) {
    write(name, data);
    load_and_render(&MODEL_SCENE.replace("MODEL", name));
}

fn find(data: &[u8], needle: &[u8]) -> Option<usize> {
    data.windows(needle.len()).position(|w| w == needle)
}

/// Loads `text` as a scene in the fuzz folder; if it loads, renders 4×3
/// pixels at 1 sample and depth ≤ 4 (the file's own size could be 32768²)
/// and checks every pixel.
fn load_and_render(text: &str) {
    let Ok(scene) = Scene::from_toml_in(text, "fuzz.toml", folder()) else {
        return;
    };
    let settings = RenderSettings {
        width: 4,
        height: 3,
        spp: 1,
        max_depth: scene.settings.max_depth.min(4),
        threads: Some(1),
        ..scene.settings
    };
    let Ok(result) = render(&scene, &settings, &()) else {
        return;
    };
    for p in result.film.pixels() {
        assert!(
            p.is_finite() && p.min_element() >= 0.0,
            "a loaded scene rendered the pixel {p}"
        );
    }
}
