//! Work done on request, bounded whatever the clients do: debug views and
//! saved images are made once per scene generation and shared by every
//! request for them; at most `MAX_RENDERS` run at once, the rest wait;
//! one that no client waits for any more is cancelled. The picture is
//! copied once per change and shared, as binary.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

use bytes::Bytes;
use prism::RenderObserver;
use prism::render::aov::Aov;
use serde::Serialize;
use tokio::sync::{Notify, Semaphore, watch};

use super::worker::Shared;

/// On-demand renders (debug views, saves, explains) running at once: each
/// already uses every core.
pub const MAX_RENDERS: usize = 2;
/// Copies of the picture alive at once (the current one and those still
/// being sent to slow clients).
pub const MAX_SNAPSHOTS: usize = 3;
/// Requests waiting for on-demand work at once; more are answered 503 at
/// once, so that they do not hold connections (`conn::MAX_CONNECTIONS`).
pub const MAX_WAITING: usize = 32;

/// Saved PNGs kept per scene generation, each at its own exposure; beyond
/// this, the finished ones at other exposures are forgotten.
pub const MAX_PNG_EXPOSURES: usize = 4;

/// What a job makes.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug)]
pub enum Kind {
    View(&'static str),
    /// The PNG at an exposure (the bits of its EV, -0 made 0; None: the
    /// scene's).
    Png(Option<u64>),
    Exr,
}

impl Kind {
    /// The PNG at `ev` stops (None: the scene's exposure).
    pub fn png(ev: Option<f64>) -> Kind {
        Kind::Png(ev.map(|ev| (ev + 0.0).to_bits()))
    }
}

/// A finished job: the file, and for heat-ramp views the value shown white.
#[derive(Debug)]
pub struct Made {
    pub bytes: Bytes,
    pub top: Option<f64>,
}

/// The outcome of a job stopped before it finished.
const STOPPED: &str = "stopped";

type Outcome = Option<Result<Arc<Made>, String>>;

struct Job {
    waiters: AtomicUsize,
    cancel: AtomicBool,
    cancelled: Notify,
    done: watch::Sender<Outcome>,
}

/// Counters for `/stats`.
#[derive(Default, Serialize)]
pub struct Counts {
    pub started: u64,
    pub running: usize,
    pub queued: usize,
    pub cancelled: u64,
    pub waiting: usize,
    pub turned_away: u64,
    /// Copies of the picture made for `/picture`, and alive now.
    pub picture_copies: u64,
    pub picture_copies_alive: usize,
}

pub struct Views {
    permits: Arc<Semaphore>,
    jobs: Mutex<HashMap<(u64, Kind), Arc<Job>>>,
    started: AtomicU64,
    running: AtomicUsize,
    queued: AtomicUsize,
    cancelled: AtomicU64,
    waiting: Arc<AtomicUsize>,
    turned_away: AtomicU64,
    copies: AtomicU64,
    /// The latest picture snapshot; its lock also makes one copy at a time.
    snapshot: tokio::sync::Mutex<Option<Snapshot>>,
    snapshots_alive: Arc<AtomicUsize>,
}

/// The picture as sent: little-endian f32 RGB.
#[derive(Clone)]
pub struct Snapshot {
    pub version: u64,
    pub generation: u64,
    pub width: u32,
    pub height: u32,
    pub finished: bool,
    pub bytes: Bytes,
}

/// Counts a snapshot's copy alive until every response holding it is gone.
struct Alive {
    data: Vec<u8>,
    count: Arc<AtomicUsize>,
}

impl AsRef<[u8]> for Alive {
    fn as_ref(&self) -> &[u8] {
        &self.data
    }
}

impl Drop for Alive {
    fn drop(&mut self) {
        self.count.fetch_sub(1, Ordering::SeqCst);
    }
}

/// A request waiting for work, counted until dropped.
pub struct Slot(Arc<AtomicUsize>);

impl Drop for Slot {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

/// A request waiting for a job; the last one to go cancels it.
struct Waiter(Arc<Job>);

impl Drop for Waiter {
    fn drop(&mut self) {
        if self.0.waiters.fetch_sub(1, Ordering::SeqCst) == 1 && self.0.done.borrow().is_none() {
            self.0.cancel.store(true, Ordering::SeqCst);
            self.0.cancelled.notify_one();
        }
    }
}

struct Stop<'a> {
    job: &'a Job,
    shared: &'a Shared,
    generation: u64,
}

impl RenderObserver for Stop<'_> {
    fn cancelled(&self) -> bool {
        self.job.cancel.load(Ordering::SeqCst)
            || self.shared.scene_generation.load(Ordering::SeqCst) != self.generation
    }
}

/// Why a request got nothing.
pub enum Refused {
    NoScene,
    Busy,
    Failed(String),
}

impl Views {
    pub fn new() -> Views {
        Views {
            permits: Arc::new(Semaphore::new(MAX_RENDERS)),
            jobs: Mutex::default(),
            started: AtomicU64::new(0),
            running: AtomicUsize::new(0),
            queued: AtomicUsize::new(0),
            cancelled: AtomicU64::new(0),
            waiting: Arc::default(),
            turned_away: AtomicU64::new(0),
            copies: AtomicU64::new(0),
            snapshot: tokio::sync::Mutex::new(None),
            snapshots_alive: Arc::new(AtomicUsize::new(0)),
        }
    }

    pub fn counts(&self) -> Counts {
        Counts {
            started: self.started.load(Ordering::SeqCst),
            running: self.running.load(Ordering::SeqCst),
            queued: self.queued.load(Ordering::SeqCst),
            cancelled: self.cancelled.load(Ordering::SeqCst),
            waiting: self.waiting.load(Ordering::SeqCst),
            turned_away: self.turned_away.load(Ordering::SeqCst),
            picture_copies: self.copies.load(Ordering::SeqCst),
            picture_copies_alive: self.snapshots_alive.load(Ordering::SeqCst),
        }
    }

    /// A place among the requests waiting for work, if one is free.
    pub fn wait_slot(&self) -> Option<Slot> {
        let before = self.waiting.fetch_add(1, Ordering::SeqCst);
        let slot = Slot(Arc::clone(&self.waiting));
        if before >= MAX_WAITING {
            self.turned_away.fetch_add(1, Ordering::SeqCst);
            return None;
        }
        Some(slot)
    }

    /// The debug view or saved image `kind` of the current scene: made
    /// once, or waited for while another request makes it. Dropping the
    /// future (the client went away) cancels it if no one else waits.
    pub async fn get(
        self: &Arc<Self>,
        shared: &Arc<Shared>,
        kind: Kind,
    ) -> Result<Arc<Made>, Refused> {
        let Some((scene, settings, generation)) = shared.last_scene() else {
            return Err(Refused::NoScene);
        };
        let slot;
        let job = {
            let mut jobs = self.jobs.lock().unwrap_or_else(|p| p.into_inner());
            // A cancelled one, and views of older scenes, are of no use.
            jobs.retain(|(g, _), j| *g == generation && !j.cancel.load(Ordering::SeqCst));
            let finished = jobs
                .get(&(generation, kind))
                .and_then(|j| j.done.borrow().clone());
            if let Some(Ok(made)) = finished {
                return Ok(made);
            }
            slot = self.wait_slot().ok_or(Refused::Busy)?;
            // PNGs at many exposures: the finished ones at other exposures
            // go (those under way are bounded by the waiting requests).
            if matches!(kind, Kind::Png(_))
                && jobs
                    .keys()
                    .filter(|(_, k)| matches!(k, Kind::Png(_)))
                    .count()
                    >= MAX_PNG_EXPOSURES
            {
                jobs.retain(|(_, k), j| !matches!(k, Kind::Png(_)) || j.done.borrow().is_none());
            }
            let job = jobs.entry((generation, kind)).or_insert_with(|| {
                let job = Arc::new(Job {
                    waiters: AtomicUsize::new(0),
                    cancel: AtomicBool::new(false),
                    cancelled: Notify::new(),
                    done: watch::channel(None).0,
                });
                let (views, shared, made) =
                    (Arc::clone(self), Arc::clone(shared), Arc::clone(&job));
                tokio::spawn(async move {
                    views
                        .make(shared, made, kind, scene, settings, generation)
                        .await;
                });
                job
            });
            job.waiters.fetch_add(1, Ordering::SeqCst);
            Arc::clone(job)
        };
        let waiter = Waiter(Arc::clone(&job));
        let mut done = job.done.subscribe();
        let outcome = done
            .wait_for(Option::is_some)
            .await
            .map(|o| o.clone())
            .ok()
            .flatten();
        drop(waiter);
        drop(slot);
        match outcome {
            Some(Ok(made)) => Ok(made),
            // Stopped (its scene changed): the client may ask again.
            Some(Err(e)) if e == STOPPED => Err(Refused::Busy),
            Some(Err(e)) => Err(Refused::Failed(e)),
            None => Err(Refused::Busy),
        }
    }

    async fn make(
        self: Arc<Self>,
        shared: Arc<Shared>,
        job: Arc<Job>,
        kind: Kind,
        scene: Arc<prism::Scene>,
        settings: prism::RenderSettings,
        generation: u64,
    ) {
        let forget = || {
            let mut jobs = self.jobs.lock().unwrap_or_else(|p| p.into_inner());
            if jobs
                .get(&(generation, kind))
                .is_some_and(|j| Arc::ptr_eq(j, &job))
            {
                jobs.remove(&(generation, kind));
            }
        };
        self.queued.fetch_add(1, Ordering::SeqCst);
        let permit = tokio::select! {
            p = Arc::clone(&self.permits).acquire_owned() => p.ok(),
            _ = job.cancelled.notified() => None,
        };
        self.queued.fetch_sub(1, Ordering::SeqCst);
        let Some(permit) = permit else {
            self.cancelled.fetch_add(1, Ordering::SeqCst);
            forget();
            let _ = job.done.send(Some(Err(STOPPED.into())));
            return;
        };
        self.started.fetch_add(1, Ordering::SeqCst);
        self.running.fetch_add(1, Ordering::SeqCst);
        let made = {
            let (job, shared) = (Arc::clone(&job), Arc::clone(&shared));
            tokio::task::spawn_blocking(move || {
                let stop = Stop {
                    job: &job,
                    shared: &shared,
                    generation,
                };
                make(&scene, &settings, kind, &stop, &shared)
            })
            .await
        };
        drop(permit);
        self.running.fetch_sub(1, Ordering::SeqCst);
        let stopped = job.cancel.load(Ordering::SeqCst)
            || shared.scene_generation.load(Ordering::SeqCst) != generation;
        let outcome = match made {
            Ok(Ok(made)) => Ok(Arc::new(made)),
            Ok(Err(_)) if stopped => Err(STOPPED.to_string()),
            Ok(Err(e)) => Err(e),
            Err(e) => Err(e.to_string()),
        };
        if outcome.is_err() {
            // Not kept: a later request tries again.
            forget();
            if stopped {
                self.cancelled.fetch_add(1, Ordering::SeqCst);
            }
        }
        let _ = job.done.send(Some(outcome));
    }

    /// A copy of the picture at least as new as when this was called.
    pub async fn picture(&self, shared: &Arc<Shared>) -> Result<Snapshot, Refused> {
        let wanted = shared.picture_version();
        let mut latest = self.snapshot.lock().await;
        if let Some(s) = latest.as_ref().filter(|s| s.version >= wanted) {
            return Ok(s.clone());
        }
        // Slow clients still hold older copies: no more memory for them.
        if self.snapshots_alive.load(Ordering::SeqCst) >= MAX_SNAPSHOTS {
            return Err(Refused::Busy);
        }
        self.snapshots_alive.fetch_add(1, Ordering::SeqCst);
        self.copies.fetch_add(1, Ordering::SeqCst);
        let count = Arc::clone(&self.snapshots_alive);
        let shared = Arc::clone(shared);
        let copied = tokio::task::spawn_blocking(move || {
            let p = shared.picture.lock().unwrap_or_else(|p| p.into_inner());
            let data: Vec<u8> = p.pixels.iter().flat_map(|v| v.to_le_bytes()).collect();
            Snapshot {
                version: p.version,
                generation: p.generation,
                width: p.width,
                height: p.height,
                finished: p.film.is_some(),
                bytes: Bytes::from_owner(Alive { data, count }),
            }
        })
        .await
        .map_err(|e| Refused::Failed(e.to_string()))?;
        *latest = Some(copied.clone());
        Ok(copied)
    }
}

/// Renders a debug view in false colour, or writes the finished picture.
fn make(
    scene: &prism::Scene,
    settings: &prism::RenderSettings,
    kind: Kind,
    stop: &Stop,
    shared: &Shared,
) -> Result<Made, String> {
    let dir = tempfile::tempdir().map_err(|e| e.to_string())?;
    match kind {
        Kind::View(name) => {
            let aov: Aov = name.parse()?;
            let region = prism::render::Region::full(settings.width, settings.height);
            let out = prism::render::aov::render_aov(scene, settings, region, aov, stop)
                .map_err(|e| e.to_string())?;
            let top =
                matches!(aov, Aov::Bounces | Aov::Feelers | Aov::Time).then(|| ramp_top(&out.film));
            let film = prism::render::aov::false_colour(&out.film, aov);
            let path = dir.path().join("view.png");
            prism::image_io::write_film(&film, &path).map_err(|e| e.to_string())?;
            let bytes = std::fs::read(path).map_err(|e| e.to_string())?;
            Ok(Made {
                bytes: Bytes::from(bytes),
                top,
            })
        }
        Kind::Png(_) | Kind::Exr => {
            let film = {
                let p = shared.picture.lock().unwrap_or_else(|p| p.into_inner());
                // The film of this scene, not of the one before.
                p.film.clone().filter(|_| p.generation == stop.generation)
            }
            .ok_or("the render is not finished yet")?;
            // The exposure asked for (as `prism render --exposure EV`)
            // applies to the 8-bit PNG only, and is in its provenance.
            let mut film = film;
            let mut settings = *settings;
            if let Kind::Png(ev) = kind {
                settings.exposure = ev.map_or(settings.exposure, f64::from_bits);
                prism::image_io::expose(&mut film, settings.exposure);
            }
            let provenance = prism::image_io::Provenance::of(scene, &settings);
            let ext = if kind == Kind::Exr { "exr" } else { "png" };
            let path = dir.path().join(format!("render.{ext}"));
            prism::image_io::write_film_unless(&film, &path, Some(&provenance), &stop.job.cancel)
                .map_err(|e| e.to_string())?;
            let bytes = std::fs::read(path).map_err(|e| e.to_string())?;
            Ok(Made {
                bytes: Bytes::from(bytes),
                top: None,
            })
        }
    }
}

/// The value the heat ramp shows white: the 99.5th percentile, as
/// `false_colour` takes it.
fn ramp_top(film: &prism::render::Film) -> f64 {
    let mut values: Vec<f64> = film
        .pixels()
        .iter()
        .map(|v| v.x)
        .filter(|v| v.is_finite())
        .collect();
    values.sort_by(f64::total_cmp);
    values
        .get((values.len().saturating_sub(1) as f64 * 0.995) as usize)
        .copied()
        .unwrap_or(0.0)
}
