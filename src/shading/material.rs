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
    /// Spread of the reflected and transmitted rays: glTF's and Blender's
    /// perceptual roughness, 0 for a sharp mirror (see `glossy.rs`).
    pub roughness: f64,
    /// Rays per lobe where a path first meets a rough surface (one at
    /// each rough surface after that, so the tree does not explode).
    pub glossy_samples: u32,
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
            roughness: 0.0,
            glossy_samples: 16,
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

    /// [`phong`](Self::phong) for each of up to `N` light directions, into
    /// `out`, lane k for the k-th direction (lanes past the last are left
    /// meaningless). The same operations as `phong`, in the same order,
    /// lane by lane, written as loops over the lanes that compile to vector
    /// code: the highlight's power by repeated squaring takes the same steps
    /// in every lane where the exponent is whole (else each lane calls
    /// `phong`). So every lane has `phong`'s bits; a test checks it.
    #[inline(always)]
    pub fn phong_batch<const N: usize>(
        &self,
        od: DVec3,
        n: DVec3,
        view: DVec3,
        directions: impl Iterator<Item = DVec3>,
        out: &mut [DVec3; N],
    ) {
        let mut l = [[0.0; N]; 3];
        let mut count = 0;
        for (k, d) in directions.take(N).enumerate() {
            (l[0][k], l[1][k], l[2][k]) = (d.x, d.y, d.z);
            count = k + 1;
        }
        let Some(exponent) = transcendental::whole_exponent(self.shininess) else {
            for (k, out) in out.iter_mut().enumerate().take(count) {
                let l = DVec3::new(l[0][k], l[1][k], l[2][k]);
                *out = self.phong(od, n, l, view);
            }
            return;
        };
        let [lx, ly, lz] = &l;
        // N·L, clamped; the highlight's base, clamped.
        let mut n_dot_l = [0.0; N];
        let mut highlight = [0.0; N];
        for k in 0..N {
            n_dot_l[k] = (n.x * lx[k] + n.y * ly[k] + n.z * lz[k]).max(0.0);
        }
        let kd_od = self.kd * od;
        let has_highlight = self.ks > 0.0;
        if !has_highlight {
            // No highlight (a matte surface): the diffuse term alone.
            for k in 0..N {
                out[k] = kd_od * n_dot_l[k] + DVec3::splat(0.0);
            }
            return;
        }
        match self.highlight {
            Highlight::Phong => {
                // R·V with R = reflect(−L, N) = I − 2N(I·N), I = −L.
                for k in 0..N {
                    let (ix, iy, iz) = (-lx[k], -ly[k], -lz[k]);
                    let i_dot_n = ix * n.x + iy * n.y + iz * n.z;
                    let rx = ix - 2.0 * n.x * i_dot_n;
                    let ry = iy - 2.0 * n.y * i_dot_n;
                    let rz = iz - 2.0 * n.z * i_dot_n;
                    highlight[k] = (rx * view.x + ry * view.y + rz * view.z).max(0.0);
                }
            }
            Highlight::Blinn => {
                // N·H with H = (L + V)/|L + V|, as glam's normalize does it.
                for k in 0..N {
                    let (hx, hy, hz) = (lx[k] + view.x, ly[k] + view.y, lz[k] + view.z);
                    let recip = 1.0 / (hx * hx + hy * hy + hz * hz).sqrt();
                    let (hx, hy, hz) = (hx * recip, hy * recip, hz * recip);
                    highlight[k] = (n.x * hx + n.y * hy + n.z * hz).max(0.0);
                }
            }
        }
        // transcendental::powi, the exponent's bits the same in every lane.
        let mut power = [1.0; N];
        let mut base = highlight;
        let mut e = exponent;
        while e > 0 {
            if e & 1 == 1 {
                for k in 0..N {
                    power[k] *= base[k];
                }
            }
            e >>= 1;
            if e > 0 {
                for b in &mut base {
                    *b *= *b;
                }
            }
        }
        for k in 0..N {
            let lit = n_dot_l[k] > 0.0;
            // pow(0, n) = 0 for n > 0, as `phong_terms` short-cuts it.
            let dark = highlight[k] == 0.0 && self.shininess > 0.0;
            let specular = if lit && !dark {
                self.ks * power[k]
            } else {
                0.0
            };
            out[k] = kd_od * n_dot_l[k] + DVec3::splat(specular);
        }
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
            ..Material::default()
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

    /// Every lane of the batch has the bits `phong` gives that direction:
    /// both highlights, whole and fractional exponents, ks of 0, lights
    /// behind the surface, highlights of exactly 0, short batches.
    #[test]
    fn a_batch_is_phong_lane_by_lane() {
        let mut rng = crate::math::rng::PixelRng::new(31, 0, 0);
        let mut u = || 2.0 * rng.uniform() - 1.0;
        let mut specular = 0;
        for i in 0..4000 {
            let mut m = material(if i % 2 == 0 {
                Highlight::Phong
            } else {
                Highlight::Blinn
            });
            m.ks = [0.0, 0.5, 0.8][i % 3];
            m.shininess = [10.0, 1.0, 0.0, 37.5, 120.0, 4097.0][i % 6];
            let od = DVec3::new(u().abs(), u().abs(), u().abs());
            let n = DVec3::new(u(), u(), u()).normalize();
            let view = DVec3::new(u(), u(), u()).normalize();
            let mut directions = [DVec3::ZERO; 16];
            for (k, d) in directions.iter_mut().enumerate() {
                *d = match k % 4 {
                    // The mirror of the view: R·V = 1; its perpendicular
                    // in the plane of N and V: R·V = 0 or nearly.
                    0 => reflect(-view, n),
                    1 => n.cross(view).normalize(),
                    _ => DVec3::new(u(), u(), u()).normalize(),
                };
            }
            let count = 1 + i % 16;
            let mut out = [DVec3::NAN; 16];
            m.phong_batch(od, n, view, directions[..count].iter().copied(), &mut out);
            for k in 0..count {
                let expected = m.phong(od, n, directions[k], view);
                assert_eq!(
                    out[k].to_array().map(f64::to_bits),
                    expected.to_array().map(f64::to_bits),
                    "{m:?} lane {k}: {} vs {expected}",
                    out[k]
                );
                specular += usize::from(expected.x != m.kd * od.x * n.dot(directions[k]).max(0.0));
            }
        }
        assert!(specular > 5000, "{specular}");
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
