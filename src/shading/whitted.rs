//! The Whitted illumination model at the closest hit:
//!
//! I = ka·Od·Ia + Σⱼ visⱼ·Ilⱼ·(kd·Od·max(0, N·Lⱼ) + ks·max(0, Rⱼ·V)ⁿ) + kr·I_reflected + kt·I_transmitted
//!
//! with shadow feelers for visⱼ, a reflected ray R = I − 2N(I·N), a
//! refracted ray by Snell's law, both followed recursively.

use glam::DVec3;

use super::optics::{fresnel_dielectric, reflect, refract, schlick};
use super::{Fresnel, Material};
use crate::geometry::Hit;
use crate::lights::{Light, LightSample};
use crate::math::Ray;
use crate::math::rng::PixelRng;
use crate::render::RayStats;
use crate::scene::Scene;

/// Nested media deeper than this are not tracked (the innermost are lost).
const MAX_NESTING: usize = 8;

/// The media a ray travels through: a stack of the materials of the
/// transparent objects it has entered, innermost last; outside everything
/// the index is 1. Keyed by material, not primitive, so a solid built of
/// several faces (a glass prism of polygons) is one medium: the ray enters
/// through one face and leaves through another.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Media {
    entered: [(u32, f64); MAX_NESTING],
    len: usize,
}

impl Default for Media {
    fn default() -> Self {
        Media {
            entered: [(0, 1.0); MAX_NESTING],
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
            self.entered[self.len - 1].1
        }
    }

    /// After entering an object of `material` with index `ior`.
    pub fn entering(mut self, material: u32, ior: f64) -> Self {
        if self.len < MAX_NESTING {
            self.entered[self.len] = (material, ior);
            self.len += 1;
        }
        self
    }

    /// After leaving `primitive` (which need not be innermost: overlapping
    /// objects may be left in any order).
    pub fn leaving(mut self, primitive: u32) -> Self {
        if let Some(i) = self.entered[..self.len]
            .iter()
            .rposition(|e| e.0 == primitive)
        {
            self.entered.copy_within(i + 1..self.len, i);
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
}

/// What kind of ray `trace` follows, for the statistics.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum RayKind {
    Camera,
    Reflection,
    Refraction,
}

impl<'a> Whitted<'a> {
    /// A tracer for `scene`.
    pub fn new(scene: &'a Scene, settings: WhittedSettings) -> Self {
        Whitted { scene, settings }
    }

    /// The colour seen along a camera ray.
    pub fn radiance(&self, ray: &Ray, rng: &mut PixelRng, stats: &mut RayStats) -> DVec3 {
        self.trace(ray, RayKind::Camera, 1, 1.0, Media::default(), rng, stats)
    }

    #[allow(clippy::too_many_arguments)]
    fn trace(
        &self,
        ray: &Ray,
        kind: RayKind,
        depth: u32,
        weight: f64,
        media: Media,
        rng: &mut PixelRng,
        stats: &mut RayStats,
    ) -> DVec3 {
        match kind {
            RayKind::Camera => stats.camera += 1,
            RayKind::Reflection => stats.reflection += 1,
            RayKind::Refraction => stats.refraction += 1,
        }
        let Some(hit) = self.scene.aggregate.closest_hit(ray, f64::INFINITY) else {
            return self.scene.background;
        };
        let primitive = &self.scene.aggregate.primitives()[hit.primitive as usize];
        let material = &self.scene.materials[primitive.material as usize];
        // Shading normal faces the incoming ray; "entering" by the sign of I·N.
        let entering = ray.direction.dot(hit.normal) < 0.0;
        let n = if entering { hit.normal } else { -hit.normal };
        let view = -ray.direction;
        let od = material.texture.color(hit.point, hit.normal);

        let mut color = material.ka * od * self.scene.ambient;
        for light in &self.scene.lights {
            color += self.direct(light, &hit, n, view, material, od, rng, stats);
        }

        if depth >= self.settings.max_depth {
            return color;
        }
        let (mut kr, mut kt) = (material.kr, material.kt);
        // Indices across the boundary: η = ηi/ηt.
        let (eta_i, eta_t, media_after) = if entering {
            (
                media.ior(),
                material.ior,
                media.entering(primitive.material, material.ior),
            )
        } else {
            let outside = media.leaving(primitive.material);
            (material.ior, outside.ior(), outside)
        };
        let cos_i = view.dot(n);
        if kt > 0.0 && material.fresnel != Fresnel::Off {
            let f = match material.fresnel {
                Fresnel::Schlick => schlick(cos_i, eta_i, eta_t),
                _ => fresnel_dielectric(cos_i, eta_i, eta_t),
            };
            let total = kr + kt;
            (kr, kt) = (f * total, (1.0 - f) * total);
        }
        let transmitted = if kt > 0.0 {
            refract(ray.direction, n, eta_i / eta_t)
        } else {
            None
        };
        if kt > 0.0 && transmitted.is_none() {
            // Total internal reflection: all the energy is reflected.
            kr += kt;
            kt = 0.0;
        }
        if kr > 0.0 && weight * kr >= self.settings.min_weight {
            let r = Ray::spawn(hit.point, hit.normal, reflect(ray.direction, n));
            color += kr
                * self.trace(
                    &r,
                    RayKind::Reflection,
                    depth + 1,
                    weight * kr,
                    media,
                    rng,
                    stats,
                );
        }
        if let Some(t) = transmitted.filter(|_| weight * kt >= self.settings.min_weight) {
            let r = Ray::spawn(hit.point, hit.normal, t.normalize());
            color += kt
                * self.trace(
                    &r,
                    RayKind::Refraction,
                    depth + 1,
                    weight * kt,
                    media_after,
                    rng,
                    stats,
                );
        }
        color
    }

    /// One light's local (Phong) contribution, averaged over its samples,
    /// each weighted by its shadow feeler's visibility.
    #[allow(clippy::too_many_arguments)]
    fn direct(
        &self,
        light: &Light,
        hit: &Hit,
        n: DVec3,
        view: DVec3,
        material: &Material,
        od: DVec3,
        rng: &mut PixelRng,
        stats: &mut RayStats,
    ) -> DVec3 {
        let sampler = light.sampler(hit.point);
        let count = sampler.count();
        let mut sum = DVec3::ZERO;
        for i in 0..count {
            let sample = sampler.sample(i, rng);
            let l = sample.direction;
            let n_dot_l = n.dot(l);
            if n_dot_l <= 0.0 {
                // The light is behind the surface: no feeler needed.
                continue;
            }
            let visibility = self.visibility(hit, &sample, stats);
            if visibility == 0.0 {
                continue;
            }
            sum += visibility * sample.falloff * material.phong(od, n, l, view);
        }
        light.radiance * sum / count as f64
    }

    /// The fraction of light that reaches the hit along a shadow feeler.
    /// Classic Whitted: any object blocks (0 or 1), found by an any-hit
    /// query. With transparent shadows, each transparent blocker passes kt.
    fn visibility(&self, hit: &Hit, sample: &LightSample, stats: &mut RayStats) -> f64 {
        let mut feeler = Ray::spawn(hit.point, hit.normal, sample.direction);
        let mut remaining = sample.distance - (feeler.origin - hit.point).length();
        if !self.scene.transparent_shadows {
            stats.shadow += 1;
            return if self.scene.aggregate.any_hit(&feeler, remaining) {
                0.0
            } else {
                1.0
            };
        }
        let mut transmission = 1.0;
        loop {
            stats.shadow += 1;
            let Some(blocker) = self.scene.aggregate.closest_hit(&feeler, remaining) else {
                return transmission;
            };
            let primitive = &self.scene.aggregate.primitives()[blocker.primitive as usize];
            transmission *= self.scene.materials[primitive.material as usize].kt;
            if transmission < 1e-6 {
                return 0.0;
            }
            let next = Ray::spawn(blocker.point, blocker.normal, sample.direction);
            remaining -= blocker.t + (next.origin - blocker.point).length();
            feeler = next;
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
