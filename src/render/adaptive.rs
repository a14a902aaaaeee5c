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
//! the cache only saves work, it never changes a value.

use std::collections::HashMap;
use std::ops::Range;

use glam::{DVec2, DVec3};

use super::frame_seed;
use crate::math::rng::{PixelRng, splitmix64};
use crate::math::sampling::concentric_disk;
use crate::scene::Scene;
use crate::settings::{Adaptive, RenderSettings};
use crate::shading::whitted::Whitted;
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
    };
    for x in xs {
        out.push(lattice.square(x << shift, top, 1 << shift, 0));
    }
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

struct Lattice<'a, 'b> {
    scene: &'a Scene,
    tracer: &'a Whitted<'a>,
    settings: &'a RenderSettings,
    adaptive: Adaptive,
    seed: u64,
    values: &'b mut HashMap<(u32, u32), DVec3>,
    stats: &'b mut RayStats,
}

impl Lattice<'_, '_> {
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
        let v = lattice_sample(
            self.scene,
            self.tracer,
            self.settings,
            self.adaptive,
            self.seed,
            i,
            j,
            self.stats,
        );
        self.values.insert((i, j), v);
        v
    }
}

/// The radiance through lattice point (i, j): from its own stream, with
/// (if asked) a jitter of up to half the spacing of the coarsest level the
/// point belongs to, and with a lens a point of the lens drawn after it.
#[allow(clippy::too_many_arguments)]
fn lattice_sample(
    scene: &Scene,
    tracer: &Whitted,
    settings: &RenderSettings,
    adaptive: Adaptive,
    seed: u64,
    i: u32,
    j: u32,
    stats: &mut RayStats,
) -> DVec3 {
    let mut rng = PixelRng::new(seed, i, j);
    let shift = lattice_shift(adaptive);
    let scale = f64::from(1u32 << shift);
    let mut point = DVec2::new(f64::from(i), f64::from(j));
    if adaptive.jitter {
        // The coarsest level the point lies on: pixel corners move up to
        // half a pixel, the centres of the first cut a quarter, …
        let level = i.trailing_zeros().min(j.trailing_zeros()).min(shift);
        let spacing = f64::from(1u32 << level);
        let u = DVec2::new(rng.uniform(), rng.uniform());
        point += (u - 0.5) * spacing;
    }
    let (x, y) = (point.x / scale, point.y / scale);
    // An open shutter: the point's own time, uniform over the exposure.
    let scene = if scene.motion.is_empty() {
        scene
    } else {
        let n = scene.motion.len();
        &scene.motion[((rng.uniform() * n as f64) as usize).min(n - 1)]
    };
    let tracer = tracer.for_scene(scene);
    let camera = &scene.camera;
    let ray = if camera.lens.is_some() {
        let disk = concentric_disk(DVec2::new(rng.uniform(), rng.uniform()));
        camera.ray_through_lens(x, y, settings.width, settings.height, disk)
    } else {
        camera.ray(x, y, settings.width, settings.height)
    };
    tracer.radiance(&ray, &mut rng, stats)
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
