//! Rendering apart and putting back together: regions (`--crop`,
//! `--tile`) merged into images byte-identical to the whole render, in EXR
//! and PNG; merge refusals; frames by name pattern; a checkpointed render
//! killed with SIGKILL and resumed to the same bytes.

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn prism(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_prism"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("prism runs")
}

fn ok(dir: &Path, args: &[&str]) {
    let o = prism(dir, args);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// Exit 2 with `expected` in the message, and `out` not written.
fn refused(dir: &Path, args: &[&str], expected: &str) {
    let o = prism(dir, args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    assert!(err.contains(expected), "want {expected:?}: {err}");
    assert!(!dir.join("out.png").exists() && !dir.join("out.exr").exists());
}

fn bytes(dir: &Path, name: &str) -> Vec<u8> {
    std::fs::read(dir.join(name)).unwrap()
}

fn scene(dir: &Path) -> &'static str {
    let from = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/whitted.toml");
    std::fs::copy(from, dir.join("s.toml")).unwrap();
    "s.toml"
}

const SIZE: [&str; 6] = ["--width", "96", "--height", "70", "--spp", "2"];

/// Renders scene `s` in `d` at the small test size with `extra` arguments.
fn render(d: &Path, s: &str, extra: &[&str]) {
    ok(d, &[&["render", s, "-q"], &SIZE[..], extra].concat());
}

#[test]
fn tiles_and_crops_merge_to_the_whole_image_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene(d);
    render(d, s, &["-o", "whole.exr"]);
    render(d, s, &["-o", "whole.png"]);
    for i in 0..5 {
        render(
            d,
            s,
            &["--tile", &format!("{i}/5"), "-o", &format!("t{i}.exr")],
        );
    }
    // In another order, and the PNG from the same EXR parts.
    ok(
        d,
        &[
            "merge", "t3.exr", "t1.exr", "t4.exr", "t0.exr", "t2.exr", "-o", "m.exr",
        ],
    );
    ok(
        d,
        &[
            "merge", "t4.exr", "t0.exr", "t1.exr", "t2.exr", "t3.exr", "-o", "m.png",
        ],
    );
    assert!(bytes(d, "whole.exr") == bytes(d, "m.exr"), "EXR differs");
    assert!(bytes(d, "whole.png") == bytes(d, "m.png"), "PNG differs");
    // Irregular crops: a 2x2 grid with uneven cuts.
    for (name, crop) in [
        ("a", "0,37,0,23"),
        ("b", "37,96,0,23"),
        ("c", "0,37,23,70"),
        ("d", "37,96,23,70"),
    ] {
        render(d, s, &["--crop", crop, "-o", &format!("{name}.exr")]);
    }
    ok(
        d,
        &["merge", "d.exr", "c.exr", "b.exr", "a.exr", "-o", "g.exr"],
    );
    assert!(bytes(d, "whole.exr") == bytes(d, "g.exr"));
    // A crop's PNG is the same pixels as that part of the whole PNG.
    render(d, s, &["--crop", "10,30,40,50", "-o", "crop.png"]);
    let whole = image::open(d.join("whole.png")).unwrap().to_rgb8();
    let crop = image::open(d.join("crop.png")).unwrap().to_rgb8();
    assert_eq!(crop.dimensions(), (20, 10));
    for (x, y, p) in crop.enumerate_pixels() {
        assert_eq!(p, whole.get_pixel(x + 10, y + 40));
    }
}

#[test]
fn merge_refuses_mixed_overlapping_and_incomplete_parts() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene(d);
    for i in 0..3 {
        render(
            d,
            s,
            &["--tile", &format!("{i}/3"), "-o", &format!("t{i}.exr")],
        );
    }
    render(d, s, &["--tile", "1/3", "--seed", "9", "-o", "seed9.exr"]);
    render(d, s, &["--tile", "1/3", "--frame", "4", "-o", "frame4.exr"]);
    ok(
        d,
        &[
            "render", s, "-q", "--width", "96", "--height", "70", "--spp", "3", "--tile", "1/3",
            "-o", "spp3.exr",
        ],
    );
    render(d, s, &["--crop", "0,10,20,30", "-o", "over.exr"]);
    refused(
        d,
        &["merge", "t0.exr", "seed9.exr", "t2.exr", "-o", "out.png"],
        "seed9.exr: belongs to another render: its seed is `9`",
    );
    refused(
        d,
        &["merge", "t0.exr", "frame4.exr", "t2.exr", "-o", "out.png"],
        "its frame is `4`",
    );
    refused(
        d,
        &["merge", "t0.exr", "spp3.exr", "t2.exr", "-o", "out.png"],
        "its settings is `96x70 spp=3",
    );
    refused(
        d,
        &[
            "merge", "t0.exr", "t1.exr", "t2.exr", "over.exr", "-o", "out.png",
        ],
        "over.exr: its region 0,10,20,30 overlaps",
    );
    refused(
        d,
        &["merge", "t2.exr", "t0.exr", "-o", "out.png"],
        "missing regions (X0,X1,Y0,Y1): 0,96,23,46",
    );
    // Another scene: its content hash differs.
    let other = std::fs::read_to_string(d.join(s)).unwrap() + "\n# edited\n";
    std::fs::write(d.join("edited.toml"), other).unwrap();
    ok(
        d,
        &[
            &["render", "edited.toml", "-q"],
            &SIZE[..],
            &["--tile", "1/3", "-o", "edited.exr"],
        ]
        .concat(),
    );
    refused(
        d,
        &["merge", "t0.exr", "edited.exr", "t2.exr", "-o", "out.png"],
        "its scene_sha256 is",
    );
    // Not a part at all.
    render(d, s, &["-o", "plain.png"]);
    refused(d, &["merge", "plain.png", "-o", "out.png"], "plain.png:");
    // Bad regions are exit 2 before rendering.
    for (args, expected) in [
        (["--crop", "5,5,0,3"], "empty or reversed"),
        (["--crop", "0,9999,0,3"], "outside"),
        (["--tile", "3/3"], "0 <= I < N"),
        (["--frames", "1-3"], "need a run of #"),
    ] {
        refused(
            d,
            &[&["render", s, "-o", "out.png"], &args[..]].concat(),
            expected,
        );
    }
}

#[test]
fn frames_render_alone_as_in_a_sequence() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene(d);
    render(d, s, &["--frames", "2-4", "-o", "seq_###.png"]);
    render(d, s, &["--frame", "3", "-o", "alone.png"]);
    assert!(bytes(d, "seq_003.png") == bytes(d, "alone.png"));
    // Frames differ in their samples; frame 0 is the still.
    assert!(bytes(d, "seq_002.png") != bytes(d, "seq_003.png"));
    render(d, s, &["--frame", "0", "-o", "f0.png"]);
    render(d, s, &["-o", "still.png"]);
    assert!(bytes(d, "f0.png") == bytes(d, "still.png"));
}

#[test]
fn a_killed_checkpointed_render_resumes_to_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene(d);
    let args = [
        "render",
        s,
        "-q",
        "--width",
        "320",
        "--height",
        "240",
        "--spp",
        "16",
        "--threads",
        "1",
    ];
    ok(d, &[&args[..], &["-o", "whole.png"]].concat());
    let mut child = Command::new(env!("CARGO_BIN_EXE_prism"))
        .args([&args[..], &["--checkpoint", "ck", "-o", "out.png"]].concat())
        .current_dir(d)
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // SIGKILL once some tiles (of 300) are saved, long before the end.
    let start = Instant::now();
    let saved = || {
        std::fs::read_dir(d.join("ck")).map_or(0, |r| {
            r.flatten()
                .filter(|e| e.path().extension().is_some_and(|x| x == "tile"))
                .count()
        })
    };
    while saved() < 20 && start.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(5));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let before = saved();
    assert!(
        (20..300).contains(&before),
        "{before} tiles saved before the kill"
    );
    assert!(!d.join("out.png").exists());
    // Another render is refused the folder.
    refused(
        d,
        &[
            &args[..],
            &["--seed", "3", "--checkpoint", "ck", "-o", "out.png"],
        ]
        .concat(),
        "another render",
    );
    let o = prism(
        d,
        &[&args[..], &["--checkpoint", "ck", "-o", "out.png"]].concat(),
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        bytes(d, "whole.png") == bytes(d, "out.png"),
        "resumed image differs"
    );
    assert!(
        !d.join("ck").exists(),
        "the checkpoint is removed after the write"
    );
}

/// The example animation: the keyed translation puts the glass ball at
/// the keys' values on the key frames and (smoothstep) half-way at the
/// middle frame; frames past the end are refused with the scene's line.
#[test]
fn keyed_values_move_the_glass_ball() {
    use prism::accel::Shape;
    use prism::scene::LoadOptions;
    let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/rolling.toml"));
    let centre = |frame: u32| {
        let options = LoadOptions {
            frame,
            ..LoadOptions::default()
        };
        let scene = prism::Scene::load_with(path, &options).unwrap();
        assert!(scene.animated);
        assert_eq!(scene.animation.map(|a| a.frames), Some(48));
        scene
            .aggregate
            .primitives()
            .iter()
            .find_map(|p| match &p.shape {
                Shape::Sphere(s) if (s.radius - 0.8).abs() < 1e-9 => Some(s.center),
                _ => None,
            })
            .unwrap()
    };
    let close = |a: glam::DVec3, b: [f64; 3]| (a - glam::DVec3::from_array(b)).length() < 1e-12;
    assert!(close(centre(0), [-3.0, 0.8, 0.8]), "{}", centre(0));
    assert!(close(centre(47), [3.0, 0.8, 0.8]), "{}", centre(47));
    // s = 23.5/47 = 0.5 exactly between frames 23 and 24: check monotone
    // motion and the smoothstep's symmetry about the middle instead.
    let xs: Vec<f64> = (0..48).map(|f| centre(f).x).collect();
    assert!(xs.windows(2).all(|w| w[1] > w[0]), "{xs:?}");
    for f in 0..48 {
        assert!((xs[f] + xs[47 - f]).abs() < 1e-12, "frame {f}");
    }
    // Slow near the keys (eased), fast in the middle.
    assert!(xs[1] - xs[0] < xs[24] - xs[23]);
    let dir = tempfile::tempdir().unwrap();
    let o = prism(
        dir.path(),
        &[
            "render",
            path.to_str().unwrap(),
            "--frame",
            "48",
            "-o",
            "out.png",
        ],
    );
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("rolling.toml:") && err.contains("past the animation's last frame 47"),
        "{err}"
    );
}

/// Parts that lie: a truncated file, garbage, a header whose region
/// disagrees with its data window. Each is exit 2 naming the file.
#[test]
fn damaged_parts_are_refused_not_crashed_on() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene(d);
    render(d, s, &["--tile", "0/2", "-o", "t0.exr"]);
    render(d, s, &["--tile", "1/2", "-o", "t1.exr"]);
    let good = std::fs::read(d.join("t1.exr")).unwrap();
    std::fs::write(d.join("cut.exr"), &good[..good.len() / 2]).unwrap();
    std::fs::write(d.join("junk.exr"), b"v/1\x01 not an exr at all").unwrap();
    // The provenance claims another region than the data window.
    let at = good.windows(7).position(|w| w == b"region=").unwrap();
    let mut lying = good.clone();
    lying[at + 7] = b'5';
    std::fs::write(d.join("lying.exr"), &lying).unwrap();
    for bad in ["cut.exr", "junk.exr", "lying.exr"] {
        let o = prism(d, &["merge", "t0.exr", bad, "-o", "out.png"]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{bad}: {err}");
        assert!(
            err.contains(bad) && !err.contains("panicked"),
            "{bad}: {err}"
        );
        assert!(!d.join("out.png").exists());
    }
}
