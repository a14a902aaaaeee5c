//! Debug views (arbitrary output values): instead of the radiance, each
//! pixel holds what its camera rays met (shading normal, distance, object
//! or material id), how deep its ray tree went, how many shadow feelers it
//! sent, or how long it took. EXR keeps the raw values; the 8-bit formats
//! get a readable false-colour picture (`false_colour`).

use std::str::FromStr;
use std::time::Instant;

use glam::DVec3;

use super::{
    Film, RayStats, Region, RenderError, RenderObserver, RenderOutput, RenderSettings,
    render_pixel_recorded, render_with,
};
use crate::geometry::Hit;
use crate::math::Ray;
use crate::scene::Scene;
use crate::shading::whitted::{RayKind, Recorder, Whitted};

/// A debug view.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Aov {
    /// Unit shading normal at the camera rays' first hit (mean over the
    /// samples), facing the camera; 0 where they miss.
    Normal,
    /// Distance to the first hit along the camera ray (mean over the
    /// samples that hit); +∞ where all miss.
    Depth,
    /// Primitive index of sample 0's first hit; −1 for a miss.
    Object,
    /// Material index of sample 0's first hit; −1 for a miss.
    Material,
    /// Depth of the deepest ray in the pixel's ray trees (1: the camera
    /// ray only; 0: nothing hit).
    Bounces,
    /// Shadow feelers sent for the pixel.
    Feelers,
    /// Time spent on the pixel, in nanoseconds.
    Time,
}

impl Aov {
    /// Every view, with its name on the command line.
    pub const ALL: [(&'static str, Aov); 7] = [
        ("normal", Aov::Normal),
        ("depth", Aov::Depth),
        ("object", Aov::Object),
        ("material", Aov::Material),
        ("bounces", Aov::Bounces),
        ("feelers", Aov::Feelers),
        ("time", Aov::Time),
    ];
}

impl Aov {
    /// The view's name on the command line.
    pub fn name(self) -> &'static str {
        Aov::ALL
            .iter()
            .find(|(_, a)| *a == self)
            .map_or("", |(n, _)| n)
    }
}

impl FromStr for Aov {
    type Err = String;
    fn from_str(s: &str) -> Result<Aov, String> {
        Aov::ALL
            .iter()
            .find(|(name, _)| *name == s)
            .map(|(_, a)| *a)
            .ok_or_else(|| {
                let names: Vec<&str> = Aov::ALL.iter().map(|(n, _)| *n).collect();
                format!("unknown AOV `{s}`; expected one of {}", names.join(", "))
            })
    }
}

/// What the view needs from a pixel's samples.
#[derive(Default)]
struct PixelRecord {
    normal_sum: DVec3,
    depth_sum: f64,
    hits: u32,
    first: Option<(u32, u32)>,
    deepest: u32,
    feelers: u64,
    /// Whether the next hit is a camera ray's.
    camera: bool,
}

impl Recorder for PixelRecord {
    fn ray(&mut self, kind: RayKind, depth: u32, _: DVec3, _: &Ray) {
        self.camera = kind == RayKind::Camera;
        self.deepest = self.deepest.max(depth);
    }

    fn hit(&mut self, hit: &Hit, _: bool, n: DVec3, _: DVec3) {
        if self.camera {
            self.normal_sum += n;
            self.depth_sum += hit.t;
            self.hits += 1;
            self.first.get_or_insert((hit.primitive, hit.material));
        }
        self.camera = false;
    }

    fn feeler(&mut self, _: usize, _: &crate::lights::LightSample, _: DVec3) {
        self.feelers += 1;
    }
}

/// Renders the view `aov` of `region`: raw values per pixel.
pub fn render_aov(
    scene: &Scene,
    settings: &RenderSettings,
    region: Region,
    aov: Aov,
    observer: &dyn RenderObserver,
) -> Result<RenderOutput, RenderError> {
    let pixel = |tracer: &Whitted, x: u32, y: u32, stats: &mut RayStats| {
        let start = Instant::now();
        let mut r = PixelRecord::default();
        render_pixel_recorded(scene, tracer, settings, x, y, stats, None, &mut r);
        let id = |v: Option<u32>| DVec3::splat(v.map_or(-1.0, f64::from));
        match aov {
            Aov::Normal if r.hits > 0 => r.normal_sum.normalize_or_zero(),
            Aov::Normal => DVec3::ZERO,
            Aov::Depth if r.hits > 0 => DVec3::splat(r.depth_sum / f64::from(r.hits)),
            Aov::Depth => DVec3::splat(f64::INFINITY),
            Aov::Object => id(r.first.map(|f| f.0)),
            Aov::Material => id(r.first.map(|f| f.1)),
            Aov::Bounces => DVec3::splat(if r.hits > 0 {
                f64::from(r.deepest)
            } else {
                0.0
            }),
            Aov::Feelers => DVec3::splat(r.feelers as f64),
            Aov::Time => DVec3::splat(start.elapsed().as_nanos() as f64),
        }
    };
    render_with(
        scene,
        settings,
        region,
        observer,
        |tracer, _: &mut (), y, xs, stats, out| {
            out.extend(xs.map(|x| pixel(tracer, x, y, stats)));
        },
    )
}

/// A readable picture of raw view values, for the 8-bit formats: normals
/// as 0.5·(n + 1); depth as grey, near bright; ids as distinct colours;
/// counts and times as a heat ramp (black, red, yellow, white) over
/// 0 … the 99.5th percentile (a few pixels preempted by the system would
/// otherwise make every other one black). Colours are given as displayed (sRGB) and
/// stored linear, as the writer expects.
pub fn false_colour(film: &Film, aov: Aov) -> Film {
    let values = film.pixels();
    let largest = values
        .iter()
        .map(|v| v.x)
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max);
    let smallest = values
        .iter()
        .map(|v| v.x)
        .filter(|v| v.is_finite())
        .fold(f64::INFINITY, f64::min);
    let mut sorted: Vec<f64> = values
        .iter()
        .map(|v| v.x)
        .filter(|v| v.is_finite())
        .collect();
    sorted.sort_by(f64::total_cmp);
    let top = sorted
        .get((sorted.len().saturating_sub(1) as f64 * 0.995) as usize)
        .copied()
        .unwrap_or(0.0)
        .max(1e-300);
    let colour = |v: DVec3| -> DVec3 {
        match aov {
            Aov::Normal => 0.5 * (v + DVec3::ONE),
            Aov::Depth if v.x.is_finite() && largest > smallest => {
                DVec3::splat(1.0 - 0.9 * (v.x - smallest) / (largest - smallest))
            }
            Aov::Depth if v.x.is_finite() => DVec3::ONE,
            Aov::Depth => DVec3::ZERO,
            Aov::Object | Aov::Material if v.x < 0.0 => DVec3::ZERO,
            Aov::Object | Aov::Material => id_colour(v.x as u64),
            Aov::Bounces | Aov::Feelers | Aov::Time => heat(v.x / top),
        }
    };
    let mut out = Film::window(film.width(), film.height(), film.region());
    let region = film.region();
    let shown: Vec<DVec3> = values
        .iter()
        .map(|&v| colour(v).map(crate::shading::texture::srgb_to_linear))
        .collect();
    out.paste(region, &shown);
    out
}

/// A distinct, stable colour per id (golden-ratio hues).
fn id_colour(id: u64) -> DVec3 {
    let h = (id as f64 * 0.618_033_988_749_895).fract() * 6.0;
    let x = 1.0 - (h % 2.0 - 1.0).abs();
    let (r, g, b) = match h as u32 {
        0 => (1.0, x, 0.0),
        1 => (x, 1.0, 0.0),
        2 => (0.0, 1.0, x),
        3 => (0.0, x, 1.0),
        4 => (x, 0.0, 1.0),
        _ => (1.0, 0.0, x),
    };
    DVec3::new(r, g, b) * 0.8 + DVec3::splat(0.15)
}

/// Black → red → yellow → white over t in [0, 1].
fn heat(t: f64) -> DVec3 {
    let t = t.clamp(0.0, 1.0) * 3.0;
    DVec3::new(
        t.min(1.0),
        (t - 1.0).clamp(0.0, 1.0),
        (t - 2.0).clamp(0.0, 1.0),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse_and_colours_are_in_range() {
        assert_eq!("depth".parse::<Aov>(), Ok(Aov::Depth));
        assert!("nope".parse::<Aov>().unwrap_err().contains("normal, depth"));
        for i in 0..50 {
            let c = id_colour(i);
            assert!(c.min_element() >= 0.15 && c.max_element() <= 0.95 + 1e-12);
            assert_ne!(id_colour(i), id_colour(i + 1));
        }
        assert_eq!(heat(0.0), DVec3::ZERO);
        assert_eq!(heat(1.0), DVec3::ONE);
    }
}
