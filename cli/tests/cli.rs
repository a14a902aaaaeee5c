//! The `prism` command end to end: bad input gives a located message and
//! exit code 2 and touches no output file; good input renders.

use std::path::{Path, PathBuf};
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

const GOOD: &str = r#"
[render]
width = 8
height = 6
spp = 1

[camera]
position = [0, 0, 5]
look_at = [0, 0, 0]

[materials.red]
color = [1, 0, 0]

[lights.key]
type = "point"
position = [2, 4, 5]

[[objects]]
type = "sphere"
material = "red"
radius = 1
"#;

/// Writes `scene`, renders it over an existing `out.png`, and checks the
/// failure: exit code 2, a message containing `line:col` and `expected`,
/// the old output untouched and no stray files.
fn assert_rejected(scene: &str, location: &str, expected: &str) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("scene.toml"), scene).unwrap();
    let out: PathBuf = dir.path().join("out.png");
    std::fs::write(&out, b"previous image").unwrap();
    let o = prism(&["render", "scene.toml", "-o", "out.png"], dir.path());
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains(&format!("scene.toml:{location}: error:")),
        "want {location}: {err}"
    );
    assert!(err.contains(expected), "want {expected:?}: {err}");
    assert!(
        !err.contains("panicked") && !err.contains("backtrace"),
        "{err}"
    );
    assert_eq!(std::fs::read(&out).unwrap(), b"previous image");
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        2,
        "no stray files"
    );
    // `check` agrees.
    let c = prism(&["check", "scene.toml"], dir.path());
    assert_eq!(c.status.code(), Some(2));
    assert_eq!(stderr(&c), err);
}

#[test]
fn good_scene_renders_and_checks() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("scene.toml"), GOOD).unwrap();
    let c = prism(&["check", "scene.toml"], dir.path());
    assert_eq!(c.status.code(), Some(0), "{}", stderr(&c));
    for name in ["a.png", "a.exr", "a.hdr", "a.ppm"] {
        let o = prism(
            &["render", "scene.toml", "-o", name, "--threads", "2"],
            dir.path(),
        );
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let img = image::open(dir.path().join(name)).unwrap();
        assert_eq!((img.width(), img.height()), (8, 6));
        // Summary line: resolution, rays by kind, Mrays/s.
        let err = stderr(&o);
        assert!(
            err.contains("8x6")
                && err.contains("camera")
                && err.contains("shadow")
                && err.contains("Mrays/s"),
            "{err}"
        );
    }
    // Command-line values override the file's.
    let o = prism(
        &[
            "render",
            "scene.toml",
            "-o",
            "b.png",
            "--width",
            "5",
            "--height",
            "3",
            "--quiet",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0));
    assert!(o.stderr.is_empty(), "--quiet prints nothing");
    let img = image::open(dir.path().join("b.png")).unwrap();
    assert_eq!((img.width(), img.height()), (5, 3));
}

#[test]
fn demo_scene_renders_without_a_file() {
    let dir = tempfile::tempdir().unwrap();
    let o = prism(
        &[
            "render", "-o", "demo.png", "--width", "32", "--height", "24",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let img = image::open(dir.path().join("demo.png")).unwrap().to_rgb8();
    // Not a blank picture: many distinct colours (floor checks, sky, glass).
    let mut colours: Vec<[u8; 3]> = img.pixels().map(|p| p.0).collect();
    colours.sort();
    colours.dedup();
    assert!(colours.len() > 50, "{} colours", colours.len());
}

#[test]
fn unknown_key_is_refused() {
    assert_rejected(
        &GOOD.replace("radius = 1", "raduis = 1"),
        "21:1",
        "unknown field `raduis`, expected",
    );
}

#[test]
fn wrong_type_is_refused() {
    assert_rejected(
        &GOOD.replace("width = 8", "width = \"eight\""),
        "3:9",
        "expected u32",
    );
}

#[test]
fn missing_required_field_is_refused() {
    assert_rejected(
        &GOOD.replace("material = \"red\"", ""),
        "18:1",
        "objects[0]: a sphere needs `material`",
    );
    assert_rejected(
        &GOOD.replace("look_at = [0, 0, 0]", ""),
        "7:1",
        "missing field `look_at`",
    );
}

#[test]
fn negative_radius_is_refused() {
    assert_rejected(
        &GOOD.replace("radius = 1", "radius = -1"),
        "21:10",
        "`radius` must be between 1e-30 and 1e30 (the supported range of lengths), got -1",
    );
}

#[test]
fn non_positive_ior_is_refused() {
    assert_rejected(
        &GOOD.replace("color = [1, 0, 0]", "ior = 0"),
        "12:7",
        "`ior` must be greater than 0",
    );
}

#[test]
fn coefficients_that_create_light_are_refused() {
    assert_rejected(
        &GOOD.replace("color = [1, 0, 0]", "kr = 0.7\nkt = 0.6"),
        "13:6",
        "kr + kt = 1.3 exceeds 1",
    );
    assert_rejected(
        &GOOD.replace("color = [1, 0, 0]", "kd = -0.5"),
        "12:6",
        "`kd` must be between 0 and 1e15, got -0.5",
    );
    // Per channel: red alone exceeds 1.
    assert_rejected(
        &GOOD.replace(
            "color = [1, 0, 0]",
            "kr = [0.7, 0.2, 0.2]\nkt = [0.6, 0.1, 0]",
        ),
        "13:6",
        "kr + kt = 1.3 exceeds 1",
    );
    assert_rejected(
        &GOOD.replace("color = [1, 0, 0]", "kr = [0.5, -1, 0]"),
        "12:6",
        "`kr` must be between 0 and 1e15 (one number, or one per colour channel), got [0.5, -1.0, 0.0]",
    );
    assert_rejected(
        &GOOD.replace("color = [1, 0, 0]", "kt = nan"),
        "12:6",
        "`kt` must be between 0 and 1e15 (one number, or one per colour channel), got NaN",
    );
}

#[test]
fn nan_and_infinity_are_refused() {
    assert_rejected(
        &GOOD.replace("color = [1, 0, 0]", "ks = nan"),
        "12:6",
        "`ks` must be a finite number",
    );
    assert_rejected(
        &GOOD.replace("position = [2, 4, 5]", "position = [2, inf, 5]"),
        "16:12",
        "finite numbers",
    );
}

#[test]
fn unknown_material_is_refused() {
    assert_rejected(
        &GOOD.replace("material = \"red\"", "material = \"blue\""),
        "20:12",
        "unknown material `blue`; known: `red`",
    );
}

#[test]
fn bad_polygons_are_refused() {
    let polygon = |v: &str| {
        GOOD.replace("type = \"sphere\"", "type = \"polygon\"\nname = \"wall\"")
            .replace("radius = 1", &format!("vertices = {v}"))
    };
    assert_rejected(
        &polygon("[[0, 0, 0], [1, 0, 0]]"),
        "22:12",
        "object `wall` (objects[0]): a polygon needs at least 3 vertices, got 2",
    );
    assert_rejected(
        &polygon("[[0, 0, 0], [1, 0, 0], [2, 0, 0]]"),
        "22:12",
        "collinear",
    );
    assert_rejected(
        &polygon("[[0, 0, 0], [1, 0, 0], [1, 0, 0], [0, 1, 0]]"),
        "22:12",
        "vertices 1 and 2 coincide",
    );
    assert_rejected(
        &polygon("[[0, 0, 0], [1, 0, 0], [1, 1, 0.5], [0, 1, 0]]"),
        "22:12",
        "off the polygon's plane",
    );
}

#[test]
fn syntax_error_is_refused() {
    assert_rejected(&GOOD.replace("[camera]", "[camera"), "7:8", "expected `]`");
}

#[test]
fn binary_file_is_refused_with_its_position() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("scene.toml"),
        b"[render]\nwidth = 8\x89PNG\n",
    )
    .unwrap();
    let o = prism(&["check", "scene.toml"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).starts_with("scene.toml:2:10: error: the file is not valid UTF-8"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn every_problem_is_reported_at_once() {
    let scene = GOOD
        .replace("radius = 1", "radius = -1")
        .replace("color = [1, 0, 0]", "ior = -2")
        .replace("spp = 1", "spp = 0");
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("scene.toml"), scene).unwrap();
    let o = prism(&["check", "scene.toml"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert_eq!(err.lines().count(), 3, "{err}");
    assert!(
        err.contains("`spp` must be between 1 and 65536, got 0")
            && err.contains("`ior`")
            && err.contains("`radius`")
    );
}

#[test]
fn bad_output_and_missing_scene_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("scene.toml"), GOOD).unwrap();
    let o = prism(&["render", "scene.toml", "-o", "out.jpg"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("unknown image format"));
    let o = prism(
        &["render", "scene.toml", "-o", "no/such/dir/out.png"],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("does not exist"));
    std::fs::create_dir(dir.path().join("folder.png")).unwrap();
    let o = prism(&["render", "scene.toml", "-o", "folder.png"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("is a directory"));
    std::fs::remove_dir(dir.path().join("folder.png")).unwrap();
    let o = prism(&["render", "missing.toml", "-o", "out.png"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("missing.toml: cannot read the scene"));
    let o = prism(&["render", "scene.toml", "--spp", "0"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    let o = prism(&["render", "scene.toml", "--width", "100000"], dir.path());
    assert_eq!(o.status.code(), Some(2));
    // The limit as stated once (src/limits.rs), enforced by the parser.
    assert!(stderr(&o).contains("1..=32768"), "{}", stderr(&o));
    // A file name longer than the file system takes: refused before
    // rendering, naming the user's path.
    let long = format!("{}.png", "x".repeat(300));
    let o = prism(&["render", "scene.toml", "-o", &long], dir.path());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("at most 255"), "{}", stderr(&o));
    assert!(stderr(&o).contains(&long[..50]) && !stderr(&o).contains(".part"));
    // Nothing was written by any of these.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn every_example_scene_checks_and_renders() {
    let scenes = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join("scenes");
    let dir = tempfile::tempdir().unwrap();
    let mut count = 0;
    for entry in std::fs::read_dir(&scenes).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        count += 1;
        let p = path.to_str().unwrap();
        let c = prism(&["check", p], dir.path());
        assert_eq!(c.status.code(), Some(0), "{p}: {}", stderr(&c));
        let o = prism(
            &[
                "render", p, "-o", "x.png", "--width", "24", "--height", "16", "--spp", "1",
            ],
            dir.path(),
        );
        assert_eq!(o.status.code(), Some(0), "{p}: {}", stderr(&o));
    }
    assert!(count >= 5, "{count} scenes");
}

#[cfg(unix)]
#[test]
fn interrupted_render_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let scene =
        Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join("scenes/soft-shadows.toml");
    std::fs::write(dir.path().join("out.png"), b"previous image").unwrap();
    // A render of a minute or more, interrupted once it is under way (its
    // first line is printed after the interrupt handler is in place).
    let mut child = Command::new(env!("CARGO_BIN_EXE_prism"))
        .args([
            "render",
            scene.to_str().unwrap(),
            "-o",
            "out.png",
            "--width",
            "4000",
            "--height",
            "2000",
        ])
        .current_dir(dir.path())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut err = std::io::BufReader::new(child.stderr.take().unwrap());
    let mut printed = String::new();
    while !printed.contains("prism: rendering") {
        let before = printed.len();
        std::io::BufRead::read_line(&mut err, &mut printed).unwrap();
        assert!(printed.len() > before, "prism ended early: {printed}");
    }
    let kill = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    std::io::Read::read_to_string(&mut err, &mut printed).unwrap();
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(130), "{printed}");
    assert!(
        printed.contains("interrupted; nothing was written"),
        "{printed}"
    );
    assert_eq!(
        std::fs::read(dir.path().join("out.png")).unwrap(),
        b"previous image"
    );
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        1,
        "no stray files"
    );
}
