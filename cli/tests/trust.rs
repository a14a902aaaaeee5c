//! Trust (issue 26): parts and checkpoints know every option that changes
//! a pixel; names from files never reach the terminal raw; errors name the
//! real cause; reads are bounded by what a file declares and by the
//! documented limits; only regular files are read.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use serde_json::{Value, json};

fn prism(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_prism"))
        .args(args)
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

/// The example pyramids glTF with a second camera `top` (looking down),
/// edited by `edit`, written as `m.gltf` in a new folder with its buffer.
fn two_cameras(edit: impl FnOnce(&mut Value)) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(
        models_dir().join("pyramid.bin"),
        dir.path().join("pyramid.bin"),
    )
    .unwrap();
    let mut g: Value =
        serde_json::from_str(&std::fs::read_to_string(models_dir().join("pyramids.gltf")).unwrap())
            .unwrap();
    let nodes = g["nodes"].as_array_mut().unwrap();
    let first_camera = nodes
        .iter()
        .position(|n| n.get("camera").is_some())
        .unwrap();
    nodes[first_camera]["name"] = json!("cam");
    nodes.push(json!({
        "camera": 0, "name": "top上", "translation": [0, 6, 0.01],
        "rotation": [-std::f64::consts::FRAC_1_SQRT_2, 0, 0, std::f64::consts::FRAC_1_SQRT_2]
    }));
    let top = nodes.len() - 1;
    g["scenes"][0]["nodes"]
        .as_array_mut()
        .unwrap()
        .push(json!(top));
    edit(&mut g);
    std::fs::write(
        dir.path().join("m.gltf"),
        serde_json::to_string(&g).unwrap(),
    )
    .unwrap();
    dir
}

/// The long options `prism render --help` lists.
fn render_options() -> Vec<String> {
    let o = prism(Path::new("."), &["render", "--help"]);
    let help = String::from_utf8_lossy(&o.stdout);
    let mut found: Vec<String> = help
        .lines()
        .filter_map(|l| {
            let l = l.trim_start();
            // `-o, --output <OUTPUT>`: the short form first.
            let l = match l.as_bytes() {
                [b'-', c, b',', b' ', ..] if *c != b'-' => &l[4..],
                _ => l,
            };
            let name = l.strip_prefix("--")?;
            Some(name.split([' ', '=', '<']).next()?.to_string())
        })
        .collect();
    found.sort();
    found.dedup();
    found
}

/// Every option of `prism render` that changes a pixel, with two values
/// and the name a refusal must give it.
const PIXEL_OPTIONS: &[(&str, &str, &str, &str)] = &[
    ("camera", "cam", "top上", "camera"),
    ("width", "48", "40", "size"),
    ("height", "30", "24", "size"),
    ("spp", "1", "2", "spp"),
    ("max-depth", "3", "5", "max_depth"),
    ("seed", "1", "2", "seed"),
    ("exposure", "0", "2", "exposure"),
    ("frame", "1", "2", "frame"),
    ("frames", "1-1", "2-2", "frame"),
    ("aov", "normal", "depth", "aov"),
];

/// Options that change no pixel (or choose which pixels: a region), each
/// with why.
const OTHER_OPTIONS: &[(&str, &str)] = &[
    ("output", "where the image goes"),
    ("threads", "the same bits on any number of threads"),
    (
        "crop",
        "a region: parts of other regions merge; overlaps are refused",
    ),
    ("tile", "a region, as --crop"),
    ("checkpoint", "where tiles are kept"),
    ("display-server", "a viewer watching"),
    ("quiet", "messages only"),
    ("allow-read", "what may be read; a refused read is an error"),
    ("texture-memory", "a budget; over it is an error"),
    ("help", "help"),
];

#[test]
fn every_render_option_is_known_to_change_pixels_or_not() {
    let mut known: Vec<String> = PIXEL_OPTIONS
        .iter()
        .map(|o| o.0)
        .chain(OTHER_OPTIONS.iter().map(|o| o.0))
        .map(str::to_string)
        .collect();
    known.sort();
    known.dedup();
    // A new option fails here until it is placed in one list (and, if it
    // changes pixels, proven to key parts and checkpoints below).
    assert_eq!(render_options(), known);
}

/// The base arguments of a part: a small image, fast.
fn base_args(option: &str) -> Vec<String> {
    let mut args: Vec<String> = vec!["render".into(), "m.gltf".into()];
    for (k, v) in [("width", "48"), ("height", "30"), ("spp", "1")] {
        if k != option {
            args.extend([format!("--{k}"), v.into()]);
        }
    }
    args
}

#[test]
fn parts_of_two_values_of_any_pixel_option_are_refused_naming_it() {
    let dir = two_cameras(|_| {});
    let d = dir.path();
    for &(option, a, b, name) in PIXEL_OPTIONS {
        for (i, value) in [a, b].into_iter().enumerate() {
            let mut args = base_args(option);
            args.extend([
                format!("--{option}"),
                value.into(),
                "--tile".into(),
                format!("{i}/2"),
                "-o".into(),
                format!("part{i}.exr"),
            ]);
            let args: Vec<&str> = args.iter().map(String::as_str).collect();
            let o = prism(d, &args);
            assert!(o.status.success(), "--{option} {value}: {}", stderr(&o));
        }
        let o = prism(d, &["merge", "part0.exr", "part1.exr", "-o", "whole.exr"]);
        let err = stderr(&o);
        assert_eq!(
            o.status.code(),
            Some(2),
            "--{option} {a} and {b} merged: {err}"
        );
        assert!(
            err.contains(&format!("its {name} is")),
            "--{option}: the refusal names `{name}`: {err}"
        );
        assert!(!d.join("whole.exr").exists());
    }
    // The same option values merge (the test can fail only on the key).
    for i in 0..2 {
        let mut args = base_args("");
        args.extend([
            "--camera".into(),
            "top上".into(),
            "--tile".into(),
            format!("{i}/2"),
        ]);
        args.extend(["-o".into(), format!("part{i}.exr")]);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        assert!(prism(d, &args).status.success());
    }
    let o = prism(d, &["merge", "part0.exr", "part1.exr", "-o", "whole.exr"]);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// Starts a render with a checkpoint in `ck` and kills it once the
/// checkpoint's manifest is written (before it can finish).
fn killed_with_checkpoint(d: &Path, args: &[String], ck: &str) {
    let mut args = args.to_vec();
    args.extend([
        "--checkpoint".into(),
        ck.into(),
        "-o".into(),
        "out.png".into(),
    ]);
    args.extend(["--threads".into(), "1".into()]);
    let mut child = Command::new(env!("CARGO_BIN_EXE_prism"))
        .args(&args)
        .current_dir(d)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let manifest = d.join(ck).join("checkpoint.txt");
    let start = Instant::now();
    while !manifest.exists() && start.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(5));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(manifest.exists(), "{args:?}: the checkpoint is left");
}

#[test]
fn a_checkpoint_refuses_a_resume_with_another_value_of_any_pixel_option() {
    let dir = two_cameras(|_| {});
    let d = dir.path();
    for &(option, a, b, name) in PIXEL_OPTIONS {
        if option == "frames" {
            // Each frame of --frames has its own folder: its key is --frame's.
            continue;
        }
        let ck = format!("ck-{option}");
        // Slow enough to be killed mid-render: many samples on one thread.
        let slow = |value: &str| {
            let mut args: Vec<String> = vec!["render".into(), "m.gltf".into()];
            for (k, v) in [("width", "96"), ("height", "60"), ("spp", "1024")] {
                if k != option {
                    args.extend([format!("--{k}"), v.into()]);
                }
            }
            let value = match (option, value) {
                ("spp", "1") => "1024",
                ("spp", _) => "2048",
                _ => value,
            };
            args.extend([format!("--{option}"), value.to_string()]);
            args
        };
        killed_with_checkpoint(d, &slow(a), &ck);
        let mut resume = slow(b);
        resume.extend([
            "--checkpoint".into(),
            ck.clone(),
            "-o".into(),
            "other.png".into(),
        ]);
        let resume: Vec<&str> = resume.iter().map(String::as_str).collect();
        let o = prism(d, &resume);
        let err = stderr(&o);
        assert_eq!(
            o.status.code(),
            Some(2),
            "--{option} {b} resumed {a}'s checkpoint: {err}"
        );
        assert!(err.contains(&format!("its {name} is")), "--{option}: {err}");
        assert!(!d.join("other.png").exists());
    }
}

/// Every C0 and C1 control character, DEL, and the ANSI sequences that set
/// the title, clear the screen and forge a line.
fn hostile_name(tag: &str) -> String {
    let mut s = format!("{tag}\u{1b}]0;pwned\u{7}\u{1b}[2J\rX\nFAKE: error ");
    s.extend((0u32..0x20).chain(0x7f..0xa0).filter_map(char::from_u32));
    s.push('\u{202e}');
    s
}

/// Asserts no raw control character (but the newlines between lines) and
/// no forged line in `text`.
fn assert_clean(text: &str, what: &str) {
    for line in text.lines() {
        assert!(!line.starts_with("FAKE"), "{what}: a forged line: {text:?}");
        assert!(
            !line.chars().any(prism::text::is_unsafe_on_terminal),
            "{what}: a raw control character in {line:?}"
        );
    }
}

#[test]
fn names_from_files_and_arguments_never_reach_the_terminal_raw() {
    // glTF: camera node, the camera's own name, node, material, image, and
    // an unknown --camera.
    let dir = two_cameras(|g| {
        g["nodes"][2]["name"] = json!(hostile_name("camnode"));
        g["cameras"][0]["name"] = json!(hostile_name("camera"));
        g["nodes"][0]["name"] = json!(hostile_name("node"));
        g["materials"][0]["name"] = json!(hostile_name("material"));
        g["images"] = json!([{ "uri": "missing.png", "name": hostile_name("image") }]);
        g["textures"] = json!([{ "source": 0 }]);
        g["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": 0 });
    });
    let d = dir.path();
    // An argument cannot hold NUL.
    let hostile_arg = hostile_name("arg").replace('\0', "");
    for args in [
        vec!["check", "m.gltf"],
        vec![
            "render", "m.gltf", "--width", "8", "--spp", "1", "-o", "a.png",
        ],
        vec!["render", "m.gltf", "--camera", &hostile_arg, "-o", "a.png"],
        vec!["explain", "m.gltf", "--pixel", "4,4"],
        vec!["render", "m.gltf", "-o", &hostile_arg],
        vec!["merge", &hostile_arg, "-o", "x.exr"],
        vec!["render", "m.gltf", "--threads", &hostile_arg],
    ] {
        let o = prism(d, &args);
        assert_clean(&stderr(&o), &format!("{args:?} stderr"));
        assert_clean(
            &String::from_utf8_lossy(&o.stdout),
            &format!("{args:?} stdout"),
        );
    }
    // The image's failure names the image; without the image, the names
    // reach the render's warnings and explain.
    let dir = two_cameras(|g| {
        g["nodes"][2]["name"] = json!(hostile_name("camnode"));
        g["materials"][0]["name"] = json!(hostile_name("material"));
        g["nodes"][0]["name"] = json!(hostile_name("node"));
    });
    let d = dir.path();
    for args in [
        vec!["check", "m.gltf"],
        vec![
            "render", "m.gltf", "--width", "8", "--spp", "1", "-o", "a.png",
        ],
        vec!["explain", "m.gltf", "--pixel", "24,14", "--width", "48"],
        vec![
            "explain", "m.gltf", "--pixel", "24,14", "--width", "48", "--json",
        ],
    ] {
        let o = prism(d, &args);
        let (out, err) = (String::from_utf8_lossy(&o.stdout), stderr(&o));
        assert!(o.status.success(), "{args:?}: {err}");
        assert_clean(&err, &format!("{args:?} stderr"));
        assert_clean(&out, &format!("{args:?} stdout"));
    }
    // The two cameras warning quotes the camera node's name, escaped.
    let o = prism(d, &["check", "m.gltf"]);
    assert!(
        stderr(&o).contains("camnode\\u{1b}]0;pwned\\u{7}"),
        "{}",
        stderr(&o)
    );

    // OBJ + MTL (object, group and material names, the MTL file name),
    // PLY comments and element names, TOML keys and values.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let name = hostile_name("mtl");
    std::fs::write(
        d.join("m.mtl"),
        format!("newmtl {name}\nKd 0.5 0.5 0.5\nmap_Kd {name}.png\n"),
    )
    .unwrap();
    std::fs::write(
        d.join("m.obj"),
        format!(
            "mtllib m.mtl\no {0}\ng {0}\nusemtl {0}\nusemtl {1}\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
            name,
            hostile_name("unknown")
        ),
    )
    .unwrap();
    std::fs::write(
        d.join("m.ply"),
        format!(
            "ply\nformat ascii 1.0\ncomment {0}\nelement vertex 3\nproperty float x\n\
             property float y\nproperty float z\nelement face 1\nproperty list uchar int \
             vertex_indices\nelement {1} 0\nproperty float q\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
            hostile_name("comment").replace('\n', " "),
            "x\u{1b}[2J"
        ),
    )
    .unwrap();
    let toml_name = toml::Value::String(hostile_name("toml")).to_string();
    for (model, extra) in [("m.obj", ""), ("m.ply", ""), ("m.obj", "bogus = 1\n")] {
        std::fs::write(
            d.join("s.toml"),
            format!(
                "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n\
                 [lights.{toml_name}]\ntype = \"point\"\nposition = [1, 1, 5]\n\
                 [materials.{toml_name}]\ncolor = [1, 1, 1]\n{extra}\
                 [[objects]]\ntype = \"mesh\"\nfile = \"{model}\"\nname = {toml_name}\n\
                 [[objects]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 0.1\n\
                 material = {toml_name}\n[[objects]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\n\
                 radius = -1\nmaterial = {}\n",
                toml::Value::String(hostile_name("nosuch"))
            ),
        )
        .unwrap();
        for args in [
            vec!["check", "s.toml"],
            vec![
                "render", "s.toml", "--width", "8", "--height", "8", "-o", "a.png",
            ],
            vec!["explain", "s.toml", "--pixel", "4,4"],
        ] {
            let o = prism(d, &args);
            assert_clean(&stderr(&o), &format!("{model} {args:?} stderr"));
            assert_clean(
                &String::from_utf8_lossy(&o.stdout),
                &format!("{model} {args:?} stdout"),
            );
        }
    }
}

/// The Blender add-on's escape is the library's, character for character.
#[test]
fn the_blender_addons_escape_is_the_librarys() {
    let every: String = (1u32..0x2100).filter_map(char::from_u32).collect();
    let script = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../blender/prism_render/text.py"
    ));
    let Ok(o) = Command::new("python3")
        .args([
            "-c",
            "import sys, importlib.util as u\n\
             s = u.spec_from_file_location('t', sys.argv[1]); m = u.module_from_spec(s)\n\
             s.loader.exec_module(m)\n\
             sys.stdout.write(m.escape_controls(sys.stdin.read()))",
        ])
        .arg(script)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .and_then(|mut child| {
            use std::io::Write;
            child.stdin.take().unwrap().write_all(every.as_bytes())?;
            child.wait_with_output()
        })
    else {
        // Every machine Prism is tested on has CPython (the Python tests
        // need it): a missing one is a failure, not a silent pass.
        panic!("python3 is needed to compare the add-on's escape with the library's");
    };
    assert!(o.status.success());
    assert_eq!(
        String::from_utf8(o.stdout).unwrap(),
        prism::text::escape_controls(&every)
    );
}

#[test]
fn errors_name_the_real_cause_once() {
    let dir = two_cameras(|_| {});
    let d = dir.path();
    let o = prism(
        d,
        &["render", "m.gltf", "--camera", "nosuch", "-o", "a.png"],
    );
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        err.contains("--camera nosuch: no model camera has that name"),
        "{err}"
    );
    assert!(err.contains("`cam`") && err.contains("`top上`"), "{err}");
    assert!(!err.contains("has no camera"), "one true thing: {err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    // NaN normals and texture coordinates: one error, at the accessor.
    for (attribute, what) in [("NORMAL", "normal"), ("TEXCOORD_0", "coordinate")] {
        let dir = two_cameras(|_| {});
        let d = dir.path();
        let mut bin = std::fs::read(d.join("pyramid.bin")).unwrap();
        let mut g: Value =
            serde_json::from_str(&std::fs::read_to_string(d.join("m.gltf")).unwrap()).unwrap();
        // Normals are accessor 1 (bytes 216..432); texture coordinates
        // get an accessor of their own over the same bytes.
        if attribute == "TEXCOORD_0" {
            g["accessors"].as_array_mut().unwrap().push(json!({
                "bufferView": 1, "componentType": 5126, "count": 18, "type": "VEC2"
            }));
            g["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = json!(3);
            let attributes = g["meshes"][0]["primitives"][0]["attributes"].as_object_mut();
            attributes.unwrap().remove("NORMAL");
        }
        bin[216..220].copy_from_slice(&f32::NAN.to_le_bytes());
        std::fs::write(d.join("pyramid.bin"), bin).unwrap();
        std::fs::write(d.join("m.gltf"), g.to_string()).unwrap();
        let o = prism(d, &["render", "m.gltf", "-o", "a.png"]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(
            err.contains(&format!(
                "meshes[0].primitives[0].attributes.{attribute}: {what} 0 is not finite"
            )),
            "{err}"
        );
        assert!(!err.contains("camera"), "{err}");
        assert_eq!(err.lines().count(), 1, "{err}");
    }
}

#[test]
fn a_buffer_is_read_to_its_declared_length_only() {
    // The buffer file is far longer than its byteLength: only the declared
    // bytes are read, so appending to the file changes nothing.
    let dir = two_cameras(|_| {});
    let d = dir.path();
    let render = |out: &str| {
        let o = prism(
            d,
            &["render", "m.gltf", "--width", "16", "--spp", "1", "-o", out],
        );
        assert!(o.status.success(), "{}", stderr(&o));
        std::fs::read(d.join(out)).unwrap()
    };
    let before = render("a.exr");
    let bin = d.join("pyramid.bin");
    let f = std::fs::OpenOptions::new().append(true).open(&bin).unwrap();
    // Past the most Prism reads of a whole file (sparse: no disk used):
    // only a read of the declared bytes can render.
    f.set_len(prism::limits::MAX_FILE_BYTES + 1).unwrap();
    assert_eq!(render("b.exr"), before, "the same scene hash and pixels");
    // Shorter than declared: refused, naming the buffer.
    std::fs::write(
        &bin,
        &std::fs::read(models_dir().join("pyramid.bin")).unwrap()[..100],
    )
    .unwrap();
    let o = prism(d, &["render", "m.gltf", "-o", "c.png"]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("buffers[0].uri") && err.contains("468 bytes are declared"),
        "{err}"
    );
}

#[test]
fn an_image_shape_derived_from_a_file_is_bounded() {
    let dir = two_cameras(|g| {
        g["cameras"][0]["perspective"]["aspectRatio"] = json!(1e-30);
    });
    let d = dir.path();
    let o = prism(d, &["render", "m.gltf", "--camera", "cam", "-o", "a.png"]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("--width") && err.contains("--height"), "{err}");
    assert!(!d.join("a.png").exists());
    // Both sides given: the user's shape, rendered.
    let o = prism(
        d,
        &[
            "render", "m.gltf", "--width", "8", "--height", "8", "--spp", "1", "-o", "a.png",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn vertex_colours_are_checked_as_other_values() {
    // COLOR_0 over the normals' bytes: +inf refused with its accessor path;
    // above 1 clamped with one warning for the file.
    for (value, refused) in [(f32::INFINITY, true), (1e30, false), (3.0, false)] {
        let dir = two_cameras(|g| {
            for m in 0..2 {
                let attributes = &mut g["meshes"][m]["primitives"][0]["attributes"];
                attributes["COLOR_0"] = json!(1);
                attributes.as_object_mut().unwrap().remove("NORMAL");
            }
        });
        let d = dir.path();
        let mut bin = std::fs::read(d.join("pyramid.bin")).unwrap();
        bin[220..224].copy_from_slice(&value.to_le_bytes());
        std::fs::write(d.join("pyramid.bin"), bin).unwrap();
        let o = prism(d, &["check", "m.gltf"]);
        let err = stderr(&o);
        if refused {
            assert_eq!(o.status.code(), Some(2), "{err}");
            assert!(
                err.contains("meshes[0].primitives[0].attributes.COLOR_0: colour 0 is not finite"),
                "{err}"
            );
        } else {
            assert!(o.status.success(), "{err}");
            assert_eq!(err.matches("COLOR_0").count(), 1, "one warning: {err}");
            assert!(err.contains("clamped"), "{err}");
        }
    }
    // A spot whose inner and outer cones are equal: a warning.
    let dir = two_cameras(|g| {
        g["extensions"]["KHR_lights_punctual"]["lights"][0] = json!({
            "type": "spot", "intensity": 100,
            "spot": { "innerConeAngle": 0.5, "outerConeAngle": 0.5 }
        });
    });
    let o = prism(dir.path(), &["check", "m.gltf"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("innerConeAngle equals outerConeAngle"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn only_regular_files_are_read_and_never_past_their_limit() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fifo = d.join("pipe.toml");
    let made = Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success());
    let mut cases = vec![
        ("/dev/zero".to_string(), "not a regular file"),
        (d.display().to_string(), "not a regular file"),
    ];
    if made {
        cases.push((fifo.display().to_string(), "not a regular file"));
        let glb = d.join("pipe.glb");
        Command::new("mkfifo").arg(&glb).status().unwrap();
        cases.push((glb.display().to_string(), "not a regular file"));
    }
    for (path, wanted) in cases {
        for cmd in ["render", "check"] {
            // A read that blocked on the FIFO would hang here.
            let o = prism(
                d,
                &[cmd, &path, "-o", "x.png"][..if cmd == "check" { 2 } else { 4 }],
            );
            let err = stderr(&o);
            assert_eq!(o.status.code(), Some(2), "{cmd} {path}: {err}");
            assert!(
                err.contains(wanted) && err.contains(&path),
                "{cmd} {path}: {err}"
            );
        }
    }
    // A model that is a device, a FIFO: refused, naming it.
    std::fs::write(
        d.join("s.toml"),
        "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n\
         [[objects]]\ntype = \"mesh\"\nfile = \"pipe.obj\"\n",
    )
    .unwrap();
    if made {
        Command::new("mkfifo")
            .arg(d.join("pipe.obj"))
            .status()
            .unwrap();
        let o = prism(d, &["check", "s.toml"]);
        assert_eq!(o.status.code(), Some(2));
        assert!(stderr(&o).contains("not a regular file"), "{}", stderr(&o));
    }
    // A scene file over its limit is refused after limit + 1 bytes (a
    // sparse file: nothing near its size is read).
    let big = d.join("big.toml");
    std::fs::File::create(&big)
        .unwrap()
        .set_len(prism::limits::MAX_SCENE_FILE_BYTES + 4096)
        .unwrap();
    let o = prism(d, &["check", "big.toml"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("larger than"), "{}", stderr(&o));
}
