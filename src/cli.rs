//! Command-line interface: argument parsing, progress display, exit codes.
//! No rendering logic lives here; it calls the `prism` library.
//!
//! Exit codes: 0 success, 1 a failure while rendering or writing, 2 bad
//! input (arguments, scene file, output path), 130 interrupted (SIGINT,
//! SIGTERM or SIGHUP); on bad input or interruption nothing is written and
//! no temporary file remains (SIGKILL cannot be caught: its one exception).

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use prism::image_io::{ImageWriteError, check_writable, write_film_unless};
use prism::render::RenderError;
use prism::scene::LoadOptions;
use prism::{RenderObserver, RenderSettings, Scene, SceneError, limits, render};

/// Prism, an exact Whitted-style ray tracer.
#[derive(Parser)]
#[command(name = "prism", version, about, after_help = limits::describe())]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene to an image (.png, .ppm, .exr, .hdr).
    Render(RenderArgs),
    /// Validate a scene file without rendering; reports every problem.
    #[command(after_help = limits::describe())]
    Check {
        /// The scene file (TOML).
        scene: PathBuf,
        #[command(flatten)]
        load: LoadArgs,
    },
}

/// What a scene may read and use while loading.
#[derive(Args)]
struct LoadArgs {
    /// Let the scene read files below DIR too (repeatable). By default a
    /// scene reads only below its own folder; PRISM_ALLOW_READ adds folders
    /// separated by ':'.
    #[arg(long, value_name = "DIR")]
    allow_read: Vec<PathBuf>,
    /// Memory for decoded textures, in MiB.
    #[arg(long, value_name = "MIB", default_value_t = limits::DEFAULT_TEXTURE_MIB,
          value_parser = clap::value_parser!(u64).range(1..=1 << 30))]
    texture_memory: u64,
}

impl LoadArgs {
    /// The load options, or a message naming a folder that does not exist.
    fn options(&self) -> Result<LoadOptions, String> {
        let from_env = std::env::var_os("PRISM_ALLOW_READ")
            .map(|v| std::env::split_paths(&v).collect::<Vec<_>>())
            .unwrap_or_default();
        let mut allow_read = Vec::new();
        for dir in self.allow_read.iter().chain(&from_env) {
            if dir.as_os_str().is_empty() {
                continue;
            }
            if !dir.is_dir() {
                return Err(format!(
                    "{}: --allow-read (or PRISM_ALLOW_READ) names no folder",
                    dir.display()
                ));
            }
            allow_read.push(dir.clone());
        }
        Ok(LoadOptions {
            allow_read,
            texture_budget: self.texture_memory << 20,
        })
    }
}

#[derive(Args)]
#[command(after_help = limits::describe(), allow_negative_numbers = true)]
struct RenderArgs {
    /// Scene file (TOML); the built-in demo scene when omitted.
    scene: Option<PathBuf>,
    /// Output image; the format follows the extension.
    #[arg(short, long, default_value = "render.png")]
    output: PathBuf,
    /// Image width in pixels (overrides the scene).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=i64::from(limits::MAX_IMAGE_SIDE)))]
    width: Option<u32>,
    /// Image height in pixels (overrides the scene).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=i64::from(limits::MAX_IMAGE_SIDE)))]
    height: Option<u32>,
    /// Samples per pixel (overrides the scene).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=i64::from(limits::MAX_SPP)))]
    spp: Option<u32>,
    /// Longest ray path counting the camera ray (overrides the scene).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=i64::from(limits::MAX_DEPTH)))]
    max_depth: Option<u32>,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    threads: Option<u32>,
    /// Seed of the sample streams (overrides the scene).
    #[arg(long)]
    seed: Option<u64>,
    /// Print nothing but errors.
    #[arg(short, long)]
    quiet: bool,
    #[command(flatten)]
    load: LoadArgs,
}

const BAD_INPUT: u8 = 2;
/// 128 + SIGINT, what shells report for a program stopped by Ctrl-C.
const INTERRUPTED: u8 = 130;

/// Progress on the bar; cancellation from Ctrl-C.
struct CliObserver {
    bar: ProgressBar,
    interrupted: Arc<AtomicBool>,
}

impl RenderObserver for CliObserver {
    fn tile_done(&self, pixels_done: u64) {
        self.bar.set_position(pixels_done);
    }

    fn cancelled(&self) -> bool {
        self.interrupted.load(Ordering::Relaxed)
    }
}

/// Runs the command line and returns the process exit code.
pub fn run() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            return ExitCode::from(if e.use_stderr() { BAD_INPUT } else { 0 });
        }
    };
    match cli.command {
        Command::Check { scene, load } => check(&scene, &load),
        Command::Render(args) => render_command(&args),
    }
}

fn report_scene_error(e: &SceneError) -> ExitCode {
    eprintln!("{e}");
    ExitCode::from(BAD_INPUT)
}

fn check(path: &Path, load: &LoadArgs) -> ExitCode {
    let options = match load.options() {
        Ok(o) => o,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(BAD_INPUT);
        }
    };
    let start = Instant::now();
    match Scene::load_with(path, &options) {
        Ok(scene) => {
            let total = start.elapsed();
            for w in &scene.warnings {
                eprintln!("warning: {w}");
            }
            let c = scene.census();
            let inv = &scene.inventory;
            println!(
                "{}: ok ({} objects, {} lights, {} materials)\n\
                 primitives: {} spheres, {} planes, {} polygons, {} mesh instances\n\
                 meshes: {} stored ({} triangles), {} triangles placed\n\
                 textures: {} ({:.1} MiB)\n\
                 estimated memory: {:.1} MiB\n\
                 load {:.2} s, build {:.2} s",
                path.display(),
                scene.aggregate.primitives().len(),
                scene.lights.len(),
                scene.materials.len(),
                c.spheres,
                c.planes,
                c.polygons,
                c.mesh_instances,
                c.meshes,
                c.triangles,
                c.placed_triangles,
                inv.textures,
                inv.texture_bytes as f64 / (1 << 20) as f64,
                c.memory_bytes as f64 / (1 << 20) as f64,
                total.saturating_sub(inv.build_time).as_secs_f64(),
                inv.build_time.as_secs_f64(),
            );
            ExitCode::SUCCESS
        }
        Err(e) => report_scene_error(&e),
    }
}

fn render_command(args: &RenderArgs) -> ExitCode {
    // Everything the user could have got wrong is checked before rendering,
    // the output location first (a file is created there and removed).
    if let Err(e) = check_writable(&args.output) {
        eprintln!("error: {e}");
        return ExitCode::from(BAD_INPUT);
    }
    let options = match args.load.options() {
        Ok(o) => o,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(BAD_INPUT);
        }
    };
    let load_start = Instant::now();
    let scene = match &args.scene {
        Some(path) => match Scene::load_with(path, &options) {
            Ok(s) => s,
            Err(e) => return report_scene_error(&e),
        },
        None => Scene::demo(),
    };
    let load_time = load_start.elapsed();
    if !args.quiet {
        for w in &scene.warnings {
            eprintln!("warning: {w}");
        }
    }
    let settings = RenderSettings {
        width: args.width.unwrap_or(scene.settings.width),
        height: args.height.unwrap_or(scene.settings.height),
        spp: args.spp.unwrap_or(scene.settings.spp),
        max_depth: args.max_depth.unwrap_or(scene.settings.max_depth),
        seed: args.seed.unwrap_or(scene.settings.seed),
        threads: args.threads.map(|t| t as usize),
        ..scene.settings
    };
    if let Err(e) = settings.check() {
        eprintln!("error: {e}");
        return ExitCode::from(BAD_INPUT);
    }
    let threads = settings.threads.unwrap_or_else(rayon::current_num_threads);
    let pixels = u64::from(settings.width) * u64::from(settings.height);
    let bar = if args.quiet {
        ProgressBar::hidden()
    } else if std::io::stderr().is_terminal() {
        let bar = ProgressBar::new(pixels);
        bar.set_style(
            ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] {wide_bar} {percent:>3}% ETA {eta}",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        bar
    } else {
        eprintln!(
            "prism: rendering {}x{}, {} spp, {} threads",
            settings.width, settings.height, settings.spp, threads
        );
        ProgressBar::hidden()
    };
    let observer = CliObserver {
        bar,
        interrupted: Arc::new(AtomicBool::new(false)),
    };
    let flag = Arc::clone(&observer.interrupted);
    // Whether the image is being written; the handler holds the lock while
    // it decides, so it never exits between the temporary file's creation
    // and its rename or removal.
    let writing = Arc::new(Mutex::new(false));
    let handler_writing = Arc::clone(&writing);
    // SIGINT, SIGTERM or SIGHUP: stop at the next row, or abandon the write
    // (the temporary file is removed), and write nothing. A second signal
    // while rendering exits at once; while writing, the write is already
    // stopping.
    let _ = ctrlc::set_handler(move || {
        let again = flag.swap(true, Ordering::SeqCst);
        let writing = handler_writing.lock().unwrap_or_else(|p| p.into_inner());
        if again && !*writing {
            std::process::exit(INTERRUPTED.into());
        }
    });
    let output = match render(&scene, &settings, &observer) {
        Ok(o) => o,
        Err(RenderError::Cancelled) => {
            observer.bar.abandon();
            eprintln!("prism: interrupted; nothing was written");
            return ExitCode::from(INTERRUPTED);
        }
        Err(e) => {
            observer.bar.abandon();
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    };
    observer.bar.finish_and_clear();
    *writing.lock().unwrap_or_else(|p| p.into_inner()) = true;
    let write_start = Instant::now();
    match write_film_unless(&output.film, &args.output, &observer.interrupted) {
        Ok(()) => {}
        Err(ImageWriteError::Interrupted { .. }) => {
            eprintln!("prism: interrupted; nothing was written");
            return ExitCode::from(INTERRUPTED);
        }
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    }
    if !args.quiet {
        let s = output.stats;
        eprintln!(
            "prism: {}x{} {} spp, {} threads; load {:.2} s, build {:.2} s, render {:.2} s, write {:.2} s; rays: {} camera, {} reflection, {} refraction, {} shadow; {:.2} Mrays/s -> {}",
            settings.width,
            settings.height,
            settings.spp,
            threads,
            load_time
                .saturating_sub(scene.inventory.build_time)
                .as_secs_f64(),
            scene.inventory.build_time.as_secs_f64(),
            output.elapsed.as_secs_f64(),
            write_start.elapsed().as_secs_f64(),
            s.camera,
            s.reflection,
            s.refraction,
            s.shadow,
            s.mrays_per_second(output.elapsed),
            args.output.display()
        );
    }
    ExitCode::SUCCESS
}
