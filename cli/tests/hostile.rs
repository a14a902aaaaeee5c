//! Hostile and careless input, as issue 6 lists it: every case ends in a
//! located exit-2 error (or a correct picture), with no panic, no output
//! file touched and no leftover file, under a 2 GB address-space limit.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::{Value, json};

/// Runs `prism` in `dir`, under `prlimit --as=2000000000` where prlimit
/// exists, so that a runaway allocation fails the test instead of the machine.
fn prism(dir: &Path, args: &[&str]) -> Output {
    let bin = env!("CARGO_BIN_EXE_prism");
    let mut cmd = if Path::new("/usr/bin/prlimit").exists() {
        let mut c = Command::new("/usr/bin/prlimit");
        c.args(["--as=2000000000", "--", bin]);
        c
    } else {
        Command::new(bin)
    };
    cmd.args(args)
        .current_dir(dir)
        .output()
        .expect("prism runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn models_dir() -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join("scenes/models")
}

/// A scene in `dir` with one mesh object reading `file`.
fn mesh_scene(dir: &Path, file: &str) {
    let toml = format!(
        "[render]\nwidth = 16\nheight = 12\nspp = 1\n\
         [camera]\nposition = [0, 1, 6]\nlook_at = [0, 0, 0]\n\
         [lights.l]\ntype = \"point\"\nposition = [2, 4, 5]\n\
         [[objects]]\ntype = \"mesh\"\nfile = {file:?}\n"
    );
    std::fs::write(dir.join("scene.toml"), toml).unwrap();
}

/// Renders `scene.toml` in `dir` over an existing output and checks the
/// refusal: exit 2, every `wanted` text in the message, no panic, the old
/// output untouched and no temporary file left.
fn assert_refused(dir: &Path, extra: &[&str], wanted: &[&str]) -> String {
    let out = dir.join("out.png");
    std::fs::write(&out, b"previous image").unwrap();
    let before: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    let mut args = vec!["render", "scene.toml", "-o", "out.png"];
    args.extend(extra);
    let o = prism(dir, &args);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    for w in wanted {
        assert!(err.contains(w), "want {w:?} in: {err}");
    }
    assert!(
        !err.contains("panicked") && !err.contains("RUST_BACKTRACE"),
        "{err}"
    );
    assert!(
        err.len() < 4000,
        "the message stays readable: {} bytes",
        err.len()
    );
    assert_eq!(std::fs::read(&out).unwrap(), b"previous image");
    let after: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(before, after, "no stray files");
    err
}

/// The example pyramids glTF as JSON, with its buffer copied beside `dir`.
fn pyramids(dir: &Path) -> Value {
    std::fs::copy(models_dir().join("pyramid.bin"), dir.join("pyramid.bin")).unwrap();
    serde_json::from_str(&std::fs::read_to_string(models_dir().join("pyramids.gltf")).unwrap())
        .unwrap()
}

/// Writes `gltf` as `m.gltf` in a new folder with a scene using it.
fn gltf_case(edit: impl FnOnce(&mut Value)) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let mut g = pyramids(dir.path());
    edit(&mut g);
    std::fs::write(
        dir.path().join("m.gltf"),
        serde_json::to_string(&g).unwrap(),
    )
    .unwrap();
    mesh_scene(dir.path(), "m.gltf");
    dir
}

#[test]
fn gltf_node_cycles_are_named() {
    let d = gltf_case(|g| g["nodes"][0]["children"] = json!([0]));
    assert_refused(
        d.path(),
        &[],
        &["m.gltf", "nodes[0] lists itself as a child"],
    );
    let d = gltf_case(|g| {
        g["nodes"][0]["children"] = json!([1]);
        g["nodes"][1]["children"] = json!([0]);
    });
    assert_refused(d.path(), &[], &["m.gltf", "cycle: 0 → 1 → 0"]);
}

#[test]
fn gltf_shared_children_cannot_expand_without_bound() {
    // 32 levels, each node listing the next twice: 2^32 instances from a
    // file of a few KB. Counted before anything is expanded.
    let d = gltf_case(|g| {
        let mut nodes = vec![];
        for i in 0..32 {
            nodes.push(json!({ "children": [i + 1, i + 1] }));
        }
        nodes.push(json!({ "mesh": 0 }));
        g["nodes"] = Value::Array(nodes);
        g["scenes"][0]["nodes"] = json!([0]);
    });
    assert_refused(
        d.path(),
        &[],
        &["m.gltf", "node instances", "limit of 1048576"],
    );
}

#[test]
fn gltf_accessors_are_checked_before_reading() {
    let d = gltf_case(|g| g["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(999));
    assert_refused(
        d.path(),
        &[],
        &[
            "m.gltf",
            "meshes[0].primitives[0].attributes.POSITION",
            "accessor 999 does not exist",
        ],
    );
    // POSITION as VEC2, and as unsigned bytes.
    let position = |g: &Value| {
        g["meshes"][0]["primitives"][0]["attributes"]["POSITION"]
            .as_u64()
            .unwrap() as usize
    };
    let d = gltf_case(|g| {
        let p = position(g);
        g["accessors"][p]["type"] = json!("VEC2");
    });
    assert_refused(
        d.path(),
        &[],
        &["POSITION", "element type is VEC2; expected VEC3"],
    );
    let d = gltf_case(|g| {
        let p = position(g);
        g["accessors"][p]["componentType"] = json!(5121);
    });
    assert_refused(
        d.path(),
        &[],
        &[
            "POSITION",
            "component type is UNSIGNED_BYTE; expected FLOAT",
        ],
    );
    // A count past the end of its buffer view, and a view past its buffer.
    let d = gltf_case(|g| {
        let p = position(g);
        g["accessors"][p]["count"] = json!(1u64 << 40);
    });
    assert_refused(d.path(), &[], &["POSITION", "but buffer view"]);
    let d = gltf_case(|g| g["bufferViews"][0]["byteOffset"] = json!(1u64 << 40));
    assert_refused(
        d.path(),
        &[],
        &["bufferViews[0]", "past the end of buffer 0"],
    );
    let d = gltf_case(|g| g["buffers"][0]["byteLength"] = json!(1u64 << 40));
    assert_refused(
        d.path(),
        &[],
        &["buffers[0].uri", "1099511627776 bytes are declared"],
    );
}

#[test]
fn glb_length_fields_are_checked_against_the_file() {
    for length in [0u32, u32::MAX] {
        let dir = tempfile::tempdir().unwrap();
        let mut glb = Vec::new();
        glb.extend(b"glTF");
        glb.extend(2u32.to_le_bytes());
        glb.extend(length.to_le_bytes());
        glb.extend(u32::MAX.to_le_bytes());
        glb.extend(b"JSON{}");
        std::fs::write(dir.path().join("m.glb"), glb).unwrap();
        mesh_scene(dir.path(), "m.glb");
        assert_refused(dir.path(), &[], &["m.glb", "GLB: the header says"]);
    }
}

#[test]
fn gltf_values_out_of_range_are_clamped_or_refused() {
    // The specification bounds factors to [0, 1]: clamped, with a warning.
    let d = gltf_case(|g| {
        g["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"] = json!([-1, 0.5, 2, 1]);
        g["materials"][0]["pbrMetallicRoughness"]["metallicFactor"] = json!(5);
    });
    let o = prism(d.path(), &["render", "scene.toml", "-o", "out.exr"]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(0), "{err}");
    assert!(
        err.contains(
            "materials[0].pbrMetallicRoughness.baseColorFactor[0]: -1 is outside [0, 1]; clamped"
        ),
        "{err}"
    );
    assert!(
        err.contains("metallicFactor: 5 is outside [0, 1]; clamped"),
        "{err}"
    );
    let img = image::open(d.path().join("out.exr")).unwrap().to_rgb32f();
    assert!(
        img.pixels()
            .all(|p| p.0.iter().all(|c| c.is_finite() && *c >= 0.0))
    );
    // Light intensities and camera fields of view are refused.
    for (intensity, want) in [
        (json!(-1), "intensity: -1"),
        (json!(1e39), "intensity: inf"),
    ] {
        let d = gltf_case(|g| {
            g["extensions"]["KHR_lights_punctual"]["lights"][0]["intensity"] = intensity
        });
        assert_refused(
            d.path(),
            &[],
            &["extensions.KHR_lights_punctual.lights[0]", want],
        );
    }
    for yfov in [0.0, 4.0] {
        let d = gltf_case(|g| g["cameras"][0]["perspective"]["yfov"] = json!(yfov));
        assert_refused(
            d.path(),
            &[],
            &["cameras[0].perspective.yfov", "between 0 and π"],
        );
    }
}

#[test]
fn a_scene_reads_only_below_its_folder_unless_allowed() {
    // A glTF buffer at file:///etc/passwd.
    let d = gltf_case(|g| g["buffers"][0]["uri"] = json!("file:///etc/passwd"));
    assert_refused(
        d.path(),
        &[],
        &["buffers[0].uri", "/etc/passwd", "--allow-read"],
    );
    // An OBJ naming mtllib /etc/passwd.
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("m.obj"),
        "mtllib /etc/passwd\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    mesh_scene(dir.path(), "m.obj");
    assert_refused(dir.path(), &[], &["/etc/passwd", "refused", "--allow-read"]);
    // A model path leading out with ../.. ; allowed with --allow-read.
    let outer = tempfile::tempdir().unwrap();
    let inner = outer.path().join("scene");
    std::fs::create_dir(&inner).unwrap();
    std::fs::copy(
        models_dir().join("icosphere.ply"),
        outer.path().join("ball.ply"),
    )
    .unwrap();
    mesh_scene(&inner, "../ball.ply");
    assert_refused(&inner, &[], &["ball.ply", "refused"]);
    let o = prism(
        &inner,
        &[
            "check",
            "scene.toml",
            "--allow-read",
            outer.path().to_str().unwrap(),
        ],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    // A device named as a model, through a link in the scene's folder.
    #[cfg(unix)]
    {
        let dir = tempfile::tempdir().unwrap();
        std::os::unix::fs::symlink("/dev/zero", dir.path().join("zero.ply")).unwrap();
        mesh_scene(dir.path(), "zero.ply");
        assert_refused(dir.path(), &[], &["zero.ply", "refused"]);
        assert_refused(
            dir.path(),
            &["--allow-read", "/dev"],
            &["zero.ply", "not a regular file"],
        );
    }
}

#[test]
fn mtl_values_are_checked_with_file_and_line() {
    for (line, want) in [
        ("Ns nan", "not a finite number"),
        ("Kd -5 0 0", "out of range"),
        ("Ni 0", "greater than 0"),
    ] {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("m.obj"),
            "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n",
        )
        .unwrap();
        std::fs::write(
            dir.path().join("m.mtl"),
            format!("newmtl a\nKd 1 1 1\n{line}\n"),
        )
        .unwrap();
        mesh_scene(dir.path(), "m.obj");
        assert_refused(dir.path(), &[], &["m.mtl:3:", want]);
    }
    // usemtl naming no material: a warning with its line, and a picture.
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("m.obj"),
        "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl missing\nf 1 2 3\n",
    )
    .unwrap();
    std::fs::write(dir.path().join("m.mtl"), "newmtl a\nKd 1 1 1\n").unwrap();
    mesh_scene(dir.path(), "m.obj");
    let o = prism(dir.path(), &["render", "scene.toml", "-o", "out.png"]);
    assert_eq!(o.status.code(), Some(0));
    assert!(
        stderr(&o).contains("m.obj:5: usemtl `missing`"),
        "{}",
        stderr(&o)
    );
}

/// A PNG of `side`² black pixels: a few hundred KB that decode to gigabytes.
fn huge_png(path: &Path, side: u32) {
    let file = std::fs::File::create(path).unwrap();
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), side, side);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_compression(png::Compression::High);
    let mut writer = encoder.write_header().unwrap();
    let mut stream = writer.stream_writer().unwrap();
    let row = vec![0u8; side as usize * 3];
    for _ in 0..side {
        std::io::Write::write_all(&mut stream, &row).unwrap();
    }
    stream.finish().unwrap();
}

#[test]
fn textures_are_refused_over_the_budget_before_decoding() {
    let dir = tempfile::tempdir().unwrap();
    huge_png(&dir.path().join("huge.png"), 22_000);
    assert!(
        std::fs::metadata(dir.path().join("huge.png"))
            .unwrap()
            .len()
            < 2_000_000
    );
    let scene = "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n\
                 [materials.m]\ntexture = \"huge.png\"\n\
                 [[objects]]\ntype = \"sphere\"\nmaterial = \"m\"\n";
    std::fs::write(dir.path().join("scene.toml"), scene).unwrap();
    let err = assert_refused(
        dir.path(),
        &[],
        &["huge.png", "texture budget", "--texture-memory"],
    );
    assert!(err.contains("scene.toml:5:"), "{err}");
}

#[test]
fn a_texture_used_by_four_materials_is_decoded_once() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(models_dir().join("tile.png"), dir.path().join("tile.png")).unwrap();
    let mut scene = String::from("[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n");
    for i in 0..4 {
        scene += &format!(
            "[materials.m{i}]\ntexture = \"tile.png\"\n[[objects]]\ntype = \"sphere\"\nmaterial = \"m{i}\"\ncenter = [{i}, 0, 0]\n"
        );
    }
    std::fs::write(dir.path().join("scene.toml"), scene).unwrap();
    let s = prism::Scene::load(&dir.path().join("scene.toml")).unwrap();
    let images: Vec<_> = s
        .materials
        .iter()
        .map(|m| match &m.texture {
            prism::shading::Texture::Image { image, .. } => image.clone(),
            other => panic!("{other:?}"),
        })
        .collect();
    assert!(images.iter().all(|i| std::sync::Arc::ptr_eq(i, &images[0])));
}

/// Sends `signals` (e.g. ["TERM"], ["INT", "INT"]) to a render `delay_ms`
/// after it starts; whatever the moment, the output is the old file or the
/// complete new image, and no temporary file remains.
fn signal_during_render(dir: &Path, delay_ms: u64, signals: &[&str]) {
    let out = dir.join("out.exr");
    std::fs::write(&out, b"old").unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_prism"))
        .args([
            "render", "-o", "out.exr", "--width", "1600", "--height", "1200", "--spp", "1",
            "--quiet",
        ])
        .current_dir(dir)
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(delay_ms));
    for s in signals {
        let _ = Command::new("kill")
            .args([format!("-{s}"), child.id().to_string()])
            .status();
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    let status = child.wait().unwrap();
    let bytes = std::fs::read(&out).unwrap();
    if bytes != b"old" {
        let img = image::load_from_memory(&bytes).expect("a complete image");
        assert_eq!((img.width(), img.height()), (1600, 1200));
    } else {
        // 130, or killed outright by a signal that came before the handler
        // was installed.
        assert!(
            matches!(status.code(), Some(130) | None),
            "{signals:?} after {delay_ms} ms: {status:?}"
        );
    }
    let leftovers: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n != "out.exr")
        .collect();
    assert!(
        leftovers.is_empty(),
        "{signals:?} after {delay_ms} ms left {leftovers:?}"
    );
}

#[test]
fn signals_at_any_moment_leave_the_old_file_or_the_new_one() {
    let dir = tempfile::tempdir().unwrap();
    for delay in [0, 20, 60, 120, 200, 300, 450, 600, 800] {
        for signals in [&["TERM"][..], &["HUP"], &["INT", "INT"]] {
            signal_during_render(dir.path(), delay, signals);
        }
    }
}

#[test]
fn messages_say_what_is_wrong_in_a_readable_length() {
    let dir = tempfile::tempdir().unwrap();
    // A model named where the scene belongs.
    std::fs::copy(
        models_dir().join("icosphere.ply"),
        dir.path().join("ball.ply"),
    )
    .unwrap();
    let o = prism(dir.path(), &["render", "ball.ply", "-o", "out.png"]);
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert!(
        err.contains("ball.ply:1:1: error: this is a .ply model, not a scene"),
        "{err}"
    );
    assert!(
        err.contains("type = \"mesh\"") && err.lines().count() == 1,
        "{err}"
    );
    // A duplicate key is named.
    std::fs::write(
        dir.path().join("scene.toml"),
        "[camera]\nposition = [0, 0, 5]\nposition = [0, 0, 6]\n",
    )
    .unwrap();
    let err = assert_refused(
        dir.path(),
        &[],
        &["scene.toml:3:1:", "duplicate key `position`"],
    );
    assert_eq!(err.lines().count(), 1, "{err}");
    // A huge value is not echoed whole.
    let long = "x".repeat(1_000_000);
    std::fs::write(
        dir.path().join("scene.toml"),
        format!("[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\ntype = \"{long}\"\n"),
    )
    .unwrap();
    assert_refused(dir.path(), &[], &["scene.toml:4:", "(cut)"]);
    // A model that fails to load is reported, not a missing camera it may
    // have brought.
    std::fs::write(dir.path().join("bad.gltf"), "{ not json").unwrap();
    std::fs::write(
        dir.path().join("scene.toml"),
        "[[objects]]\ntype = \"mesh\"\nfile = \"bad.gltf\"\n",
    )
    .unwrap();
    let err = assert_refused(dir.path(), &[], &["bad.gltf", "not valid glTF JSON"]);
    assert!(!err.contains("missing [camera]"), "{err}");
}

#[test]
fn check_reports_what_the_scene_holds() {
    let o = prism(
        Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")),
        &["check", "scenes/models.toml"],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    for want in [
        "5 mesh instances",
        "3 stored (1294 triangles), 3854 triangles placed",
        "textures: 1",
        "estimated memory:",
        "load ",
        "build ",
    ] {
        assert!(out.contains(want), "want {want:?} in:\n{out}");
    }
}

#[test]
fn out_of_range_model_placements_are_errors_not_silently_moved_or_dropped() {
    // A glTF node scaled past the range: refused, not placed untransformed.
    let d = gltf_case(|g| g["nodes"][0]["scale"] = json!([1e31, 1, 1]));
    assert_refused(
        d.path(),
        &[],
        &["m.gltf", "node's transform is singular or out of range"],
    );
    // An object transform that takes the model past ±1e30: refused, not dropped.
    let d = gltf_case(|_| {});
    let scene = std::fs::read_to_string(d.path().join("scene.toml")).unwrap()
        + "transform = [{ scale = 1e20 }, { translate = [1e29, 0, 0] }, { scale = 1e5 }]\n";
    std::fs::write(d.path().join("scene.toml"), scene).unwrap();
    assert_refused(d.path(), &[], &["objects[0]", "out of range"]);
}

/// A valid scene of `n` small spheres in `[[objects]]` tables.
fn many_spheres(n: usize) -> String {
    let mut s = String::from(
        "[render]\nwidth = 8\nheight = 6\nspp = 1\n\
         [camera]\nposition = [0, 0, 30]\nlook_at = [0, 0, 0]\n\
         [materials.m]\ncolor = [0.8, 0.8, 0.8]\n\
         [lights.l]\ntype = \"point\"\nposition = [10, 20, 30]\n",
    );
    for i in 0..n {
        let x = (i as f64 * 0.618_034).fract() * 20.0 - 10.0;
        let y = (i as f64 * 0.414_214).fract() * 20.0 - 10.0;
        s.push_str(&format!(
            "[[objects]]\ntype = \"sphere\"\nmaterial = \"m\"\ncenter = [{x:.4}, {y:.4}, 0]\nradius = 0.01\n"
        ));
    }
    s
}

#[test]
fn large_scene_text_is_read_table_by_table_within_limits() {
    let dir = tempfile::tempdir().unwrap();
    // An object whose table is larger than 16 MiB (a polygon of a million
    // vertices, 23 MB) is refused before it is parsed, with its line.
    let mut s = many_spheres(2);
    s.push_str("[[objects]]\ntype = \"polygon\"\nmaterial = \"m\"\nvertices = [\n");
    for i in 0..1_000_000 {
        s.push_str(&format!("[{i}.25, 0.5, 0.75],\n"));
    }
    s.push_str("]\n");
    std::fs::write(dir.path().join("scene.toml"), &s).unwrap();
    let line = many_spheres(2).lines().count() + 1;
    let err = assert_refused(
        dir.path(),
        &[],
        &[
            &format!("scene.toml:{line}:1"),
            "MiB of text; at most 16 MiB",
            "model file",
        ],
    );
    assert_eq!(
        err.lines().filter(|l| l.contains("error")).count(),
        1,
        "{err}"
    );

    // 20,000 spheres: loads, and a syntax error in one table and a bad
    // value in another are both reported, each at its own line.
    let good = many_spheres(20_000);
    std::fs::write(dir.path().join("scene.toml"), &good).unwrap();
    let o = prism(dir.path(), &["check", "scene.toml"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let bad = good
        .replacen(
            "radius = 0.01\n[[objects]]",
            "radius = 0.01\n[[objects]]\n= 3",
            1,
        )
        .replacen("radius = 0.01", "radius = 0.01\nradius = 2", 1);
    std::fs::write(dir.path().join("scene.toml"), &bad).unwrap();
    let first = bad.lines().position(|l| l == "radius = 2").unwrap() + 1;
    let second = bad.lines().position(|l| l == "= 3").unwrap() + 1;
    let err = assert_refused(
        dir.path(),
        &[],
        &[
            &format!("scene.toml:{first}:1: error: duplicate key `radius`"),
            &format!("scene.toml:{second}:1"),
        ],
    );
    assert_eq!(
        err.lines().filter(|l| l.contains("error")).count(),
        2,
        "{err}"
    );
}
