//! Model files: meshes load, instance, render, and bad files give clear
//! errors naming the file and the line or element.

use std::path::Path;

use prism::accel::Shape;
use prism::{RenderSettings, Scene, render};

fn scene_with(dir: &Path, object: &str) -> Result<Scene, String> {
    let toml = format!(
        "[render]\nwidth = 100\nheight = 100\nspp = 1\nambient = [1, 1, 1]\n\
         [camera]\ntype = \"orthographic\"\nposition = [0, 0, 10]\nlook_at = [0, 0, 0]\nview_height = 4\n\
         [materials.white]\nka = 1\nkd = 0\n\
         [[objects]]\ntype = \"mesh\"\nmaterial = \"white\"\n{object}\n"
    );
    std::fs::write(dir.join("scene.toml"), toml).unwrap();
    load_allowing_models(&dir.join("scene.toml")).map_err(|e| e.to_string())
}

/// Loads a scene that may also read the repository's example models.
fn load_allowing_models(path: &Path) -> Result<Scene, prism::SceneError> {
    let options = prism::scene::LoadOptions {
        allow_read: vec![models_dir()],
        ..Default::default()
    };
    Scene::load_with(path, &options)
}

/// Renders `scene` with its own settings on `threads` threads.
fn render_film(scene: &Scene, threads: usize) -> prism::render::Film {
    let settings = RenderSettings {
        threads: Some(threads),
        ..scene.settings
    };
    render(scene, &settings, &()).unwrap().film
}

/// The mesh placements of a scene, in object order.
fn mesh_instances(scene: &Scene) -> Vec<&prism::geometry::MeshInstance> {
    scene
        .aggregate
        .primitives()
        .iter()
        .filter_map(|p| match &p.shape {
            Shape::Mesh(m) => Some(&**m),
            _ => None,
        })
        .collect()
}

fn models_dir() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/models")
}

#[test]
fn binary_ply_icosphere_covers_nearly_pi_r_squared() {
    let dir = tempfile::tempdir().unwrap();
    let file = models_dir().join("icosphere.ply");
    let s = scene_with(dir.path(), &format!("file = {:?}", file.to_str().unwrap())).unwrap();
    let out = render_film(&s, 2);
    let lit = out.pixels().iter().filter(|p| p.x > 0.5).count() as f64;
    let area = lit * (4.0f64 / 100.0).powi(2);
    // A 1280-triangle icosphere is a little smaller than its sphere (its
    // outline lies within 1% of the circle); pixels add a little noise.
    assert!(
        (area - std::f64::consts::PI).abs() / std::f64::consts::PI < 0.02,
        "area {area}"
    );
}

#[test]
fn a_model_placed_twice_is_loaded_once() {
    let s = Scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/models.toml")).unwrap();
    let meshes: Vec<_> = mesh_instances(&s).iter().map(|m| m.mesh.clone()).collect();
    assert_eq!(meshes.len(), 5);
    // Three placements of the icosphere share one mesh.
    assert!(std::sync::Arc::ptr_eq(&meshes[0], &meshes[1]));
    assert!(std::sync::Arc::ptr_eq(&meshes[0], &meshes[2]));
    assert!(!std::sync::Arc::ptr_eq(&meshes[0], &meshes[3]));
}

fn expect_error(dir: &Path, file: &str, contents: &[u8], wanted: &[&str]) {
    std::fs::write(dir.join(file), contents).unwrap();
    let err = scene_with(dir, &format!("file = {file:?}")).unwrap_err();
    assert!(err.contains("scene.toml:"), "{err}");
    for w in wanted {
        assert!(err.contains(w), "want {w:?} in: {err}");
    }
}

#[test]
fn obj_faces_past_the_vertex_list_are_located() {
    let dir = tempfile::tempdir().unwrap();
    let obj = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 7\n";
    expect_error(
        dir.path(),
        "bad.obj",
        obj,
        &["bad.obj:5:", "vertex 7, but only 3"],
    );
}

#[test]
fn obj_nan_coordinates_are_located() {
    let dir = tempfile::tempdir().unwrap();
    let obj = b"v 0 0 0\nv 1 NaN 0\nv 0 1 0\nf 1 2 3\n";
    expect_error(
        dir.path(),
        "nan.obj",
        obj,
        &["nan.obj:2:", "not a finite number"],
    );
}

#[test]
fn missing_texture_is_named() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("t.mtl"),
        "newmtl m\nKd 1 1 1\nmap_Kd nowhere.png\n",
    )
    .unwrap();
    let obj = b"mtllib t.mtl\nusemtl m\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n";
    expect_error(dir.path(), "t.obj", obj, &["t.obj", "nowhere.png"]);
}

fn binary_ply(vertices: &[[f32; 3]], faces: &[[i32; 3]], announced_faces: usize) -> Vec<u8> {
    let mut b = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         element face {announced_faces}\nproperty list uchar int vertex_indices\nend_header\n",
        vertices.len()
    )
    .into_bytes();
    for v in vertices {
        for c in v {
            b.extend(c.to_le_bytes());
        }
    }
    for f in faces {
        b.push(3);
        for i in f {
            b.extend(i.to_le_bytes());
        }
    }
    b
}

#[test]
fn truncated_binary_ply_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let ply = binary_ply(
        &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        &[[0, 1, 2]],
        5,
    );
    expect_error(
        dir.path(),
        "cut.ply",
        &ply,
        &["cut.ply", "element `face` (5 announced)", "truncated"],
    );
}

#[test]
fn ply_faces_past_the_vertex_list_name_the_face() {
    let dir = tempfile::tempdir().unwrap();
    let ply = binary_ply(
        &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        &[[0, 1, 2], [0, 1, 9]],
        2,
    );
    expect_error(
        dir.path(),
        "far.ply",
        &ply,
        &[
            "far.ply",
            "face 1 refers to vertex 9, but there are 3 vertices",
        ],
    );
}

#[test]
fn ascii_ply_with_quads_loads() {
    let dir = tempfile::tempdir().unwrap();
    let ply = "ply\nformat ascii 1.0\nelement vertex 4\nproperty double x\nproperty double y\nproperty double z\n\
               element face 1\nproperty list uchar uint vertex_indices\nend_header\n\
               -1 -1 0\n1 -1 0\n1 1 0\n-1 1 0\n4 0 1 2 3\n";
    std::fs::write(dir.path().join("quad.ply"), ply).unwrap();
    let s = scene_with(dir.path(), "file = \"quad.ply\"").unwrap();
    let out = render_film(&s, 1);
    let lit = out.pixels().iter().filter(|p| p.x > 0.5).count();
    // A 2×2 square in a 4×4 view: a quarter of the pixels.
    assert_eq!(lit, 2500);
}

#[test]
fn unknown_model_format_and_missing_file_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    expect_error(
        dir.path(),
        "x.stl",
        b"solid",
        &["x.stl", "expected a .obj, .ply, .gltf or .glb file"],
    );
    let err = scene_with(dir.path(), "file = \"missing.obj\"").unwrap_err();
    assert!(
        err.contains("missing.obj") && err.contains("cannot read"),
        "{err}"
    );
    // `file` only applies to meshes; meshes need one.
    let err = scene_with(dir.path(), "").unwrap_err();
    assert!(err.contains("a mesh needs `file`"), "{err}");
}

#[test]
fn gltf_brings_meshes_node_transforms_camera_and_lights() {
    let s = Scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/gltf.toml")).unwrap();
    // The scene has no [camera]: the file's, at its node's translation.
    assert!(
        (s.camera.position - glam::DVec3::new(0.0, 1.6 + 0.002, 4.2)).length() < 1e-6,
        "{}",
        s.camera.position
    );
    assert_eq!(s.lights.len(), 1, "KHR_lights_punctual point light");
    // Two nodes, two glTF meshes: two placements of six triangles each.
    let meshes: Vec<_> = mesh_instances(&s);
    assert_eq!(meshes.len(), 2);
    assert!(meshes.iter().all(|m| m.mesh.triangle_count() == 6));
    // The glass pyramid is scaled ×1.4 in y by its node: 1.4 tall.
    let tallest = meshes.iter().map(|m| m.bounds().max.y).fold(0.0, f64::max);
    assert!((tallest - (1.4 + 0.002)).abs() < 1e-6, "{tallest}");
    // Its glass material: transmission and ior.
    assert!(
        s.materials
            .iter()
            .any(|mat| mat.kt.min_element() > 0.8 && (mat.ior - 1.5).abs() < 1e-9)
    );
}

/// The example glTF's JSON, for the edits the tests below make to it.
fn pyramid_gltf_json() -> String {
    std::fs::read_to_string(models_dir().join("pyramids.gltf")).unwrap()
}

#[test]
fn gltf_with_an_unsupported_required_extension_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(
        models_dir().join("pyramid.bin"),
        dir.path().join("pyramid.bin"),
    )
    .unwrap();
    let json = pyramid_gltf_json().replacen(
        "\"extensionsUsed\"",
        "\"extensionsRequired\": [\"KHR_draco_mesh_compression\"],\n \"extensionsUsed\"",
        1,
    );
    expect_error(
        dir.path(),
        "draco.gltf",
        json.as_bytes(),
        &[
            "draco.gltf",
            "KHR_draco_mesh_compression",
            "does not support",
        ],
    );
}

#[test]
fn glb_binary_container_loads() {
    let dir = tempfile::tempdir().unwrap();
    let bin = std::fs::read(models_dir().join("pyramid.bin")).unwrap();
    let mut json = pyramid_gltf_json().replace("\"uri\": \"pyramid.bin\",", "");
    while !json.len().is_multiple_of(4) {
        json.push(' ');
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut glb = Vec::new();
    glb.extend(b"glTF");
    glb.extend(2u32.to_le_bytes());
    glb.extend((total as u32).to_le_bytes());
    glb.extend((json.len() as u32).to_le_bytes());
    glb.extend(b"JSON");
    glb.extend(json.as_bytes());
    glb.extend((bin.len() as u32).to_le_bytes());
    glb.extend(b"BIN\0");
    glb.extend(&bin);
    std::fs::write(dir.path().join("p.glb"), glb).unwrap();
    let s = scene_with(dir.path(), "file = \"p.glb\"").unwrap();
    let triangles: usize = mesh_instances(&s)
        .iter()
        .map(|m| m.mesh.triangle_count())
        .sum();
    assert_eq!(triangles, 12);
}

#[test]
fn a_gltf_mesh_used_by_two_nodes_is_stored_once() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(
        models_dir().join("pyramid.bin"),
        dir.path().join("pyramid.bin"),
    )
    .unwrap();
    // Point the second node at the first node's mesh.
    let json = pyramid_gltf_json().replacen("\"mesh\": 1", "\"mesh\": 0", 1);
    std::fs::write(dir.path().join("twice.gltf"), json).unwrap();
    let s = scene_with(dir.path(), "file = \"twice.gltf\"").unwrap();
    let meshes: Vec<_> = mesh_instances(&s);
    assert_eq!(meshes.len(), 2);
    assert!(std::sync::Arc::ptr_eq(&meshes[0].mesh, &meshes[1].mesh));
    // Each placement keeps its own node transform.
    assert_ne!(meshes[0].transform, meshes[1].transform);
}

#[test]
fn scene_materials_take_image_textures_and_uv_checkers() {
    let dir = tempfile::tempdir().unwrap();
    let tile = models_dir().join("tile.png");
    let toml = format!(
        "[render]\nwidth = 64\nheight = 64\nspp = 1\nambient = [1, 1, 1]\n\
         [camera]\ntype = \"orthographic\"\nposition = [0, 0, 10]\nlook_at = [0, 0, 0]\nview_height = 4\n\
         [materials.image]\nka = 1\nkd = 0\ntexture = {:?}\n\
         [materials.uv]\nka = 1\nkd = 0\ncolor = [1, 1, 1]\nchecker = {{ color = [0, 0, 0], size = 0.5, mapping = \"uv\" }}\n\
         [[objects]]\ntype = \"plane\"\nmaterial = \"uv\"\nnormal = [0, 0, 1]\ndistance = -1\n\
         [[objects]]\ntype = \"sphere\"\nmaterial = \"image\"\nradius = 1\n",
        tile.to_str().unwrap()
    );
    std::fs::write(dir.path().join("scene.toml"), toml).unwrap();
    let s = load_allowing_models(&dir.path().join("scene.toml")).unwrap();
    let out = render_film(&s, 1);
    // The plane behind: a uv checker of equal black and white areas.
    let corner: Vec<f64> = (0..16)
        .flat_map(|y| (0..16).map(move |x| (x, y)))
        .map(|(x, y)| out.get(x, y).x)
        .collect();
    let white = corner.iter().filter(|&&v| v > 0.5).count();
    assert!(white > 64 && white < 192, "{white} of 256 white");
    // The sphere shows the tile image's blue and yellow.
    let centre = out.get(32, 32);
    assert!(
        centre.max_element() > 0.0 && (centre.x - centre.z).abs() > 0.05,
        "{centre}"
    );
    // A missing texture file is an error naming it.
    std::fs::write(dir.path().join("bad.toml"), "[camera]\nposition = [0, 0, 1]\nlook_at = [0, 0, 0]\n[materials.m]\ntexture = \"nope.png\"\n").unwrap();
    let err = Scene::load(&dir.path().join("bad.toml"))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("bad.toml:5:11") && err.contains("nope.png"),
        "{err}"
    );
}

#[test]
fn smooth_shaded_icosphere_shades_like_the_true_sphere() {
    // Interpolated vertex normals: away from the outline the faceted
    // icosphere lit by a point light matches the analytic sphere closely.
    let dir = tempfile::tempdir().unwrap();
    let file = models_dir().join("icosphere.ply");
    let scene = |object: &str| {
        let toml = format!(
            "[render]\nwidth = 80\nheight = 80\nspp = 1\nambient = [0, 0, 0]\n\
             [camera]\ntype = \"orthographic\"\nposition = [0, 0, 10]\nlook_at = [0, 0, 0]\nview_height = 2.4\n\
             [materials.white]\nka = 0\nkd = 1\n\
             [lights.l]\ntype = \"directional\"\ndirection = [-1, -1, -2]\n\
             [[objects]]\nmaterial = \"white\"\n{object}\n"
        );
        std::fs::write(dir.path().join("s.toml"), toml).unwrap();
        let s = load_allowing_models(&dir.path().join("s.toml")).unwrap();
        render_film(&s, 1)
    };
    let mesh = scene(&format!(
        "type = \"mesh\"\nfile = {:?}",
        file.to_str().unwrap()
    ));
    let sphere = scene("type = \"sphere\"\nradius = 1");
    let (mut total, mut count) = (0.0, 0);
    for y in 0..80 {
        for x in 0..80 {
            let (u, v) = (
                (x as f64 + 0.5) / 80.0 * 2.4 - 1.2,
                (y as f64 + 0.5) / 80.0 * 2.4 - 1.2,
            );
            if u * u + v * v < 0.8 {
                total += (mesh.get(x, y).x - sphere.get(x, y).x).abs();
                count += 1;
            }
        }
    }
    let mean = total / count as f64;
    assert!(sphere.get(40, 40).x > 0.3, "the sphere is lit");
    assert!(mean < 0.01, "mean difference {mean}");
}

#[test]
fn metals_reflect_their_colour_from_gltf_and_mtl() {
    // glTF: kr = metallicFactor × baseColorFactor (the example's gold is
    // metallic 0.6 over [1, 0.75, 0.3]).
    let s = Scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/gltf.toml")).unwrap();
    let gold = glam::DVec3::new(1.0, 0.75, 0.3) * 0.6;
    assert!(
        s.materials
            .iter()
            .any(|m| (m.kr - gold).abs().max_element() < 1e-6),
        "{:?}",
        s.materials.iter().map(|m| m.kr).collect::<Vec<_>>()
    );
    // MTL illum 3: kr = Ks, a colour; Tf filters transmission by channel.
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("m.mtl"),
        "newmtl copper\nKd 0 0 0\nKs 0.95 0.64 0.54\nillum 3\n\
         newmtl green_glass\nTf 0.2 0.9 0.3\nNi 1.5\nillum 6\n",
    )
    .unwrap();
    std::fs::write(
        dir.path().join("m.obj"),
        "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl copper\nf 1 2 3\nusemtl green_glass\nf 1 3 2\n",
    )
    .unwrap();
    let s = scene_with(dir.path(), "file = \"m.obj\"").unwrap();
    let close =
        |a: glam::DVec3, b: [f64; 3]| (a - glam::DVec3::from_array(b)).abs().max_element() < 1e-6;
    assert!(s.materials.iter().any(|m| close(m.kr, [0.95, 0.64, 0.54])));
    assert!(s.materials.iter().any(|m| close(m.kt, [0.2, 0.9, 0.3])));
}
