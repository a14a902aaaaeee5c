//! `prism farm`: renders on a batch system as many small `prism render`
//! tasks, one per (frame, tile), each writing an EXR part, and one merge
//! task per frame. This module plans the work in an output folder and
//! reports on it; `slurm.rs` turns the plan into Slurm jobs. The library
//! knows nothing of batch systems: tasks run the `prism` command itself.
//!
//! The output folder holds `farm.toml` (the plan), `parts/` (the tiles as
//! they finish: written atomically, so a part that exists is whole),
//! `logs/`, the job scripts, and the merged frames.

/// `println!` that a reader who stops early (`| head`) does not turn into
/// a panic.
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout().lock(), $($arg)*);
    }};
}

mod openjd;
mod slurm;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Args, Subcommand};
use serde::{Deserialize, Serialize};

use crate::cli::{BAD_INPUT, parse_frames};

#[derive(Subcommand)]
pub enum FarmCommand {
    /// Write a Slurm job for SCENE: an array with one task per (frame,
    /// tile), throttled to K at once, and a merge job that runs after it.
    /// Run again after failures: only the missing parts are submitted.
    Slurm(SlurmArgs),
    /// Write an Open Job Description template for SCENE (a render step
    /// over Frame and Tile, a merge step after it), for `openjd run` or
    /// AWS Deadline Cloud.
    Openjd(FarmArgs),
    /// Show which frames and parts of a farm render are done and which are
    /// missing.
    Status {
        /// The output folder of `prism farm slurm`.
        outdir: PathBuf,
    },
}

/// What every farm render takes: the scene, where the output goes, how
/// the work is cut.
#[derive(Args)]
pub struct FarmArgs {
    /// Scene file (TOML).
    scene: PathBuf,
    /// Output folder: parts, logs, job scripts and the merged frames.
    #[arg(short, long)]
    output: PathBuf,
    /// Parts per frame (bands of rows, as `prism render --tile I/N`).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    tiles: u32,
    /// Frames A to B (inclusive).
    #[arg(long, value_name = "A-B", default_value = "0", value_parser = parse_frames)]
    frames: (u32, u32),
    /// Format of the merged frames: exr, png, ppm or hdr.
    #[arg(long, default_value = "exr", value_parser = ["exr", "png", "ppm", "hdr"])]
    format: String,
}

#[derive(Args)]
pub struct SlurmArgs {
    #[command(flatten)]
    common: FarmArgs,
    /// At most K tasks of the array run at once.
    #[arg(long, value_name = "K", value_parser = clap::value_parser!(u32).range(1..))]
    max_running: Option<u32>,
    /// Slurm partition.
    #[arg(long, value_name = "P")]
    partition: Option<String>,
    /// CPUs per task (each task renders on that many threads).
    #[arg(long, value_name = "C", value_parser = clap::value_parser!(u32).range(1..=1024))]
    cpus_per_task: Option<u32>,
    /// Submit the jobs with sbatch and print their IDs.
    #[arg(long)]
    submit: bool,
}

/// What to render, as saved in `farm.toml`; a later run must ask for the
/// same, or use another folder.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    /// The scene, absolute.
    pub scene: PathBuf,
    /// Parts per frame.
    pub tiles: u32,
    /// First and last frame.
    pub first_frame: u32,
    /// Last frame (inclusive).
    pub last_frame: u32,
    /// Extension of the merged frames.
    pub format: String,
}

impl Plan {
    /// Number of (frame, tile) tasks.
    pub fn task_count(&self) -> u64 {
        u64::from(self.last_frame - self.first_frame + 1) * u64::from(self.tiles)
    }

    /// Task `k`'s (frame, tile); the job scripts compute the same.
    pub fn task(&self, k: u64) -> (u32, u32) {
        let tiles = u64::from(self.tiles);
        (self.first_frame + (k / tiles) as u32, (k % tiles) as u32)
    }

    /// The part of `frame`'s tile `tile`, relative to the output folder.
    pub fn part(frame: u32, tile: u32) -> String {
        format!("parts/frame_{frame:04}_tile_{tile:04}.exr")
    }

    /// The merged frame, relative to the output folder.
    pub fn frame_file(&self, frame: u32) -> String {
        format!("frame_{frame:04}.{}", self.format)
    }

    fn frames(&self) -> std::ops::RangeInclusive<u32> {
        self.first_frame..=self.last_frame
    }
}

/// Where a farm render stands, from the files in its folder.
pub struct Progress {
    /// Frames merged.
    pub merged: Vec<u32>,
    /// Tasks whose part is missing and whose frame is not merged.
    pub missing_tasks: Vec<u64>,
    /// Frames with every part but no merged image.
    pub mergeable: Vec<u32>,
}

impl Progress {
    fn of(plan: &Plan, outdir: &Path) -> Progress {
        let merged: Vec<u32> = plan
            .frames()
            .filter(|&f| outdir.join(plan.frame_file(f)).is_file())
            .collect();
        let missing_tasks: Vec<u64> = (0..plan.task_count())
            .filter(|&k| {
                let (frame, tile) = plan.task(k);
                !merged.contains(&frame) && !outdir.join(Plan::part(frame, tile)).is_file()
            })
            .collect();
        let mergeable = plan
            .frames()
            .filter(|f| !merged.contains(f))
            .filter(|&f| (0..plan.tiles).all(|t| outdir.join(Plan::part(f, t)).is_file()))
            .collect();
        Progress {
            merged,
            missing_tasks,
            mergeable,
        }
    }
}

pub fn run(command: FarmCommand) -> ExitCode {
    let result = match command {
        FarmCommand::Slurm(args) => slurm::run(&args),
        FarmCommand::Openjd(args) => openjd::run(&args),
        FarmCommand::Status { outdir } => status(&outdir),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(Failure::BadInput(e)) => {
            eprintln!("error: {e}");
            ExitCode::from(BAD_INPUT)
        }
        Err(Failure::Failed(e)) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Why a farm command stopped.
pub enum Failure {
    /// The user asked for something impossible (exit 2).
    BadInput(String),
    /// The batch system or the file system failed (exit 1).
    Failed(String),
}

const PLAN: &str = "farm.toml";

/// The plan for `args` in its output folder: created on the first run,
/// and on later runs checked to be the same.
fn plan_in(args: &FarmArgs) -> Result<Plan, Failure> {
    let bad = Failure::BadInput;
    let scene = args
        .scene
        .canonicalize()
        .map_err(|e| bad(format!("{}: {e}", args.scene.display())))?;
    let plan = Plan {
        scene,
        tiles: args.tiles,
        first_frame: args.frames.0,
        last_frame: args.frames.1,
        format: args.format.clone(),
    };
    let outdir = &args.output;
    for sub in ["", "parts", "logs"] {
        std::fs::create_dir_all(outdir.join(sub))
            .map_err(|e| bad(format!("{}: {e}", outdir.join(sub).display())))?;
    }
    let path = outdir.join(PLAN);
    match std::fs::read_to_string(&path) {
        Ok(text) => {
            let old: Plan = toml::from_str(&text)
                .map_err(|e| bad(format!("{}: not a farm plan: {e}", path.display())))?;
            if old != plan {
                return Err(bad(format!(
                    "{}: holds another farm render ({} tiles, frames {}-{}, scene {}); \
                     use another folder",
                    outdir.display(),
                    old.tiles,
                    old.first_frame,
                    old.last_frame,
                    old.scene.display()
                )));
            }
        }
        Err(_) => {
            let text = toml::to_string(&plan).map_err(|e| Failure::Failed(e.to_string()))?;
            std::fs::write(&path, text)
                .map_err(|e| Failure::Failed(format!("{}: {e}", path.display())))?;
        }
    }
    Ok(plan)
}

fn status(outdir: &Path) -> Result<(), Failure> {
    let path = outdir.join(PLAN);
    let text = std::fs::read_to_string(&path).map_err(|e| {
        Failure::BadInput(format!(
            "{}: {e}; expected the output folder of `prism farm slurm`",
            path.display()
        ))
    })?;
    let plan: Plan = toml::from_str(&text)
        .map_err(|e| Failure::BadInput(format!("{}: not a farm plan: {e}", path.display())))?;
    let progress = Progress::of(&plan, outdir);
    // A reader that stops early (`| head`) is not an error.
    let mut out = std::io::stdout().lock();
    let frames = plan.last_frame - plan.first_frame + 1;
    let _ = writeln!(
        out,
        "{}: frames {}-{}, {} tiles each ({} tasks); scene {}",
        outdir.display(),
        plan.first_frame,
        plan.last_frame,
        plan.tiles,
        plan.task_count(),
        plan.scene.display()
    );
    let _ = writeln!(
        out,
        "merged: {} of {frames} frames; parts missing: {}",
        progress.merged.len(),
        progress.missing_tasks.len()
    );
    for f in plan.frames() {
        let done = (0..plan.tiles)
            .filter(|&t| outdir.join(Plan::part(f, t)).is_file())
            .count();
        let state = if progress.merged.contains(&f) {
            "merged".to_string()
        } else if progress.mergeable.contains(&f) {
            "all parts done, not merged".to_string()
        } else {
            let missing: Vec<String> = (0..plan.tiles)
                .filter(|&t| !outdir.join(Plan::part(f, t)).is_file())
                .map(|t| t.to_string())
                .collect();
            format!("missing tiles {}", missing.join(","))
        };
        let _ = writeln!(out, "frame {f}: {done}/{} parts; {state}", plan.tiles);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tasks_enumerate_every_frame_and_tile_once() {
        let plan = Plan {
            scene: PathBuf::from("/s.toml"),
            tiles: 3,
            first_frame: 5,
            last_frame: 6,
            format: "png".into(),
        };
        let tasks: Vec<(u32, u32)> = (0..plan.task_count()).map(|k| plan.task(k)).collect();
        assert_eq!(tasks, [(5, 0), (5, 1), (5, 2), (6, 0), (6, 1), (6, 2)]);
        assert_eq!(Plan::part(5, 2), "parts/frame_0005_tile_0002.exr");
        assert_eq!(plan.frame_file(6), "frame_0006.png");
    }
}
