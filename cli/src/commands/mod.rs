//! Command-line interface: argument parsing, progress display, exit codes.
//! No rendering logic lives here; it calls the `prism` library.
//!
//! Exit codes: 0 success, 1 a failure while rendering or writing, 2 bad
//! input (arguments, scene file, output path), 130 interrupted (SIGINT,
//! SIGTERM or SIGHUP); on bad input or interruption nothing is written and
//! no temporary file remains (SIGKILL cannot be caught: its one exception).

mod explain;
mod merge;
mod render;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use clap::{Parser, Subcommand};
use prism::{Scene, SceneError, limits};

pub use crate::args::{BAD_INPUT, INTERRUPTED, LoadArgs};
use crate::farm::FarmCommand;
use explain::ExplainArgs;
use merge::MergeArgs;
use render::RenderArgs;

/// Prism, an exact Whitted-style ray tracer.
#[derive(Parser)]
#[command(name = "prism", version, about, after_help = limits::describe())]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene to an image (.png, .ppm, .exr, .hdr), a region of it
    /// or a range of frames.
    Render(RenderArgs),
    /// Preview a scene in the browser: renders as you save, shows errors,
    /// explains pixels.
    Serve(crate::serve::ServeArgs),
    /// Explain one pixel: its ray tree and the terms of the Whitted
    /// formula at every hit.
    Explain(ExplainArgs),
    /// Merge EXR parts of one frame (from --crop or --tile) into the whole
    /// image.
    Merge(MergeArgs),
    /// Render on a batch system: write (and submit) the jobs, or report
    /// what is done.
    #[command(subcommand)]
    Farm(FarmCommand),
    /// Validate a scene file without rendering; reports every problem.
    #[command(after_help = limits::describe())]
    Check {
        /// The scene file (TOML).
        scene: PathBuf,
        #[command(flatten)]
        load: LoadArgs,
    },
}

/// Runs the command line and returns the process exit code.
pub fn run() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) if !e.use_stderr() => {
            // --help, --version: the command's own text.
            let _ = e.print();
            return ExitCode::SUCCESS;
        }
        Err(e) => {
            eprint!("{}", escaped_usage_error(&e));
            return ExitCode::from(BAD_INPUT);
        }
    };
    match cli.command {
        Command::Check { scene, load } => check(&scene, &load),
        Command::Render(args) => render::render_command(&args),
        Command::Merge(args) => merge::merge_command(&args),
        Command::Explain(args) => explain::explain_command(&args),
        Command::Serve(args) => crate::serve::run(&args),
        Command::Farm(command) => crate::farm::run(command),
    }
}

/// clap's message for bad arguments (several lines: the error, usage, a
/// tip), with every argument it quotes shown escaped: the arguments are
/// escaped and parsed again for the message, so a value cannot drive the
/// terminal or forge a line. Any control character left is escaped too,
/// the message's own line breaks kept.
fn escaped_usage_error(e: &clap::Error) -> String {
    let escaped: Vec<String> = std::env::args_os()
        .map(|a| prism::text::escape_controls(&a.to_string_lossy()).into_owned())
        .collect();
    let text = match Cli::try_parse_from(&escaped) {
        Err(again) if again.kind() == e.kind() => again.render().to_string(),
        _ => e.render().to_string(),
    };
    text.split('\n')
        .map(|line| prism::text::escape_controls(line).into_owned())
        .collect::<Vec<_>>()
        .join("\n")
}

fn report_scene_error(e: &SceneError) -> ExitCode {
    // Several lines, each escaped by the library (SceneError's Display).
    eprintln!("{e}");
    ExitCode::from(BAD_INPUT)
}

fn check(path: &Path, load: &LoadArgs) -> ExitCode {
    let options = match load.options() {
        Ok(o) => o,
        Err(e) => {
            say_err!("error: {e}");
            return ExitCode::from(BAD_INPUT);
        }
    };
    let start = Instant::now();
    match Scene::load_with(path, &options) {
        Ok(scene) => {
            let total = start.elapsed();
            for w in &scene.warnings {
                say_err!("warning: {w}");
            }
            let c = scene.census();
            let instants_bytes: u64 = scene.motion.iter().map(|s| s.census().memory_bytes).sum();
            let inv = &scene.inventory;
            // A reader that stops early (`| head`) is not an error.
            let _ = writeln!(
                std::io::stdout().lock(),
                "{}: ok ({} objects, {} lights, {} materials)\n\
                 primitives: {} spheres, {} planes, {} polygons, {} boxes, {} cones and \
                 cylinders, {} discs, {} tori, {} mesh instances, {} CSG operations\n\
                 meshes: {} stored ({} triangles), {} triangles placed\n\
                 textures: {} ({:.1} MiB)\n\
                 estimated memory: {:.1} MiB\n\
                 lights: {}{}\n\
                 load {:.2} s, build {:.2} s",
                prism::text::Shown(path.display()),
                scene.aggregate.primitives().len(),
                scene.lights.len(),
                scene.materials.len(),
                c.spheres,
                c.planes,
                c.polygons,
                c.boxes,
                c.cones,
                c.discs,
                c.tori,
                c.mesh_instances,
                c.csg,
                c.meshes,
                c.triangles,
                c.placed_triangles,
                inv.textures,
                inv.texture_bytes as f64 / (1 << 20) as f64,
                (c.memory_bytes + instants_bytes) as f64 / (1 << 20) as f64,
                light_summary(&scene.lights),
                if scene.motion.is_empty() {
                    String::new()
                } else {
                    format!(
                        "\nshutter: {} instants, each a scene built apart (counted in the memory)",
                        scene.motion.len()
                    )
                },
                total.saturating_sub(inv.build_time).as_secs_f64(),
                inv.build_time.as_secs_f64(),
            );
            ExitCode::SUCCESS
        }
        Err(e) => report_scene_error(&e),
    }
}

/// "2 sphere, 1 rectangle; 48 shadow feelers per shading point" (each kind
/// in the order the scene first names it), or "none".
fn light_summary(lights: &[prism::lights::Light]) -> String {
    if lights.is_empty() {
        return "none".into();
    }
    let mut kinds: Vec<(&str, usize)> = Vec::new();
    for light in lights {
        let kind = light.shape.kind();
        match kinds.iter_mut().find(|(k, _)| *k == kind) {
            Some((_, n)) => *n += 1,
            None => kinds.push((kind, 1)),
        }
    }
    let feelers: u64 = lights.iter().map(|l| u64::from(l.shape.feelers())).sum();
    let kinds: Vec<String> = kinds.iter().map(|(k, n)| format!("{n} {k}")).collect();
    format!(
        "{}; up to {feelers} shadow feelers per shading point",
        kinds.join(", ")
    )
}
