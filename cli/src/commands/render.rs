//! `prism render`: one image, a region of it (`--crop`, `--tile`), or a
//! range of frames; optionally resumable (`--checkpoint`).

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use clap::Args;
use glam::DVec3;
use indicatif::{ProgressBar, ProgressStyle};
use prism::image_io::OutputFormat;
use prism::image_io::{ImageWriteError, Provenance, check_writable, write_film_unless};
use prism::render::aov::{Aov, false_colour, render_aov};
use prism::render::{Checkpoint, Region, RenderError, render_region};
use prism::{RenderObserver, RenderSettings, Scene, limits};

use super::{BAD_INPUT, INTERRUPTED, LoadArgs, report_scene_error};
use crate::args::parse_frames;
use crate::tev::Tev;

#[derive(Args)]
#[command(after_help = limits::describe(), allow_negative_numbers = true)]
pub struct RenderArgs {
    /// Scene file (TOML); the built-in demo scene when omitted.
    scene: Option<PathBuf>,
    /// Output image; the format follows the extension. A run of `#` is
    /// replaced by the frame number, zero-padded to its length
    /// (`out_####.png`); needed with --frames.
    #[arg(short, long, default_value = "render.png")]
    output: PathBuf,
    #[command(flatten)]
    overrides: SettingsArgs,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=i64::from(limits::MAX_THREADS)))]
    threads: Option<u32>,
    /// Render only pixels X0 <= x < X1, Y0 <= y < Y1 (EXR: a data window in
    /// the whole frame; other formats: the region alone).
    #[arg(long, value_name = "X0,X1,Y0,Y1", value_parser = parse_crop, conflicts_with = "tile")]
    crop: Option<[u32; 4]>,
    /// Render part I of N (0 <= I < N): the frame cut into N bands of whole
    /// rows, band I holding rows floor(I*H/N) to floor((I+1)*H/N).
    #[arg(long, value_name = "I/N", value_parser = parse_tile)]
    tile: Option<(u32, u32)>,
    /// Render frame F of the animation.
    #[arg(long, value_name = "F", conflicts_with = "frames")]
    frame: Option<u32>,
    /// Render frames A to B (inclusive), one image each.
    #[arg(long, value_name = "A-B", value_parser = parse_frames)]
    frames: Option<(u32, u32)>,
    /// Save finished tiles in DIR as they finish; run the same command
    /// again after an interruption or crash and only the missing tiles are
    /// rendered. DIR is removed once the image is written.
    #[arg(long, value_name = "DIR")]
    checkpoint: Option<PathBuf>,
    /// Write a debug view instead of the picture: normal, depth, object,
    /// material, bounces, feelers or time (EXR: raw values; PNG, PPM:
    /// false colour).
    #[arg(long, value_name = "NAME")]
    aov: Option<Aov>,
    /// Stream the tiles to the tev image viewer listening at HOST:PORT
    /// (tev's default port is 14158).
    #[arg(long, value_name = "HOST:PORT")]
    display_server: Option<String>,
    /// Print nothing but errors.
    #[arg(short, long)]
    quiet: bool,
    #[command(flatten)]
    load: LoadArgs,
}

/// Settings the command line may override.
#[derive(Args)]
pub struct SettingsArgs {
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
    /// Seed of the sample streams (overrides the scene).
    #[arg(long)]
    seed: Option<u64>,
    /// Exposure in stops for PNG and PPM output: radiance × 2^EV before
    /// the 8-bit encoding (overrides the scene; EXR and HDR stay linear).
    #[arg(long, value_name = "EV", allow_hyphen_values = true,
          value_parser = parse_exposure)]
    exposure: Option<f64>,
}

fn parse_exposure(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if (-64.0..=64.0).contains(&v) => Ok(v),
        _ => Err(format!(
            "expected a number of stops between -64 and 64, got `{s}`"
        )),
    }
}

impl SettingsArgs {
    /// The scene's settings with these overrides; an error when a side
    /// derived from a model camera's shape is past the limits.
    pub fn apply(&self, scene: &RenderSettings) -> Result<RenderSettings, String> {
        // A model camera's shape: one side given here derives the other.
        let (width, height) = match (scene.aspect, self.width, self.height) {
            (Some(aspect), Some(_), None) | (Some(aspect), None, Some(_)) => {
                prism::settings::image_shape(aspect, self.width, self.height)?
            }
            _ => (
                self.width.unwrap_or(scene.width),
                self.height.unwrap_or(scene.height),
            ),
        };
        Ok(RenderSettings {
            exposure: self.exposure.unwrap_or(scene.exposure),
            width,
            height,
            spp: self.spp.unwrap_or(scene.spp),
            max_depth: self.max_depth.unwrap_or(scene.max_depth),
            seed: self.seed.unwrap_or(scene.seed),
            ..*scene
        })
    }
}

fn parse_crop(s: &str) -> Result<[u32; 4], String> {
    let v: Vec<u32> = s
        .split(',')
        .map(|p| p.trim().parse())
        .collect::<Result<_, _>>()
        .map_err(|_| "expected four pixel bounds X0,X1,Y0,Y1 (whole numbers)".to_string())?;
    v.try_into()
        .map_err(|_| "expected four pixel bounds X0,X1,Y0,Y1".to_string())
}

fn parse_tile(s: &str) -> Result<(u32, u32), String> {
    let (i, n) = s.split_once('/').ok_or("expected I/N, e.g. 0/8")?;
    let (i, n) = (
        i.trim()
            .parse::<u32>()
            .map_err(|_| "expected I/N with whole numbers")?,
        n.trim()
            .parse::<u32>()
            .map_err(|_| "expected I/N with whole numbers")?,
    );
    if n == 0 || i >= n {
        return Err(format!("tile {i}/{n}: needs 0 <= I < N"));
    }
    Ok((i, n))
}

/// `path` with its run of `#` replaced by `frame`, zero-padded to the run's
/// length; `None` when it has no `#`.
pub fn frame_path(path: &Path, frame: u32) -> Option<PathBuf> {
    let name = path.file_name()?.to_str()?;
    let start = name.find('#')?;
    let len = name[start..].chars().take_while(|&c| c == '#').count();
    let named = format!("{}{frame:0len$}{}", &name[..start], &name[start + len..]);
    Some(path.with_file_name(named))
}

/// Progress on the bar or as log lines; checkpoint tiles; cancellation
/// from Ctrl-C.
struct CliObserver<'a> {
    bar: ProgressBar,
    /// Log lines `prism: progress ...` for batch logs (no terminal).
    log: Option<String>,
    total: u64,
    logged_percent: AtomicU64,
    interrupted: Arc<AtomicBool>,
    checkpoint: Option<Checkpoint>,
    checkpoint_error: Mutex<Option<String>>,
    tev: Option<&'a Tev>,
}

impl RenderObserver for CliObserver<'_> {
    fn tile_done(&self, tile: Region, pixels: &[DVec3], pixels_done: u64) {
        self.bar.set_position(pixels_done);
        if let Some(tev) = self.tev {
            tev.update(tile, pixels);
        }
        if let Some(c) = &self.checkpoint
            && let Err(e) = c.save(tile, pixels)
        {
            self.checkpoint_error
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .get_or_insert(e);
        }
        if let Some(what) = &self.log {
            // One line per 5 %: what a log reader parses.
            let percent = pixels_done * 100 / self.total.max(1);
            let step = percent / 5 * 5;
            if self.logged_percent.fetch_max(step + 1, Ordering::Relaxed) < step + 1 {
                say_err!(
                    "prism: progress {what} pixels={pixels_done}/{} percent={step}",
                    self.total
                );
            }
        }
    }

    fn finished_before(&self, tile: Region) -> Option<Vec<DVec3>> {
        self.checkpoint.as_ref()?.take(tile)
    }

    fn cancelled(&self) -> bool {
        self.interrupted.load(Ordering::Relaxed)
            || self
                .checkpoint_error
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .is_some()
    }
}

pub fn render_command(args: &RenderArgs) -> ExitCode {
    let bad = |message: String| {
        say_err!("error: {message}");
        ExitCode::from(BAD_INPUT)
    };
    let frames = match (args.frame, args.frames) {
        (Some(f), _) => (f, f),
        (None, Some(range)) => range,
        (None, None) => (0, 0),
    };
    let several = frames.0 != frames.1;
    let outputs: Vec<(u32, PathBuf)> = match (several, frame_path(&args.output, frames.0)) {
        (true, None) => {
            return bad(format!(
                "{}: several frames need a run of # in the output name for the frame number (e.g. out_####.png)",
                args.output.display()
            ));
        }
        (_, None) => vec![(frames.0, args.output.clone())],
        (_, Some(_)) => (frames.0..=frames.1)
            .filter_map(|f| Some((f, frame_path(&args.output, f)?)))
            .collect(),
    };
    // Everything the user could have got wrong is checked before
    // rendering, the output location first (a file is created there and
    // removed).
    for (_, path) in &outputs {
        if let Err(e) = check_writable(path) {
            return bad(e.to_string());
        }
    }
    let mut options = match args.load.options() {
        Ok(o) => o,
        Err(e) => return bad(e),
    };
    options.frame = frames.0;
    let load = |options: &prism::scene::LoadOptions| {
        let start = Instant::now();
        let scene = match &args.scene {
            Some(path) => Scene::load_with(path, options),
            None => Ok(Scene::demo()),
        };
        scene.map(|s| (s, start.elapsed()))
    };
    let (mut scene, mut load_time) = match load(&options) {
        Ok(s) => s,
        Err(e) => return report_scene_error(&e),
    };
    if let Some(animation) = scene.animation
        && frames.1 >= animation.frames
    {
        return bad(format!(
            "frame {} is past the animation's last frame {} ([animation] frames = {})",
            frames.1,
            animation.frames - 1,
            animation.frames
        ));
    }
    if !args.quiet {
        for w in &scene.warnings {
            say_err!("warning: {w}");
        }
    }
    let settings = match args.overrides.apply(&scene.settings) {
        Ok(s) => RenderSettings {
            threads: args.threads.map(|t| t as usize),
            ..s
        },
        Err(e) => return bad(e),
    };
    if let Err(e) = settings.check() {
        return bad(e);
    }
    let (width, height) = (settings.width, settings.height);
    let region = match (args.crop, args.tile) {
        (Some([x0, x1, y0, y1]), _) => Region::crop(x0, x1, y0, y1, width, height),
        (None, Some((i, n))) => Region::tile(i, n, width, height),
        (None, None) => Ok(Region::full(width, height)),
    };
    let region = match region {
        Ok(r) => r,
        Err(e) => return bad(e),
    };
    let tev = match &args.display_server {
        None => None,
        Some(address) => {
            let name = args.output.display().to_string();
            match Tev::connect(address, &name) {
                Ok(t) => Some(t),
                Err(e) => return bad(e),
            }
        }
    };
    let interrupted = Arc::new(AtomicBool::new(false));
    // Whether an image is being written; the handler holds the lock while
    // it decides, so it never exits between the temporary file's creation
    // and its rename or removal.
    let writing = Arc::new(Mutex::new(false));
    let (flag, handler_writing) = (Arc::clone(&interrupted), Arc::clone(&writing));
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
    for (frame, output) in outputs {
        // Keyed values: each frame is built anew.
        if scene.animated && frame != options.frame {
            options.frame = frame;
            (scene, load_time) = match load(&options) {
                Ok(s) => s,
                Err(e) => return report_scene_error(&e),
            };
        }
        let job = Job {
            args,
            scene: &scene,
            settings: RenderSettings { frame, ..settings },
            region,
            output: &output,
            interrupted: &interrupted,
            writing: &writing,
            load_time,
            tev: tev.as_ref(),
        };
        let code = job.run();
        if code != ExitCode::SUCCESS {
            return code;
        }
    }
    if let Some(dir) = args.checkpoint.as_ref().filter(|_| args.frames.is_some()) {
        remove_frame_records(dir);
    }
    ExitCode::SUCCESS
}

/// One frame (or a region of it) to render and write.
struct Job<'a> {
    args: &'a RenderArgs,
    scene: &'a Scene,
    settings: RenderSettings,
    region: Region,
    output: &'a Path,
    interrupted: &'a Arc<AtomicBool>,
    writing: &'a Mutex<bool>,
    load_time: std::time::Duration,
    tev: Option<&'a Tev>,
}

impl Job<'_> {
    fn run(&self) -> ExitCode {
        let (args, settings, region) = (self.args, &self.settings, self.region);
        let mut provenance = Provenance::of(self.scene, settings);
        if let Some(aov) = args.aov {
            // A debug view is another image: its parts never merge with
            // the picture's.
            provenance.settings = format!("{} aov={}", provenance.settings, aov.name());
        }
        // With --frames, a frame written before an interruption is not
        // rendered again: its record in the checkpoint folder says so, and
        // the image is still the one written.
        let record = args
            .checkpoint
            .as_ref()
            .filter(|_| args.frames.is_some())
            .map(|dir| FrameRecord::new(dir, settings.frame, &provenance, region, self.output));
        if let Some(r) = &record
            && r.done()
        {
            if !args.quiet {
                say_err!(
                    "prism: frame {} is already written ({}); skipped",
                    settings.frame,
                    self.output.display()
                );
            }
            return ExitCode::SUCCESS;
        }
        let checkpoint = match &args.checkpoint {
            None => None,
            Some(dir) => {
                let dir = if args.frames.is_some() {
                    dir.join(format!("frame_{:04}", settings.frame))
                } else {
                    dir.clone()
                };
                match Checkpoint::open(&dir, &provenance.to_text(region)) {
                    Ok(c) => Some(c),
                    Err(e) => {
                        say_err!("error: {e}");
                        return ExitCode::from(BAD_INPUT);
                    }
                }
            }
        };
        let threads = settings.threads.unwrap_or_else(rayon::current_num_threads);
        let what = format!(
            "frame={} region={region} output={}",
            settings.frame,
            self.output.display()
        );
        let terminal = std::io::stderr().is_terminal();
        let bar = if args.quiet || !terminal {
            ProgressBar::hidden()
        } else {
            let bar = ProgressBar::new(region.area());
            bar.set_style(
                ProgressStyle::with_template(
                    "{spinner} [{elapsed_precise}] {wide_bar} {percent:>3}% ETA {eta}",
                )
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            bar
        };
        if !args.quiet && !terminal {
            say_err!(
                "prism: rendering {}x{} {what}, {}, {} threads",
                settings.width,
                settings.height,
                settings.sampling(),
                threads
            );
        }
        if let Some(c) = checkpoint
            .as_ref()
            .filter(|c| c.resumed() > 0 && !args.quiet)
        {
            say_err!(
                "prism: resuming from the checkpoint: {} tiles already done",
                c.resumed()
            );
        }
        let observer = CliObserver {
            bar,
            log: (!args.quiet && !terminal).then_some(what),
            total: region.area(),
            logged_percent: AtomicU64::new(0),
            interrupted: Arc::clone(self.interrupted),
            checkpoint,
            checkpoint_error: Mutex::new(None),
            tev: self.tev,
        };
        if let Some(tev) = self.tev {
            tev.create(settings.width, settings.height);
        }
        let rendered = match args.aov {
            Some(aov) => render_aov(self.scene, settings, region, aov, &observer).map(|mut o| {
                let eight_bit = matches!(
                    OutputFormat::from_path(self.output),
                    Ok(OutputFormat::Png | OutputFormat::Ppm)
                );
                if eight_bit {
                    o.film = false_colour(&o.film, aov);
                }
                o
            }),
            None => render_region(self.scene, settings, region, &observer).map(|mut o| {
                let eight_bit = matches!(
                    OutputFormat::from_path(self.output),
                    Ok(OutputFormat::Png | OutputFormat::Ppm)
                );
                if eight_bit {
                    prism::image_io::expose(&mut o.film, settings.exposure);
                }
                o
            }),
        };
        let output = match rendered {
            Ok(o) => o,
            Err(RenderError::Cancelled) => {
                observer.bar.abandon();
                if let Some(e) = observer
                    .checkpoint_error
                    .lock()
                    .ok()
                    .and_then(|e| e.clone())
                {
                    say_err!("error: cannot save a tile: {e}");
                    return ExitCode::FAILURE;
                }
                let kept = if observer.checkpoint.is_some() {
                    "; the finished tiles are in the checkpoint"
                } else {
                    ""
                };
                say_err!("prism: interrupted; nothing was written{kept}");
                return ExitCode::from(INTERRUPTED);
            }
            Err(e) => {
                observer.bar.abandon();
                say_err!("error: {e}");
                return ExitCode::FAILURE;
            }
        };
        observer.bar.finish_and_clear();
        *self.writing.lock().unwrap_or_else(|p| p.into_inner()) = true;
        let write_start = Instant::now();
        let written = write_film_unless(
            &output.film,
            self.output,
            Some(&provenance),
            &observer.interrupted,
        );
        *self.writing.lock().unwrap_or_else(|p| p.into_inner()) = false;
        match written {
            Ok(()) => {}
            Err(ImageWriteError::Interrupted { .. }) => {
                say_err!("prism: interrupted; nothing was written");
                return ExitCode::from(INTERRUPTED);
            }
            Err(e) => {
                say_err!("error: {e}");
                return ExitCode::FAILURE;
            }
        }
        if let Some(c) = observer.checkpoint
            && let Err(e) = c.remove()
        {
            say_err!("warning: the checkpoint could not be removed: {e}");
        }
        if let Some(r) = &record
            && let Err(e) = r.save()
        {
            say_err!("warning: {e}");
        }
        if !args.quiet {
            let s = output.stats;
            say_err!(
                "prism: {}x{} {}, {} threads, {} boxes; load {:.2} s, build {:.2} s, render {:.2} s, write {:.2} s; rays: {} camera, {} reflection, {} refraction, {} shadow; {:.2} Mrays/s -> {}",
                settings.width,
                settings.height,
                settings.sampling(),
                threads,
                prism::accel::simd_path().name(),
                self.load_time
                    .saturating_sub(self.scene.inventory.build_time)
                    .as_secs_f64(),
                self.scene.inventory.build_time.as_secs_f64(),
                output.elapsed.as_secs_f64(),
                write_start.elapsed().as_secs_f64(),
                s.camera,
                s.reflection,
                s.refraction,
                s.shadow,
                s.mrays_per_second(output.elapsed),
                self.output.display()
            );
        }
        ExitCode::SUCCESS
    }
}

/// That a frame of a checkpointed `--frames` render was written: what it
/// was rendered from (the checkpoint key), where it went, and the SHA-256
/// of the file, in `DIR/frame_FFFF.done`.
struct FrameRecord {
    path: PathBuf,
    key: String,
    output: PathBuf,
}

impl FrameRecord {
    fn new(dir: &Path, frame: u32, provenance: &Provenance, region: Region, output: &Path) -> Self {
        FrameRecord {
            path: dir.join(format!("frame_{frame:04}.done")),
            key: format!(
                "{}output={}\n",
                provenance.to_text(region),
                output.display()
            ),
            output: output.to_path_buf(),
        }
    }

    fn text(&self) -> Option<String> {
        use sha2::{Digest, Sha256};
        let bytes = std::fs::read(&self.output).ok()?;
        let digest: String = Sha256::digest(&bytes)
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect();
        Some(format!("{}sha256={digest}\n", self.key))
    }

    /// Whether the frame was written by this render and its file is as
    /// written.
    fn done(&self) -> bool {
        std::fs::read_to_string(&self.path).is_ok_and(|saved| Some(saved) == self.text())
    }

    fn save(&self) -> Result<(), String> {
        let fail = |e: std::io::Error| format!("{}: {e}", self.path.display());
        let text = self.text().ok_or_else(|| {
            format!(
                "{}: cannot be read back to record it",
                self.output.display()
            )
        })?;
        let dir = self.path.parent().unwrap_or(Path::new("."));
        std::fs::create_dir_all(dir).map_err(fail)?;
        let mut temp = tempfile::Builder::new()
            .prefix(RECORD_TEMP.0)
            .suffix(RECORD_TEMP.1)
            .tempfile_in(dir)
            .map_err(fail)?;
        std::io::Write::write_all(&mut temp, text.as_bytes()).map_err(fail)?;
        temp.persist(&self.path).map_err(|e| fail(e.error))?;
        Ok(())
    }
}

/// The prefix and suffix of a frame record's temporary file.
const RECORD_TEMP: (&str, &str) = (".frame-", ".part");

/// Removes the frame records (and the temporary files of records a killed
/// run was writing) and the checkpoint folder once every frame is written;
/// anything else a user put there stays, and so does the folder then.
fn remove_frame_records(dir: &Path) {
    if let Ok(entries) = std::fs::read_dir(dir) {
        for entry in entries.flatten() {
            let name = entry.file_name();
            let name = name.to_string_lossy();
            let record = name.starts_with("frame_") && name.ends_with(".done");
            let temporary = name.starts_with(RECORD_TEMP.0) && name.ends_with(RECORD_TEMP.1);
            if (record || temporary) && entry.file_type().is_ok_and(|t| t.is_file()) {
                let _ = std::fs::remove_file(entry.path());
            }
        }
    }
    if let Err(e) = std::fs::remove_dir(dir)
        && e.kind() != std::io::ErrorKind::NotFound
    {
        say_err!(
            "warning: the checkpoint folder {} is not removed: {e}",
            dir.display()
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_names_and_ranges() {
        assert_eq!(
            frame_path(Path::new("out/f_####.png"), 7),
            Some(PathBuf::from("out/f_0007.png"))
        );
        assert_eq!(
            frame_path(Path::new("a#.exr"), 12),
            Some(PathBuf::from("a12.exr"))
        );
        assert_eq!(frame_path(Path::new("plain.png"), 1), None);
        assert_eq!(parse_frames("3-5"), Ok((3, 5)));
        assert_eq!(parse_frames("4"), Ok((4, 4)));
        assert!(parse_frames("5-3").is_err() && parse_frames("x").is_err());
        assert_eq!(parse_tile("1/4"), Ok((1, 4)));
        assert!(parse_tile("4/4").is_err() && parse_tile("1").is_err());
        assert_eq!(parse_crop("0,10,2,3"), Ok([0, 10, 2, 3]));
        assert!(parse_crop("0,10,2").is_err());
    }
}
