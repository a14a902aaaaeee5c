//! The preview's render loop, on its own thread: load the scene, render a
//! coarse pass (1 sample at 1/8 resolution), then the full resolution at 1
//! sample, then the scene's sample count, streaming every finished tile to
//! the page; watch the scene file and every file it read, and start again
//! (cancelling the render under way) when one changes. A broken scene
//! reports its errors and keeps the last good picture.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use glam::DVec3;
use notify::{RecursiveMode, Watcher};
use prism::render::{Film, Region, RenderError, render};
use prism::scene::LoadOptions;
use prism::{RenderObserver, RenderSettings, Scene, SceneError};
use serde::Serialize;
use tokio::sync::broadcast;

use crate::tev::Tev;

/// A located problem in the scene, as the page shows it.
#[derive(Clone, Debug, Serialize)]
pub struct Problem {
    /// The file.
    pub file: String,
    /// 1-based line (0: the whole file).
    pub line: usize,
    /// 1-based column.
    pub column: usize,
    /// What is wrong.
    pub message: String,
}

/// What the page is told about the render.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Status {
    /// The scene's file name.
    pub scene: String,
    /// Bumped on every (re)load.
    pub generation: u64,
    /// `loading`, `coarse`, `preview` (full resolution, 1 sample),
    /// `final`, `done` or `error`.
    pub phase: &'static str,
    /// Image size.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Samples per pixel of the final pass.
    pub spp: u32,
    /// The exposure in stops of the last scene that loaded (`[render]
    /// exposure`; None before one has): where the page's slider starts,
    /// and follows while the user leaves it there.
    pub exposure: Option<f64>,
    /// Pixels done in the current pass, and in all.
    pub done: u64,
    /// Pixels in the current pass.
    pub total: u64,
    /// Seconds since the (re)load.
    pub elapsed_s: f64,
    /// Estimated seconds left in the current pass.
    pub eta_s: Option<f64>,
    /// Summary once done: rays by kind and the rate.
    pub summary: Option<String>,
    /// Problems of the last load (the picture is the last good one).
    pub errors: Vec<Problem>,
    /// Seconds from the change to the first coarse picture.
    pub first_picture_s: Option<f64>,
}

/// The picture the page shows: linear f32 RGB over the whole frame.
#[derive(Clone, Debug, Default)]
pub struct Picture {
    /// The generation it shows.
    pub generation: u64,
    /// Bumped on every change of the pixels.
    pub version: u64,
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// Row-major RGB.
    pub pixels: Vec<f32>,
    /// The final film (f64) once the last pass is done.
    pub film: Option<Film>,
}

/// State shared by the render thread and the HTTP handlers.
pub struct Shared {
    /// The scene file served, as given.
    pub scene_path: PathBuf,
    /// The same, absolute, with its folder's real path: what is watched.
    scene_abs: PathBuf,
    /// How it is loaded.
    pub options: LoadOptions,
    /// Incremented on every file change: a render whose generation is
    /// stale stops.
    pub generation: AtomicU64,
    wake: (Mutex<()>, Condvar),
    /// The page's view of things.
    pub status: Mutex<Status>,
    /// The current picture.
    pub picture: Mutex<Picture>,
    /// The last scene that loaded, with its settings and generation.
    pub scene: Mutex<Option<(Arc<Scene>, RenderSettings, u64)>>,
    /// The generation of the last scene that loaded.
    pub scene_generation: AtomicU64,
    /// Events for the pages: (name, JSON).
    pub events: broadcast::Sender<(&'static str, Arc<String>)>,
    /// The tev viewer the tiles also go to.
    tev: Option<Tev>,
}

impl Shared {
    /// State for serving `scene_path`.
    pub fn new(scene_path: PathBuf, options: LoadOptions, tev: Option<Tev>) -> Arc<Shared> {
        let scene_abs = resolve(&scene_path);
        let name = scene_path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        Arc::new(Shared {
            scene_path,
            scene_abs,
            options,
            generation: AtomicU64::new(1),
            wake: (Mutex::new(()), Condvar::new()),
            status: Mutex::new(Status {
                scene: name,
                ..Status::default()
            }),
            picture: Mutex::new(Picture::default()),
            scene: Mutex::new(None),
            scene_generation: AtomicU64::new(0),
            events: broadcast::channel(4096).0,
            tev,
        })
    }

    /// A watched file changed: stop the render under way and start again.
    pub fn changed(&self) {
        self.generation.fetch_add(1, Ordering::SeqCst);
        let _lock = self.wake.0.lock();
        self.wake.1.notify_all();
    }

    /// The last scene that loaded, its settings and generation.
    pub fn last_scene(&self) -> Option<(Arc<Scene>, RenderSettings, u64)> {
        lock(&self.scene).clone()
    }

    /// The picture's version now.
    pub fn picture_version(&self) -> u64 {
        lock(&self.picture).version
    }

    fn send(&self, name: &'static str, json: String) {
        let _ = self.events.send((name, Arc::new(json)));
    }

    /// Changes the status and sends it, holding its lock while it does: a
    /// page that opens its stream takes its first status and subscribes
    /// under the same lock, so it gets each status once (not a change both
    /// in its first status and again as an event).
    fn update(&self, f: impl FnOnce(&mut Status)) {
        let mut status = lock(&self.status);
        f(&mut status);
        self.send(
            "status",
            serde_json::to_string(&*status).unwrap_or_default(),
        );
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// Little-endian f32 RGB, base64: how pixels travel to the page.
pub fn encode_pixels(pixels: impl Iterator<Item = f32>) -> String {
    let bytes: Vec<u8> = pixels.flat_map(f32::to_le_bytes).collect();
    base64::encode(bytes)
}

fn to_f32(p: DVec3) -> [f32; 3] {
    p.to_array().map(prism::image_io::to_f32)
}

/// Streams the tiles of one pass to the page and into the picture, and
/// stops when the generation moves on.
struct PassObserver<'a> {
    shared: &'a Shared,
    generation: u64,
    pass: &'static str,
    total: u64,
    start: Instant,
    last_status: Mutex<Instant>,
}

impl RenderObserver for PassObserver<'_> {
    fn tile_done(&self, tile: Region, pixels: &[DVec3], pixels_done: u64) {
        if let Some(tev) = &self.shared.tev {
            tev.update(tile, pixels);
        }
        {
            let mut picture = lock(&self.shared.picture);
            picture.version += 1;
            let width = picture.width as usize;
            for (i, p) in pixels.iter().enumerate() {
                let (x, y) = (
                    tile.x0 as usize + i % tile.width() as usize,
                    tile.y0 as usize + i / tile.width() as usize,
                );
                let at = 3 * (y * width + x);
                if let Some(slot) = picture.pixels.get_mut(at..at + 3) {
                    slot.copy_from_slice(&to_f32(*p));
                }
            }
        }
        let data = encode_pixels(pixels.iter().flat_map(|p| to_f32(*p)));
        self.shared.send(
            "tile",
            format!(
                r#"{{"generation":{},"pass":"{}","x0":{},"y0":{},"w":{},"h":{},"data":"{data}"}}"#,
                self.generation,
                self.pass,
                tile.x0,
                tile.y0,
                tile.width(),
                tile.height()
            ),
        );
        // Progress a few times a second, not per tile.
        let mut last = lock(&self.last_status);
        if last.elapsed() > Duration::from_millis(200) || pixels_done == self.total {
            *last = Instant::now();
            drop(last);
            let elapsed = self.start.elapsed().as_secs_f64();
            let rate = pixels_done as f64 / elapsed.max(1e-9);
            self.shared.update(|s| {
                s.done = pixels_done;
                s.total = self.total;
                s.eta_s = Some((self.total - pixels_done) as f64 / rate.max(1e-9));
            });
        }
    }

    fn cancelled(&self) -> bool {
        self.shared.generation.load(Ordering::SeqCst) != self.generation
    }
}

/// Runs the render loop for ever (on its own thread).
pub fn run(shared: Arc<Shared>) {
    let watched: Arc<Mutex<BTreeSet<PathBuf>>> = Arc::default();
    let on_change = {
        let (shared, watched) = (Arc::clone(&shared), Arc::clone(&watched));
        move |event: notify::Result<notify::Event>| {
            let Ok(event) = event else { return };
            if matches!(event.kind, notify::EventKind::Access(_)) {
                return;
            }
            let watched = lock(&watched);
            if event.paths.iter().any(|p| watched.contains(&resolve(p))) {
                shared.changed();
            }
        }
    };
    let mut watcher = notify::recommended_watcher(on_change).ok();
    let mut dirs: BTreeSet<PathBuf> = BTreeSet::new();
    loop {
        let generation = shared.generation.load(Ordering::SeqCst);
        let changed_at = Instant::now();
        shared.update(|s| {
            s.generation = generation;
            s.phase = "loading";
            s.done = 0;
            s.eta_s = None;
            s.summary = None;
            s.first_picture_s = None;
        });
        let loaded = Scene::load_with(&shared.scene_path, &shared.options);
        // Watch the scene file always (by its absolute path, and the file
        // a link points to), and what the last good load read.
        let mut files = BTreeSet::from([shared.scene_abs.clone()]);
        if let Ok(target) = shared.scene_abs.canonicalize() {
            files.insert(target);
        }
        match &loaded {
            Ok(scene) => files.extend(scene.inventory.files_read.iter().map(|f| resolve(&f.path))),
            Err(_) => files.extend(lock(&watched).iter().cloned()),
        }
        // Editors save by writing a new file and renaming it over the old:
        // watch the folders, and filter by path. Watched again on every
        // load, in case a folder was replaced.
        let new_dirs: BTreeSet<PathBuf> = files
            .iter()
            .filter_map(|f| f.parent().map(Path::to_path_buf))
            .collect();
        if let Some(w) = watcher.as_mut() {
            for d in dirs.difference(&new_dirs) {
                let _ = w.unwatch(d);
            }
            for d in &new_dirs {
                let _ = w.watch(d, RecursiveMode::NonRecursive);
            }
        }
        dirs = new_dirs;
        *lock(&watched) = files.clone();
        match loaded {
            Err(e) => {
                let errors = problems(&e, &shared.scene_path);
                shared.update(|s| {
                    s.phase = "error";
                    s.errors = errors;
                });
            }
            Ok(scene) => {
                let scene = Arc::new(scene);
                let settings = scene.settings;
                *lock(&shared.scene) = Some((Arc::clone(&scene), settings, generation));
                shared.scene_generation.store(generation, Ordering::SeqCst);
                shared.update(|s| {
                    s.errors.clear();
                    s.exposure = Some(settings.exposure);
                });
                render_passes(&shared, &scene, &settings, generation, changed_at);
            }
        }
        // Wait for the next change. The files are also looked at twice a
        // second, in case the watcher missed one (a folder replaced, a
        // file system without events).
        let seen = signatures(&files);
        let mut guard = lock(&shared.wake.0);
        while shared.generation.load(Ordering::SeqCst) == generation {
            guard = shared
                .wake
                .1
                .wait_timeout(guard, Duration::from_millis(500))
                .map(|(g, _)| g)
                .unwrap_or_else(|p| p.into_inner().0);
            if shared.generation.load(Ordering::SeqCst) == generation && signatures(&files) != seen
            {
                shared.generation.fetch_add(1, Ordering::SeqCst);
            }
        }
        drop(guard);
        // Let an editor finish writing (several events per save).
        std::thread::sleep(Duration::from_millis(30));
    }
}

/// What tells a file's versions apart: its size, time and inode (None:
/// missing).
type Signature = Option<(u64, Option<std::time::SystemTime>, u64)>;

fn signatures(files: &BTreeSet<PathBuf>) -> Vec<Signature> {
    files
        .iter()
        .map(|f| {
            let m = std::fs::metadata(f).ok()?;
            #[cfg(unix)]
            let inode = std::os::unix::fs::MetadataExt::ino(&m);
            #[cfg(not(unix))]
            let inode = 0;
            Some((m.len(), m.modified().ok(), inode))
        })
        .collect()
}

/// A path as the watcher reports it: absolute, its folder's real path
/// and its own name, whether the file exists now or not.
pub fn resolve(p: &Path) -> PathBuf {
    let absolute = std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    match (absolute.parent(), absolute.file_name()) {
        (Some(dir), Some(name)) => dir
            .canonicalize()
            .map(|d| d.join(name))
            .unwrap_or_else(|_| absolute.clone()),
        _ => absolute,
    }
}

/// The load error as located problems.
fn problems(e: &SceneError, path: &Path) -> Vec<Problem> {
    match e {
        SceneError::Invalid {
            origin,
            diagnostics,
        } => diagnostics
            .iter()
            .map(|d| Problem {
                file: origin.clone(),
                line: d.line,
                column: d.column,
                message: d.message.clone(),
            })
            .collect(),
        other => vec![Problem {
            file: path.display().to_string(),
            line: 0,
            column: 0,
            message: other.to_string(),
        }],
    }
}

/// Coarse, preview and final passes; returns early when cancelled.
fn render_passes(
    shared: &Shared,
    scene: &Scene,
    settings: &RenderSettings,
    generation: u64,
    changed_at: Instant,
) {
    let (width, height) = (settings.width, settings.height);
    // The coarse pass: 1 sample at 1/8 resolution, sent whole.
    let coarse = RenderSettings {
        width: width.div_ceil(8),
        height: height.div_ceil(8),
        spp: 1,
        ..*settings
    };
    let stale = || shared.generation.load(Ordering::SeqCst) != generation;
    shared.update(|s| {
        s.phase = "coarse";
        s.width = width;
        s.height = height;
        s.spp = settings.spp;
    });
    let coarse_film = match render(scene, &coarse, &StopWhen(&stale)) {
        Ok(o) => o.film,
        Err(_) => return,
    };
    {
        // Upscale into the picture, so late pages see it too.
        let mut picture = lock(&shared.picture);
        picture.generation = generation;
        picture.version += 1;
        picture.width = width;
        picture.height = height;
        picture.film = None;
        picture.pixels = (0..height)
            .flat_map(|y| (0..width).map(move |x| (x, y)))
            .flat_map(|(x, y)| to_f32(coarse_film.get(x / 8, y / 8)))
            .collect();
    }
    shared.send(
        "frame",
        format!(
            r#"{{"generation":{generation},"pass":"coarse","width":{},"height":{},"data":"{}"}}"#,
            coarse.width,
            coarse.height,
            encode_pixels(coarse_film.pixels().iter().flat_map(|p| to_f32(*p)))
        ),
    );
    let first = changed_at.elapsed().as_secs_f64();
    shared.update(|s| s.first_picture_s = Some(first));
    let passes: &[(&'static str, u32)] = if settings.spp > 1 {
        &[("preview", 1), ("final", settings.spp)]
    } else {
        &[("final", 1)]
    };
    if let Some(tev) = &shared.tev {
        tev.create(width, height);
    }
    for &(pass, spp) in passes {
        let start = Instant::now();
        shared.update(|s| {
            s.phase = pass;
            s.done = 0;
            s.total = u64::from(width) * u64::from(height);
        });
        let observer = PassObserver {
            shared,
            generation,
            pass,
            total: u64::from(width) * u64::from(height),
            start,
            last_status: Mutex::new(Instant::now()),
        };
        let out = match render(scene, &RenderSettings { spp, ..*settings }, &observer) {
            Ok(o) => o,
            Err(RenderError::Cancelled) => return,
            Err(e) => {
                shared.update(|s| {
                    s.phase = "error";
                    s.errors = vec![Problem {
                        file: shared.scene_path.display().to_string(),
                        line: 0,
                        column: 0,
                        message: e.to_string(),
                    }];
                });
                return;
            }
        };
        if pass == "final" {
            lock(&shared.picture).film = Some(out.film);
            let s = out.stats;
            let summary = format!(
                "{}x{} {} spp in {:.2} s; rays: {} camera, {} reflection, {} refraction, {} shadow; {:.2} Mrays/s",
                width,
                height,
                spp,
                out.elapsed.as_secs_f64(),
                s.camera,
                s.reflection,
                s.refraction,
                s.shadow,
                s.mrays_per_second(out.elapsed)
            );
            shared.update(|st| {
                st.phase = "done";
                st.eta_s = Some(0.0);
                st.elapsed_s = changed_at.elapsed().as_secs_f64();
                st.summary = Some(summary);
            });
        }
    }
}

/// Cancels a render once `stale` says so.
struct StopWhen<'a, F: Fn() -> bool + Sync>(&'a F);

impl<F: Fn() -> bool + Sync> RenderObserver for StopWhen<'_, F> {
    fn cancelled(&self) -> bool {
        (self.0)()
    }
}
