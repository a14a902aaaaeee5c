//! The laws of reflection and refraction (lecture notes, "Secondary Rays"),
//! and the Fresnel reflectance of a dielectric boundary.

use crate::geometry::steps::Steps;
use crate::math::transcendental;
use glam::DVec3;

/// Law of reflection: R = I − 2N(I·N). `incident` points towards the
/// surface; R makes the same angle with N as I, in the plane of I and N.
#[inline]
pub fn reflect(incident: DVec3, normal: DVec3) -> DVec3 {
    reflect_steps(incident, normal, &mut ())
}

/// [`reflect`], telling `steps` I·N and R.
#[inline(always)]
pub fn reflect_steps<S: Steps>(incident: DVec3, normal: DVec3, steps: &mut S) -> DVec3 {
    let i_dot_n = incident.dot(normal);
    let r = incident - 2.0 * normal * i_dot_n;
    steps.reflection(i_dot_n, r);
    r
}

/// Snell's law, η = ηi/ηt = sin θt / sin θi, in vector form:
/// T = ηI + (η·cos θi − cos θt)N, cos θt = √(1 − η²(1 − cos² θi)).
/// `incident` is unit and points towards the surface; `normal` is unit and
/// faces the incident side (I·N ≤ 0). `None` is total internal reflection:
/// the radicand is negative, no light is transmitted.
#[inline]
pub fn refract(incident: DVec3, normal: DVec3, eta: f64) -> Option<DVec3> {
    refract_steps(incident, normal, eta, &mut ())
}

/// [`refract`], telling `steps` cos θi, the radicand (cos² θt) and T.
#[inline(always)]
pub fn refract_steps<S: Steps>(
    incident: DVec3,
    normal: DVec3,
    eta: f64,
    steps: &mut S,
) -> Option<DVec3> {
    let cos_i = -incident.dot(normal);
    let radicand = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
    let t = (radicand >= 0.0).then(|| eta * incident + (eta * cos_i - radicand.sqrt()) * normal);
    steps.refraction(cos_i, radicand, t);
    t
}

/// The critical angle θc = asin(ηt/ηi) past which light going from index
/// ηi into ηt is totally reflected; `None` when ηi ≤ ηt (no TIR possible).
pub fn critical_angle(eta_i: f64, eta_t: f64) -> Option<f64> {
    (eta_i > eta_t).then(|| transcendental::asin(eta_t / eta_i))
}

/// Exact Fresnel reflectance of unpolarised light at a dielectric boundary,
/// the mean of the s and p reflectances:
/// rs = (ηi cos θi − ηt cos θt)/(ηi cos θi + ηt cos θt),
/// rp = (ηt cos θi − ηi cos θt)/(ηt cos θi + ηi cos θt), F = (rs² + rp²)/2.
/// Returns 1 under total internal reflection.
pub fn fresnel_dielectric(cos_i: f64, eta_i: f64, eta_t: f64) -> f64 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin_t = eta_i / eta_t * (1.0 - cos_i * cos_i).sqrt();
    if sin_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin_t * sin_t).sqrt();
    let rs = (eta_i * cos_i - eta_t * cos_t) / (eta_i * cos_i + eta_t * cos_t);
    let rp = (eta_t * cos_i - eta_i * cos_t) / (eta_t * cos_i + eta_i * cos_t);
    0.5 * (rs * rs + rp * rp)
}

/// Schlick's approximation F ≈ F₀ + (1 − F₀)(1 − cos θ)⁵, F₀ = ((ηi − ηt)/(ηi + ηt))²,
/// with θ the angle on the optically thinner side (θt when leaving a denser
/// medium), and 1 under total internal reflection.
pub fn schlick(cos_i: f64, eta_i: f64, eta_t: f64) -> f64 {
    let r0 = ((eta_i - eta_t) / (eta_i + eta_t)).powi(2);
    let mut cos = cos_i.clamp(0.0, 1.0);
    if eta_i > eta_t {
        let sin_t2 = (eta_i / eta_t).powi(2) * (1.0 - cos * cos);
        if sin_t2 >= 1.0 {
            return 1.0;
        }
        cos = (1.0 - sin_t2).sqrt();
    }
    r0 + (1.0 - r0) * (1.0 - cos).powi(5)
}

#[cfg(test)]
#[allow(clippy::disallowed_methods)] // hand-worked values use the platform's functions
mod tests {
    use super::*;
    use crate::math::rng::PixelRng;

    fn random_unit(rng: &mut PixelRng) -> DVec3 {
        loop {
            let v = DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 2.0 - 1.0;
            if v.length_squared() > 1e-3 && v.length_squared() <= 1.0 {
                return v.normalize();
            }
        }
    }

    /// A random unit incident direction and a unit normal facing against it.
    fn random_pair(rng: &mut PixelRng) -> (DVec3, DVec3) {
        let i = random_unit(rng);
        let n = random_unit(rng);
        (i, if i.dot(n) > 0.0 { -n } else { n })
    }

    #[test]
    fn reflection_hand_worked() {
        let r = reflect(DVec3::new(1.0, -1.0, 0.0), DVec3::Y);
        assert_eq!(r, DVec3::new(1.0, 1.0, 0.0));
    }

    #[test]
    fn reflection_law_on_random_inputs() {
        let mut rng = PixelRng::new(1, 2, 3);
        for _ in 0..10_000 {
            let (i, n) = random_pair(&mut rng);
            let r = reflect(i, n);
            // Angle in = angle out.
            assert!(((-i).dot(n) - r.dot(n)).abs() < 1e-12);
            assert!((r.length() - 1.0).abs() < 1e-12);
            // I, N and R are coplanar.
            assert!(i.cross(n).dot(r).abs() < 1e-12);
        }
    }

    #[test]
    fn snell_hand_worked() {
        // 45° from air into η = √2: sin θt = sin 45° / √2 = 1/2, θt = 30°.
        let i = DVec3::new(1.0, -1.0, 0.0).normalize();
        let t = refract(i, DVec3::Y, 1.0 / 2f64.sqrt()).unwrap();
        assert!((t - DVec3::new(0.5, -(3f64.sqrt()) / 2.0, 0.0)).length() < 1e-12);
        // Normal incidence passes straight through.
        assert_eq!(refract(-DVec3::Y, DVec3::Y, 0.7).unwrap(), -DVec3::Y);
    }

    #[test]
    fn snell_law_on_random_inputs() {
        let mut rng = PixelRng::new(4, 5, 6);
        for _ in 0..10_000 {
            let (i, n) = random_pair(&mut rng);
            let eta = 0.4 + 2.0 * rng.uniform();
            let sin_i = i.cross(n).length();
            match refract(i, n, eta) {
                Some(t) => {
                    assert!((t.length() - 1.0).abs() < 1e-10);
                    // sin θt / sin θi = η.
                    let sin_t = t.cross(n).length();
                    assert!((sin_t - eta * sin_i).abs() < 1e-10);
                    // Transmitted to the other side, coplanar with I and N.
                    assert!(t.dot(n) < 0.0 || sin_t > 1.0 - 1e-9);
                    assert!(i.cross(n).dot(t).abs() < 1e-10);
                }
                None => assert!(eta * sin_i > 1.0),
            }
        }
    }

    #[test]
    fn total_internal_reflection_exactly_past_the_critical_angle() {
        let (eta_i, eta_t) = (1.5, 1.0);
        let theta_c = critical_angle(eta_i, eta_t).unwrap();
        assert!((theta_c.sin() - 1.0 / 1.5).abs() < 1e-15);
        let at = |theta: f64| DVec3::new(theta.sin(), -theta.cos(), 0.0);
        assert!(refract(at(theta_c - 1e-9), DVec3::Y, eta_i / eta_t).is_some());
        assert!(refract(at(theta_c + 1e-9), DVec3::Y, eta_i / eta_t).is_none());
        assert_eq!(critical_angle(1.0, 1.5), None);
        assert_eq!(
            fresnel_dielectric((theta_c + 1e-6).cos(), eta_i, eta_t),
            1.0
        );
        assert_eq!(schlick((theta_c + 1e-6).cos(), eta_i, eta_t), 1.0);
    }

    #[test]
    fn fresnel_known_values() {
        // Normal incidence, glass: ((1.5 − 1)/(1.5 + 1))² = 0.04.
        assert!((fresnel_dielectric(1.0, 1.0, 1.5) - 0.04).abs() < 1e-12);
        assert!((schlick(1.0, 1.0, 1.5) - 0.04).abs() < 1e-12);
        // Brewster's angle: rp = 0, so F = rs²/2.
        let brewster = 1.5f64.atan();
        let cos_t = (1.0 - (brewster.sin() / 1.5).powi(2)).sqrt();
        let rs = (brewster.cos() - 1.5 * cos_t) / (brewster.cos() + 1.5 * cos_t);
        assert!((fresnel_dielectric(brewster.cos(), 1.0, 1.5) - 0.5 * rs * rs).abs() < 1e-12);
        // Grazing incidence reflects everything.
        assert!((fresnel_dielectric(0.0, 1.0, 1.5) - 1.0).abs() < 1e-12);
        // Reciprocity: same reflectance from either side at matched angles.
        let theta_i = 0.6f64;
        let theta_t = (theta_i.sin() / 1.5).asin();
        let a = fresnel_dielectric(theta_i.cos(), 1.0, 1.5);
        let b = fresnel_dielectric(theta_t.cos(), 1.5, 1.0);
        assert!((a - b).abs() < 1e-12);
    }

    #[test]
    fn schlick_stays_close_to_exact() {
        for k in 0..=100 {
            let cos = k as f64 / 100.0;
            let (e, s) = (fresnel_dielectric(cos, 1.0, 1.5), schlick(cos, 1.0, 1.5));
            assert!((e - s).abs() < 0.05, "cos {cos}: exact {e}, schlick {s}");
        }
    }
}
