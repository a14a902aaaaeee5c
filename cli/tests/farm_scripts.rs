//! The farm's generated jobs, run: paths full of what a shell or Slurm
//! would interpret (`;`, `$()`, backticks, quotes, `%`, spaces, non-ASCII)
//! in the scene's folder, the output folder and the executable's folder
//! give the same frames as `prism render`, and run nothing they contain.
//! The Slurm scripts run under bash as Slurm would run them (one task per
//! SLURM_ARRAY_TASK_ID), the OpenJD template's actions as `openjd run`
//! would (parameters substituted, the command run without a shell);
//! scripts/test-farm-slurm.sh and test-farm-openjd.sh run them on the
//! real systems. Also: plans that cannot run are refused before anything
//! is written, and a merge that refuses a part merges the other frames and
//! lets a rerun render that part again.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Every kind of character a path could hide a command or pattern in.
const HOSTILE: [&str; 9] = [
    ";",
    "$(touch PWNED)",
    "`touch PWNED`",
    "'",
    "\"",
    "%j%A",
    " a b ",
    "é✓",
    "&|<>*?[]{}!#~",
];

fn run(prism: &Path, dir: &Path, args: &[&str]) -> Output {
    Command::new(prism)
        .args(args)
        .current_dir(dir)
        .output()
        .expect("prism runs")
}

fn ok(o: Output, what: &str) -> String {
    assert!(
        o.status.success(),
        "{what}: {}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// A copy of the prism executable in `dir`, so that its own path is
/// hostile too.
fn prism_in(dir: &Path) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let to = dir.join("prism");
    // Copied by another process: a file this process held open for
    // writing would be inherited by the children other tests fork
    // meanwhile, and running the copy would fail with "Text file busy".
    let copied = Command::new("cp")
        .arg(env!("CARGO_BIN_EXE_prism"))
        .arg(&to)
        .status()
        .unwrap();
    assert!(copied.success());
    to
}

/// The Whitted scene at 40 × 30, 1 spp, in `dir`.
fn small_scene(dir: &Path) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenes/whitted.toml"
    ))
    .unwrap();
    let text: String = text
        .lines()
        .map(|l| {
            if l.starts_with("width =") {
                "width = 40".to_string()
            } else if l.starts_with("height =") {
                "height = 30".to_string()
            } else if l.starts_with("spp =") {
                "spp = 1".to_string()
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// No file named PWNED anywhere below `dir`.
fn nothing_ran(dir: &Path) {
    for entry in std::fs::read_dir(dir).unwrap().flatten() {
        assert_ne!(entry.file_name(), "PWNED", "a path ran a command");
        if entry.file_type().unwrap().is_dir() {
            nothing_ran(&entry.path());
        }
    }
}

/// Runs render.sbatch as Slurm runs array task `k`.
fn run_task(out: &Path, k: u32) {
    let o = Command::new("bash")
        .arg(out.join("render.sbatch"))
        .env("SLURM_ARRAY_TASK_ID", k.to_string())
        .current_dir(out)
        .output()
        .unwrap();
    ok(o, &format!("render.sbatch task {k}"));
}

/// Runs render.sbatch for every task and merge.sbatch, as Slurm would.
fn run_slurm_scripts(out: &Path, tasks: u32) {
    for k in 0..tasks {
        run_task(out, k);
    }
    let o = Command::new("bash")
        .arg(out.join("merge.sbatch"))
        .current_dir(out)
        .output()
        .unwrap();
    ok(o, "merge.sbatch");
}

/// Runs the template's actions as `openjd run` would: `{{...}}` replaced
/// by the parameter values, the command run directly.
fn run_openjd_template(out: &Path, prism: &Path, scene: &Path, frames: u32, tiles: u32) {
    let text = std::fs::read_to_string(out.join("job.template.json")).unwrap();
    let template: serde_json::Value = serde_json::from_str(&text).unwrap();
    let action = |step: usize, frame: u32, tile: u32| {
        let on_run = &template["steps"][step]["script"]["actions"]["onRun"];
        let args: Vec<String> = on_run["args"]
            .as_array()
            .unwrap()
            .iter()
            .map(|a| {
                a.as_str()
                    .unwrap()
                    .replace("{{Param.Prism}}", prism.to_str().unwrap())
                    .replace("{{Param.Scene}}", scene.to_str().unwrap())
                    .replace("{{Param.OutputDir}}", out.to_str().unwrap())
                    .replace("{{Task.Param.Frame}}", &frame.to_string())
                    .replace("{{Task.Param.Tile}}", &tile.to_string())
            })
            .collect();
        let o = Command::new(on_run["command"].as_str().unwrap())
            .args(&args)
            .output()
            .unwrap();
        ok(o, &format!("openjd step {step} frame {frame} tile {tile}"));
    };
    for frame in 0..frames {
        for tile in 0..tiles {
            action(0, frame, tile);
        }
    }
    for frame in 0..frames {
        action(1, frame, 0);
    }
}

#[test]
fn hostile_paths_render_the_same_frames_and_run_nothing() {
    let dir = tempfile::tempdir().unwrap();
    for (i, h) in HOSTILE.iter().enumerate() {
        let base = dir.path().join(format!("case{i}"));
        let prism = prism_in(&base.join(format!("bin{h}")));
        let scene = small_scene(&base.join(format!("scene{h}")));
        let reference = base.join("reference.exr");
        ok(
            run(
                &prism,
                &base,
                &[
                    "render",
                    scene.to_str().unwrap(),
                    "-q",
                    "-o",
                    reference.to_str().unwrap(),
                ],
            ),
            "reference render",
        );
        let want = std::fs::read(&reference).unwrap();

        let out = base.join(format!("slurm{h}"));
        let printed = ok(
            run(
                &prism,
                &base,
                &[
                    "farm",
                    "slurm",
                    scene.to_str().unwrap(),
                    "-o",
                    out.to_str().unwrap(),
                    "--tiles",
                    "3",
                    "--partition",
                    "main",
                    "--cpus-per-task",
                    "1",
                ],
            ),
            &format!("farm slurm with {h:?}"),
        );
        assert!(printed.contains("sbatch"), "{printed}");
        run_slurm_scripts(&out, 3);
        assert!(
            std::fs::read(out.join("frame_0000.exr")).unwrap() == want,
            "Slurm frame with {h:?} differs from prism render"
        );

        let out = base.join(format!("openjd{h}"));
        ok(
            run(
                &prism,
                &base,
                &[
                    "farm",
                    "openjd",
                    scene.to_str().unwrap(),
                    "-o",
                    out.to_str().unwrap(),
                    "--tiles",
                    "3",
                ],
            ),
            &format!("farm openjd with {h:?}"),
        );
        run_openjd_template(&out, &prism, &scene, 1, 3);
        assert!(
            std::fs::read(out.join("frame_0000.exr")).unwrap() == want,
            "OpenJD frame with {h:?} differs from prism render"
        );
        nothing_ran(dir.path());
    }
}

/// Exit 2 naming `expected`, and no output folder made.
fn refused(prism: &Path, dir: &Path, args: &[&str], out: &Path, expected: &[&str]) {
    let o = run(prism, dir, args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    for e in expected {
        assert!(err.contains(e), "{args:?}: want {e:?} in {err}");
    }
    assert!(!out.exists(), "{args:?} wrote {}", out.display());
}

#[test]
fn plans_that_cannot_run_are_refused_before_anything_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let prism = PathBuf::from(env!("CARGO_BIN_EXE_prism"));
    let scene = small_scene(d);
    let s = scene.to_str().unwrap();
    let out = d.join("out");
    let o = out.to_str().unwrap();
    for backend in ["slurm", "openjd"] {
        let name = if backend == "slurm" {
            "the Slurm backend"
        } else {
            "the Open Job Description backend"
        };
        for (bad, what) in [
            ("x\ny", "a newline"),
            ("x\ry", "a carriage return"),
            ("x\ty", "a tab"),
        ] {
            let folder = d.join(bad);
            refused(
                &prism,
                d,
                &["farm", backend, s, "-o", folder.to_str().unwrap()],
                &folder,
                &[what, name],
            );
        }
        // The scene's own path.
        let odd = d.join("sc\nene.toml");
        std::fs::copy(&scene, &odd).unwrap();
        refused(
            &prism,
            d,
            &["farm", backend, odd.to_str().unwrap(), "-o", o],
            &out,
            &["a newline"],
        );
        // More tiles than rows; frames past the animation; a broken scene;
        // a plan beyond the task limit (refused at once).
        refused(
            &prism,
            d,
            &["farm", backend, s, "-o", o, "--tiles", "31"],
            &out,
            &["--tiles 31", "image height 30"],
        );
        let rolling = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/rolling.toml");
        refused(
            &prism,
            d,
            &["farm", backend, rolling, "-o", o, "--frames", "40-60"],
            &out,
            &["past the animation's last frame 47"],
        );
        let broken = d.join("broken.toml");
        std::fs::write(&broken, "[render]\nwidth = \"wide\"\n").unwrap();
        refused(
            &prism,
            d,
            &["farm", backend, broken.to_str().unwrap(), "-o", o],
            &out,
            &["broken.toml:2:"],
        );
        let start = std::time::Instant::now();
        refused(
            &prism,
            d,
            &[
                "farm",
                backend,
                s,
                "-o",
                o,
                "--frames",
                "0-4294967295",
                "--tiles",
                "30",
            ],
            &out,
            &["at most 1000000"],
        );
        assert!(start.elapsed().as_secs() < 10);
    }
    // Slurm's own limits: partition names, and a backslash in the folder.
    for p in ["a;b", "a\nb", "$(x)", "a b", "%j"] {
        refused(
            &prism,
            d,
            &["farm", "slurm", s, "-o", o, "--partition", p],
            &out,
            &["--partition", "partition name"],
        );
    }
    let folder = d.join("a\\b");
    refused(
        &prism,
        d,
        &["farm", "slurm", s, "-o", folder.to_str().unwrap()],
        &folder,
        &["a backslash"],
    );
    // A hand-edited plan with its frames reversed: status answers at once.
    ok(
        run(
            &prism,
            d,
            &[
                "farm", "slurm", s, "-o", o, "--frames", "0-1", "--tiles", "2",
            ],
        ),
        "plan",
    );
    let plan = std::fs::read_to_string(out.join("farm.toml")).unwrap();
    std::fs::write(
        out.join("farm.toml"),
        plan.replace("first_frame = 0", "first_frame = 9"),
    )
    .unwrap();
    let o2 = run(&prism, d, &["farm", "status", o]);
    assert_eq!(o2.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o2.stderr).contains("reversed"));
}

/// Frame 0's tile 1 is damaged after rendering: the merge merges frame 1,
/// records why frame 0 failed, sets the part aside; status says so; the
/// rerun asks for that one task; once it is rendered the merge completes.
#[test]
fn a_refused_part_is_rendered_again_and_other_frames_merge() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let prism = PathBuf::from(env!("CARGO_BIN_EXE_prism"));
    let scene = small_scene(d);
    let s = scene.to_str().unwrap();
    let out = d.join("out");
    let o = out.to_str().unwrap();
    let plan = [
        "farm", "slurm", s, "-o", o, "--frames", "0-1", "--tiles", "2",
    ];
    ok(run(&prism, d, &plan), "plan");
    for k in 0..4 {
        run_task(&out, k);
    }
    // A part of another frame copied over frame 0's tile 1.
    std::fs::copy(
        out.join("parts/frame_0001_tile_0001.exr"),
        out.join("parts/frame_0000_tile_0001.exr"),
    )
    .unwrap();
    let merged = run(&prism, d, &["farm", "merge", o]);
    assert_eq!(merged.status.code(), Some(1));
    assert!(out.join("frame_0001.exr").is_file() && !out.join("frame_0000.exr").exists());
    assert!(out.join("parts/refused/frame_0000_tile_0001.exr").is_file());
    let status = ok(run(&prism, d, &["farm", "status", o]), "status");
    assert!(
        status.contains("frame 0: 1/2 parts; merge failed:") && status.contains("not of frame 0"),
        "{status}"
    );
    // A reason planted with terminal controls is shown escaped, on its line.
    let reason = out.join("failed/frame_0000.txt");
    let kept = std::fs::read(&reason).unwrap();
    std::fs::write(
        &reason,
        "x\u{1b}]0;pwned\u{7}\u{1b}[2J\r\nFAKE: error\u{9b}",
    )
    .unwrap();
    let status = ok(run(&prism, d, &["farm", "status", o]), "status");
    assert!(
        !status.lines().any(|l| l.starts_with("FAKE"))
            && !status
                .chars()
                .any(|c| c != '\n' && prism::text::is_unsafe_on_terminal(c)),
        "{status:?}"
    );
    assert!(status.contains("\\u{1b}]0;pwned"), "{status}");
    std::fs::write(&reason, kept).unwrap();
    let rerun = ok(run(&prism, d, &plan), "rerun");
    assert!(rerun.contains("--array=1 "), "{rerun}");
    run_task(&out, 1);
    ok(run(&prism, d, &["farm", "merge", o]), "merge");
    let status = ok(run(&prism, d, &["farm", "status", o]), "status");
    assert!(status.contains("merged: 2 of 2 frames"), "{status}");
    let reference = d.join("f0.exr");
    ok(
        run(
            &prism,
            d,
            &[
                "render",
                s,
                "-q",
                "--frame",
                "0",
                "-o",
                reference.to_str().unwrap(),
            ],
        ),
        "reference",
    );
    assert!(
        std::fs::read(reference).unwrap() == std::fs::read(out.join("frame_0000.exr")).unwrap()
    );
}
