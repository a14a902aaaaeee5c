//! The coefficients of the Whitted model for one surface.

use glam::DVec3;

use super::Texture;
use super::optics::reflect;
use crate::math::transcendental;

/// How kr and kt are found at a hit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Fresnel {
    /// Classic Whitted: the material's kr and kt as given.
    #[default]
    Off,
    /// kr + kt split by the exact dielectric Fresnel reflectance.
    Exact,
    /// kr + kt split by Schlick's approximation.
    Schlick,
}

/// Which specular highlight term the local model uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Highlight {
    /// Phong: max(0, R·V)ⁿ with R the mirror of L.
    #[default]
    Phong,
    /// Blinn-Phong: max(0, N·H)ⁿ with H the half vector of L and V.
    Blinn,
}

/// A Whitted material.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Surface colour Od.
    pub texture: Texture,
    /// Ambient coefficient.
    pub ka: f64,
    /// Diffuse coefficient.
    pub kd: f64,
    /// Specular highlight coefficient.
    pub ks: f64,
    /// Phong exponent n.
    pub shininess: f64,
    /// Weight of the reflected ray, per colour channel (equal channels
    /// for the classic grey mirror; a metal's tint otherwise).
    pub kr: DVec3,
    /// Weight of the transmitted ray, per colour channel (tinted glass).
    pub kt: DVec3,
    /// Index of refraction of the inside.
    pub ior: f64,
    /// Fresnel mode.
    pub fresnel: Fresnel,
    /// Highlight model.
    pub highlight: Highlight,
    /// Light the surface gives off itself, added to the local model (as
    /// POV-Ray's `emission`); in a Whitted renderer it lights nothing else.
    pub emission: Texture,
}

impl Default for Material {
    /// A plain grey diffuse surface, what models without materials get.
    fn default() -> Self {
        Material {
            texture: Texture::Solid(DVec3::splat(0.8)),
            ka: 0.1,
            kd: 0.8,
            ks: 0.0,
            shininess: 32.0,
            kr: DVec3::ZERO,
            kt: DVec3::ZERO,
            ior: 1.0,
            fresnel: Fresnel::Off,
            highlight: Highlight::Phong,
            emission: Texture::Solid(DVec3::ZERO),
        }
    }
}

impl Material {
    /// kr and kt scaled down together, if needed, so that no channel of
    /// kr + kt exceeds 1 (more would create light). Model formats do not
    /// forbid such values, so their loaders use this instead of refusing.
    pub fn conserving(kr: DVec3, kt: DVec3) -> (DVec3, DVec3) {
        let sum = (kr + kt).max_element();
        if sum > 1.0 {
            (kr / sum, kt / sum)
        } else {
            (kr, kt)
        }
    }

    /// The local (Phong) term of the Whitted model for one light direction,
    /// per unit of light: kd·Od·max(0, N·L) + ks·max(0, R·V)ⁿ with
    /// R = reflect(−L, N) (or ks·max(0, N·H)ⁿ, H = (L + V)/|L + V|, for
    /// Blinn). `n`, `l`, `view` are unit; the highlight is white.
    #[inline]
    pub fn phong(&self, od: DVec3, n: DVec3, l: DVec3, view: DVec3) -> DVec3 {
        let (diffuse, specular) = self.phong_terms(od, n, l, view);
        diffuse + DVec3::splat(specular)
    }

    /// The two terms of [`phong`](Self::phong): the diffuse kd·Od·max(0, N·L)
    /// and the (white) specular ks·max(0, R·V)ⁿ.
    #[inline]
    pub fn phong_terms(&self, od: DVec3, n: DVec3, l: DVec3, view: DVec3) -> (DVec3, f64) {
        let n_dot_l = n.dot(l).max(0.0);
        let specular = if self.ks > 0.0 && n_dot_l > 0.0 {
            let highlight = match self.highlight {
                Highlight::Phong => reflect(-l, n).dot(view),
                Highlight::Blinn => n.dot((l + view).normalize()),
            };
            let highlight = highlight.max(0.0);
            if highlight == 0.0 && self.shininess > 0.0 {
                // pow(0, n) = 0 for n > 0: no power to work out (a feeler
                // per sample makes this the hottest arithmetic of a render).
                0.0
            } else {
                self.ks * transcendental::pow_whole_fast(highlight, self.shininess)
            }
        } else {
            0.0
        };
        (self.kd * od * n_dot_l, specular)
    }
}

#[cfg(test)]
#[allow(clippy::disallowed_methods)] // hand-worked values use the platform's functions
mod tests {
    use super::*;

    fn material(highlight: Highlight) -> Material {
        Material {
            texture: Texture::Solid(DVec3::ONE),
            ka: 0.0,
            kd: 0.6,
            ks: 0.5,
            shininess: 10.0,
            kr: DVec3::ZERO,
            kt: DVec3::ZERO,
            ior: 1.0,
            fresnel: Fresnel::Off,
            highlight,
            emission: Texture::Solid(DVec3::ZERO),
        }
    }

    #[test]
    fn phong_hand_worked() {
        let m = material(Highlight::Phong);
        let od = DVec3::new(1.0, 0.5, 0.25);
        let n = DVec3::Y;
        // Light 60° from the normal: N·L = 1/2. Viewer along the mirror
        // direction: R·V = 1, so the highlight is ks.
        let l = DVec3::new(3f64.sqrt() / 2.0, 0.5, 0.0);
        let v = DVec3::new(-(3f64.sqrt()) / 2.0, 0.5, 0.0);
        let c = m.phong(od, n, l, v);
        let expected = 0.6 * od * 0.5 + DVec3::splat(0.5);
        assert!((c - expected).length() < 1e-12, "{c}");
        // Viewer straight above: R·V = cos 60° = 1/2, highlight ks·2⁻¹⁰.
        let c = m.phong(od, n, l, n);
        let expected = 0.6 * od * 0.5 + DVec3::splat(0.5 * 0.5f64.powi(10));
        assert!((c - expected).length() < 1e-12, "{c}");
        // Light below the surface: nothing.
        assert_eq!(m.phong(od, n, -l, v), DVec3::ZERO);
    }

    #[test]
    fn conserving_scales_the_strongest_channel_to_one() {
        let (kr, kt) = Material::conserving(DVec3::new(0.9, 0.5, 0.1), DVec3::splat(0.3));
        assert!((kr + kt).max_element() <= 1.0 + 1e-15);
        assert!((kr - DVec3::new(0.75, 0.5 / 1.2, 0.1 / 1.2)).length() < 1e-15);
        assert!((kt - DVec3::splat(0.25)).length() < 1e-15);
        // Within bounds: untouched, bit for bit.
        let (kr, kt) = Material::conserving(DVec3::splat(0.4), DVec3::new(0.6, 0.1, 0.0));
        assert_eq!((kr, kt), (DVec3::splat(0.4), DVec3::new(0.6, 0.1, 0.0)));
    }

    #[test]
    fn blinn_uses_the_half_vector() {
        let m = material(Highlight::Blinn);
        let n = DVec3::Y;
        // L and V symmetric about N: H = N, highlight ks.
        let l = DVec3::new(0.6, 0.8, 0.0);
        let v = DVec3::new(-0.6, 0.8, 0.0);
        let c = m.phong(DVec3::ZERO, n, l, v);
        assert!((c - DVec3::splat(0.5)).length() < 1e-12);
        // Viewer straight above: H is halfway between L and N.
        let h = (l + n).normalize();
        let c = m.phong(DVec3::ZERO, n, l, n);
        assert!((c.x - 0.5 * h.y.powf(10.0)).abs() < 1e-12);
    }
}
