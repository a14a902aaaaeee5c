//! glTF node animations: translation, rotation and scale channels played at
//! Prism's frame F = glTF time F / fps, each interpolation against values
//! worked by hand; a node moving at constant speed under an open shutter
//! leaves the streak `tests/motion_blur.rs` measures for keyed transforms;
//! a still file keeps its bits; hostile samplers are refused with the JSON
//! path. The files are written here (GLB containers), so no Blender is
//! needed.

use std::path::Path;
use std::sync::Arc;

use glam::{DMat4, DVec3};
use prism::accel::Shape;
use prism::limits::MAX_ANIMATION_KEYS;
use prism::scene::LoadOptions;
use prism::scene::models::load_model;
use prism::scene::resources::Resources;
use prism::{RenderSettings, Scene, render};
use serde_json::{Value, json};

/// A binary buffer and the views and accessors over it.
#[derive(Default)]
struct Bin {
    bytes: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Bin {
    /// Appends `data` as one view and accessor of `kind` (SCALAR, VEC3,
    /// VEC4) and component type `component`; returns the accessor's index.
    fn add(&mut self, raw: &[u8], count: usize, kind: &str, component: u32) -> usize {
        while !self.bytes.len().is_multiple_of(4) {
            self.bytes.push(0);
        }
        self.views
            .push(json!({"buffer": 0, "byteOffset": self.bytes.len(), "byteLength": raw.len()}));
        self.bytes.extend_from_slice(raw);
        self.accessors.push(
            json!({"bufferView": self.views.len() - 1, "componentType": component,
                                   "count": count, "type": kind}),
        );
        self.accessors.len() - 1
    }

    fn floats(&mut self, data: &[f32], kind: &str) -> usize {
        let per = match kind {
            "SCALAR" => 1,
            "VEC3" => 3,
            _ => 4,
        };
        let raw: Vec<u8> = data.iter().flat_map(|x| x.to_le_bytes()).collect();
        self.add(&raw, data.len() / per, kind, 5126)
    }
}

/// A 1 × 1 square in z = 0 facing +z (white, rough, not metallic), placed
/// by node 0 ("Square"), with node 0's `animation` channels over `bin`
/// (the animation's JSON built by `animate(bin)`) and `extra` nodes after
/// it (roots too).
fn square_file(animate: impl FnOnce(&mut Bin) -> Option<Value>, extra: Vec<Value>) -> Vec<u8> {
    let mut bin = Bin::default();
    let positions = [
        -0.5f32, -0.5, 0.0, 0.5, -0.5, 0.0, 0.5, 0.5, 0.0, -0.5, 0.5, 0.0,
    ];
    let p = bin.floats(&positions, "VEC3");
    bin.accessors[p]["min"] = json!([-0.5, -0.5, 0.0]);
    bin.accessors[p]["max"] = json!([0.5, 0.5, 0.0]);
    let n = bin.floats(&[0.0, 0.0, 1.0].repeat(4), "VEC3");
    let indices: Vec<u8> = [0u16, 1, 2, 0, 2, 3]
        .iter()
        .flat_map(|i| i.to_le_bytes())
        .collect();
    let i = bin.add(&indices, 6, "SCALAR", 5123);
    let animation = animate(&mut bin);
    let mut nodes = vec![json!({"name": "Square", "mesh": 0})];
    nodes.extend(extra);
    let roots: Vec<usize> = (0..nodes.len()).collect();
    let mut root = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": roots}],
        "nodes": nodes,
        "meshes": [{"primitives": [{"attributes": {"POSITION": p, "NORMAL": n}, "indices": i, "material": 0}]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1],
                        "metallicFactor": 0, "roughnessFactor": 1}}],
        "cameras": [{"type": "orthographic",
                     "orthographic": {"xmag": 3, "ymag": 1, "znear": 0.1, "zfar": 100}}],
    });
    if let Some(a) = animation {
        // One animation, or the file's list of them.
        root["animations"] = if a.is_array() { a } else { json!([a]) };
    }
    root["buffers"] = json!([{"byteLength": bin.bytes.len()}]);
    root["bufferViews"] = json!(bin.views);
    root["accessors"] = json!(bin.accessors);
    glb(&serde_json::to_vec(&root).unwrap(), &bin.bytes)
}

/// A GLB container of `json` and `bin`, each chunk padded to 4 bytes.
fn glb(json: &[u8], bin: &[u8]) -> Vec<u8> {
    let pad = |data: &[u8], with: u8| {
        let mut v = data.to_vec();
        while !v.len().is_multiple_of(4) {
            v.push(with);
        }
        v
    };
    let (json, bin) = (pad(json, b' '), pad(bin, 0));
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((json.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(&json);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(&bin);
    out
}

/// One channel on node 0's `path`, keys at `times` with `values` of
/// `kind`, interpolated as `interpolation`.
fn channel(
    path: &'static str,
    interpolation: &'static str,
    times: Vec<f32>,
    values: Vec<f32>,
    kind: &'static str,
) -> impl FnOnce(&mut Bin) -> Option<Value> {
    move |bin| {
        let input = bin.floats(&times, "SCALAR");
        let output = bin.floats(&values, kind);
        Some(json!({
            "channels": [{"sampler": 0, "target": {"node": 0, "path": path}}],
            "samplers": [{"input": input, "output": output, "interpolation": interpolation}]
        }))
    }
}

/// The camera node: 10 above the square, looking down −z at it.
fn camera_node() -> Value {
    json!({"name": "Camera", "camera": 0, "translation": [0, 0, 10]})
}

fn write(dir: &Path, name: &str, bytes: &[u8]) {
    std::fs::write(dir.join(name), bytes).unwrap();
}

/// The square's placement at `seconds` of the file's animation.
fn placement(bytes: &[u8], seconds: f64) -> DMat4 {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "m.glb", bytes);
    let mut res = Resources::new(dir.path(), &LoadOptions::default());
    let model = load_model(&dir.path().join("m.glb"), &mut res).unwrap_or_else(|e| panic!("{e}"));
    let motion = model.motion.expect("the file is animated");
    motion.pose(seconds).unwrap().placements[0].1
}

fn close(a: DVec3, b: DVec3) -> bool {
    (a - b).abs().max_element() < 1e-6
}

#[test]
fn translation_plays_linear_and_step_and_holds_the_ends() {
    let linear = square_file(
        channel(
            "translation",
            "LINEAR",
            vec![1.0, 3.0],
            vec![0.0, 0.0, 0.0, 4.0, 2.0, -2.0],
            "VEC3",
        ),
        vec![],
    );
    let at = |t| placement(&linear, t).w_axis.truncate();
    assert_eq!(
        at(0.0),
        DVec3::ZERO,
        "before the first key, the first value"
    );
    assert!(close(at(1.5), DVec3::new(1.0, 0.5, -0.5)));
    assert!(close(at(2.0), DVec3::new(2.0, 1.0, -1.0)));
    assert_eq!(
        at(10.0),
        DVec3::new(4.0, 2.0, -2.0),
        "after the last, the last"
    );
    let step = square_file(
        channel(
            "translation",
            "STEP",
            vec![0.0, 1.0, 2.0],
            vec![1., 0., 0., 2., 0., 0., 3., 0., 0.],
            "VEC3",
        ),
        vec![],
    );
    for (t, x) in [(0.5, 1.0), (1.0, 2.0), (1.75, 2.0), (2.5, 3.0)] {
        assert_eq!(placement(&step, t).w_axis.x, x, "t = {t}");
    }
}

#[test]
fn rotation_slerps_and_normalized_short_keys_are_read() {
    let h = std::f32::consts::FRAC_1_SQRT_2;
    let file = square_file(
        channel(
            "rotation",
            "LINEAR",
            vec![0.0, 1.0],
            vec![0.0, 0.0, 0.0, 1.0, 0.0, h, 0.0, h],
            "VEC4",
        ),
        vec![],
    );
    // Half way from nothing to 90° about y: 45°, x̂ turned to (cos 45°, 0, −sin 45°).
    let x = placement(&file, 0.5).transform_vector3(DVec3::X);
    let c = std::f64::consts::FRAC_1_SQRT_2;
    assert!(close(x, DVec3::new(c, 0.0, -c)), "{x}");
    // A quarter of the way, where slerp and nlerp part: slerp turns 22.5°;
    // the normalised straight line between the keys only 21.6°, which
    // moves x̂ by 0.015.
    let x = placement(&file, 0.25).transform_vector3(DVec3::X);
    // cos and sin of 22.5°.
    let (ca, sa) = (0.923_879_532_511_286_7, 0.382_683_432_365_089_8);
    assert!(close(x, DVec3::new(ca, 0.0, -sa)), "{x}");
    let nlerp = glam::DQuat::from_xyzw(0.0, 0.25 * c, 0.0, 0.75 + 0.25 * c).normalize();
    assert!((nlerp * DVec3::X - x).length() > 0.01);
    // The same keys as normalized signed shorts (32767 = 1).
    let shorts: Vec<u8> = [0i16, 0, 0, 32767, 0, 23170, 0, 23170]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let file = square_file(
        |bin| {
            let input = bin.floats(&[0.0, 1.0], "SCALAR");
            let output = bin.add(&shorts, 2, "VEC4", 5122);
            bin.accessors[output]["normalized"] = json!(true);
            Some(json!({
                "channels": [{"sampler": 0, "target": {"node": 0, "path": "rotation"}}],
                "samplers": [{"input": input, "output": output}]
            }))
        },
        vec![],
    );
    let x = placement(&file, 1.0).transform_vector3(DVec3::X);
    assert!(close(x, DVec3::new(0.0, 0.0, -1.0)), "{x}");
}

#[test]
fn cubic_spline_scale_follows_the_hermite_curve() {
    // Scale 1 → 1 two seconds apart, out-tangent (1, 0, 0) at the first
    // key: at t = 1, sx = 1 + 2·(1/8 − 1/2 + 1/2)·1 = 1.25.
    let values = vec![
        0., 0., 0., 1., 1., 1., 1., 0., 0., // key 0: in, value, out
        0., 0., 0., 1., 1., 1., 0., 0., 0., // key 1
    ];
    let file = square_file(
        channel("scale", "CUBICSPLINE", vec![0.0, 2.0], values, "VEC3"),
        vec![],
    );
    let m = placement(&file, 1.0);
    assert!((m.x_axis.x - 1.25).abs() < 1e-9, "{}", m.x_axis.x);
    assert_eq!(m.y_axis.y, 1.0);
    assert_eq!(placement(&file, 2.0).x_axis.x, 1.0);
}

#[test]
fn children_follow_their_animated_parent() {
    // The square under a parent (node 1) moving 2 along y in a second; the
    // scene's roots are the parent and the camera.
    let bytes = square_file(
        |bin| {
            let input = bin.floats(&[0.0, 1.0], "SCALAR");
            let output = bin.floats(&[0.0, 0.0, 0.0, 0.0, 2.0, 0.0], "VEC3");
            Some(json!({
                "channels": [{"sampler": 0, "target": {"node": 1, "path": "translation"}}],
                "samplers": [{"input": input, "output": output}]
            }))
        },
        vec![json!({"name": "Parent", "children": [0]}), camera_node()],
    );
    let (json_chunk, bin_chunk) = chunks(&bytes);
    let mut root: Value = serde_json::from_slice(json_chunk).unwrap();
    root["scenes"] = json!([{"nodes": [1, 2]}]);
    let file = glb(&serde_json::to_vec(&root).unwrap(), bin_chunk);
    assert!(close(
        placement(&file, 0.25).w_axis.truncate(),
        DVec3::new(0.0, 0.5, 0.0)
    ));
}

/// The JSON and BIN chunks of a GLB written by [`glb`].
fn chunks(bytes: &[u8]) -> (&[u8], &[u8]) {
    let word = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
    let json_len = word(12);
    let json = &bytes[20..20 + json_len];
    let bin_at = 20 + json_len;
    (json, &bytes[bin_at + 8..bin_at + 8 + word(bin_at)])
}

/// A scene placing `file` (the square and its camera), white under ambient
/// light only: 20 pixels a unit, 120 × 40.
fn square_scene(dir: &Path, file: &[u8], extra: &str) -> Scene {
    write(dir, "square.glb", file);
    let text = format!(
        "[render]\nwidth = 120\nheight = 40\nspp = 64\nambient = [1, 1, 1]\n{extra}\n\
         [[objects]]\ntype = \"mesh\"\nfile = \"square.glb\"\n"
    );
    Scene::from_toml_in(&text, "test", dir).unwrap_or_else(|e| panic!("{e}"))
}

/// The square moving along x from −1.5 at 0 s to +1.5 at 0.5 s.
fn moving_square() -> Vec<u8> {
    square_file(
        channel(
            "translation",
            "LINEAR",
            vec![0.0, 0.5],
            vec![-1.5, 0.0, 0.0, 1.5, 0.0, 0.0],
            "VEC3",
        ),
        vec![camera_node()],
    )
}

#[test]
fn a_node_moving_at_constant_speed_leaves_the_analytic_streak() {
    let dir = tempfile::tempdir().unwrap();
    // At 4 frames a second the shutter's 2 frames are the key's half second.
    let s = square_scene(
        dir.path(),
        &moving_square(),
        "shutter = [0, 2]\nshutter_samples = 128\n[animation]\nframes = 3\nfps = 4",
    );
    assert_eq!(s.motion.len(), 128);
    // The file is read once: every instant places the same mesh.
    let mesh_of = |scene: &Scene| match &scene.aggregate.primitives()[0].shape {
        Shape::Mesh(m) => m.mesh.clone(),
        _ => panic!("not a mesh"),
    };
    assert!(
        s.motion
            .iter()
            .all(|i| Arc::ptr_eq(&mesh_of(i), &mesh_of(&s)))
    );
    let film = render(&s, &s.settings, &()).unwrap().film;
    // As in tests/motion_blur.rs: on a row through the square a point x is
    // covered for |[x − 0.5, x + 0.5] ∩ [−1.5, 1.5]| / 3 of the exposure.
    let row = 20;
    let mut worst: f64 = 0.0;
    for px in 0..120u32 {
        let x = (f64::from(px) + 0.5) / 20.0 - 3.0;
        let covered = ((x + 0.5).min(1.5) - (x - 0.5).max(-1.5)).max(0.0) / 3.0;
        let got = film.pixels()[(row * 120 + px) as usize].x;
        worst = worst.max((got - covered).abs());
    }
    let lit = (0..120u32)
        .filter(|&px| film.pixels()[(row * 120 + px) as usize].x > 0.0)
        .count();
    eprintln!("glTF streak: {lit} px lit (analytic 80), worst |measured − analytic| = {worst:.4}");
    assert!(worst < 0.035, "{worst}");
    assert!((79..=81).contains(&lit), "{lit}");
}

#[test]
fn the_frame_picks_the_time_and_a_glb_alone_plays_at_24_fps() {
    let dir = tempfile::tempdir().unwrap();
    let file = moving_square();
    // Frame 1 at 4 fps is 0.25 s: half way, x = 0.
    let s = square_scene(dir.path(), &file, "[animation]\nframes = 3\nfps = 4");
    assert!(s.animated && s.motion.is_empty());
    let centre = |s: &Scene| {
        let settings = RenderSettings {
            spp: 1,
            ..s.settings
        };
        let film = render(s, &settings, &()).unwrap().film;
        // The square against the background (it is black in the .glb alone:
        // no light, no ambient).
        let lit: Vec<u32> = (0..120u32)
            .filter(|&px| (film.get(px, 20).x - s.background.x).abs() > 0.02)
            .collect();
        (f64::from(lit[0] + lit[lit.len() - 1]) / 2.0 + 0.5) / 20.0 - 3.0
    };
    assert!((centre(&s) + 1.5).abs() < 0.05, "frame 0: {}", centre(&s));
    let options = LoadOptions {
        frame: 1,
        ..LoadOptions::default()
    };
    let text = "[render]\nwidth = 120\nheight = 40\nambient = [1, 1, 1]\n[animation]\nframes = 3\nfps = 4\n\
                [[objects]]\ntype = \"mesh\"\nfile = \"square.glb\"\n";
    write(dir.path(), "scene.toml", text.as_bytes());
    let s = Scene::load_with(&dir.path().join("scene.toml"), &options).unwrap();
    assert!(centre(&s).abs() < 0.05, "frame 1 at 4 fps: {}", centre(&s));
    // The .glb alone: 24 frames a second, frame 6 = 0.25 s.
    let options = LoadOptions {
        frame: 6,
        ..LoadOptions::default()
    };
    let s = Scene::load_with(&dir.path().join("square.glb"), &options).unwrap();
    let s = Scene {
        settings: RenderSettings {
            width: 120,
            height: 40,
            ..s.settings
        },
        ..s
    };
    assert!(s.animated);
    assert!(
        centre(&s).abs() < 0.05,
        "the glb alone at frame 6: {}",
        centre(&s)
    );
}

#[test]
fn a_still_file_keeps_its_bits_with_the_shutter_open() {
    let dir = tempfile::tempdir().unwrap();
    let still = square_file(|_| None, vec![camera_node()]);
    let closed = square_scene(dir.path(), &still, "");
    let open = square_scene(dir.path(), &still, "shutter = [0, 1]");
    assert!(!open.animated && open.motion.is_empty());
    let a = render(&closed, &closed.settings, &()).unwrap().film;
    let b = render(&open, &open.settings, &()).unwrap().film;
    assert!(
        a.pixels()
            .iter()
            .zip(b.pixels())
            .all(|(x, y)| x.to_array().map(f64::to_bits) == y.to_array().map(f64::to_bits))
    );
    assert!(a.pixels().iter().any(|p| p.x > 0.5));
}

/// The error loading a scene that places `file`.
fn refusal(file: &[u8]) -> String {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "bad.glb", file);
    let text = "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n[[objects]]\ntype = \"mesh\"\nfile = \"bad.glb\"\n";
    Scene::from_toml_in(text, "scene.toml", dir.path())
        .map(|_| ())
        .unwrap_err()
        .to_string()
}

#[test]
fn hostile_samplers_are_refused_with_the_file_and_json_path() {
    let e = refusal(&square_file(
        channel(
            "translation",
            "LINEAR",
            vec![0.0, 1.0, 2.0],
            vec![0.0; 6],
            "VEC3",
        ),
        vec![],
    ));
    assert!(
        e.contains("bad.glb: animations[0].samplers[0].output: 2 values for 3 keys"),
        "{e}"
    );
    let e = refusal(&square_file(
        channel(
            "translation",
            "CUBICSPLINE",
            vec![0.0, 1.0],
            vec![0.0; 6],
            "VEC3",
        ),
        vec![],
    ));
    assert!(
        e.contains("animations[0].samplers[0].output: 2 values for 2 keys"),
        "{e}"
    );
    let e = refusal(&square_file(
        channel(
            "translation",
            "LINEAR",
            vec![0.0, 2.0, 1.0],
            vec![0.0; 9],
            "VEC3",
        ),
        vec![],
    ));
    assert!(
        e.contains("animations[0].samplers[0].input: times must increase"),
        "{e}"
    );
    let e = refusal(&square_file(
        channel(
            "translation",
            "LINEAR",
            vec![0.0, f32::NAN],
            vec![0.0; 6],
            "VEC3",
        ),
        vec![],
    ));
    assert!(
        e.contains("animations[0].samplers[0].input: time 1 is not finite"),
        "{e}"
    );
    let e = refusal(&square_file(
        channel(
            "scale",
            "LINEAR",
            vec![0.0, 1.0],
            vec![1.0, 1.0, 1.0, f32::INFINITY, 1.0, 1.0],
            "VEC3",
        ),
        vec![],
    ));
    assert!(
        e.contains("animations[0].samplers[0].output: value 1 is not finite"),
        "{e}"
    );
    // A rotation written as VEC3, a channel on a node that does not exist,
    // a scale that reaches zero during the animation.
    let e = refusal(&square_file(
        channel("rotation", "LINEAR", vec![0.0, 1.0], vec![0.0; 6], "VEC3"),
        vec![],
    ));
    assert!(
        e.contains(
            "animations[0].samplers[0].output (accessors[4]): element type is VEC3; expected VEC4"
        ),
        "{e}"
    );
    let e = refusal(&square_file(
        |bin| {
            let input = bin.floats(&[0.0], "SCALAR");
            let output = bin.floats(&[1.0, 0.0, 0.0], "VEC3");
            Some(json!({
                "channels": [{"sampler": 0, "target": {"node": 7, "path": "translation"}}],
                "samplers": [{"input": input, "output": output}]
            }))
        },
        vec![],
    ));
    assert!(
        e.contains("animations[0].channels[0].target.node: node 7 does not exist"),
        "{e}"
    );
}

#[test]
fn weights_channels_and_skins_are_named_as_ignored() {
    let dir = tempfile::tempdir().unwrap();
    let file = square_file(
        channel("weights", "LINEAR", vec![0.0, 1.0], vec![0.0; 8], "VEC4"),
        vec![camera_node()],
    );
    let s = square_scene(dir.path(), &file, "");
    assert!(!s.animated);
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("morph target weight animations (animations[0].channels[0])")),
        "{:?}",
        s.warnings
    );
}

/// `bytes` (a GLB written by [`glb`]) with its JSON changed by `edit`.
fn edited(bytes: &[u8], edit: impl FnOnce(&mut Value)) -> Vec<u8> {
    let (json_chunk, bin_chunk) = chunks(bytes);
    let mut root: Value = serde_json::from_slice(json_chunk).unwrap();
    edit(&mut root);
    glb(&serde_json::to_vec(&root).unwrap(), bin_chunk)
}

/// [`square_scene`] built for `frame`.
fn square_scene_at(dir: &Path, file: &[u8], extra: &str, frame: u32) -> Scene {
    write(dir, "square.glb", file);
    let text = format!(
        "[render]\nwidth = 120\nheight = 40\nspp = 64\nambient = [1, 1, 1]\n{extra}\n\
         [[objects]]\ntype = \"mesh\"\nfile = \"square.glb\"\n"
    );
    write(dir, "scene.toml", text.as_bytes());
    let options = LoadOptions {
        frame,
        ..LoadOptions::default()
    };
    Scene::load_with(&dir.join("scene.toml"), &options).unwrap_or_else(|e| panic!("{e}"))
}

/// The warnings of a scene placing `file` (the square and its camera).
fn warnings(file: &[u8]) -> Vec<String> {
    let dir = tempfile::tempdir().unwrap();
    square_scene_at(dir.path(), file, "", 0).warnings
}

/// A scene placing `file`, which must load.
fn accepted(file: &[u8], extra: &str) -> Scene {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "ok.glb", file);
    let text = format!(
        "[render]\nwidth = 8\nheight = 8\n{extra}\n[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n\
         [[objects]]\ntype = \"mesh\"\nfile = \"ok.glb\"\n"
    );
    Scene::from_toml_in(&text, "scene.toml", dir.path()).unwrap_or_else(|e| panic!("{e}"))
}

/// The square growing from nothing: scale 0 until 1 s, then linearly to
/// its full size at 2 s.
fn growing_square() -> Vec<u8> {
    square_file(
        channel(
            "scale",
            "LINEAR",
            vec![1.0, 2.0],
            vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
            "VEC3",
        ),
        vec![camera_node()],
    )
}

#[test]
fn a_node_growing_from_nothing_is_hidden_while_it_has_no_size() {
    let dir = tempfile::tempdir().unwrap();
    let file = growing_square();
    // At 1 fps frame F is F seconds.
    let timing = "[animation]\nframes = 3\nfps = 1";
    let film = |s: &Scene| render(s, &s.settings, &()).unwrap().film;
    // Frames 0 and 1: scale 0, nothing there (the file's pose at 0 s used
    // to refuse the file at every frame).
    for frame in [0, 1] {
        let s = square_scene_at(dir.path(), &file, timing, frame);
        assert!(s.animated);
        assert_eq!(s.aggregate.primitives().len(), 0, "frame {frame}");
        assert!(
            film(&s).pixels().iter().all(|p| p.x == 0.0),
            "frame {frame}"
        );
    }
    // Frame 2: the whole square, 20 × 20 px.
    let s = square_scene_at(dir.path(), &file, timing, 2);
    let f = film(&s);
    let lit = f.pixels().iter().filter(|p| p.x > 0.5).count();
    assert!((390..=410).contains(&lit), "frame 2: {lit} px lit");
    // Shutter open for frames 0 to 2: hidden for the first half of the
    // exposure, growing through the second. A point (x, y) is covered
    // once the scale passes 2·max(|x|, |y|): for (1 − 2·max(|x|, |y|)) / 2
    // of the exposure; over the square that is a sixth of its area.
    let s = square_scene_at(
        dir.path(),
        &file,
        "shutter = [0, 2]\nshutter_samples = 64\n[animation]\nframes = 3\nfps = 1",
        0,
    );
    assert_eq!(s.motion.len(), 64);
    let hidden = s
        .motion
        .iter()
        .filter(|i| i.aggregate.primitives().is_empty())
        .count();
    assert_eq!(hidden, 32, "the instants before 1 s");
    let f = film(&s);
    let total: f64 = f.pixels().iter().map(|p| p.x).sum();
    assert!((total / (400.0 / 6.0) - 1.0).abs() < 0.05, "{total}");
    let row = 20;
    let y = 1.0 - (f64::from(row) + 0.5) / 20.0;
    let mut worst: f64 = 0.0;
    for px in 0..120u32 {
        let x = (f64::from(px) + 0.5) / 20.0 - 3.0;
        let covered = ((1.0 - 2.0 * x.abs().max(y.abs())) / 2.0).max(0.0);
        worst = worst.max((f.get(px, row).x - covered).abs());
    }
    eprintln!(
        "growing square under the shutter: sum {total:.2} (analytic 66.67), worst |measured − analytic| on row {row} = {worst:.4}"
    );
    assert!(worst < 0.05, "worst |measured − analytic| = {worst}");
    assert!(f.get(60, row).x > 0.4 && f.get(60, row).x < 0.55);
}

#[test]
fn a_still_zero_scale_stays_an_error() {
    let still = edited(&square_file(|_| None, vec![]), |root| {
        root["nodes"][0]["scale"] = json!([0, 0, 0]);
    });
    let e = refusal(&still);
    assert!(
        e.contains("bad.glb: nodes[0]: its world transform is singular (a zero scale)"),
        "{e}"
    );
}

#[test]
fn valid_channels_prism_cannot_read_are_named_not_refused() {
    let file = square_file(
        |bin| {
            let input = bin.floats(&[0.0, 1.0], "SCALAR");
            let output = bin.floats(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0], "VEC3");
            // All zeros: no bufferView.
            bin.accessors
                .push(json!({"componentType": 5126, "count": 2, "type": "VEC3"}));
            let zeros = bin.accessors.len() - 1;
            // Key 1 replaced through a sparse accessor.
            bin.add(&1u32.to_le_bytes(), 1, "SCALAR", 5125);
            let indices = bin.views.len() - 1;
            bin.floats(&[2.0, 2.0, 2.0], "VEC3");
            let values = bin.views.len() - 1;
            let mut sparse = bin.accessors[output].clone();
            sparse["sparse"] = json!({"count": 1,
                "indices": {"bufferView": indices, "componentType": 5125},
                "values": {"bufferView": values}});
            bin.accessors.push(sparse);
            let sparse = bin.accessors.len() - 1;
            Some(json!({
                "channels": [{"sampler": 0, "target": {"node": 0, "path": "translation"}},
                             {"sampler": 1, "target": {"node": 0, "path": "scale"}}],
                "samplers": [{"input": input, "output": zeros}, {"input": input, "output": sparse}]
            }))
        },
        vec![camera_node()],
    );
    let dir = tempfile::tempdir().unwrap();
    let s = square_scene_at(dir.path(), &file, "shutter = [0, 1]", 0);
    assert!(!s.animated && s.motion.is_empty());
    assert!(
        s.warnings.iter().any(|w| w.contains(
            "animation channels whose keys are in a sparse accessor or one without a bufferView \
             (animations[0].channels[0], animations[0].channels[1])"
        )),
        "{:?}",
        s.warnings
    );
}

/// A file whose first animation has `channels` translation channels on
/// nodes 1 to `channels` (no mesh), each with its own sampler over the same
/// 100,000 keys: through the same two accessors, or (`alias`) through
/// accessors of their own over the same bytes. The nodes are in the scene
/// unless `outside`.
fn aliasing_file(channels: usize, alias: bool, outside: bool) -> Vec<u8> {
    const KEYS: usize = 100_000;
    let times: Vec<f32> = (0..KEYS).map(|k| k as f32 / 1000.0).collect();
    let values: Vec<f32> = (0..KEYS)
        .flat_map(|k| [k as f32 / KEYS as f32, 0.0, 0.0])
        .collect();
    let file = square_file(
        |bin| {
            let input = bin.floats(&times, "SCALAR");
            let output = bin.floats(&values, "VEC3");
            let (mut samplers, mut list) = (Vec::new(), Vec::new());
            for c in 0..channels {
                let (i, o) = if alias && c > 0 {
                    let (a, b) = (bin.accessors[input].clone(), bin.accessors[output].clone());
                    bin.accessors.push(a);
                    bin.accessors.push(b);
                    (bin.accessors.len() - 2, bin.accessors.len() - 1)
                } else {
                    (input, output)
                };
                samplers.push(json!({"input": i, "output": o}));
                list.push(json!({"sampler": c, "target": {"node": c + 1, "path": "translation"}}));
            }
            Some(json!({"channels": list, "samplers": samplers}))
        },
        (0..channels).map(|_| json!({})).collect(),
    );
    if outside {
        edited(&file, |root| root["scenes"] = json!([{"nodes": [0]}]))
    } else {
        file
    }
}

#[test]
fn channels_sharing_a_sampler_read_it_once_and_keys_are_bounded() {
    // 60 channels over one sampler's 200,000 key times and values: 12
    // million read one by one, past the limit; 200,000 read once.
    let per = 200_000u64;
    assert!(60 * per > MAX_ANIMATION_KEYS);
    let s = accepted(&aliasing_file(60, false, false), "");
    assert!(s.animated);
    // The same bytes through accessors of their own count each time.
    let e = refusal(&aliasing_file(60, true, false));
    let k = MAX_ANIMATION_KEYS / per;
    assert!(
        e.contains(&format!(
            "bad.glb: animations[0].samplers[{k}]: its 100000 key times and 100000 values bring \
             the animation's keys to {}, more than the limit of {MAX_ANIMATION_KEYS}",
            (k + 1) * per
        )),
        "{e}"
    );
    // On nodes outside the scene they are not read at all.
    let s = accepted(&aliasing_file(60, true, true), "shutter = [0, 1]");
    assert!(!s.animated && s.motion.is_empty());
}

#[test]
fn channels_on_nodes_outside_the_scene_key_nothing() {
    // Node 1 moves, but the scene's roots are the square and the camera.
    let file = edited(
        &square_file(
            |bin| {
                let input = bin.floats(&[0.0, 1.0], "SCALAR");
                let output = bin.floats(&[0.0, 0.0, 0.0, 5.0, 0.0, 0.0], "VEC3");
                Some(json!({
                    "channels": [{"sampler": 0, "target": {"node": 1, "path": "translation"}}],
                    "samplers": [{"input": input, "output": output}]
                }))
            },
            vec![json!({"name": "Elsewhere"}), camera_node()],
        ),
        |root| root["scenes"] = json!([{"nodes": [0, 2]}]),
    );
    let dir = tempfile::tempdir().unwrap();
    let s = square_scene_at(
        dir.path(),
        &file,
        "shutter = [0, 1]\nshutter_samples = 256",
        0,
    );
    assert!(!s.animated, "nothing the scene reaches moves");
    assert!(s.motion.is_empty(), "{} instants built", s.motion.len());
}

#[test]
fn only_the_first_animation_plays() {
    let h = std::f32::consts::FRAC_1_SQRT_2;
    let file = square_file(
        |bin| {
            let input = bin.floats(&[0.0, 1.0], "SCALAR");
            let moves = bin.floats(&[0.0, 0.0, 0.0, 2.0, 0.0, 0.0], "VEC3");
            let turns = bin.floats(&[0.0, 0.0, 0.0, 1.0, 0.0, h, 0.0, h], "VEC4");
            Some(json!([
                {"channels": [{"sampler": 0, "target": {"node": 0, "path": "translation"}}],
                 "samplers": [{"input": input, "output": moves}]},
                {"channels": [{"sampler": 0, "target": {"node": 0, "path": "rotation"}}],
                 "samplers": [{"input": input, "output": turns}]}
            ]))
        },
        vec![camera_node()],
    );
    let m = placement(&file, 1.0);
    assert_eq!(m.w_axis.truncate(), DVec3::new(2.0, 0.0, 0.0));
    assert_eq!(
        m.transform_vector3(DVec3::X),
        DVec3::X,
        "animations[1] turned it"
    );
    assert!(
        warnings(&file).iter().any(|w| w.contains(
            "animations after the first (Prism plays animations[0], the clip a viewer shows) \
             (animations[1])"
        )),
        "{:?}",
        warnings(&file)
    );
}

#[test]
fn a_cubic_rotation_through_zero_holds_the_nearer_key() {
    // Keys q and −q (half a turn about y, written twice) with zero
    // tangents: the spline passes through the zero quaternion at 0.5 s.
    let values = vec![
        0., 0., 0., 0., 0., 1., 0., 0., 0., 0., 0., 0., // key 0: in, value, out
        0., 0., 0., 0., 0., -1., 0., 0., 0., 0., 0., 0., // key 1
    ];
    let file = square_file(
        channel("rotation", "CUBICSPLINE", vec![0.0, 1.0], values, "VEC4"),
        vec![camera_node()],
    );
    for t in [0.25, 0.5, 0.75] {
        let x = placement(&file, t).transform_vector3(DVec3::X);
        assert!(close(x, -DVec3::X), "t = {t}: {x}");
    }
    let dir = tempfile::tempdir().unwrap();
    let s = square_scene_at(dir.path(), &file, "[animation]\nframes = 3\nfps = 2", 1);
    assert_eq!(s.aggregate.primitives().len(), 1);
}

#[test]
fn a_channel_on_a_matrix_node_is_refused_in_one_sentence() {
    let file = square_file(
        |bin| {
            let input = bin.floats(&[0.0], "SCALAR");
            let output = bin.floats(&[1.0, 0.0, 0.0], "VEC3");
            Some(json!({
                "channels": [{"sampler": 0, "target": {"node": 1, "path": "translation"}}],
                "samplers": [{"input": input, "output": output}]
            }))
        },
        vec![json!({"matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]})],
    );
    let e = refusal(&file);
    assert!(
        e.contains(
            "bad.glb: animations[0].channels[0].target.node: nodes[1] has a `matrix`, which \
             animations cannot drive (the glTF specification animates translation, rotation and \
             scale only)"
        ),
        "{e}"
    );
    assert!(!e.contains("  "), "{e}");
}

#[test]
fn a_second_channel_on_a_property_is_named_and_the_first_plays() {
    let file = square_file(
        |bin| {
            let input = bin.floats(&[0.0, 1.0], "SCALAR");
            let first = bin.floats(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0], "VEC3");
            let second = bin.floats(&[0.0, 0.0, 0.0, 0.0, 9.0, 0.0], "VEC3");
            Some(json!({
                "channels": [{"sampler": 0, "target": {"node": 0, "path": "translation"}},
                             {"sampler": 1, "target": {"node": 0, "path": "translation"}}],
                "samplers": [{"input": input, "output": first}, {"input": input, "output": second}]
            }))
        },
        vec![camera_node()],
    );
    assert_eq!(placement(&file, 1.0).w_axis.truncate(), DVec3::X);
    assert!(
        warnings(&file).iter().any(|w| w.contains(
            "animation channels on a property another channel already drives \
             (animations[0].channels[1])"
        )),
        "{:?}",
        warnings(&file)
    );
}

#[test]
fn byte_and_unsigned_rotation_keys_are_read_normalized() {
    // Identity to 90° about y as BYTE (127 = 1), UNSIGNED_BYTE (255 = 1)
    // and UNSIGNED_SHORT (65535 = 1) keys: both components of the turn
    // equal, so normalising gives the turn exactly.
    let bytes = |v: &[i64], size: usize| -> Vec<u8> {
        v.iter()
            .flat_map(|&x| x.to_le_bytes()[..size].to_vec())
            .collect()
    };
    for (raw, component) in [
        (bytes(&[0, 0, 0, 127, 0, 90, 0, 90], 1), 5120),
        (bytes(&[0, 0, 0, 255, 0, 180, 0, 180], 1), 5121),
        (bytes(&[0, 0, 0, 65535, 0, 46341, 0, 46341], 2), 5123),
    ] {
        let file = square_file(
            |bin| {
                let input = bin.floats(&[0.0, 1.0], "SCALAR");
                let output = bin.add(&raw, 2, "VEC4", component);
                bin.accessors[output]["normalized"] = json!(true);
                Some(json!({
                    "channels": [{"sampler": 0, "target": {"node": 0, "path": "rotation"}}],
                    "samplers": [{"input": input, "output": output}]
                }))
            },
            vec![],
        );
        assert_eq!(
            placement(&file, 0.0).transform_vector3(DVec3::X),
            DVec3::X,
            "{component}"
        );
        let x = placement(&file, 1.0).transform_vector3(DVec3::X);
        assert!(close(x, DVec3::new(0.0, 0.0, -1.0)), "{component}: {x}");
    }
}

#[test]
fn a_skin_is_named_as_ignored() {
    let file = edited(&square_file(|_| None, vec![camera_node()]), |root| {
        root["skins"] = json!([{"joints": [0]}]);
    });
    assert!(
        warnings(&file)
            .iter()
            .any(|w| w.contains("Prism ignores what it cannot render of this file: skins")),
        "{:?}",
        warnings(&file)
    );
}

/// FNV-1a over the bits of every pixel of `s` rendered with `settings`.
fn film_hash(s: &Scene, settings: &RenderSettings) -> u64 {
    let film = render(s, settings, &()).unwrap().film;
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for p in film.pixels() {
        for v in p.to_array() {
            for b in v.to_bits().to_le_bytes() {
                h ^= u64::from(b);
                h = h.wrapping_mul(0x0100_0000_01b3);
            }
        }
    }
    h
}

#[test]
fn still_files_render_the_bits_they_rendered_before_animations_played() {
    // The hashes are of the same code run against c886bcc~1, before glTF
    // animations were read (the CLI's EXR bytes of scenes/gltf.toml,
    // scenes/models.toml and scenes/models/pyramids.gltf at 96 × 64, 4
    // spp, were compared the same way: equal).
    let dir = tempfile::tempdir().unwrap();
    write(
        dir.path(),
        "square.glb",
        &square_file(|_| None, vec![camera_node()]),
    );
    let text = "[render]\nwidth = 120\nheight = 40\nspp = 4\nambient = [1, 1, 1]\nshutter = [0, 1]\n\
                [lights.key]\ntype = \"point\"\nposition = [1, 2, 5]\nintensity = 40\n\
                [[objects]]\ntype = \"mesh\"\nfile = \"square.glb\"\n";
    let s = Scene::from_toml_in(text, "test", dir.path()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(film_hash(&s, &s.settings), 0x2782_fc38_56f0_6410);
    let s = Scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/gltf.toml")).unwrap();
    let settings = RenderSettings {
        width: 64,
        height: 48,
        spp: 2,
        ..s.settings
    };
    assert_eq!(film_hash(&s, &settings), 0xde4b_4fda_8417_4c59);
}
