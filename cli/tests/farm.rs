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
    let from = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/whitted.toml");
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
        "its spp is `3`, but",
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
    let path = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenes/rolling.toml"
    ));
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

/// Every single-byte change of a part either makes it unreadable or leaves
/// what it says unchanged: a damaged part never merges into another frame.
#[test]
fn a_flipped_byte_anywhere_in_a_part_is_caught() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene(d);
    render(d, s, &["--crop", "40,41,30,31", "-o", "px.exr"]);
    let good = std::fs::read(d.join("px.exr")).unwrap();
    let original = prism::image_io::read_part(&d.join("px.exr")).unwrap();
    let flipped = d.join("flipped.exr");
    let mut accepted = 0;
    for at in 0..good.len() {
        let mut bytes = good.clone();
        bytes[at] ^= 0x10;
        std::fs::write(&flipped, &bytes).unwrap();
        if let Ok(part) = prism::image_io::read_part(&flipped) {
            accepted += 1;
            assert_eq!(part.provenance, original.provenance, "byte {at}");
            assert_eq!(part.film.region(), original.film.region(), "byte {at}");
            assert_eq!(part.film.pixels(), original.film.pixels(), "byte {at}");
        }
    }
    // Only bytes that carry nothing (unused header fields) may change.
    assert!(
        accepted < good.len() / 4,
        "{accepted} of {} accepted",
        good.len()
    );
}

/// An EXR not written by prism, with a part's `prism` attribute copied in
/// (its pixels NaN and infinite), and a part whose digest is right but
/// whose radiance is negative: both refused, naming the file.
#[test]
fn foreign_and_impossible_pixels_are_refused() {
    use exr::prelude::*;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene(d);
    render(d, s, &["--crop", "0,2,0,1", "-o", "a.exr"]);
    render(d, s, &["--crop", "2,96,0,1", "-o", "b.exr"]);
    let meta = exr::meta::MetaData::read_from_file(d.join("a.exr"), false).unwrap();
    let attribute = meta.headers[0].own_attributes.other[&Text::from("prism")].clone();
    let mut attributes = LayerAttributes::default();
    attributes.other.insert(Text::from("prism"), attribute);
    let layer = Layer::new(
        (2, 1),
        attributes,
        Encoding::SMALL_LOSSLESS,
        SpecificChannels::rgb(|at: Vec2<usize>| {
            if at.x() == 0 {
                (f32::NAN, 0.0, 0.0)
            } else {
                (f32::INFINITY, 1.0, 1.0)
            }
        }),
    );
    let mut image = Image::from_layer(layer);
    image.attributes.display_window = IntegerBounds::new((0, 0), (96, 70));
    image.write().to_file(d.join("foreign.exr")).unwrap();
    let o = prism(d, &["merge", "foreign.exr", "b.exr", "-o", "out.exr"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("foreign.exr") && err.contains("digest"),
        "{err}"
    );
    assert!(!d.join("out.exr").exists());

    let a = prism::image_io::read_part(&d.join("a.exr")).unwrap();
    let mut film = prism::render::Film::window(96, 70, a.film.region());
    film.set(1, 0, glam::DVec3::new(0.5, -1.0, 0.5));
    let file = std::fs::File::create(d.join("negative.exr")).unwrap();
    prism::image_io::exr::write(&film, Some(&a.provenance), std::io::BufWriter::new(file)).unwrap();
    let o = prism(d, &["merge", "negative.exr", "b.exr", "-o", "out.exr"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("negative.exr: its pixel (1, 0)"), "{err}");
}

/// A small part whose header promises a 16384 × 16384 frame: refused from
/// its header in an instant, under a 2 GB address-space limit, not after
/// allocating gigabytes.
#[test]
fn a_lying_header_is_refused_before_allocating() {
    use exr::prelude::*;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let text = format!(
        "scene_sha256=0\nsettings=16384x16384 spp=1 max_depth=8 min_weight=0.001\nseed=0\n\
         frame=0\nregion=0,16384,0,16384\npixels_sha256={}\n",
        "0".repeat(64)
    );
    let mut attributes = LayerAttributes::default();
    attributes.other.insert(
        Text::from("prism"),
        AttributeValue::Text(Text::from(text.as_str())),
    );
    let layer = Layer::new(
        (1, 1),
        attributes,
        Encoding::SMALL_LOSSLESS,
        SpecificChannels::rgb(|_: Vec2<usize>| (0.5f32, 0.5, 0.5)),
    );
    let mut image = Image::from_layer(layer);
    image.attributes.display_window = IntegerBounds::new((0, 0), (16384, 16384));
    let path = d.join("huge.exr");
    image.write().to_file(&path).unwrap();
    // Make the data window claim the whole frame.
    let mut bytes = std::fs::read(&path).unwrap();
    let at = bytes
        .windows(17)
        .position(|w| w == b"dataWindow\0box2i\0")
        .unwrap()
        + 17
        + 4;
    bytes[at + 8..at + 12].copy_from_slice(&16383i32.to_le_bytes());
    bytes[at + 12..at + 16].copy_from_slice(&16383i32.to_le_bytes());
    std::fs::write(&path, &bytes).unwrap();
    let start = Instant::now();
    let o = Command::new("prlimit")
        .args(["--as=2000000000", "--"])
        .arg(env!("CARGO_BIN_EXE_prism"))
        .args(["merge", "huge.exr", "-o", "out.exr"])
        .current_dir(d)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("huge.exr") && err.contains("promises"),
        "{err}"
    );
    assert!(start.elapsed() < Duration::from_secs(30));
}

/// `prism merge a.exr b.exr -o a.exr` would destroy a part: refused, and
/// the part is untouched.
#[test]
fn merge_onto_one_of_its_parts_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene(d);
    render(d, s, &["--tile", "0/2", "-o", "t0.exr"]);
    render(d, s, &["--tile", "1/2", "-o", "t1.exr"]);
    let before = bytes(d, "t0.exr");
    for out in ["t0.exr", "./t0.exr"] {
        let o = prism(d, &["merge", "t0.exr", "t1.exr", "-o", out]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains("is one of the parts"), "{err}");
        assert!(bytes(d, "t0.exr") == before);
    }
}

/// A tile of another render (seed 1) copied into a seed-0 checkpoint is
/// traced again: the resumed image equals the whole render.
#[test]
fn a_foreign_checkpoint_tile_is_traced_again() {
    use prism::render::Checkpoint;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene(d);
    let args = ["render", s, "--width", "64", "--height", "48", "--spp", "2"];
    ok(d, &[&args[..], &["-q", "-o", "whole.png"]].concat());
    // The render keys and pixels of seeds 0 and 1, from their parts.
    let part_of = |seed: &str| {
        let out = format!("seed{seed}.exr");
        ok(
            d,
            &[&args[..], &["-q", "--seed", seed, "-o", &out]].concat(),
        );
        let part = prism::image_io::read_part(&d.join(out)).unwrap();
        (part.provenance.to_text(part.film.region()), part.film)
    };
    let (key1, film1) = part_of("1");
    let (key0, _) = part_of("0");
    assert_ne!(key0, key1);
    // Seed 1's checkpoint, every tile saved.
    let ck1 = Checkpoint::open(&d.join("ck1"), &key1).unwrap();
    for tile in film1.region().tiles(16) {
        let pixels: Vec<glam::DVec3> = (tile.y0..tile.y1)
            .flat_map(|y| (tile.x0..tile.x1).map(move |x| (x, y)))
            .map(|(x, y)| film1.get(x, y))
            .collect();
        ck1.save(tile, &pixels).unwrap();
    }
    assert_eq!(
        Checkpoint::open(&d.join("ck1"), &key1).unwrap().resumed(),
        12
    );
    // Its tiles copied into a fresh seed-0 checkpoint.
    drop(Checkpoint::open(&d.join("ck0"), &key0).unwrap());
    for entry in std::fs::read_dir(d.join("ck1")).unwrap().flatten() {
        if entry.path().extension().is_some_and(|e| e == "tile") {
            std::fs::copy(entry.path(), d.join("ck0").join(entry.file_name())).unwrap();
        }
    }
    let o = prism(
        d,
        &[&args[..], &["--checkpoint", "ck0", "-o", "out.png"]].concat(),
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(!err.contains("resuming"), "{err}");
    assert!(
        bytes(d, "whole.png") == bytes(d, "out.png"),
        "a foreign tile was used"
    );
}

/// `--frames` with `--checkpoint`, killed after the first frame is written:
/// the rerun skips that frame (its record and file still match), renders
/// the rest, gives the same bytes, and leaves no checkpoint folder.
#[test]
fn a_killed_frame_sequence_resumes_without_rendering_finished_frames() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene(d);
    let args = [
        "render",
        s,
        "--width",
        "200",
        "--height",
        "150",
        "--spp",
        "16",
        "--threads",
        "1",
        "--frames",
        "0-2",
    ];
    ok(d, &[&args[..], &["-q", "-o", "ref_####.png"]].concat());
    let mut child = Command::new(env!("CARGO_BIN_EXE_prism"))
        .args(
            [
                &args[..],
                &["-q", "--checkpoint", "ck", "-o", "out_####.png"],
            ]
            .concat(),
        )
        .current_dir(d)
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while !d.join("ck/frame_0000.done").exists() && start.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(2));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(d.join("out_0000.png").exists() && !d.join("out_0002.png").exists());
    let first = std::fs::metadata(d.join("out_0000.png"))
        .unwrap()
        .modified()
        .unwrap();
    // What a kill at a less lucky moment leaves: the next frame's folder
    // holding only its manifest's temporary file (once, a real kill landed
    // there and the rerun refused the folder), and a frame record's
    // temporary file.
    if !d.join("ck/frame_0001/checkpoint.txt").exists() {
        std::fs::create_dir_all(d.join("ck/frame_0001")).unwrap();
        std::fs::write(d.join("ck/frame_0001/.tile-kIlL3d.part"), "scene=").unwrap();
    }
    std::fs::write(d.join("ck/.frame-kIlL3d.part"), "scene=").unwrap();
    let o = prism(
        d,
        &[&args[..], &["--checkpoint", "ck", "-o", "out_####.png"]].concat(),
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("frame 0 is already written"), "{err}");
    assert_eq!(
        std::fs::metadata(d.join("out_0000.png"))
            .unwrap()
            .modified()
            .unwrap(),
        first,
        "frame 0 was written again"
    );
    for f in 0..3 {
        let name = format!("_{f:04}.png");
        assert!(
            bytes(d, &format!("ref{name}")) == bytes(d, &format!("out{name}")),
            "frame {f}"
        );
    }
    assert!(!d.join("ck").exists(), "the checkpoint folder stays behind");
}

/// With an exposure, a PNG merged from EXR parts equals the PNG rendered
/// whole: the parts carry the exposure and the merge applies it as the
/// render does (to the radiance as stored, then 2^EV).
#[test]
fn an_exposed_png_merges_to_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene(d);
    for ev in ["1.5", "-0.7"] {
        let exposed = ["--exposure", ev];
        render(d, s, &[&exposed[..], &["-o", "whole.png"]].concat());
        for i in 0..3 {
            let tile = format!("{i}/3");
            let out = format!("t{i}.exr");
            render(
                d,
                s,
                &[&exposed[..], &["--tile", &tile, "-o", &out]].concat(),
            );
        }
        ok(d, &["merge", "t0.exr", "t1.exr", "t2.exr", "-o", "m.png"]);
        assert!(bytes(d, "whole.png") == bytes(d, "m.png"), "exposure {ev}");
    }
    // Parts of different exposures are parts of different pictures.
    render(d, s, &["--tile", "1/3", "-o", "plain.exr"]);
    refused(
        d,
        &["merge", "t0.exr", "plain.exr", "t2.exr", "-o", "out.png"],
        "plain.exr: belongs to another render: its exposure is `0`",
    );
}

#[test]
fn a_lens_adaptive_sampling_and_an_area_light_merge_to_the_whole_image_byte_for_byte() {
    // scenes/distributed.toml has a thin lens, a rectangle light and glossy
    // materials; adaptive anti-aliasing shares its corner samples across
    // tiles and regions, which must not change a bit.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let from = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/distributed.toml");
    let text = std::fs::read_to_string(from).unwrap().replace(
        "[render]\n",
        "[render]\nadaptive = { threshold = 0.05, depth = 2, jitter = true }\n",
    );
    std::fs::write(d.join("s.toml"), text).unwrap();
    let size = ["--width", "72", "--height", "41"];
    let run = |extra: &[&str]| ok(d, &[&["render", "s.toml", "-q"], &size[..], extra].concat());
    run(&["-o", "whole.exr"]);
    for i in 0..3 {
        run(&["--tile", &format!("{i}/3"), "-o", &format!("t{i}.exr")]);
    }
    ok(d, &["merge", "t2.exr", "t0.exr", "t1.exr", "-o", "m.exr"]);
    assert!(bytes(d, "whole.exr") == bytes(d, "m.exr"), "tiles differ");
    for (name, crop) in [
        ("a", "0,29,0,17"),
        ("b", "29,72,0,17"),
        ("c", "0,29,17,41"),
        ("d", "29,72,17,41"),
    ] {
        run(&[
            "--crop",
            crop,
            "-o",
            &format!("{name}.exr"),
            "--threads",
            "1",
        ]);
    }
    ok(
        d,
        &["merge", "c.exr", "a.exr", "d.exr", "b.exr", "-o", "g.exr"],
    );
    assert!(bytes(d, "whole.exr") == bytes(d, "g.exr"), "crops differ");
    // A part rendered without adaptive sampling does not merge with them.
    let plain = std::fs::read_to_string(d.join("s.toml")).unwrap().replace(
        "adaptive = { threshold = 0.05, depth = 2, jitter = true }\n",
        "",
    );
    std::fs::write(d.join("p.toml"), plain).unwrap();
    ok(
        d,
        &[
            &["render", "p.toml", "-q"],
            &size[..],
            &["--crop", "0,29,0,17", "-o", "pa.exr"],
        ]
        .concat(),
    );
    let o = prism(
        d,
        &["merge", "pa.exr", "b.exr", "c.exr", "d.exr", "-o", "x.exr"],
    );
    assert_eq!(
        o.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
}
