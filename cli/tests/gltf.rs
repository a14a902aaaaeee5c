//! `prism render|check|explain model.gltf`: a glTF file is a scene, with
//! its own camera (and its shape), lights, `--camera` and `--exposure`.

use std::path::Path;
use std::process::{Command, Output};

fn prism(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_prism"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("prism runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The example glTF (two pyramids, a camera made for 1.6:1, a point
/// light) copied into a new folder.
fn pyramids() -> tempfile::TempDir {
    let models = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/models");
    let dir = tempfile::tempdir().unwrap();
    for f in ["pyramids.gltf", "pyramid.bin"] {
        std::fs::copy(models.join(f), dir.path().join(f)).unwrap();
    }
    dir
}

/// (width, height, 8-bit RGB pixels) of a PNG.
fn read_png(path: &Path) -> (u32, u32, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

#[test]
fn a_gltf_file_renders_checks_and_explains_without_a_scene_file() {
    let dir = pyramids();
    let o = prism(&["check", "pyramids.gltf"], dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    // --width alone: the camera's 1.6:1 gives the height.
    let o = prism(
        &[
            "render",
            "pyramids.gltf",
            "--width",
            "32",
            "--spp",
            "1",
            "-o",
            "a.png",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let (w, h, plain) = read_png(&dir.path().join("a.png"));
    assert_eq!((w, h), (32, 20));
    // Two stops brighter before the 8-bit encoding.
    let o = prism(
        &[
            "render",
            "pyramids.gltf",
            "--width",
            "32",
            "--spp",
            "1",
            "--exposure",
            "2",
            "-o",
            "b.png",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let (_, _, bright) = read_png(&dir.path().join("b.png"));
    let sum = |p: &[u8]| p.iter().map(|&v| u64::from(v)).sum::<u64>();
    assert!(sum(&bright) > sum(&plain), "exposure +2 brightens");
    // A darker exposure is a negative number, not an option.
    let o = prism(
        &[
            "render",
            "pyramids.gltf",
            "--width",
            "8",
            "--spp",
            "1",
            "--exposure",
            "-1",
            "-o",
            "c.png",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let o = prism(
        &["explain", "pyramids.gltf", "--pixel", "320,200"],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn an_unknown_camera_name_is_refused_naming_the_cameras() {
    let dir = pyramids();
    let o = prism(
        &["render", "pyramids.gltf", "--camera", "Nope", "-o", "x.png"],
        dir.path(),
    );
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("pyramids.gltf:1:1: error: --camera Nope"),
        "{err}"
    );
    assert!(err.contains("`camera`"), "{err}");
    assert!(!dir.path().join("x.png").exists());
    let o = prism(
        &[
            "render",
            "pyramids.gltf",
            "--camera",
            "camera",
            "--width",
            "8",
            "--spp",
            "1",
            "-o",
            "x.png",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn explain_shows_a_spot_lights_cone_and_a_camera_less_file_is_refused() {
    let dir = pyramids();
    let path = dir.path().join("pyramids.gltf");
    let text = std::fs::read_to_string(&path).unwrap();
    // The lamp becomes a spot pointing down −z, its cone 86° wide.
    let spot = text.replacen(
        "\"type\": \"point\",",
        "\"type\": \"spot\", \"spot\": {\"outerConeAngle\": 1.5},",
        1,
    );
    std::fs::write(&path, &spot).unwrap();
    // A pixel on the left pyramid.
    let o = prism(
        &["explain", "pyramids.gltf", "--pixel", "220,180"],
        dir.path(),
    );
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(out.contains("(spot: its cone sends 0."), "{out}");
    // Without its camera node the file cannot be rendered alone.
    let no_camera = spot.replacen("\"camera\": 0,", "", 1);
    std::fs::write(&path, no_camera).unwrap();
    let o = prism(&["check", "pyramids.gltf"], dir.path());
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("pyramids.gltf:1:1: error: the file has no camera"),
        "{err}"
    );
}
