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
        // One line; its pieces (paths, reasons read from the folder)
        // shown with control characters escaped.
        let _ = writeln!(
            std::io::stdout().lock(),
            "{}",
            prism::text::escape_controls(&format!($($arg)*))
        );
    }};
}

mod merge;
mod openjd;
mod slurm;

use std::collections::HashSet;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Args, Subcommand};
use prism::Scene;
use prism::render::Region;
use serde::{Deserialize, Serialize};

use crate::args::{BAD_INPUT, LoadArgs, parse_frames};

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
    /// missing, and why a merge failed.
    Status {
        /// The output folder of `prism farm slurm`.
        outdir: PathBuf,
    },
    /// Merge every frame of a farm render whose parts are all there, each
    /// on its own (what the merge job runs). A part the merge refuses is
    /// set aside in parts/refused/, so that a rerun renders it again.
    Merge {
        /// The output folder of `prism farm slurm`.
        outdir: PathBuf,
        /// Only this frame.
        #[arg(long, value_name = "F")]
        frame: Option<u32>,
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
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..=MAX_TILES as i64))]
    tiles: u32,
    /// Frames A to B (inclusive).
    #[arg(long, value_name = "A-B", default_value = "0", value_parser = parse_frames)]
    frames: (u32, u32),
    /// Format of the merged frames: exr, png, ppm or hdr.
    #[arg(long, default_value = "exr", value_parser = FORMATS)]
    format: String,
}

#[derive(Args)]
pub struct SlurmArgs {
    #[command(flatten)]
    common: FarmArgs,
    /// At most K tasks of the array run at once.
    #[arg(long, value_name = "K", value_parser = clap::value_parser!(u32).range(1..))]
    max_running: Option<u32>,
    /// Slurm partition (letters, digits, `_`, `.`, `-`; several separated
    /// by `,`).
    #[arg(long, value_name = "P")]
    partition: Option<String>,
    /// CPUs per task (each task renders on that many threads).
    #[arg(long, value_name = "C", value_parser = clap::value_parser!(u32).range(1..=1024))]
    cpus_per_task: Option<u32>,
    /// Submit the jobs with sbatch and print their IDs.
    #[arg(long)]
    submit: bool,
}

/// Formats of the merged frames.
const FORMATS: [&str; 4] = ["exr", "png", "ppm", "hdr"];
/// Most parts per frame.
pub const MAX_TILES: u32 = 100_000;
/// Most tasks (frames × tiles) in one farm render. Slurm allows at most
/// MaxArraySize − 1 as an array index (1001 by default, 4,000,001 at
/// most); `prism farm slurm` also checks the cluster's own value. A plan
/// this large is still read and reported on in seconds.
pub const MAX_TASKS: u64 = 1_000_000;

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
        (u64::from(self.last_frame) - u64::from(self.first_frame) + 1) * u64::from(self.tiles)
    }

    /// Task `k`'s (frame, tile); the job scripts compute the same.
    #[cfg(test)]
    pub fn task(&self, k: u64) -> (u32, u32) {
        let tiles = u64::from(self.tiles);
        (self.first_frame + (k / tiles) as u32, (k % tiles) as u32)
    }

    /// The part of `frame`'s tile `tile`, relative to the output folder.
    pub fn part(frame: u32, tile: u32) -> String {
        format!("parts/{}", Plan::part_name(frame, tile))
    }

    fn part_name(frame: u32, tile: u32) -> String {
        format!("frame_{frame:04}_tile_{tile:04}.exr")
    }

    /// The merged frame, relative to the output folder.
    pub fn frame_file(&self, frame: u32) -> String {
        format!("frame_{frame:04}.{}", self.format)
    }

    /// Why `frame`'s last merge failed, relative to the output folder.
    fn failure_file(frame: u32) -> String {
        format!("failed/frame_{frame:04}.txt")
    }

    fn frames(&self) -> std::ops::RangeInclusive<u32> {
        self.first_frame..=self.last_frame
    }

    /// The plan's own consistency, whether typed or read from a
    /// hand-edited `farm.toml`: a reversed range or a plan beyond the task
    /// limit is refused at once rather than enumerated.
    fn check(&self) -> Result<(), String> {
        if self.first_frame > self.last_frame {
            return Err(format!(
                "frames {}-{} are reversed",
                self.first_frame, self.last_frame
            ));
        }
        if !(1..=MAX_TILES).contains(&self.tiles) {
            return Err(format!(
                "{} tiles per frame: between 1 and {MAX_TILES} are allowed",
                self.tiles
            ));
        }
        if self.task_count() > MAX_TASKS {
            return Err(format!(
                "{} frames x {} tiles is {} tasks; a farm render may have at most {MAX_TASKS} \
                 (fewer tiles, or several renders of fewer frames)",
                u64::from(self.last_frame) - u64::from(self.first_frame) + 1,
                self.tiles,
                self.task_count()
            ));
        }
        if !FORMATS.contains(&self.format.as_str()) {
            return Err(format!(
                "format `{}`: expected one of {}",
                self.format,
                FORMATS.join(", ")
            ));
        }
        if !self.scene.is_absolute() {
            return Err(format!(
                "scene {}: expected an absolute path",
                self.scene.display()
            ));
        }
        Ok(())
    }

    /// Reads and checks the plan in `outdir`.
    fn read(outdir: &Path) -> Result<Plan, Failure> {
        let path = outdir.join(PLAN);
        let text = std::fs::read_to_string(&path).map_err(|e| {
            Failure::BadInput(format!(
                "{}: {e}; expected the output folder of `prism farm`",
                path.display()
            ))
        })?;
        let plan: Plan = toml::from_str(&text)
            .map_err(|e| Failure::BadInput(format!("{}: not a farm plan: {e}", path.display())))?;
        plan.check()
            .map_err(|e| Failure::BadInput(format!("{}: {e}", path.display())))?;
        Ok(plan)
    }
}

/// How far one frame of a farm render is.
pub struct FrameProgress {
    /// The frame.
    pub frame: u32,
    /// Whether its merged image exists.
    pub merged: bool,
    /// Its tiles whose part is missing.
    pub missing: Vec<u32>,
    /// Why its last merge failed, if it did and it is not merged since.
    pub failure: Option<String>,
}

/// Where a farm render stands, from the files in its folder.
pub struct Progress {
    /// Every frame of the plan, in order.
    pub frames: Vec<FrameProgress>,
    /// Tasks whose part is missing and whose frame is not merged.
    pub missing_tasks: Vec<u64>,
    /// Frames with every part but no merged image.
    pub mergeable: Vec<u32>,
}

impl Progress {
    /// One listing of each folder, not a look-up per file, so a plan of
    /// [`MAX_TASKS`] is read in a moment.
    fn of(plan: &Plan, outdir: &Path) -> Progress {
        let names = |dir: &Path| -> HashSet<String> {
            std::fs::read_dir(dir)
                .map(|d| {
                    d.flatten()
                        .filter(|e| e.file_type().is_ok_and(|t| t.is_file()))
                        .filter_map(|e| e.file_name().into_string().ok())
                        .collect()
                })
                .unwrap_or_default()
        };
        let top = names(outdir);
        let parts = names(&outdir.join("parts"));
        let mut frames = Vec::new();
        let mut missing_tasks = Vec::new();
        let mut mergeable = Vec::new();
        for (i, frame) in plan.frames().enumerate() {
            let merged = top.contains(&plan.frame_file(frame));
            let missing: Vec<u32> = (0..plan.tiles)
                .filter(|&t| !parts.contains(&Plan::part_name(frame, t)))
                .collect();
            if !merged {
                let first_task = i as u64 * u64::from(plan.tiles);
                missing_tasks.extend(missing.iter().map(|&t| first_task + u64::from(t)));
                if missing.is_empty() {
                    mergeable.push(frame);
                }
            }
            let failure = if merged {
                None
            } else {
                // A merge's reason is a line or two: read as a regular
                // file, never more than 64 KiB of it.
                prism::scene::resources::read_regular(
                    &outdir.join(Plan::failure_file(frame)),
                    prism::scene::resources::Extent::Whole(1 << 16),
                )
                .ok()
                .map(|b| String::from_utf8_lossy(&b).into_owned())
            };
            frames.push(FrameProgress {
                frame,
                merged,
                missing,
                failure,
            });
        }
        Progress {
            frames,
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
        FarmCommand::Merge { outdir, frame } => merge::run(&outdir, frame),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(Failure::BadInput(e)) => {
            say_err!("error: {e}");
            ExitCode::from(BAD_INPUT)
        }
        Err(Failure::Failed(e)) => {
            say_err!("error: {e}");
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

/// `path` as text a job script can carry: valid UTF-8 and no control
/// characters (a newline would end a line of the script or the job
/// description). Everything else is quoted where it is used.
fn carriable<'a>(path: &'a Path, what: &str, backend: &str) -> Result<&'a str, Failure> {
    let text = path.to_str().ok_or_else(|| {
        Failure::BadInput(format!(
            "{what} {}: is not valid UTF-8, which {backend} cannot carry; rename it",
            path.display()
        ))
    })?;
    if let Some(c) = text.chars().find(|c| c.is_control()) {
        let name = match c {
            '\n' => "a newline".to_string(),
            '\r' => "a carriage return".to_string(),
            '\t' => "a tab".to_string(),
            c => format!("the control character U+{:04X}", u32::from(c)),
        };
        return Err(Failure::BadInput(format!(
            "{what} {text:?}: contains {name}, which {backend} cannot carry; rename it"
        )));
    }
    Ok(text)
}

/// `s` as one word for a POSIX shell: as is when it holds nothing the
/// shell would interpret, else in single quotes.
pub fn shell_word(s: &str) -> String {
    let plain = !s.is_empty()
        && s.bytes()
            .all(|b| b.is_ascii_alphanumeric() || b"/._-+,:=@".contains(&b));
    if plain {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', r"'\''"))
    }
}

/// The paths a job script names, as text checked by [`carriable`] for
/// the backend (valid UTF-8, no control characters).
struct Paths {
    outdir: PathBuf,
    outdir_text: String,
    scene: String,
    prism: String,
}

impl Paths {
    fn outdir(&self) -> &str {
        &self.outdir_text
    }

    fn scene(&self) -> &str {
        &self.scene
    }

    fn prism(&self) -> &str {
        &self.prism
    }
}

/// Checks everything a farm render needs before anything is written: the
/// paths (for `backend`), the scene (loaded as a task will load it), the
/// tiles against the image height, the frames against the animation, the
/// task limit, the merged frames' format. Then creates the output folder
/// and its plan (or checks that an earlier run planned the same).
fn plan_in(args: &FarmArgs, backend: &str) -> Result<(Plan, Paths), Failure> {
    let bad = Failure::BadInput;
    carriable(&args.scene, "the scene", backend)?;
    carriable(&args.output, "the output folder", backend)?;
    let scene = args
        .scene
        .canonicalize()
        .map_err(|e| bad(format!("{}: {e}", args.scene.display())))?;
    let prism = std::env::current_exe()
        .and_then(|p| p.canonicalize())
        .map_err(|e| Failure::Failed(format!("cannot find the prism executable: {e}")))?;
    let prism = carriable(&prism, "the prism executable", backend)?.to_string();
    let scene_text = carriable(&scene, "the scene", backend)?.to_string();
    let plan = Plan {
        scene,
        tiles: args.tiles,
        first_frame: args.frames.0,
        last_frame: args.frames.1,
        format: args.format.clone(),
    };
    plan.check().map_err(bad)?;
    check_scene(&plan)?;

    let outdir = &args.output;
    for sub in ["", "parts", "logs"] {
        std::fs::create_dir_all(outdir.join(sub))
            .map_err(|e| bad(format!("{}: {e}", outdir.join(sub).display())))?;
    }
    let outdir = outdir
        .canonicalize()
        .map_err(|e| Failure::Failed(format!("{}: {e}", outdir.display())))?;
    let outdir_text = carriable(&outdir, "the output folder", backend)?.to_string();
    prism::image_io::check_writable(&outdir.join(plan.frame_file(plan.first_frame)))
        .map_err(|e| bad(e.to_string()))?;
    let path = outdir.join(PLAN);
    if path.exists() {
        let old = Plan::read(&outdir)?;
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
    } else {
        let text = toml::to_string(&plan).map_err(|e| Failure::Failed(e.to_string()))?;
        write_file(&path, &text)?;
    }
    Ok((
        plan.clone(),
        Paths {
            outdir,
            outdir_text,
            scene: scene_text,
            prism,
        },
    ))
}

/// Loads the scene at the plan's first and last frame, as the tasks will,
/// and checks the work fits it: the scene's errors (with their lines), its
/// render settings, a tile count the image height allows, frames inside
/// its animation.
fn check_scene(plan: &Plan) -> Result<(), Failure> {
    let options = LoadArgs::default().options().map_err(Failure::BadInput)?;
    for frame in [plan.first_frame, plan.last_frame] {
        let scene = Scene::load_with(
            &plan.scene,
            &prism::scene::LoadOptions {
                frame,
                ..options.clone()
            },
        )
        .map_err(|e| Failure::BadInput(e.to_string()))?;
        let settings = scene.settings;
        settings.check().map_err(Failure::BadInput)?;
        Region::tile(0, plan.tiles, settings.width, settings.height)
            .map_err(|e| Failure::BadInput(format!("--tiles {}: {e}", plan.tiles)))?;
        if let Some(animation) = scene.animation
            && plan.last_frame >= animation.frames
        {
            return Err(Failure::BadInput(format!(
                "frame {} is past the animation's last frame {} ([animation] frames = {} in {})",
                plan.last_frame,
                animation.frames - 1,
                animation.frames,
                plan.scene.display()
            )));
        }
        if !scene.animated {
            break;
        }
    }
    Ok(())
}

/// Writes `text` to `path` through a temporary file renamed into place.
fn write_file(path: &Path, text: &str) -> Result<(), Failure> {
    let failed = |e: std::io::Error| Failure::Failed(format!("{}: {e}", path.display()));
    let dir = path.parent().unwrap_or(Path::new("."));
    let mut temp = tempfile::NamedTempFile::new_in(dir).map_err(failed)?;
    temp.write_all(text.as_bytes()).map_err(failed)?;
    temp.persist(path).map_err(|e| failed(e.error))?;
    Ok(())
}

fn status(outdir: &Path) -> Result<(), Failure> {
    let plan = Plan::read(outdir)?;
    let progress = Progress::of(&plan, outdir);
    let merged = progress.frames.iter().filter(|f| f.merged).count();
    say!(
        "{}: frames {}-{}, {} tiles each ({} tasks); scene {}",
        outdir.display(),
        plan.first_frame,
        plan.last_frame,
        plan.tiles,
        plan.task_count(),
        plan.scene.display()
    );
    say!(
        "merged: {merged} of {} frames; parts missing: {}",
        progress.frames.len(),
        progress.missing_tasks.len()
    );
    for f in &progress.frames {
        let done = plan.tiles as usize - f.missing.len();
        let state = if f.merged {
            "merged".to_string()
        } else if let Some(why) = &f.failure {
            format!("merge failed: {}", why.trim())
        } else if f.missing.is_empty() {
            "all parts done, not merged".to_string()
        } else {
            let missing: Vec<String> = f.missing.iter().map(u32::to_string).collect();
            format!("missing tiles {}", missing.join(","))
        };
        say!("frame {}: {done}/{} parts; {state}", f.frame, plan.tiles);
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
        assert!(plan.check().is_ok());
        let tasks: Vec<(u32, u32)> = (0..plan.task_count()).map(|k| plan.task(k)).collect();
        assert_eq!(tasks, [(5, 0), (5, 1), (5, 2), (6, 0), (6, 1), (6, 2)]);
        assert_eq!(Plan::part(5, 2), "parts/frame_0005_tile_0002.exr");
        assert_eq!(plan.frame_file(6), "frame_0006.png");
    }

    #[test]
    fn plans_beyond_the_limits_are_refused_at_once() {
        let plan = Plan {
            scene: PathBuf::from("/s.toml"),
            tiles: 100_000,
            first_frame: 0,
            last_frame: u32::MAX,
            format: "exr".into(),
        };
        assert!(plan.check().unwrap_err().contains("at most 1000000"));
        let reversed = Plan {
            first_frame: 5,
            last_frame: 4,
            tiles: 1,
            ..plan.clone()
        };
        assert!(reversed.check().unwrap_err().contains("reversed"));
        let relative = Plan {
            scene: PathBuf::from("s.toml"),
            last_frame: 0,
            tiles: 1,
            ..plan
        };
        assert!(relative.check().is_err());
    }

    #[test]
    fn shell_words_are_quoted_when_needed() {
        assert_eq!(shell_word("/a/b-c_d.toml"), "/a/b-c_d.toml");
        assert_eq!(shell_word("a b"), "'a b'");
        assert_eq!(shell_word("it's $(x)"), r"'it'\''s $(x)'");
        assert_eq!(shell_word(""), "''");
    }
}
