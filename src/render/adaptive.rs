//! Whitted's adaptive anti-aliasing (1980; POV-Ray's method 2): rays go
//! through the corners and the centre of each pixel, and where these five
//! differ by more than a threshold (in any colour channel of linear
//! radiance) the square is cut in four and the new corners and centres are
//! traced too, down to `depth` cuts. A square's value is half its centre
//! plus half its corners' mean (the midpoint and trapezoid rules
//! averaged), or the mean of its four quarters where it was cut; a pixel
//! is its square's value. The centre catches what lies between the
//! corners (a bar thinner than a pixel), which corners alone miss.
//!
//! Every sample point lies on one lattice of spacing 2^−(depth+1) pixels, and
//! what is traced there is a function of its lattice coordinates alone:
//! its random stream is keyed by them (not by a pixel), and with jitter
//! its offset too. So a corner shared by two pixels, two tiles, two
//! threads or two farm regions is the same sample, and any region split
//! gives the whole render's bits. A tile keeps its samples while a row of
//! pixels and the row below it are rendered, so neighbours share the work;
//! the cache only saves work, it never changes a value. For the same
//! reason one pixel can be worked out alone, its samples traced afresh,
//! and equal its value in the render: what `prism explain` and the debug
//! views do, through [`pixel_recorded`].

use std::collections::HashMap;
use std::ops::Range;

use glam::{DVec2, DVec3};

use super::{RecordedPixel, frame_seed};
use crate::math::rng::{PixelRng, splitmix64};
use crate::math::sampling::concentric_disk;
use crate::scene::Scene;
use crate::settings::{Adaptive, RenderSettings};
use crate::shading::whitted::{Recorder, Whitted};
use crate::stats::RayStats;

/// The samples a tile has traced, by lattice coordinates: those of the
/// row being rendered and the edge it shares with the row below.
#[derive(Default)]
pub struct TileSamples {
    values: HashMap<(u32, u32), DVec3>,
}

/// Pushes onto `out` the pixels `xs` of row `y`, anti-aliased adaptively;
/// `samples` are the tile's, its rows rendered top to bottom.
#[allow(clippy::too_many_arguments)]
pub fn render_row_adaptive(
    scene: &Scene,
    tracer: &Whitted,
    settings: &RenderSettings,
    adaptive: Adaptive,
    samples: &mut TileSamples,
    y: u32,
    xs: Range<u32>,
    stats: &mut RayStats,
    out: &mut Vec<DVec3>,
) {
    let shift = lattice_shift(adaptive);
    let top = y << shift;
    // Of the row above, only its bottom edge (this row's top) is shared.
    samples.values.retain(|&(_, j), _| j == top);
    let mut lattice = Lattice {
        scene,
        tracer,
        settings,
        adaptive,
        seed: lattice_seed(settings),
        values: &mut samples.values,
        stats,
        recorder: &mut (),
        record: None,
        traced: 0,
        recorded: None,
    };
    for x in xs {
        out.push(lattice.square(x << shift, top, 1 << shift, 0));
    }
}

/// Pixel (x, y) alone, equal to its value in the render, with its samples
/// (the lattice points it traces, corners and centres, in the order the
/// subdivision reaches them) told to `recorder`: sample `record`, or every
/// one when `None`. `samples` in the result is how many it traced.
#[allow(clippy::too_many_arguments)]
pub fn pixel_recorded<R: Recorder>(
    scene: &Scene,
    tracer: &Whitted,
    settings: &RenderSettings,
    adaptive: Adaptive,
    x: u32,
    y: u32,
    stats: &mut RayStats,
    record: Option<usize>,
    recorder: &mut R,
) -> RecordedPixel {
    let shift = lattice_shift(adaptive);
    let mut values = HashMap::new();
    let mut lattice = Lattice {
        scene,
        tracer,
        settings,
        adaptive,
        seed: lattice_seed(settings),
        values: &mut values,
        stats,
        recorder,
        record,
        traced: 0,
        recorded: None,
    };
    let pixel = lattice.square(x << shift, y << shift, 1 << shift, 0);
    let traced = lattice.traced;
    let recorded = lattice.recorded.unwrap_or_default();
    RecordedPixel {
        pixel,
        sample: recorded.radiance,
        lens: recorded.lens,
        time: recorded.time,
        samples: traced,
    }
}

/// What one lattice sample saw.
#[derive(Clone, Copy, Default)]
struct LatticeSample {
    radiance: DVec3,
    /// Its point on the lens, in world units (see `camera_ray`).
    lens: Option<DVec2>,
    /// Its instant, in frames after the frame's start.
    time: Option<f64>,
}

/// The lattice's spacing as a power of two per pixel: `depth` cuts, and
/// the centre of the smallest square.
fn lattice_shift(adaptive: Adaptive) -> u32 {
    adaptive.depth + 1
}

/// The seed of the lattice's streams: the frame's, kept apart from the
/// pixel streams of the uniform sampler.
fn lattice_seed(settings: &RenderSettings) -> u64 {
    splitmix64(frame_seed(settings.seed, settings.frame) ^ 0x6164_6170_7469_7665)
}

struct Lattice<'a, 'b, R> {
    scene: &'a Scene,
    tracer: &'a Whitted<'a>,
    settings: &'a RenderSettings,
    adaptive: Adaptive,
    seed: u64,
    values: &'b mut HashMap<(u32, u32), DVec3>,
    stats: &'b mut RayStats,
    /// Hears the samples `record` picks (all of them when `None`).
    recorder: &'b mut R,
    record: Option<usize>,
    /// Samples traced so far.
    traced: usize,
    /// The last sample recorded.
    recorded: Option<LatticeSample>,
}

impl<R: Recorder> Lattice<'_, '_, R> {
    /// The value of the square with lattice corner (i, j) and side `side`
    /// (in lattice units) at cut `level`.
    fn square(&mut self, i: u32, j: u32, side: u32, level: u32) -> DVec3 {
        let half = side / 2;
        let c = [
            self.sample(i, j),
            self.sample(i + side, j),
            self.sample(i, j + side),
            self.sample(i + side, j + side),
            self.sample(i + half, j + half),
        ];
        if level >= self.adaptive.depth || !differ(&c, self.adaptive.threshold) {
            // Half the centre, half the corners' mean: the midpoint and
            // trapezoid rules averaged.
            return 0.125 * (c[0] + c[1] + c[2] + c[3]) + 0.5 * c[4];
        }
        let level = level + 1;
        0.25 * (self.square(i, j, half, level)
            + self.square(i + half, j, half, level)
            + self.square(i, j + half, half, level)
            + self.square(i + half, j + half, half, level))
    }

    /// The radiance through lattice point (i, j), traced once.
    fn sample(&mut self, i: u32, j: u32) -> DVec3 {
        if let Some(&v) = self.values.get(&(i, j)) {
            return v;
        }
        let k = self.traced;
        self.traced += 1;
        let (scene, tracer, settings) = (self.scene, self.tracer, self.settings);
        let (adaptive, seed) = (self.adaptive, self.seed);
        let sample = if self.record.is_none_or(|r| r == k) {
            let s = lattice_sample(
                scene,
                tracer,
                settings,
                adaptive,
                seed,
                (i, j),
                self.stats,
                self.recorder,
            );
            self.recorded = Some(s);
            s
        } else {
            lattice_sample(
                scene,
                tracer,
                settings,
                adaptive,
                seed,
                (i, j),
                self.stats,
                &mut (),
            )
        };
        self.values.insert((i, j), sample.radiance);
        sample.radiance
    }
}

/// The radiance through lattice point (i, j): from its own stream, with
/// (if asked) a jitter of up to half the spacing of the coarsest level the
/// point belongs to, and with a lens a point of the lens drawn after it;
/// its ray tree told to `recorder`.
#[allow(clippy::too_many_arguments)]
fn lattice_sample<R: Recorder>(
    scene: &Scene,
    tracer: &Whitted,
    settings: &RenderSettings,
    adaptive: Adaptive,
    seed: u64,
    (i, j): (u32, u32),
    stats: &mut RayStats,
    recorder: &mut R,
) -> LatticeSample {
    let mut rng = PixelRng::new(seed, i, j);
    let shift = lattice_shift(adaptive);
    let scale = f64::from(1u32 << shift);
    let mut point = DVec2::new(f64::from(i), f64::from(j));
    // The coarsest level the point lies on: pixel corners are a pixel
    // apart, the centres of the first cut half a pixel from the corners, …
    let level = i.trailing_zeros().min(j.trailing_zeros()).min(shift);
    let spacing = f64::from(1u32 << level);
    if adaptive.jitter {
        // Pixel corners move up to half a pixel, the centres of the first
        // cut a quarter, …
        let u = DVec2::new(rng.uniform(), rng.uniform());
        point += (u - 0.5) * spacing;
    }
    let (x, y) = (point.x / scale, point.y / scale);
    // An open shutter: the point's own time, uniform over the exposure.
    let (scene, instant) = if scene.motion.is_empty() {
        (scene, None)
    } else {
        let n = scene.motion.len();
        let k = ((rng.uniform() * n as f64) as usize).min(n - 1);
        (&scene.motion[k], Some(k))
    };
    let tracer = tracer.for_scene(scene);
    let film = scene.camera.film(settings.width, settings.height);
    let (ray, lens, disk) = match film.camera().lens {
        Some(lens) => {
            let disk = concentric_disk(DVec2::new(rng.uniform(), rng.uniform()));
            let ray = film.ray_through_lens(x, y, disk);
            (ray, Some(lens.radius * disk), disk)
        }
        None => (film.ray(x, y), None, DVec2::ZERO),
    };
    // For a filtered texture, a sample stands for a square of half its
    // level's spacing: half a pixel at the pixel corners, a quarter at
    // their centres, … (on bench/edges.toml with its checker filtered,
    // 0.35, 0.7, 1 and 2 times the spacing did no better for the same
    // error, bench/README.md).
    let differential = tracer
        .wants_differentials()
        .then(|| film.differential(x, y, disk, DVec2::splat(0.5 * spacing / scale)));
    LatticeSample {
        radiance: tracer.radiance_recorded(&ray, differential.as_ref(), &mut rng, stats, recorder),
        lens,
        time: instant
            .zip(settings.shutter)
            .map(|(k, shutter)| shutter.instant(k as u32)),
    }
}

/// Whether the four corners differ by more than `threshold` in some
/// channel (NaN counts as a difference, so it is looked at closer).
fn differ(c: &[DVec3], threshold: f64) -> bool {
    if c.iter().any(|v| v.is_nan()) {
        return true;
    }
    let low = c.iter().fold(c[0], |a, b| a.min(*b));
    let high = c.iter().fold(c[0], |a, b| a.max(*b));
    (high - low).max_element() > threshold
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corners_differ_by_their_widest_channel() {
        let flat = [DVec3::splat(0.5); 4];
        assert!(!differ(&flat, 0.0));
        let mut edge = flat;
        edge[3].y = 0.75;
        assert!(differ(&edge, 0.2));
        assert!(!differ(&edge, 0.25));
        edge[2].x = f64::NAN;
        assert!(differ(&edge, 10.0));
    }
}
