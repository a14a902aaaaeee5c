//! The Whitted illumination model at the closest hit:
//!
//! I = ka·Od·Ia + Σⱼ visⱼ·Ilⱼ·(kd·Od·max(0, N·Lⱼ) + ks·max(0, Rⱼ·V)ⁿ) + kr·I_reflected + kt·I_transmitted
//!
//! with shadow feelers for visⱼ, a reflected ray R = I − 2N(I·N), a
//! refracted ray by Snell's law, both followed recursively. On a rough
//! material each of the two is a lobe of rays about microfacet normals
//! (`glossy.rs`), averaged.

use arrayvec::ArrayVec;
use glam::DVec3;

use super::glossy::{ggx_alpha, glossy_reflection, glossy_refraction, sample_ggx_normal};
use super::optics::{fresnel_dielectric, reflect, refract, schlick};
use super::{Fresnel, Material};
use crate::accel::{Blocker, FeelerBatch, FirstBlockers, MAX_CANDIDATES, ShadowCandidates, simd};
use crate::geometry::Hit;
use crate::lights::{Light, LightSample, LightSampler, SAMPLE_BATCH};
use crate::math::ray::SpawnOrigins;
use crate::math::rng::PixelRng;
use crate::math::sampling::Strata;
use crate::math::{Ray, RayDifferential};
use crate::scene::Scene;
use crate::stats::RayStats;

/// From this many feelers to a sphere light on, the scene is culled
/// against their hull first (below, the BVH query alone is cheaper).
const CULL_FROM: usize = 4;

/// Nested media deeper than this are not tracked (the innermost are lost).
const MAX_NESTING: usize = 8;

/// The media a ray travels through: a stack of the materials of the
/// transparent objects it has entered, innermost last; outside everything
/// the index is 1. Keyed by material, not primitive, so a solid built of
/// several faces (a glass prism of polygons) is one medium: the ray enters
/// through one face and leaves through another.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Media {
    // Materials and their indices side by side, not as (u32, f64) pairs:
    // without the pairs' padding the stack is small enough to be copied
    // in registers as a path's rays hand it on, not by a memcpy call.
    materials: [u32; MAX_NESTING],
    iors: [f64; MAX_NESTING],
    len: usize,
}

impl Default for Media {
    fn default() -> Self {
        Media {
            materials: [0; MAX_NESTING],
            iors: [1.0; MAX_NESTING],
            len: 0,
        }
    }
}

impl Media {
    /// Index of refraction of the medium the ray travels in.
    pub fn ior(&self) -> f64 {
        if self.len == 0 {
            1.0
        } else {
            self.iors[self.len - 1]
        }
    }

    /// After entering an object of `material` with index `ior`.
    pub fn entering(mut self, material: u32, ior: f64) -> Self {
        if self.len < MAX_NESTING {
            self.materials[self.len] = material;
            self.iors[self.len] = ior;
            self.len += 1;
        }
        self
    }

    /// After leaving `primitive` (which need not be innermost: overlapping
    /// objects may be left in any order).
    pub fn leaving(mut self, primitive: u32) -> Self {
        if let Some(i) = self.materials[..self.len]
            .iter()
            .rposition(|&m| m == primitive)
        {
            self.materials.copy_within(i + 1..self.len, i);
            self.iors.copy_within(i + 1..self.len, i);
            self.len -= 1;
        }
        self
    }
}

/// Scene-wide knobs of the model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WhittedSettings {
    /// Longest ray path, counting the camera ray (1: no secondary rays).
    pub max_depth: u32,
    /// A secondary ray whose weight in the pixel falls below this is not
    /// traced (Whitted's adaptive tree depth control).
    pub min_weight: f64,
}

/// The Whitted ray tracer over one scene.
pub struct Whitted<'a> {
    scene: &'a Scene,
    settings: WhittedSettings,
    /// Whether some material's texture averages over a footprint, so
    /// camera rays should come with their differentials.
    filters: bool,
}

/// What kind of ray `trace` follows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RayKind {
    /// From the camera.
    Camera,
    /// Reflected: R = I − 2N(I·N).
    Reflection,
    /// Refracted by Snell's law.
    Refraction,
}

/// Why a branch of the ray tree ends.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stop {
    /// The ray hit nothing: it brings the background.
    Miss,
    /// The path reached `max_depth`: no secondary rays.
    Depth,
    /// The reflected (or, below, refracted) ray's weight in the pixel is
    /// below `min_weight`.
    ReflectionWeight,
    /// The refracted ray's weight is below `min_weight`.
    RefractionWeight,
}

/// Hears what the tracer does, step by step, to explain a pixel (see
/// `shading::explain`). Every method does nothing by default; `()` hears
/// nothing and costs nothing (the calls compile away).
pub trait Recorder {
    /// A ray starts: its kind, depth (1 = camera), weight in the pixel.
    fn ray(&mut self, kind: RayKind, depth: u32, weight: DVec3, ray: &Ray) {
        let _ = (kind, depth, weight, ray);
    }
    /// It hits `hit`; `n` is the shading normal facing the ray, `od` the
    /// surface colour.
    fn hit(&mut self, hit: &Hit, entering: bool, n: DVec3, od: DVec3) {
        let _ = (hit, entering, n, od);
    }
    /// The ambient term ka·Od·Ia.
    fn ambient(&mut self, term: DVec3) {
        let _ = term;
    }
    /// The light the surface gives off itself.
    fn emission(&mut self, term: DVec3) {
        let _ = term;
    }
    /// One sample of light `light` (its unit direction, the feeler's
    /// length, the falloff) and the visibility its shadow feeler found (not
    /// called for samples that need no feeler).
    fn feeler(&mut self, light: usize, sample: &LightSample, visibility: DVec3) {
        let _ = (light, sample, visibility);
    }
    /// Light `light` (of colour × intensity `radiance`, as the scene
    /// being traced has it: an instant's under an open shutter): its whole
    /// contribution, over `samples` samples.
    fn light(&mut self, light: usize, radiance: DVec3, samples: usize, contribution: DVec3) {
        let _ = (light, radiance, samples, contribution);
    }
    /// The weights of the secondary rays at this hit, the indices on the
    /// incoming and the far side, and whether total internal reflection
    /// moved the transmitted weight to reflection.
    fn split(&mut self, kr: DVec3, kt: DVec3, eta: Option<(f64, f64)>, tir: bool) {
        let _ = (kr, kt, eta, tir);
    }
    /// A branch ends here.
    fn stop(&mut self, why: Stop) {
        let _ = why;
    }
    /// The ray's colour, once its subtree is done.
    fn done(&mut self, color: DVec3) {
        let _ = color;
    }
}

/// Hears nothing.
impl Recorder for () {}

/// Where a ray stands in the ray tree.
#[derive(Clone, Copy, Debug)]
struct PathState {
    kind: RayKind,
    /// 1 for the camera ray.
    depth: u32,
    /// Product of the kr/kt factors from the camera to this ray, per
    /// colour channel.
    weight: DVec3,
    /// The media the ray travels through.
    media: Media,
    /// Whether a rough surface earlier on the path split it into a lobe
    /// of rays: then later rough surfaces send one ray each.
    spread: bool,
}

impl PathState {
    /// A camera ray's: depth 1, full weight, in the scene's outer medium.
    fn camera() -> PathState {
        PathState {
            kind: RayKind::Camera,
            depth: 1,
            weight: DVec3::ONE,
            media: Media::default(),
            spread: false,
        }
    }

    fn child(&self, kind: RayKind, k: DVec3, media: Media) -> PathState {
        PathState {
            kind,
            depth: self.depth + 1,
            weight: self.weight * k,
            media,
            spread: self.spread,
        }
    }
}

/// What the local model needs at a hit.
struct ShadingPoint<'m> {
    hit: &'m Hit,
    /// Unit normal facing the incoming ray.
    n: DVec3,
    /// Unit direction towards the viewer (−D).
    view: DVec3,
    material: &'m Material,
    /// Surface colour Od at the hit.
    od: DVec3,
}

impl ShadingPoint<'_> {
    /// Where this point's shadow feelers start: the hit lifted by its
    /// shadow-terminator offset (smooth meshes), then off the surface.
    #[inline]
    fn feeler_origins(&self) -> SpawnOrigins {
        SpawnOrigins::new(self.hit.point + self.hit.feeler_offset, self.hit.normal)
    }
}

/// How a hit divides the rest of the path: the weights of the reflected and
/// transmitted rays, the transmitted direction, the media beyond.
struct Split {
    kr: DVec3,
    kt: DVec3,
    refracted: Option<DVec3>,
    media_beyond: Media,
    /// η = ηi/ηt across the surface (1 where nothing is transmitted).
    eta: f64,
}

impl<'a> Whitted<'a> {
    /// A tracer for `scene`.
    pub fn new(scene: &'a Scene, settings: WhittedSettings) -> Self {
        let filters = scene
            .materials
            .iter()
            .any(|m| m.texture.filtered() || m.emission.filtered());
        Whitted {
            scene,
            settings,
            filters,
        }
    }

    /// The same tracer for another scene (an instant of an open shutter).
    pub fn for_scene<'b>(&self, scene: &'b Scene) -> Whitted<'b> {
        // The instants share the scene's materials (a key changes values,
        // never whether a texture is filtered).
        Whitted {
            scene,
            settings: self.settings,
            filters: self.filters,
        }
    }

    /// Whether the camera's rays should come with their differentials
    /// (some texture averages over the footprint they give); without one,
    /// a differential is not looked at.
    pub fn wants_differentials(&self) -> bool {
        self.filters
    }

    /// The colour seen along a camera ray.
    pub fn radiance(&self, ray: &Ray, rng: &mut PixelRng, stats: &mut RayStats) -> DVec3 {
        self.radiance_recorded(ray, None, rng, stats, &mut ())
    }

    /// [`radiance`](Self::radiance) of a camera ray with its
    /// `differential` (for filtered textures at its first hit), telling
    /// `recorder` every step.
    pub fn radiance_recorded<R: Recorder>(
        &self,
        ray: &Ray,
        differential: Option<&RayDifferential>,
        rng: &mut PixelRng,
        stats: &mut RayStats,
        recorder: &mut R,
    ) -> DVec3 {
        let color = self.trace_inner(ray, PathState::camera(), differential, rng, stats, recorder);
        recorder.done(color);
        color
    }

    /// The colour seen along camera ray `ray` whose first hit, `hit`, is
    /// already known (what the aggregate's `closest_hit` answers for it
    /// without limit): to the bit what
    /// [`radiance_recorded`](Self::radiance_recorded) gives.
    pub fn camera_radiance(
        &self,
        ray: &Ray,
        differential: Option<&RayDifferential>,
        hit: Option<&Hit>,
        rng: &mut PixelRng,
        stats: &mut RayStats,
    ) -> DVec3 {
        stats.camera += 1;
        self.shade(
            ray,
            PathState::camera(),
            differential,
            hit,
            rng,
            stats,
            &mut (),
        )
    }

    fn trace<R: Recorder>(
        &self,
        ray: &Ray,
        path: PathState,
        rng: &mut PixelRng,
        stats: &mut RayStats,
        rec: &mut R,
    ) -> DVec3 {
        let color = self.trace_inner(ray, path, None, rng, stats, rec);
        rec.done(color);
        color
    }

    fn trace_inner<R: Recorder>(
        &self,
        ray: &Ray,
        path: PathState,
        differential: Option<&RayDifferential>,
        rng: &mut PixelRng,
        stats: &mut RayStats,
        rec: &mut R,
    ) -> DVec3 {
        match path.kind {
            RayKind::Camera => stats.camera += 1,
            RayKind::Reflection => stats.reflection += 1,
            RayKind::Refraction => stats.refraction += 1,
        }
        rec.ray(path.kind, path.depth, path.weight, ray);
        let hit = self.scene.aggregate.closest_hit(ray, f64::INFINITY);
        self.shade(ray, path, differential, hit.as_ref(), rng, stats, rec)
    }

    /// The colour along `ray` from its first hit on: the local model,
    /// and the reflected and refracted rays traced on. Only a camera ray
    /// brings a `differential`: reflected and refracted rays point-sample
    /// textures (their footprints would need the differentials carried
    /// through each bounce).
    #[allow(clippy::too_many_arguments)]
    fn shade<R: Recorder>(
        &self,
        ray: &Ray,
        path: PathState,
        differential: Option<&RayDifferential>,
        hit: Option<&Hit>,
        rng: &mut PixelRng,
        stats: &mut RayStats,
        rec: &mut R,
    ) -> DVec3 {
        let Some(hit) = hit else {
            rec.stop(Stop::Miss);
            return self.scene.background;
        };
        let material_index = hit.material;
        let material = &self.scene.materials[material_index as usize];
        let aggregate = &self.scene.aggregate;
        // Shading normal faces the incoming ray; "entering" by the sign of I·N.
        let entering = ray.direction.dot(hit.normal) < 0.0;
        let footprint = differential
            .filter(|_| self.filters)
            .and_then(|d| d.footprint(hit.point, hit.normal));
        let point = ShadingPoint {
            hit,
            // Shade with the (possibly interpolated) shading normal, on the
            // incoming side like the geometric one.
            n: if entering {
                hit.shading_normal
            } else {
                -hit.shading_normal
            },
            view: -ray.direction,
            material,
            od: material
                .texture
                .color(hit.point, hit.normal, footprint, || aggregate.uv(hit))
                * hit.color,
        };

        rec.hit(hit, entering, point.n, point.od);
        let mut color = material.ka * point.od * self.scene.ambient;
        rec.ambient(color);
        let emitted = material
            .emission
            .color(hit.point, hit.normal, footprint, || aggregate.uv(hit));
        rec.emission(emitted);
        color += emitted;
        for (index, light) in self.scene.lights.iter().enumerate() {
            color += self.direct(index, light, &point, rng, stats, rec);
        }
        if path.depth >= self.settings.max_depth {
            rec.stop(Stop::Depth);
            return color;
        }

        let split = self.split(&point, hit.medium, entering, path.media, rec);
        if material.roughness > 0.0 {
            return color + self.glossy(ray, &point, &split, path, rng, stats, rec);
        }
        if split.kr != DVec3::ZERO && self.goes_on(&path, split.kr, Stop::ReflectionWeight, rec) {
            let r = Ray::spawn(hit.point, hit.normal, reflect(ray.direction, point.n));
            let child = path.child(RayKind::Reflection, split.kr, path.media);
            color += split.kr * self.trace(&r, child, rng, stats, rec);
        }
        if let Some(t) = split.refracted
            && self.goes_on(&path, split.kt, Stop::RefractionWeight, rec)
        {
            let r = Ray::spawn(hit.point, hit.normal, t.normalize());
            let child = path.child(RayKind::Refraction, split.kt, split.media_beyond);
            color += split.kt * self.trace(&r, child, rng, stats, rec);
        }
        color
    }

    /// Whether a secondary ray of weight `k` at this hit is traced
    /// ([`worth_tracing`](Self::worth_tracing)); if not, `rec` hears why.
    fn goes_on<R: Recorder>(&self, path: &PathState, k: DVec3, stop: Stop, rec: &mut R) -> bool {
        let worth = self.worth_tracing(path.weight * k);
        if !worth {
            rec.stop(stop);
        }
        worth
    }

    /// The reflected and transmitted light of a rough surface: each a
    /// lobe of rays about microfacet normals drawn from GGX (one stratum
    /// of the square each), averaged with equal weights. The first rough
    /// surface on a path sends the material's `glossy_samples` rays per
    /// lobe, later ones one each. A facet that totally reflects the
    /// transmitted share sends it on as reflected light.
    #[allow(clippy::too_many_arguments)]
    fn glossy<R: Recorder>(
        &self,
        ray: &Ray,
        point: &ShadingPoint,
        split: &Split,
        path: PathState,
        rng: &mut PixelRng,
        stats: &mut RayStats,
        rec: &mut R,
    ) -> DVec3 {
        let hit = point.hit;
        let reflects =
            split.kr != DVec3::ZERO && self.goes_on(&path, split.kr, Stop::ReflectionWeight, rec);
        let transmits = split.refracted.is_some()
            && split.kt != DVec3::ZERO
            && self.goes_on(&path, split.kt, Stop::RefractionWeight, rec);
        if !reflects && !transmits {
            return DVec3::ZERO;
        }
        let count = if path.spread {
            1
        } else {
            point.material.glossy_samples as usize
        };
        let strata = Strata::new(count);
        let alpha = ggx_alpha(point.material.roughness);
        let mut path = path;
        path.spread = true;
        let mut sum = DVec3::ZERO;
        if reflects {
            for i in 0..count {
                let m = sample_ggx_normal(point.n, alpha, strata.point(i, rng));
                let direction = glossy_reflection(ray.direction, point.n, m);
                let r = Ray::spawn(hit.point, hit.normal, direction);
                let child = path.child(RayKind::Reflection, split.kr, path.media);
                sum += split.kr * self.trace(&r, child, rng, stats, rec);
            }
        }
        if transmits {
            for i in 0..count {
                let m = sample_ggx_normal(point.n, alpha, strata.point(i, rng));
                let (direction, kind, media) =
                    match glossy_refraction(ray.direction, point.n, m, split.eta) {
                        Some(t) => (t, RayKind::Refraction, split.media_beyond),
                        None => (
                            glossy_reflection(ray.direction, point.n, m),
                            RayKind::Reflection,
                            path.media,
                        ),
                    };
                let r = Ray::spawn(hit.point, hit.normal, direction);
                let child = path.child(kind, split.kt, media);
                sum += split.kt * self.trace(&r, child, rng, stats, rec);
            }
        }
        sum / count as f64
    }

    /// Whitted's adaptive depth control: a ray is traced while its weight in
    /// the pixel, in its strongest channel, reaches `min_weight`.
    fn worth_tracing(&self, weight: DVec3) -> bool {
        weight.max_element() >= self.settings.min_weight
    }

    /// kr, kt and the refracted direction at a hit: the material's weights,
    /// or their sum split by Fresnel if asked; under total internal
    /// reflection the transmitted weight goes to reflection.
    fn split<R: Recorder>(
        &self,
        point: &ShadingPoint,
        medium: u32,
        entering: bool,
        media: Media,
        rec: &mut R,
    ) -> Split {
        let material = point.material;
        // The index of the solid behind the surface (a CSG's, whichever
        // part's material paints the surface).
        let ior = self.scene.materials[medium as usize].ior;
        let (mut kr, mut kt) = (material.kr, material.kt);
        if kt == DVec3::ZERO {
            rec.split(kr, kt, None, false);
            return Split {
                kr,
                kt,
                refracted: None,
                media_beyond: media,
                eta: 1.0,
            };
        }
        // Indices on both sides: η = ηi/ηt.
        let (eta_i, eta_t, media_beyond) = if entering {
            (media.ior(), ior, media.entering(medium, ior))
        } else {
            let outside = media.leaving(medium);
            (ior, outside.ior(), outside)
        };
        let cos_i = point.view.dot(point.n);
        if material.fresnel != Fresnel::Off {
            let f = match material.fresnel {
                Fresnel::Schlick => schlick(cos_i, eta_i, eta_t),
                _ => fresnel_dielectric(cos_i, eta_i, eta_t),
            };
            (kr, kt) = (f * (kr + kt), (1.0 - f) * (kr + kt));
        }
        let refracted = refract(-point.view, point.n, eta_i / eta_t);
        if refracted.is_none() {
            // Total internal reflection: all the energy is reflected.
            (kr, kt) = (kr + kt, DVec3::ZERO);
        }
        rec.split(kr, kt, Some((eta_i, eta_t)), refracted.is_none());
        Split {
            kr,
            kt,
            refracted,
            media_beyond,
            eta: eta_i / eta_t,
        }
    }

    /// One light's local (Phong) contribution, averaged over its samples,
    /// each weighted by its shadow feeler's visibility.
    fn direct<R: Recorder>(
        &self,
        index: usize,
        light: &Light,
        point: &ShadingPoint,
        rng: &mut PixelRng,
        stats: &mut RayStats,
        rec: &mut R,
    ) -> DVec3 {
        let sampler = light.sampler(point.hit.point);
        let count = sampler.count();
        if count == 1 {
            return self.direct_one(index, light, &sampler, point, rng, stats, rec);
        }
        if sampler.behind(point.n) {
            // Every sample would be unlit: none is drawn or traced (nor
            // are the shadow candidates looked for), and the stream moves
            // on as the draws would have moved it, so the bits stay. 16-19 %
            // of the points that sample the light in bench/solids.toml and
            // bench/csg.toml.
            rng.skip(sampler.draws());
            // The sum the loop leaves, weighted as it is (a radiance that
            // is not finite gives what it gave there).
            let contribution = light.radiance * DVec3::ZERO / count as f64;
            rec.light(index, light.radiance, count, contribution);
            return contribution;
        }
        // Many feelers to one sphere light: cull the scene against their
        // hull once, then test each against what is left.
        let mut candidates = match sampler.light_sphere() {
            Some((to_center, radius)) if count >= CULL_FROM => {
                self.scene.aggregate.shadow_candidates(
                    point.hit.point,
                    point.hit.primitive,
                    to_center,
                    radius,
                    count,
                )
            }
            _ => None,
        };
        let origins = point.feeler_origins();
        let mut sum = DVec3::ZERO;
        let mut batch = ArrayVec::<LightSample, SAMPLE_BATCH>::new();
        let mut feelers = FeelerBatch::<SAMPLE_BATCH>::default();
        let mut shade = [DVec3::ZERO; SAMPLE_BATCH];
        let mut first = FirstBlockers::default();
        for start in (0..count).step_by(SAMPLE_BATCH) {
            // Draw a batch of directions first (vector code), then trace
            // them; the draws and the sum keep their order.
            sampler.sample_batch(start, rng, &mut batch);
            // Against a few candidates, the whole batch of feelers at once:
            // whether each is blocked, or (transparent shadows) the first
            // surface each meets.
            // Two options rather than one enum: a 16-lane enum was copied
            // about (memmove) and measured slower.
            let (mut blocked, mut nearest) = (None, None);
            if let Some(c) = candidates.as_ref() {
                Self::set_feelers(&mut feelers, &origins, point.n, &batch);
                let aggregate = &self.scene.aggregate;
                if self.scene.transparent_shadows {
                    c.nearest_batch(aggregate, &feelers, &mut first);
                    nearest = Some(&first);
                } else {
                    blocked = Some(c.any_hit_batch(aggregate, &feelers));
                }
            }
            let mut visible = [DVec3::ZERO; SAMPLE_BATCH];
            for (k, sample) in batch.iter().enumerate() {
                if sample.unlit(point.n) {
                    // The light is behind the surface (or the point behind
                    // the light): no feeler needed.
                    continue;
                }
                let visibility = match (&blocked, &nearest) {
                    (Some(blocked), _) => {
                        stats.shadow += 1;
                        if blocked[k] { DVec3::ZERO } else { DVec3::ONE }
                    }
                    (_, Some(nearest)) => {
                        stats.shadow += 1;
                        match nearest.blockers[k] {
                            // Most feelers: nothing in the way.
                            None => DVec3::ONE,
                            first => {
                                let (feeler, gap) = origins.spawn(sample.direction);
                                let remaining = sample.distance - gap;
                                let c = candidates.as_ref();
                                let ends = Some((nearest.slots[k] as usize, nearest.ends[k]));
                                self.transmission(feeler, remaining, first, ends, c, stats)
                            }
                        }
                    }
                    _ => self.visibility(
                        origins.spawn(sample.direction),
                        sample,
                        candidates.as_mut(),
                        stats,
                    ),
                };
                rec.feeler(index, sample, visibility);
                visible[k] = visibility;
            }
            // The local model of the feelers that got through, the whole
            // batch in vector code, summed in the order of the samples.
            if visible.iter().any(|&v| v != DVec3::ZERO) {
                simd::kernel().vectorize(|| {
                    point.material.phong_batch(
                        point.od,
                        point.n,
                        point.view,
                        batch.iter().map(|s| s.direction),
                        &mut shade,
                    )
                });
                for (k, sample) in batch.iter().enumerate() {
                    if visible[k] != DVec3::ZERO {
                        sum += visible[k] * sample.falloff * shade[k];
                    }
                }
            }
        }
        let contribution = light.radiance * sum / count as f64;
        rec.light(index, light.radiance, count, contribution);
        contribution
    }

    /// [`direct`](Self::direct) for a light of one sample (a point, spot or
    /// directional light), to the bit, without the batch's arrays (their
    /// set-up was a tenth of a render under a point light).
    #[allow(clippy::too_many_arguments)]
    fn direct_one<R: Recorder>(
        &self,
        index: usize,
        light: &Light,
        sampler: &LightSampler,
        point: &ShadingPoint,
        rng: &mut PixelRng,
        stats: &mut RayStats,
        rec: &mut R,
    ) -> DVec3 {
        let mut batch = ArrayVec::<LightSample, SAMPLE_BATCH>::new();
        let sample = match sampler {
            // A point, spot or directional light: its one sample, which is
            // what the batch would hold (drawing nothing), without the call.
            LightSampler::Fixed(s) => Some(s),
            _ => {
                sampler.sample_batch(0, rng, &mut batch);
                batch.first()
            }
        };
        let mut sum = DVec3::ZERO;
        // As `direct`: no feeler where the light is behind the surface
        // (N·L ≤ 0; NaN is traced).
        let behind = sample.is_none_or(|s| s.unlit(point.n));
        if let Some(sample) = sample.filter(|_| !behind) {
            // One feeler: only the side of the surface it leaves by.
            let feeler = SpawnOrigins::spawn_one(
                point.hit.point + point.hit.feeler_offset,
                point.hit.normal,
                sample.direction,
            );
            let visibility = self.visibility(feeler, sample, None, stats);
            rec.feeler(index, sample, visibility);
            if visibility != DVec3::ZERO {
                let shade = point
                    .material
                    .phong(point.od, point.n, sample.direction, point.view);
                sum += visibility * sample.falloff * shade;
            }
        }
        // `direct` divides by the count, here 1: exact, so left out.
        let contribution = light.radiance * sum;
        rec.light(index, light.radiance, 1, contribution);
        contribution
    }

    /// Sets `feelers` to those of `batch`, lanes switched on where the light
    /// is in front of the surface (N·L > 0): those the loop in `direct`
    /// traces.
    fn set_feelers(
        feelers: &mut FeelerBatch<SAMPLE_BATCH>,
        origins: &SpawnOrigins,
        n: DVec3,
        batch: &[LightSample],
    ) {
        for (k, sample) in batch.iter().enumerate() {
            let (ray, gap) = origins.spawn(sample.direction);
            // NaN included.
            let behind = sample.unlit(n);
            feelers.set(k, &ray, sample.distance - gap, !behind);
        }
        // A short last batch: its unused lanes off.
        feelers.active[batch.len()..].fill(false);
    }

    /// The fraction of light that reaches the hit along a shadow feeler, per
    /// colour channel. Classic Whitted: any object blocks (0 or 1), found by
    /// an any-hit query. With transparent shadows, each transparent blocker
    /// passes its kt (so tinted glass casts a tinted shadow). `(feeler,
    /// gap)` is the feeler towards `sample` and its origin's distance from
    /// the point, as [`SpawnOrigins::spawn`] gives them.
    fn visibility(
        &self,
        (feeler, gap): (Ray, f64),
        sample: &LightSample,
        mut candidates: Option<&mut ShadowCandidates>,
        stats: &mut RayStats,
    ) -> DVec3 {
        let remaining = sample.distance - gap;
        if !self.scene.transparent_shadows {
            stats.shadow += 1;
            let blocked = match candidates.as_mut() {
                Some(c) => c.any_hit(&self.scene.aggregate, &feeler, remaining),
                None => self.scene.aggregate.any_hit(&feeler, remaining),
            };
            return if blocked { DVec3::ZERO } else { DVec3::ONE };
        }
        stats.shadow += 1;
        match self.nearest_blocker(&feeler, remaining, candidates.as_deref()) {
            // Most feelers: nothing in the way (what `transmission` gives
            // for no blocker, without the call).
            None => DVec3::ONE,
            first => {
                let c = candidates.as_deref();
                self.transmission(feeler, remaining, first, None, c, stats)
            }
        }
    }

    /// The first surface `feeler` meets within `remaining`.
    fn nearest_blocker(
        &self,
        feeler: &Ray,
        remaining: f64,
        candidates: Option<&ShadowCandidates>,
    ) -> Option<Blocker> {
        match candidates {
            Some(c) => c.nearest(&self.scene.aggregate, feeler, remaining),
            None => self
                .scene
                .aggregate
                .closest_hit(feeler, remaining)
                .map(|h| Blocker {
                    t: h.t,
                    normal: h.normal,
                    material: h.material,
                }),
        }
    }

    /// Transparent shadows: the light a feeler carries past `first`, the
    /// first surface it meets (already found, and counted), and every one
    /// after it, each passing its kt. `first_ends`: the candidate slot
    /// `first` belongs to and how far along `feeler` its surfaces end, where
    /// the search that found it knows (see `FirstBlockers::ends`).
    fn transmission(
        &self,
        mut feeler: Ray,
        mut remaining: f64,
        first: Option<Blocker>,
        first_ends: Option<(usize, f64)>,
        candidates: Option<&ShadowCandidates>,
        stats: &mut RayStats,
    ) -> DVec3 {
        let direction = feeler.direction;
        let mut transmission = DVec3::ONE;
        let mut blocker = first;
        // Where each candidate's surfaces end along the line (see
        // `ShadowCandidates::nearest_along`), measured from `feeler`.
        let mut beyond = [f64::INFINITY; MAX_CANDIDATES];
        if let Some((slot, at)) = first_ends.filter(|e| e.1.is_finite()) {
            beyond[slot] = at.max(0.0);
        }
        let mut travelled = 0.0;
        loop {
            let Some(b) = blocker else {
                return transmission;
            };
            transmission *= self.scene.materials[b.material as usize].kt;
            if transmission.max_element() < 1e-6 {
                return DVec3::ZERO;
            }
            let point = feeler.at(b.t);
            let next = Ray::spawn(point, b.normal, direction);
            let step = b.t + (next.origin - point).length();
            remaining -= step;
            feeler = next;
            stats.shadow += 1;
            blocker = match candidates {
                Some(c) => {
                    travelled += step;
                    c.nearest_along(
                        &self.scene.aggregate,
                        &feeler,
                        remaining,
                        travelled,
                        &mut beyond,
                    )
                }
                None => self.nearest_blocker(&feeler, remaining, None),
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn media_stack_tracks_nested_and_overlapping_objects() {
        let m = Media::default();
        assert_eq!(m.ior(), 1.0);
        let m = m.entering(1, 1.5).entering(2, 1.33);
        assert_eq!(m.ior(), 1.33);
        // Leave the outer one first (overlap): still inside water.
        let m2 = m.leaving(1);
        assert_eq!(m2.ior(), 1.33);
        assert_eq!(m.leaving(2).ior(), 1.5);
        assert_eq!(m.leaving(2).leaving(1).ior(), 1.0);
        // Leaving something never entered changes nothing.
        assert_eq!(m.leaving(7), m);
    }
}
