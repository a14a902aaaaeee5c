//! Glossy reflection and translucency, the second use of distributed ray
//! tracing (Cook, Porter and Carpenter 1984): a rough surface reflects and
//! refracts about a microfacet normal m drawn near the surface normal N
//! instead of about N itself, so the reflected and transmitted rays spread
//! over a lobe around the mirror and Snell directions.
//!
//! - `roughness` is glTF's and Blender's perceptual roughness r; the
//!   microfacet normals follow the GGX (Trowbridge–Reitz) distribution of
//!   width α = r², drawn in proportion to D(m)·cos θm (importance
//!   sampling: no sample is wasted where D is small). r = 0 is the mirror.
//! - Each sample carries an equal share of kr (or kt): the lobe moves
//!   light, it neither makes nor loses any. A reflected direction that
//!   would go under the surface is folded back above it (mirrored in the
//!   tangent plane), a transmitted one that would stay above folded below;
//!   a microfacet past the critical angle reflects the transmitted share
//!   (total internal reflection). So under a uniform sky a glossy mirror
//!   returns exactly kr times the sky.

use glam::{DVec2, DVec3};

use super::optics::{reflect, refract};
use crate::math::Frame;
use crate::math::transcendental::sin_cos_turns;

/// GGX's width α from perceptual roughness r (glTF, Blender): α = r².
#[inline]
pub fn ggx_alpha(roughness: f64) -> f64 {
    roughness * roughness
}

/// A microfacet normal about the unit normal `n`, drawn from GGX's
/// D(m)·cos θm for width `alpha` from a point `u` of the unit square:
/// tan² θm = α²·u.x/(1 − u.x) (the inverse of its CDF in θm),
/// φ = 2π·u.y. α = 0 gives `n` itself.
#[inline]
pub fn sample_ggx_normal(n: DVec3, alpha: f64, u: DVec2) -> DVec3 {
    let tan2 = alpha * alpha * u.x / (1.0 - u.x);
    let cos_theta = 1.0 / (1.0 + tan2).sqrt();
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let (sin_phi, cos_phi) = sin_cos_turns(u.y);
    Frame::from_z(n).to_world(DVec3::new(
        sin_theta * cos_phi,
        sin_theta * sin_phi,
        cos_theta,
    ))
}

/// The reflected direction of unit `incident` about microfacet normal `m`
/// on a surface of unit normal `n` (facing the incident side), folded
/// back above the surface if it would go under it.
#[inline]
pub fn glossy_reflection(incident: DVec3, n: DVec3, m: DVec3) -> DVec3 {
    let r = reflect(incident, m);
    fold(r, n, 1.0)
}

/// The transmitted direction of unit `incident` through microfacet normal
/// `m` (η = ηi/ηt), folded under the surface if it would stay above;
/// `None` when the microfacet reflects it all (total internal reflection).
#[inline]
pub fn glossy_refraction(incident: DVec3, n: DVec3, m: DVec3, eta: f64) -> Option<DVec3> {
    // A facet drawn facing away from the ray (possible at grazing angles:
    // normals are drawn by D(m)·cos θm, not as seen from the ray) is met
    // from its other side; Snell's law wants the normal facing the ray.
    let m = if incident.dot(m) > 0.0 { -m } else { m };
    let t = refract(incident, m, eta)?.normalize();
    Some(fold(t, n, -1.0))
}

/// `d` mirrored in the plane of normal `n` unless it lies on the side
/// `side` (+1: the side `n` faces, −1: the other).
#[inline]
fn fold(d: DVec3, n: DVec3, side: f64) -> DVec3 {
    let along = d.dot(n);
    if along * side > 0.0 {
        d
    } else {
        d - 2.0 * along * n
    }
}

#[cfg(test)]
#[allow(clippy::disallowed_methods)] // references computed with the platform's functions
mod tests {
    use super::*;
    use crate::math::rng::PixelRng;

    fn random_unit(rng: &mut PixelRng) -> DVec3 {
        loop {
            let v = DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 2.0 - 1.0;
            if v.length_squared() > 1e-6 && v.length_squared() <= 1.0 {
                return v.normalize();
            }
        }
    }

    #[test]
    fn roughness_zero_is_the_mirror_to_the_bit() {
        let mut rng = PixelRng::new(1, 2, 3);
        for _ in 0..1000 {
            let n = random_unit(&mut rng);
            let u = DVec2::new(rng.uniform(), rng.uniform());
            let m = sample_ggx_normal(n, 0.0, u);
            assert_eq!(m, Frame::from_z(n).to_world(DVec3::Z));
            assert!((m - n).length() < 1e-15);
        }
    }

    #[test]
    fn microfacet_normals_follow_ggx() {
        // P(tan² θm ≤ x) = x/(α² + x) for D(m)·cos θm; compared with the
        // drawn normals at nine points (Kolmogorov–Smirnov distance).
        let mut rng = PixelRng::new(9, 9, 9);
        let n = DVec3::new(0.3, -0.5, 0.8).normalize();
        for alpha in [0.05, 0.3, 0.8] {
            let count = 100_000;
            let mut tan2: Vec<f64> = (0..count)
                .map(|_| {
                    let m = sample_ggx_normal(n, alpha, DVec2::new(rng.uniform(), rng.uniform()));
                    let c = m.dot(n);
                    assert!(c > 0.0 && (m.length() - 1.0).abs() < 1e-12);
                    (1.0 - c * c) / (c * c)
                })
                .collect();
            tan2.sort_by(f64::total_cmp);
            for k in 1..10 {
                let x = alpha * alpha * f64::from(k) / f64::from(10 - k);
                let below = tan2.partition_point(|&t| t <= x) as f64 / count as f64;
                let expected = x / (alpha * alpha + x);
                assert!(
                    (below - expected).abs() < 0.006,
                    "α {alpha}: {below} against {expected}"
                );
            }
        }
    }

    #[test]
    fn lobe_directions_stay_on_their_side() {
        let mut rng = PixelRng::new(4, 5, 6);
        for _ in 0..10_000 {
            let n = random_unit(&mut rng);
            // Incident towards the surface, at any angle.
            let mut i = random_unit(&mut rng);
            if i.dot(n) > 0.0 {
                i = -i;
            }
            let m = sample_ggx_normal(n, 0.9, DVec2::new(rng.uniform(), rng.uniform()));
            let r = glossy_reflection(i, n, m);
            assert!(r.dot(n) >= 0.0 && (r.length() - 1.0).abs() < 1e-12);
            for eta in [1.0 / 1.5, 1.5] {
                match glossy_refraction(i, n, m, eta) {
                    Some(t) => assert!(t.dot(n) <= 0.0 && (t.length() - 1.0).abs() < 1e-12),
                    // Only leaving the denser side can a facet reflect all.
                    None => assert!(eta > 1.0),
                }
            }
        }
    }

    #[test]
    fn past_the_critical_angle_the_facet_reflects_everything() {
        // From glass (1.5) into air the critical angle is 41.8°: at 60°
        // on a facet facing straight up there is no transmitted ray.
        let n = DVec3::Z;
        let (s, c) = (60f64.to_radians().sin(), 60f64.to_radians().cos());
        let i = DVec3::new(s, 0.0, -c);
        assert_eq!(glossy_refraction(i, n, n, 1.5), None);
        let i = DVec3::new(30f64.to_radians().sin(), 0.0, -30f64.to_radians().cos());
        assert!(glossy_refraction(i, n, n, 1.5).is_some());
    }
}
