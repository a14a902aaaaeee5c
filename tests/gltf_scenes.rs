//! glTF files as Blender exports them: light units against Cycles' values
//! (worked by hand), cameras, skipped primitives, a glTF file as a scene.
//! The files are written here (JSON with a base64 buffer), so no Blender
//! is needed.

use std::f64::consts::PI;
use std::path::Path;

use prism::scene::LoadOptions;
use prism::{RenderSettings, Scene, render};
use serde_json::{Value, json};

/// A 20 × 20 quad in y = 0 facing +y (mesh 0, albedo 0.8, rough: no
/// highlight), a line strip (mesh 1), and the accessors they use.
fn buffer() -> (String, Value, Value) {
    let mut bytes: Vec<u8> = Vec::new();
    let positions: [[f32; 3]; 4] = [
        [-10.0, 0.0, -10.0],
        [-10.0, 0.0, 10.0],
        [10.0, 0.0, 10.0],
        [10.0, 0.0, -10.0],
    ];
    for p in positions.iter().flatten() {
        bytes.extend(p.to_le_bytes());
    }
    for _ in 0..4 {
        for c in [0f32, 1.0, 0.0] {
            bytes.extend(c.to_le_bytes());
        }
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        bytes.extend(i.to_le_bytes());
    }
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::encode(&bytes)
    );
    let views = json!([
        {"buffer": 0, "byteOffset": 0, "byteLength": 48},
        {"buffer": 0, "byteOffset": 48, "byteLength": 48},
        {"buffer": 0, "byteOffset": 96, "byteLength": 12}
    ]);
    let accessors = json!([
        {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
         "min": [-10, 0, -10], "max": [10, 0, 10]},
        {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
        {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}
    ]);
    (uri, views, accessors)
}

/// Looking straight down (−z turned onto −y).
const DOWN: [f64; 4] = [
    -std::f64::consts::FRAC_1_SQRT_2,
    0.0,
    0.0,
    std::f64::consts::FRAC_1_SQRT_2,
];

/// A glTF file: the quad (node 0, named "Plane"), then `nodes`, with
/// `lights` and `cameras`; `mesh0` the quad's primitives.
fn gltf(nodes: Value, lights: Value, cameras: Value, mesh0: Value) -> String {
    let (uri, views, accessors) = buffer();
    let mut all = vec![json!({"name": "Plane", "mesh": 0})];
    all.extend(nodes.as_array().unwrap().iter().cloned());
    let roots: Vec<usize> = (0..all.len()).collect();
    let mut root = json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_lights_punctual"],
        "scene": 0,
        "scenes": [{"nodes": roots}],
        "nodes": all,
        "meshes": [{"name": "Plane", "primitives": mesh0}],
        "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1],
                        "metallicFactor": 0, "roughnessFactor": 1}}],
        "buffers": [{"uri": uri, "byteLength": 108}],
        "bufferViews": views,
        "accessors": accessors,
        "extensions": {"KHR_lights_punctual": {"lights": lights}}
    });
    if !cameras.as_array().unwrap().is_empty() {
        root["cameras"] = cameras;
    }
    serde_json::to_string_pretty(&root).unwrap()
}

fn quad() -> Value {
    json!([{"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2, "material": 0}])
}

/// An orthographic camera 8 units wide 10 above the origin, looking down.
fn top_camera() -> (Value, Value) {
    (
        json!({"name": "Top", "camera": 0, "translation": [0, 10, 0], "rotation": DOWN}),
        json!({"type": "orthographic", "orthographic": {"xmag": 4, "ymag": 4, "znear": 0.1, "zfar": 100}}),
    )
}

/// Writes `text` as `name` in a new folder and loads it as a scene.
fn load(
    name: &str,
    text: &str,
    options: &LoadOptions,
) -> (tempfile::TempDir, Result<Scene, String>) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join(name), text).unwrap();
    let scene = Scene::load_with(&dir.path().join(name), options).map_err(|e| e.to_string());
    (dir, scene)
}

/// A 9 × 9, 1 spp render's pixel (x, y).
fn pixel(scene: &Scene, x: u32, y: u32) -> glam::DVec3 {
    let settings = RenderSettings {
        width: 9,
        height: 9,
        spp: 1,
        threads: Some(1),
        ..scene.settings
    };
    render(scene, &settings, &()).unwrap().film.get(x, y)
}

/// A light 4 above the quad's centre, pointing down.
fn light_node() -> Value {
    json!({"name": "Light", "translation": [0, 4, 0], "rotation": DOWN,
           "extensions": {"KHR_lights_punctual": {"light": 0}}})
}

/// Blender's exporter: a light of `watts` is `watts / (4π) × 683` cd.
fn blender_candela(watts: f64) -> f64 {
    watts / (4.0 * PI) * 683.0
}

fn probe(light: Value) -> Scene {
    let (cam, camera) = top_camera();
    let text = gltf(
        json!([cam, light_node()]),
        json!([light]),
        json!([camera]),
        quad(),
    );
    let (_dir, scene) = load("probe.gltf", &text, &LoadOptions::default());
    scene.unwrap()
}

/// Within 5 % of Cycles' value, and within rounding of the hand-worked one.
fn matches_cycles(got: f64, cycles: f64, exact: f64) {
    assert!((got - exact).abs() < 1e-6 * exact, "{got} vs {exact}");
    assert!(
        (got / cycles - 1.0).abs() < 0.05,
        "{got} vs Cycles' {cycles}"
    );
}

#[test]
fn a_100_w_point_light_gives_what_cycles_gives() {
    // Cycles: 0.1266 at the plane under a 100 W point light 4 m up;
    // by hand 0.8/π × (100/(4π)) / 4².
    let s = probe(json!({"type": "point", "intensity": blender_candela(100.0)}));
    let exact = 0.8 / PI * (100.0 / (4.0 * PI)) / 16.0;
    matches_cycles(pixel(&s, 4, 4).x, 0.1266, exact);
}

#[test]
fn a_1_w_sun_gives_what_cycles_gives() {
    // Cycles: 0.2546 under a 1 W/m² sun overhead (683 lux): 0.8/π.
    let s = probe(json!({"type": "directional", "intensity": 683.0}));
    matches_cycles(pixel(&s, 4, 4).x, 0.2546, 0.8 / PI);
}

#[test]
fn a_spot_light_lights_its_cone_only() {
    let s = probe(json!({"type": "spot", "intensity": blender_candela(100.0),
                         "spot": {"innerConeAngle": 0.3, "outerConeAngle": 0.5}}));
    // On the axis a spot is its point light.
    let exact = 0.8 / PI * (100.0 / (4.0 * PI)) / 16.0;
    matches_cycles(pixel(&s, 4, 4).x, 0.1266, exact);
    // Pixel 8's centre is 3.56 off the axis, 41.6° > the outer 28.6°.
    assert_eq!(pixel(&s, 8, 4), glam::DVec3::ZERO);
    // Pixel 5's is 0.89 off, 12.5°: inside the inner cone (17.2°), lit
    // as the point light would be there: cos³θ × the value on the axis.
    let cos = 4.0 / (4.0f64 * 4.0 + 0.888_888_888_888_9 * 0.888_888_888_888_9).sqrt();
    let lit = pixel(&s, 5, 4).x;
    assert!((lit - exact * cos.powi(3)).abs() < 1e-6, "{lit}");
}

#[test]
fn a_spot_light_in_a_scene_file_has_the_same_cone() {
    let dir = tempfile::tempdir().unwrap();
    let text = "[render]\nambient = [0, 0, 0]\n\
        [camera]\ntype = \"orthographic\"\nposition = [0, 10, 0]\nlook_at = [0, 0, 0]\nup = [0, 0, -1]\nview_height = 8\n\
        [materials.m]\ncolor = [0.8, 0.8, 0.8]\nkd = 1\nks = 0\n\
        [lights.s]\ntype = \"spot\"\nposition = [0, 4, 0]\ndirection = [0, -1, 0]\n\
        inner_angle = 17.188733853924695\nouter_angle = 28.64788975654116\nfalloff = \"inverse_square\"\n\
        [[objects]]\ntype = \"plane\"\nmaterial = \"m\"\nnormal = [0, 1, 0]\n";
    std::fs::write(dir.path().join("s.toml"), text).unwrap();
    let s = Scene::load(&dir.path().join("s.toml")).unwrap();
    let glb = probe(json!({"type": "spot", "intensity": 683.0 * PI,
                           "spot": {"innerConeAngle": 0.3, "outerConeAngle": 0.5}}));
    // kd·Od = 0.8 and Il = 1 in the scene; Il = π, kd·Od = 0.8/π from
    // the glTF.
    for x in 0..9 {
        let (a, b) = (pixel(&s, x, 4).x, pixel(&glb, x, 4).x);
        assert!((a - b).abs() < 1e-9, "pixel {x}: {a} vs {b}");
    }
    // Outside the cone: dark; the keys are checked.
    assert_eq!(pixel(&s, 0, 4).x, 0.0);
    let bad = text.replace("outer_angle = 28.64788975654116", "outer_angle = 10");
    std::fs::write(dir.path().join("bad.toml"), bad).unwrap();
    let e = Scene::load(&dir.path().join("bad.toml"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("`inner_angle` (17.188733853924695°) is wider than `outer_angle`"),
        "{e}"
    );
}

#[test]
fn light_scale_scales_or_drops_a_models_lights() {
    let dir = tempfile::tempdir().unwrap();
    let (cam, camera) = top_camera();
    let text = gltf(
        json!([cam, light_node()]),
        json!([{"type": "directional", "intensity": 683.0}]),
        json!([camera]),
        quad(),
    );
    std::fs::write(dir.path().join("m.gltf"), text).unwrap();
    let scene = |extra: &str| {
        let t = format!(
            "[render]\nambient = [0, 0, 0]\n[[objects]]\ntype = \"mesh\"\nfile = \"m.gltf\"\n{extra}\n"
        );
        std::fs::write(dir.path().join("s.toml"), t).unwrap();
        Scene::load(&dir.path().join("s.toml"))
    };
    let one = pixel(&scene("").unwrap(), 4, 4).x;
    let half = pixel(&scene("light_scale = 0.5").unwrap(), 4, 4).x;
    assert!((half - 0.5 * one).abs() < 1e-12, "{half} vs {one}");
    let none = scene("light_scale = 0").unwrap();
    assert!(none.lights.is_empty());
    assert!(
        none.warnings.iter().any(|w| w.contains("no lights")),
        "{:?}",
        none.warnings
    );
    let e = scene("light_scale = -1").unwrap_err().to_string();
    assert!(e.contains("light_scale"), "{e}");
}

#[test]
fn exposure_is_read_from_render() {
    let dir = tempfile::tempdir().unwrap();
    let text = "[render]\nexposure = -1.5\n[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n";
    std::fs::write(dir.path().join("s.toml"), text).unwrap();
    let s = Scene::load(&dir.path().join("s.toml")).unwrap();
    assert_eq!(s.settings.exposure, -1.5);
    std::fs::write(dir.path().join("s.toml"), text.replace("-1.5", "100")).unwrap();
    let e = Scene::load(&dir.path().join("s.toml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("s.toml:2:") && e.contains("exposure"), "{e}");
}

/// Two perspective cameras, "Wide" (16:9) then "Tall", and an
/// orthographic one, "Top", with a sun.
fn three_cameras() -> String {
    let (top, ortho) = top_camera();
    gltf(
        json!([
            {"name": "Wide", "camera": 1, "translation": [0, 1, 5]},
            {"name": "Tall", "camera": 2, "translation": [0, 2, 5]},
            top,
            light_node()
        ]),
        json!([{"type": "directional", "intensity": 683.0}]),
        json!([
            ortho,
            {"name": "WideData", "type": "perspective", "perspective": {"yfov": 0.5, "aspectRatio": 1.7777778, "znear": 0.1}},
            {"type": "perspective", "perspective": {"yfov": 0.5, "aspectRatio": 0.5, "znear": 0.1}}
        ]),
        quad(),
    )
}

#[test]
fn the_first_camera_in_node_order_is_used_and_named() {
    let (_d, s) = load("c.gltf", &three_cameras(), &LoadOptions::default());
    let s = s.unwrap();
    assert!((s.camera.position - glam::DVec3::new(0.0, 1.0, 5.0)).length() < 1e-6);
    // Its 16:9 shape sets the image's: the default width, the height it
    // implies.
    assert_eq!((s.settings.width, s.settings.height), (640, 360));
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("3 cameras (`Wide`, `Tall`, `Top`); using `Wide`")),
        "{:?}",
        s.warnings
    );
}

#[test]
fn a_camera_is_chosen_by_name() {
    // --camera, by node name or by the camera's own name.
    for name in ["Tall", "WideData", "Top"] {
        let options = LoadOptions {
            camera: Some(name.into()),
            ..LoadOptions::default()
        };
        let (_d, s) = load("c.gltf", &three_cameras(), &options);
        let s = s.unwrap();
        let y = match name {
            "Tall" => 2.0,
            "WideData" => 1.0,
            _ => 10.0,
        };
        assert!((s.camera.position.y - y).abs() < 1e-6, "{name}");
        if name == "Tall" {
            assert_eq!((s.settings.width, s.settings.height), (640, 1280));
        }
        if name == "Top" {
            // Orthographic, 2·ymag tall, square.
            assert_eq!(
                s.camera.projection,
                prism::camera::Projection::Orthographic { view_height: 8.0 }
            );
            assert_eq!((s.settings.width, s.settings.height), (640, 640));
        }
    }
    let options = LoadOptions {
        camera: Some("Nope".into()),
        ..LoadOptions::default()
    };
    let (_d, s) = load("c.gltf", &three_cameras(), &options);
    let e = s.unwrap_err();
    assert!(
        e.contains("--camera Nope") && e.contains("`Wide`, `Tall`, `Top`"),
        "{e}"
    );
    // In a scene file: `camera = "NAME"` in the mesh object; [render]'s
    // size disagreeing with the camera's shape is warned about.
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("c.gltf"), three_cameras()).unwrap();
    let scene = |extra: &str| {
        std::fs::write(
            dir.path().join("s.toml"),
            format!("[render]\nwidth = 100\nheight = 100\n[[objects]]\ntype = \"mesh\"\nfile = \"c.gltf\"\n{extra}\n"),
        )
        .unwrap();
        Scene::load(&dir.path().join("s.toml")).map_err(|e| e.to_string())
    };
    let s = scene("camera = \"Tall\"").unwrap();
    assert!((s.camera.position.y - 2.0).abs() < 1e-6);
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("camera `Tall` was made for an image 0.5000")),
        "{:?}",
        s.warnings
    );
    let e = scene("camera = \"Nope\"").unwrap_err();
    assert!(
        e.contains("s.toml:7:10") && e.contains("no camera named `Nope`"),
        "{e}"
    );
}

#[test]
fn lines_and_points_are_skipped_with_a_warning_naming_mesh_and_primitive() {
    let (cam, camera) = top_camera();
    let mut prims = quad();
    prims
        .as_array_mut()
        .unwrap()
        .push(json!({"attributes": {"POSITION": 0}, "mode": 1}));
    let text = gltf(
        json!([cam, light_node()]),
        json!([{"type": "point", "intensity": 1}]),
        json!([camera]),
        prims,
    );
    let (_d, s) = load("l.gltf", &text, &LoadOptions::default());
    let s = s.unwrap();
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("meshes[0].primitives[1] (mesh `Plane`): lines")),
        "{:?}",
        s.warnings
    );
    // Only loose edges: an error naming the file, and nothing about the
    // camera after it.
    let loose = json!([{"attributes": {"POSITION": 0}, "mode": 1}, {"attributes": {"POSITION": 0}, "mode": 0}]);
    let text = gltf(json!([]), json!([]), json!([]), loose);
    let (_d, s) = load("loose.gltf", &text, &LoadOptions::default());
    let e = s.unwrap_err();
    assert!(
        e.contains("loose.gltf") && e.contains("has no triangles"),
        "{e}"
    );
    assert!(!e.contains("camera"), "{e}");
    assert_eq!(e.lines().count(), 1, "{e}");
}

#[test]
fn a_gltf_file_without_lights_is_warned_about() {
    let (cam, camera) = top_camera();
    let text = gltf(json!([cam]), json!([]), json!([camera]), quad());
    let (_d, s) = load("dark.glb.gltf", &text, &LoadOptions::default());
    let s = s.unwrap();
    assert!(
        s.warnings.iter().any(|w| w.contains("no lights")),
        "{:?}",
        s.warnings
    );
}

#[test]
fn a_gltf_file_is_a_scene_reading_below_its_folder_only() {
    let (cam, camera) = top_camera();
    let text = gltf(
        json!([cam, light_node()]),
        json!([{"type": "point", "intensity": 1}]),
        json!([camera]),
        quad(),
    );
    let (_d, s) = load("m.gltf", &text, &LoadOptions::default());
    let s = s.unwrap();
    assert_eq!(s.background, glam::DVec3::splat(0.05));
    assert_eq!(s.ambient, glam::DVec3::ZERO);
    // A buffer outside its folder is refused, naming the file.
    let mut outside: Value = serde_json::from_str(&text).unwrap();
    outside["buffers"][0]["uri"] = json!("../x.bin");
    let (d, s) = load("m.gltf", &outside.to_string(), &LoadOptions::default());
    let e = s.unwrap_err();
    assert!(
        e.contains("m.gltf:1:1: error: ") && e.contains("x.bin"),
        "{e}"
    );
    assert!(Path::new(d.path()).exists());
}

/// A 2 × 1 PNG, black then white, as a data URI.
fn black_white_png() -> String {
    let img = image::RgbImage::from_raw(2, 1, vec![0, 0, 0, 255, 255, 255]).unwrap();
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    format!("data:image/png;base64,{}", base64::encode(&png))
}

/// The probe with `material` on the quad, which gets texture coordinates
/// u = (x + 10)/20, v = (z + 10)/20 (glTF's, v down); texture 0 is the
/// black-and-white image through sampler 0 = `sampler`. No lights.
fn textured(material: Value, sampler: Value) -> String {
    let (cam, camera) = top_camera();
    let text = gltf(json!([cam]), json!([]), json!([camera]), quad());
    let mut root: Value = serde_json::from_str(&text).unwrap();
    let mut uvs = Vec::new();
    for uv in [[0f32, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]] {
        for c in uv {
            uvs.extend(c.to_le_bytes());
        }
    }
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::encode(&uvs)
    );
    root["buffers"]
        .as_array_mut()
        .unwrap()
        .push(json!({"uri": uri, "byteLength": 32}));
    root["bufferViews"]
        .as_array_mut()
        .unwrap()
        .push(json!({"buffer": 1, "byteLength": 32}));
    root["accessors"]
        .as_array_mut()
        .unwrap()
        .push(json!({"bufferView": 3, "componentType": 5126, "count": 4, "type": "VEC2"}));
    root["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = json!(3);
    // Not metallic (glTF's default is 1: a mirror of the background).
    let mut material = material;
    material["pbrMetallicRoughness"]["metallicFactor"] = json!(0);
    root["materials"] = json!([material]);
    root["images"] = json!([{"uri": black_white_png()}]);
    root["samplers"] = json!([sampler]);
    root["textures"] = json!([{"source": 0, "sampler": 0}]);
    root.to_string()
}

/// The red channel of pixels 0..9 along the middle row.
fn row(text: &str) -> Vec<f64> {
    let (_d, s) = load("t.gltf", text, &LoadOptions::default());
    let s = s.unwrap();
    (0..9).map(|x| pixel(&s, x, 4).x).collect()
}

#[test]
fn emission_is_factor_times_texture_times_strength() {
    let text = textured(
        json!({"emissiveFactor": [1, 0.5, 0],
               "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 2}}}),
        json!({}),
    );
    let (_d, s) = load("e.gltf", &text, &LoadOptions::default());
    // No lights, no ambient: only the emission shows.
    assert_eq!(pixel(&s.unwrap(), 4, 4), glam::DVec3::new(2.0, 1.0, 0.0));
    // Through the texture: black on the left half, 2 on the right.
    let r = row(&textured(
        json!({"emissiveFactor": [1, 1, 1], "emissiveTexture": {"index": 0},
               "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 2}}}),
        json!({"magFilter": 9728}),
    ));
    assert_eq!(r[3], 0.0);
    assert_eq!(r[5], 2.0);
}

#[test]
fn samplers_filter_and_wrap_and_texture_transforms_tile() {
    let emissive = |transform: Option<Value>| {
        let mut info = json!({"index": 0});
        if let Some(t) = transform {
            info["extensions"] = json!({"KHR_texture_transform": t});
        }
        json!({"emissiveFactor": [1, 1, 1], "emissiveTexture": info})
    };
    // Pixel 4 looks at u = 0.5, the edge between the texels.
    let linear = row(&textured(emissive(None), json!({})));
    assert!((linear[4] - 0.5).abs() < 1e-9, "{linear:?}");
    let nearest = row(&textured(
        emissive(None),
        json!({"magFilter": 9728, "minFilter": 9728}),
    ));
    assert_eq!((nearest[3], nearest[4], nearest[5]), (0.0, 1.0, 1.0));
    // Tiled twice (Blender's Mapping node scale 2): pixel 3's u = 0.456
    // reads 0.911 (white), pixel 5's 0.544 reads 1.089, repeated 0.089
    // (black), or clamped to the white edge.
    let scale = Some(json!({"scale": [2, 2]}));
    let tiled = row(&textured(
        emissive(scale.clone()),
        json!({"magFilter": 9728}),
    ));
    assert_eq!((tiled[3], tiled[5]), (1.0, 0.0));
    let clamped = row(&textured(
        emissive(scale.clone()),
        json!({"magFilter": 9728, "wrapS": 33071}),
    ));
    assert_eq!((clamped[3], clamped[5]), (1.0, 1.0));
    // Mirrored: 1.089 reads 0.911, white.
    let mirrored = row(&textured(
        emissive(scale),
        json!({"magFilter": 9728, "wrapS": 33648}),
    ));
    assert_eq!(mirrored[5], 1.0);
    // An offset of ½ swaps the halves.
    let offset = row(&textured(
        emissive(Some(json!({"offset": [0.5, 0]}))),
        json!({"magFilter": 9728}),
    ));
    assert_eq!((offset[3], offset[5]), (1.0, 0.0));
}

#[test]
fn ignored_features_are_named_in_one_warning_and_required_ones_explained() {
    let mut root: Value = serde_json::from_str(&textured(
        json!({"normalTexture": {"index": 0}, "alphaMode": "BLEND",
               "pbrMetallicRoughness": {"baseColorTexture": {"index": 0, "texCoord": 1}}}),
        json!({}),
    ))
    .unwrap();
    root["extensionsUsed"] = json!([
        "KHR_lights_punctual",
        "KHR_materials_clearcoat",
        "KHR_texture_transform"
    ]);
    root["extensionsRequired"] = json!(["KHR_texture_transform"]);
    let (_d, s) = load("w.gltf", &root.to_string(), &LoadOptions::default());
    let s = s.unwrap();
    let ignored: Vec<&String> = s
        .warnings
        .iter()
        .filter(|w| w.contains("Prism ignores"))
        .collect();
    assert_eq!(ignored.len(), 1, "{:?}", s.warnings);
    for feature in [
        "normal maps (materials[0])",
        "alpha (alphaMode BLEND or MASK) (materials[0])",
        "texture coordinate sets other than TEXCOORD_0",
        "the extension KHR_materials_clearcoat",
    ] {
        assert!(ignored[0].contains(feature), "{feature}: {}", ignored[0]);
    }
    assert!(
        !ignored[0].contains("KHR_texture_transform"),
        "{}",
        ignored[0]
    );
    root["extensionsRequired"] = json!(["KHR_draco_mesh_compression"]);
    let (_d, s) = load("d.gltf", &root.to_string(), &LoadOptions::default());
    let e = s.unwrap_err();
    assert!(
        e.contains("KHR_draco_mesh_compression") && e.contains("untick Data > Compression"),
        "{e}"
    );
}

#[test]
fn vertex_colours_multiply_the_base_colour() {
    let (cam, camera) = top_camera();
    let text = gltf(
        json!([cam, light_node()]),
        json!([{"type": "directional", "intensity": 683.0}]),
        json!([camera]),
        quad(),
    );
    let mut root: Value = serde_json::from_str(&text).unwrap();
    // RGBA as Blender writes it, normalized unsigned shorts: (1, ½, ¼, 1).
    let mut colors = Vec::new();
    for _ in 0..4 {
        for c in [65535u16, 32768, 16384, 65535] {
            colors.extend(c.to_le_bytes());
        }
    }
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::encode(&colors)
    );
    root["buffers"]
        .as_array_mut()
        .unwrap()
        .push(json!({"uri": uri, "byteLength": 32}));
    root["bufferViews"]
        .as_array_mut()
        .unwrap()
        .push(json!({"buffer": 1, "byteLength": 32}));
    root["accessors"].as_array_mut().unwrap().push(
        json!({"bufferView": 3, "componentType": 5123, "normalized": true, "count": 4, "type": "VEC4"}),
    );
    root["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = json!(3);
    let (_d, s) = load("v.gltf", &root.to_string(), &LoadOptions::default());
    let got = pixel(&s.unwrap(), 4, 4);
    let want = 0.8 / PI * glam::DVec3::new(1.0, 32768.0 / 65535.0, 16384.0 / 65535.0);
    // baseColorFactor 0.8 is an f32.
    assert!((got - want).length() < 1e-7, "{got} vs {want}");
}
