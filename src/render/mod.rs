//! The render loop: the image is cut into tiles rendered in parallel; each
//! pixel draws from its own random stream, so the result does not depend on
//! the thread count or the tile order.

mod adaptive;
pub mod aov;
mod checkpoint;
pub mod explain;
mod film;
mod region;

pub use crate::settings::RenderSettings;
pub use crate::stats::RayStats;
pub use checkpoint::Checkpoint;
pub use film::Film;
pub use region::Region;

use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use glam::{DVec2, DVec3};
use rayon::prelude::*;
use thiserror::Error;

use crate::accel::PACKET;
use crate::accel::simd::{self, Job};
use crate::camera::{FilmRays, RayLanes};
use crate::math::permutation::{Permutation, permutation_element};
use crate::math::rng::PixelRng;
use crate::math::sampling::{Strata, concentric_disk};
use crate::math::{Ray, RayDifferential};
use crate::scene::Scene;
use crate::shading::whitted::{Recorder, Whitted, WhittedSettings};

/// Side of the square tiles the image is cut into.
const TILE: u32 = 16;

/// Why a render could not run.
#[derive(Debug, Error)]
pub enum RenderError {
    /// The observer asked the render to stop.
    #[error("the render was cancelled")]
    Cancelled,
    /// The settings are out of range (see [`RenderSettings::check`]).
    #[error("{0}")]
    Settings(String),
    /// The thread pool could not be built.
    #[error("cannot start {threads} render threads: {source}")]
    Threads {
        /// Threads asked for.
        threads: usize,
        /// The cause.
        source: rayon::ThreadPoolBuildError,
    },
}

/// A finished render.
pub struct RenderOutput {
    /// Linear radiance per pixel.
    pub film: Film,
    /// Rays traced, by kind.
    pub stats: RayStats,
    /// Wall-clock time of the render itself.
    pub elapsed: Duration,
}

/// What the caller of [`render`] sees of it while it runs, and how it stops
/// it. Both methods are called from the worker threads.
pub trait RenderObserver: Sync {
    /// A tile is finished: its pixels, row-major; `pixels_done` pixels of
    /// the render are finished so far.
    fn tile_done(&self, tile: Region, pixels: &[DVec3], pixels_done: u64) {
        let _ = (tile, pixels, pixels_done);
    }

    /// The pixels of `tile` if an earlier, interrupted run finished it (a
    /// checkpoint); the render then takes them instead of tracing it.
    fn finished_before(&self, tile: Region) -> Option<Vec<DVec3>> {
        let _ = tile;
        None
    }

    /// Whether the render should stop (checked before every row of pixels).
    fn cancelled(&self) -> bool {
        false
    }
}

/// No progress display, never cancelled.
impl RenderObserver for () {}

/// Renders `scene` with `settings`, reporting to `observer`.
pub fn render(
    scene: &Scene,
    settings: &RenderSettings,
    observer: &dyn RenderObserver,
) -> Result<RenderOutput, RenderError> {
    render_region(
        scene,
        settings,
        Region::full(settings.width, settings.height),
        observer,
    )
}

/// Renders the pixels of `region` only; each is bit-identical to the same
/// pixel of the whole frame's render (every pixel has its own random
/// stream), so regions rendered apart can be merged.
pub fn render_region(
    scene: &Scene,
    settings: &RenderSettings,
    region: Region,
    observer: &dyn RenderObserver,
) -> Result<RenderOutput, RenderError> {
    render_with(
        scene,
        settings,
        region,
        observer,
        |tracer, samples: &mut adaptive::TileSamples, y, xs, stats, out| match settings.adaptive {
            Some(a) => adaptive::render_row_adaptive(
                scene, tracer, settings, a, samples, y, xs, stats, out,
            ),
            None => render_row(scene, tracer, settings, y, xs, stats, out),
        },
    )
}

/// The render loop over `region`'s tiles, `row(tracer, tile_state, y, xs,
/// stats, out)` pushing onto `out` the values (the radiance, or an AOV) of
/// the pixels `xs` of row `y`, in order. `tile_state` starts afresh
/// (`S::default()`) at every tile and goes with it row by row, top to
/// bottom (the adaptive sampler keeps the samples a row shares with the
/// next there).
fn render_with<S: Default>(
    scene: &Scene,
    settings: &RenderSettings,
    region: Region,
    observer: &dyn RenderObserver,
    row: impl Fn(&Whitted, &mut S, u32, Range<u32>, &mut RayStats, &mut Vec<DVec3>) + Sync,
) -> Result<RenderOutput, RenderError> {
    settings.check().map_err(RenderError::Settings)?;
    if !Region::full(settings.width, settings.height).contains(&region) || region.area() == 0 {
        return Err(RenderError::Settings(format!(
            "region {region} is empty or outside the {}x{} image",
            settings.width, settings.height
        )));
    }
    let start = Instant::now();
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(threads) = settings.threads {
        builder = builder.num_threads(threads);
    }
    let pool = builder.build().map_err(|source| RenderError::Threads {
        threads: settings.threads.unwrap_or(0),
        source,
    })?;
    let tracer = Whitted::new(
        scene,
        WhittedSettings {
            max_depth: settings.max_depth.max(1),
            min_weight: settings.min_weight,
        },
    );
    let done = AtomicU64::new(0);
    let rendered: Option<Vec<(Region, Vec<DVec3>, RayStats)>> = pool.install(|| {
        region
            .tiles(TILE)
            .into_par_iter()
            .map(|tile| {
                let mut stats = RayStats::default();
                if let Some(pixels) = observer.finished_before(tile)
                    && pixels.len() as u64 == tile.area()
                {
                    let n = pixels.len() as u64;
                    observer.tile_done(tile, &pixels, done.fetch_add(n, Ordering::Relaxed) + n);
                    return Some((tile, pixels, stats));
                }
                let mut pixels = Vec::with_capacity(tile.area() as usize);
                let mut state = S::default();
                for y in tile.y0..tile.y1 {
                    if observer.cancelled() {
                        return None;
                    }
                    let xs = tile.x0..tile.x1;
                    row(&tracer, &mut state, y, xs, &mut stats, &mut pixels);
                }
                let n = pixels.len() as u64;
                observer.tile_done(tile, &pixels, done.fetch_add(n, Ordering::Relaxed) + n);
                Some((tile, pixels, stats))
            })
            .collect()
    });
    let rendered = rendered.ok_or(RenderError::Cancelled)?;
    let mut film = Film::window(settings.width, settings.height, region);
    let mut stats = RayStats::default();
    for (tile, pixels, tile_stats) in rendered {
        film.paste(tile, &pixels);
        stats += tile_stats;
    }
    Ok(RenderOutput {
        film,
        stats,
        elapsed: start.elapsed(),
    })
}

/// One pixel: `spp` camera rays through a stratified (jittered) grid over
/// the pixel, box-filtered; a single sample goes through the centre.
pub fn render_pixel(
    scene: &Scene,
    tracer: &Whitted,
    settings: &RenderSettings,
    x: u32,
    y: u32,
    stats: &mut RayStats,
) -> DVec3 {
    render_pixel_recorded(scene, tracer, settings, x, y, stats, None, &mut ()).pixel
}

/// [`render_pixel`] for each pixel of `xs` in row `y`, pushed onto `out`
/// in order, to the bit: the camera rays of each sample of up to
/// [`PACKET`] neighbouring pixels are traced to their first hit together
/// (see [`Aggregate::closest_hit_packet`](crate::accel::Aggregate::closest_hit_packet)),
/// and each is then shaded from there as `render_pixel` shades it, drawing
/// from its pixel's own stream in the same order.
pub fn render_row(
    scene: &Scene,
    tracer: &Whitted,
    settings: &RenderSettings,
    y: u32,
    xs: Range<u32>,
    stats: &mut RayStats,
    out: &mut Vec<DVec3>,
) {
    if !scene.motion.is_empty() {
        // Neighbouring pixels' samples look at different instants: no
        // packets of one scene to trace.
        for x in xs {
            out.push(render_pixel(scene, tracer, settings, x, y, stats));
        }
        return;
    }
    let seed = frame_seed(settings.seed, settings.frame);
    let strata = Strata::new(settings.spp as usize);
    let spp = strata.len();
    let film = scene.camera.film(settings.width, settings.height);
    let mut x0 = xs.start;
    while x0 < xs.end {
        let n = (xs.end - x0).min(PACKET as u32) as usize;
        let mut rngs: [PixelRng; PACKET] =
            std::array::from_fn(|k| PixelRng::new(seed, x0 + k.min(n - 1) as u32, y));
        let lens_orders: [Permutation; PACKET] =
            std::array::from_fn(|k| Permutation::new(spp as u32, lens_key(scene, &mut rngs[k])));
        let mut sums = [DVec3::ZERO; PACKET];
        let mut rays = [Ray::new(DVec3::ZERO, DVec3::Z); PACKET];
        let mut lanes = RayLanes::default();
        let mut hits = [None; PACKET];
        // Lanes past `n` (a row's last, short packet) are traced by no one.
        let mut points = [glam::DVec2::ZERO; PACKET];
        let mut disks = [glam::DVec2::ZERO; PACKET];
        for s in 0..spp {
            for (k, rng) in rngs.iter_mut().enumerate().take(n) {
                let x = x0 + k as u32;
                (points[k], disks[k]) =
                    camera_sample(&film, &strata, s, x, y, &lens_orders[k], rng);
            }
            simd::kernel().vectorize_job(LensRays {
                film: &film,
                points: &points,
                disks: &mut disks,
                rays: &mut lanes,
            });
            for (k, ray) in rays.iter_mut().enumerate().take(n) {
                *ray = lanes.ray(k);
            }
            let spacing = differential_spacing(tracer, &strata, s);
            scene
                .aggregate
                .closest_hit_packet(&rays[..n], f64::INFINITY, &mut hits[..n]);
            for k in 0..n {
                let differential =
                    spacing.map(|h| film.differential(points[k].x, points[k].y, disks[k], h));
                sums[k] += tracer.camera_radiance(
                    &rays[k],
                    differential.as_ref(),
                    hits[k].as_ref(),
                    &mut rngs[k],
                    stats,
                );
            }
        }
        out.extend(sums[..n].iter().map(|&sum| sum / spp as f64));
        x0 += n as u32;
    }
}

/// The camera rays of a packet's lanes from their film points and lens
/// points (of the unit square), as [`camera_ray`] makes each: the lanes'
/// concentric maps and rays side by side, in vector code on the AVX2 path
/// (the same operations, so the same bits on every path). A job of its
/// own: inlined into the draws before it, it was left one lane at a time.
struct LensRays<'a> {
    film: &'a FilmRays,
    points: &'a [DVec2; PACKET],
    disks: &'a mut [DVec2; PACKET],
    rays: &'a mut RayLanes<PACKET>,
}

impl Job for LensRays<'_> {
    type Output = ();

    #[inline(always)]
    fn run(self) {
        if self.film.camera().lens.is_some() {
            for disk in self.disks.iter_mut() {
                *disk = concentric_disk(*disk);
            }
        }
        self.film
            .rays_through_lens(self.points, self.disks, self.rays);
    }
}

/// A pixel and the last of its samples a recorder heard.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RecordedPixel {
    /// The pixel: the mean of its samples.
    pub pixel: DVec3,
    /// The recorded sample's radiance.
    pub sample: DVec3,
    /// Its point on the lens, in world units along the camera's right and
    /// up from the lens centre; `None` for a pinhole.
    pub lens: Option<glam::DVec2>,
    /// The instant it saw, in frames after the frame's start; `None`
    /// without an open shutter on a moving scene.
    pub time: Option<f64>,
    /// How many samples the pixel traced: `spp` (rounded to its strata),
    /// or under adaptive anti-aliasing the lattice points its
    /// subdivision reached.
    pub samples: usize,
}

/// [`render_pixel`], with sample `recorded` (every sample: `None`) traced
/// through `recorder`; under adaptive anti-aliasing the samples are the
/// pixel's lattice points, the corners and centres its subdivision
/// reaches in order, and the pixel is its value in the render.
#[allow(clippy::too_many_arguments)]
pub fn render_pixel_recorded<R: Recorder>(
    scene: &Scene,
    tracer: &Whitted,
    settings: &RenderSettings,
    x: u32,
    y: u32,
    stats: &mut RayStats,
    recorded: Option<usize>,
    recorder: &mut R,
) -> RecordedPixel {
    if let Some(a) = settings.adaptive {
        return adaptive::pixel_recorded(
            scene, tracer, settings, a, x, y, stats, recorded, recorder,
        );
    }
    let mut rng = PixelRng::new(frame_seed(settings.seed, settings.frame), x, y);
    let strata = Strata::new(settings.spp as usize);
    let spp = strata.len();
    let lens_order = Permutation::new(spp as u32, lens_key(scene, &mut rng));
    let time_key = time_key(scene, &mut rng);
    let mut sum = DVec3::ZERO;
    let mut recorded_sample = RecordedPixel {
        pixel: DVec3::ZERO,
        sample: DVec3::ZERO,
        lens: None,
        time: None,
        samples: spp,
    };
    for s in 0..spp {
        let instant = instant_of(scene, s, spp, time_key, &mut rng);
        let time = instant
            .zip(settings.shutter)
            .map(|(k, sh)| sh.instant(k as u32));
        let (scene, tracer) = match instant {
            Some(k) => (&scene.motion[k], tracer.for_scene(&scene.motion[k])),
            None => (scene, tracer.for_scene(scene)),
        };
        let film = scene.camera.film(settings.width, settings.height);
        let (ray, lens, differential) = camera_ray(
            &film,
            &strata,
            s,
            (x, y),
            &lens_order,
            differential_spacing(&tracer, &strata, s),
            &mut rng,
        );
        let radiance = if recorded.is_none_or(|k| k == s) {
            let r =
                tracer.radiance_recorded(&ray, differential.as_ref(), &mut rng, stats, recorder);
            (
                recorded_sample.sample,
                recorded_sample.lens,
                recorded_sample.time,
            ) = (r, lens, time);
            r
        } else {
            tracer.radiance_recorded(&ray, differential.as_ref(), &mut rng, stats, &mut ())
        };
        sum += radiance;
    }
    RecordedPixel {
        pixel: sum / spp as f64,
        ..recorded_sample
    }
}

/// The key of the pixel's pairing of film strata with lens strata, drawn
/// first from its stream when the camera has a lens (a pinhole draws
/// nothing, so its pictures keep their bits). Sample s looks through lens
/// stratum `permutation_element(s, spp, key)`: pairing stratum s with lens
/// stratum s in every pixel would sample only the diagonal blocks of
/// film × lens, a bias; a shuffle per pixel pairs them at random, as
/// pbrt's stratified sampler shuffles each dimension.
fn lens_key(scene: &Scene, rng: &mut PixelRng) -> u32 {
    // A keyed aperture may open during the shutter: any instant's lens.
    let lens = |s: &Scene| s.camera.lens.is_some();
    if lens(scene) || scene.motion.iter().any(lens) {
        draw_key(rng)
    } else {
        0
    }
}

/// 32 random bits from the pixel's stream: a permutation's key.
fn draw_key(rng: &mut PixelRng) -> u32 {
    (rng.uniform() * 4_294_967_296.0) as u32
}

/// The key of the pixel's pairing of samples with shares of the exposure,
/// drawn (after the lens key) only when the shutter is open on something
/// that moves, so other pictures keep their bits.
fn time_key(scene: &Scene, rng: &mut PixelRng) -> u32 {
    if scene.motion.is_empty() {
        0
    } else {
        draw_key(rng)
    }
}

/// Which of the shutter's instants sample `s` of `spp` looks at (`None`:
/// the scene itself, no shutter): its time is stratified over the
/// exposure, share `permutation_element(s, spp, key)` (a shuffle per pixel,
/// as for the lens), jittered within the share by the pixel's stream, and
/// the instant is the one whose share of the exposure holds that time.
fn instant_of(scene: &Scene, s: usize, spp: usize, key: u32, rng: &mut PixelRng) -> Option<usize> {
    if scene.motion.is_empty() {
        return None;
    }
    let share = permutation_element(s as u32, spp as u32, key);
    let time = (f64::from(share) + rng.uniform()) / spp as f64;
    Some(((time * scene.motion.len() as f64) as usize).min(scene.motion.len() - 1))
}

/// The camera ray of sample `s` of pixel (x, y): through the pixel's
/// centre at one sample, else through a point of stratum `s` drawn from
/// the pixel's stream `rng`; with a thin lens, through a point of the lens
/// stratum [`lens_key`] pairs with it, drawn next from the same stream and
/// carried onto the lens by the concentric map (which keeps strata
/// compact). Returns the ray, with a lens its point on the lens in world
/// units along the camera's right and up from the lens centre, and given
/// a `spacing` its differential (see [`differential_spacing`]).
#[allow(clippy::too_many_arguments)]
fn camera_ray(
    film: &FilmRays,
    strata: &Strata,
    s: usize,
    (x, y): (u32, u32),
    lens_order: &Permutation,
    spacing: Option<DVec2>,
    rng: &mut PixelRng,
) -> (Ray, Option<glam::DVec2>, Option<RayDifferential>) {
    let (point, lens_point) = camera_sample(film, strata, s, x, y, lens_order, rng);
    let (ray, lens, disk) = match film.camera().lens {
        None => (film.ray(point.x, point.y), None, DVec2::ZERO),
        Some(lens) => {
            let disk = concentric_disk(lens_point);
            let ray = film.ray_through_lens(point.x, point.y, disk);
            (ray, Some(lens.radius * disk), disk)
        }
    };
    let differential = spacing.map(|h| film.differential(point.x, point.y, disk, h));
    (ray, lens, differential)
}

/// The film spacing of sample `s` of a pixel's `strata`, where `tracer`
/// wants differentials at all: its stratum's sides, so the footprints of
/// a pixel's samples tile it (pbrt scales the differentials by 1/√spp,
/// the same for square counts; 2 spp are two half-pixel columns).
fn differential_spacing(tracer: &Whitted, strata: &Strata, s: usize) -> Option<DVec2> {
    tracer.wants_differentials().then(|| strata.cell(s).1)
}

/// The samples of [`camera_ray`]: its film point, in pixels, and its
/// point of the lens's unit square (zero without a lens), which
/// [`concentric_disk`] carries onto the lens, drawn from `rng` in that
/// order.
fn camera_sample(
    film: &FilmRays,
    strata: &Strata,
    s: usize,
    x: u32,
    y: u32,
    lens_order: &Permutation,
    rng: &mut PixelRng,
) -> (glam::DVec2, glam::DVec2) {
    let offset = if strata.len() == 1 {
        glam::DVec2::splat(0.5)
    } else {
        strata.point(s, rng)
    };
    let point = glam::DVec2::new(f64::from(x) + offset.x, f64::from(y) + offset.y);
    if film.camera().lens.is_none() {
        return (point, glam::DVec2::ZERO);
    }
    let stratum = lens_order.element(s as u32) as usize;
    (point, strata.point(stratum, rng))
}

/// The seed of frame `frame`'s pixel streams: the scene's seed for frame
/// 0 (so a still and an animation's first frame agree), otherwise the seed
/// mixed with the frame number, so that every frame renders alone exactly
/// as it does in a sequence.
pub fn frame_seed(seed: u64, frame: u32) -> u64 {
    if frame == 0 {
        seed
    } else {
        seed ^ crate::math::rng::splitmix64(0x6672_616d_6500_0000 | u64::from(frame))
    }
}
