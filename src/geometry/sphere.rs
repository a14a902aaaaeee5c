//! Spheres, analytic, and ellipsoids (spheres under a non-uniform scale).

use glam::DVec3;

use super::span::{Interval, Intervals, Surface, interval};
use super::steps::Steps;
use super::{Aabb, ShapeHit};
use crate::math::{Ray, Transform};

/// A sphere of `radius` around `center`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    /// Centre.
    pub center: DVec3,
    /// Radius (> 0).
    pub radius: f64,
}

/// Roots t₀ ≤ t₁ of |O + tD − C|² = r², or `None` when the line misses.
///
/// Numerically stable form (Haines et al., Ray Tracing Gems ch. 7): with
/// f = O − C, a = D·D, b' = f·D, the discriminant is computed as
/// a·(r² − |f − (b'/a)D|²), the squared distance of the line from the centre,
/// which does not cancel for far or large spheres as b'² − a·c does; the
/// roots come from q = −(b' + sign(b')√Δ) as q/a and c/q, so the smaller
/// root is not the difference of two nearly equal numbers either.
#[inline]
pub fn sphere_roots(
    origin: DVec3,
    direction: DVec3,
    center: DVec3,
    radius: f64,
) -> Option<(f64, f64)> {
    sphere_roots_steps(origin, direction, center, radius, &mut ())
}

/// [`sphere_roots`], telling `steps` the quadratic's coefficients, its
/// discriminant and the roots.
#[inline(always)]
pub fn sphere_roots_steps<S: Steps>(
    origin: DVec3,
    direction: DVec3,
    center: DVec3,
    radius: f64,
    steps: &mut S,
) -> Option<(f64, f64)> {
    let f = origin - center;
    let a = direction.length_squared();
    let b = f.dot(direction);
    let perpendicular = f - (b / a) * direction;
    let discriminant = a * (radius * radius - perpendicular.length_squared());
    if discriminant < 0.0 {
        // c is not needed past here; told only (unused by `()`, and so
        // not computed for it).
        steps.quadratic(a, b, f.length_squared() - radius * radius, discriminant);
        steps.roots(None);
        return None;
    }
    let c = f.length_squared() - radius * radius;
    steps.quadratic(a, b, c, discriminant);
    let q = -(b + discriminant.sqrt().copysign(b));
    if q == 0.0 {
        // Tangent at the origin: b' = 0 and Δ = 0.
        steps.roots(Some((0.0, 0.0)));
        return Some((0.0, 0.0));
    }
    let (t0, t1) = (q / a, c / q);
    let roots = if t0 <= t1 { (t0, t1) } else { (t1, t0) };
    steps.roots(Some(roots));
    Some(roots)
}

/// The nearest root of the ray (origin, direction) in (0, t_max), if it
/// has one: the answer of [`sphere_roots`] and `nearest_root`, the same
/// operations in the same order, but without a branch (every value is
/// computed, the cases become masks and selects), so that a loop over many
/// rays compiles to vector code. Coordinates come one by one, as a
/// structure of arrays hands them over. The root is meaningful only where
/// the flag is set.
#[inline(always)]
pub fn sphere_first_root(
    [ox, oy, oz]: [f64; 3],
    [dx, dy, dz]: [f64; 3],
    t_max: f64,
    center: DVec3,
    radius: f64,
) -> (bool, f64) {
    let (fx, fy, fz) = (ox - center.x, oy - center.y, oz - center.z);
    let a = dx * dx + dy * dy + dz * dz;
    let b = fx * dx + fy * dy + fz * dz;
    let along = b / a;
    let (px, py, pz) = (fx - along * dx, fy - along * dy, fz - along * dz);
    let discriminant = a * (radius * radius - (px * px + py * py + pz * pz));
    let c = fx * fx + fy * fy + fz * fz - radius * radius;
    let q = -(b + discriminant.sqrt().copysign(b));
    let (t0, t1) = (q / a, c / q);
    let within = |t: f64| t > 0.0 && t < t_max;
    // A root of 0 (q = 0, tangent at the origin) is not in (0, t_max).
    let hit = (discriminant >= 0.0) & (q != 0.0) & (within(t0) | within(t1));
    // Which root (an any-hit caller leaves this unused, and unevaluated).
    let (near, far) = if t0 <= t1 { (t0, t1) } else { (t1, t0) };
    (hit, if within(near) { near } else { far })
}

/// Whether the ray (origin, direction) meets the sphere with t in
/// (0, t_max): [`sphere_first_root`]'s flag, for any-hit feelers.
#[inline(always)]
pub fn sphere_blocks(
    origin: [f64; 3],
    direction: [f64; 3],
    t_max: f64,
    center: DVec3,
    radius: f64,
) -> bool {
    sphere_first_root(origin, direction, t_max, center, radius).0
}

/// The nearest root in (t_min, t_max).
#[inline]
fn nearest_root((t0, t1): (f64, f64), t_min: f64, t_max: f64) -> Option<f64> {
    if t0 > t_min && t0 < t_max {
        Some(t0)
    } else if t1 > t_min && t1 < t_max {
        Some(t1)
    } else {
        None
    }
}

impl Sphere {
    /// The nearest hit in (t_min, t_max), from outside or inside.
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<ShapeHit> {
        self.intersect_steps(ray, t_min, t_max, &mut ())
    }

    /// [`intersect`](Self::intersect), telling `steps` the quadratic, its
    /// roots and the root taken.
    #[inline(always)]
    pub fn intersect_steps<S: Steps>(
        &self,
        ray: &Ray,
        t_min: f64,
        t_max: f64,
        steps: &mut S,
    ) -> Option<ShapeHit> {
        let roots = sphere_roots_steps(ray.origin, ray.direction, self.center, self.radius, steps)?;
        let t = nearest_root(roots, t_min, t_max);
        steps.root_taken(t);
        Some(self.hit_at(ray, t?))
    }

    /// The hit of `ray` at its root `t`.
    #[inline]
    pub fn hit_at(&self, ray: &Ray, t: f64) -> ShapeHit {
        let normal = (ray.at(t) - self.center) / self.radius;
        ShapeHit::geometric(t, normal, ray.direction.dot(normal) < 0.0)
    }

    /// Whether the ray meets the sphere with t in (t_min, t_max): the
    /// roots of [`intersect`](Self::intersect) without the hit's normal.
    #[inline]
    pub fn occludes(&self, ray: &Ray, t_min: f64, t_max: f64) -> bool {
        sphere_roots(ray.origin, ray.direction, self.center, self.radius)
            .and_then(|roots| nearest_root(roots, t_min, t_max))
            .is_some()
    }

    /// Where the whole line of `ray` is inside: between the two roots.
    pub fn inside(&self, ray: &Ray) -> Intervals {
        self.interval(ray).into_iter().collect()
    }

    /// [`inside`](Self::inside)'s one interval, if any.
    #[inline(always)]
    pub fn interval(&self, ray: &Ray) -> Option<Interval> {
        let (t0, t1) = sphere_roots(ray.origin, ray.direction, self.center, self.radius)?;
        interval(Surface::at(t0), Surface::at(t1))
    }

    /// The outward unit normal where `ray` crosses the surface at `s`.
    pub fn surface_normal(&self, ray: &Ray, s: Surface) -> DVec3 {
        (ray.at(s.t) - self.center) / self.radius
    }

    /// The bounding box.
    pub fn bounds(&self) -> Aabb {
        Aabb {
            min: self.center - DVec3::splat(self.radius),
            max: self.center + DVec3::splat(self.radius),
        }
    }
}

/// The unit sphere under an arbitrary affine transform: an ellipsoid.
/// Rays are taken to object space (direction not renormalised, so t is the
/// same in both spaces); normals come back by the inverse transpose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ellipsoid {
    /// Unit sphere to world.
    pub transform: Transform,
}

impl Ellipsoid {
    /// The nearest hit in (t_min, t_max).
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<ShapeHit> {
        self.intersect_steps(ray, t_min, t_max, &mut ())
    }

    /// [`intersect`](Self::intersect), telling `steps` the unit sphere's
    /// quadratic in object space, its roots and the root taken.
    #[inline(always)]
    pub fn intersect_steps<S: Steps>(
        &self,
        ray: &Ray,
        t_min: f64,
        t_max: f64,
        steps: &mut S,
    ) -> Option<ShapeHit> {
        let (origin, direction) = self.transform.ray_to_object(ray);
        let roots = sphere_roots_steps(origin, direction, DVec3::ZERO, 1.0, steps)?;
        let t = nearest_root(roots, t_min, t_max);
        steps.root_taken(t);
        let t = t?;
        let normal = self.transform.normal(origin + t * direction);
        Some(ShapeHit::geometric(
            t,
            normal,
            ray.direction.dot(normal) < 0.0,
        ))
    }

    /// Where the whole line of `ray` is inside: between the roots of the
    /// unit sphere in object space.
    pub fn inside(&self, ray: &Ray) -> Intervals {
        let (origin, direction) = self.transform.ray_to_object(ray);
        let mut out = Intervals::new();
        if let Some((t0, t1)) = sphere_roots(origin, direction, DVec3::ZERO, 1.0) {
            out.extend(interval(Surface::at(t0), Surface::at(t1)));
        }
        out
    }

    /// The outward unit normal where `ray` crosses the surface at `s`.
    pub fn surface_normal(&self, ray: &Ray, s: Surface) -> DVec3 {
        let (origin, direction) = self.transform.ray_to_object(ray);
        self.transform.normal(origin + s.t * direction)
    }

    /// The bounding box: along world axis i the half extent is the length of
    /// row i of the linear part.
    pub fn bounds(&self) -> Aabb {
        let m = self.transform.to_world.matrix3.transpose();
        let half = DVec3::new(m.x_axis.length(), m.y_axis.length(), m.z_axis.length());
        let c = self.transform.to_world.translation;
        Aabb {
            min: c - half,
            max: c + half,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::PixelRng;
    use glam::DAffine3;

    const INF: f64 = f64::INFINITY;

    /// The branch-free test answers as `occludes` does, ray by ray: rays
    /// from outside, inside and on the sphere, towards and away from it,
    /// grazing it, with short and infinite reach.
    #[test]
    fn branch_free_roots_answer_as_occludes_and_intersect() {
        let mut rng = PixelRng::new(21, 0, 0);
        let mut u = || 2.0 * rng.uniform() - 1.0;
        let mut blocked = 0;
        for i in 0..200_000 {
            let s = Sphere {
                center: DVec3::new(u(), u(), u()) * 3.0,
                radius: 0.1 + u().abs(),
            };
            let origin = match i % 4 {
                // On the sphere (as a feeler from its own surface).
                0 => s.center + DVec3::new(u(), u(), u()).normalize() * s.radius,
                _ => DVec3::new(u(), u(), u()) * 4.0,
            };
            let aim = s.center + DVec3::new(u(), u(), u()) * s.radius * 1.2;
            let direction = match i % 3 {
                0 => (aim - origin).normalize(),
                1 => DVec3::new(u(), u(), u()).normalize(),
                // Not unit (a = |D|² ≠ 1).
                _ => (aim - origin) * 0.37,
            };
            let t_max = match i % 5 {
                0 => INF,
                _ => u().abs() * 8.0,
            };
            let ray = Ray { origin, direction };
            let expected = s.occludes(&ray, 0.0, t_max);
            let root = sphere_first_root(
                origin.to_array(),
                direction.to_array(),
                t_max,
                s.center,
                s.radius,
            );
            let nearest = s.intersect(&ray, 0.0, t_max).map(|h| h.t);
            assert_eq!(root.0.then_some(root.1), nearest, "{ray:?} {s:?} {t_max}");
            let got = sphere_blocks(
                origin.to_array(),
                direction.to_array(),
                t_max,
                s.center,
                s.radius,
            );
            assert_eq!(got, expected, "{ray:?} {s:?} {t_max}");
            blocked += expected as usize;
        }
        assert!(blocked > 40_000, "{blocked}");
        // Tangent at the origin: q = 0, no root in (0, t_max).
        let s = Sphere {
            center: DVec3::Y,
            radius: 1.0,
        };
        let ray = Ray {
            origin: DVec3::ZERO,
            direction: DVec3::X,
        };
        assert!(!s.occludes(&ray, 0.0, INF));
        assert!(!sphere_blocks(
            [0.0; 3],
            [1.0, 0.0, 0.0],
            INF,
            s.center,
            s.radius
        ));
    }

    #[test]
    fn hit_from_outside() {
        let s = Sphere {
            center: DVec3::new(0.0, 0.0, -5.0),
            radius: 1.0,
        };
        let h = s
            .intersect(&Ray::new(DVec3::ZERO, -DVec3::Z), 0.0, INF)
            .unwrap();
        assert_eq!(h.t, 4.0);
        assert_eq!(h.normal, DVec3::Z);
        assert!(h.front_face);
    }

    #[test]
    fn hit_from_inside_is_a_back_face() {
        let s = Sphere {
            center: DVec3::ZERO,
            radius: 2.0,
        };
        let h = s
            .intersect(&Ray::new(DVec3::ZERO, DVec3::X), 0.0, INF)
            .unwrap();
        assert_eq!(h.t, 2.0);
        assert!(!h.front_face);
    }

    #[test]
    fn tangent_and_miss() {
        let s = Sphere {
            center: DVec3::new(0.0, 1.0, -5.0),
            radius: 1.0,
        };
        let tangent = s
            .intersect(&Ray::new(DVec3::ZERO, -DVec3::Z), 0.0, INF)
            .unwrap();
        assert!((tangent.t - 5.0).abs() < 1e-12);
        assert!(tangent.normal.dot(DVec3::Z).abs() < 1e-12);
        let miss = Ray::new(DVec3::new(0.0, -1e-6, 0.0), -DVec3::Z);
        assert!(s.intersect(&miss, 0.0, INF).is_none());
        // Sphere behind the ray.
        assert!(
            s.intersect(&Ray::new(DVec3::ZERO, DVec3::Z), 0.0, INF)
                .is_none()
        );
    }

    #[test]
    fn far_small_sphere_is_hit_accurately() {
        // Classic b² − c loses all digits here: b² ≈ 1e16, r² = 1e-6.
        let s = Sphere {
            center: DVec3::new(0.0, 0.0, -1e8),
            radius: 1e-3,
        };
        let h = s
            .intersect(&Ray::new(DVec3::ZERO, -DVec3::Z), 0.0, INF)
            .unwrap();
        assert!((h.t - (1e8 - 1e-3)).abs() < 1e-7, "t = {}", h.t);
        let r = Ray::new(DVec3::ZERO, DVec3::new(0.0, 0.9e-3, -1e8));
        assert!(s.intersect(&r, 0.0, INF).is_some());
    }

    #[test]
    fn random_hits_lie_on_the_sphere() {
        let mut rng = PixelRng::new(5, 0, 0);
        let mut u = || rng.uniform() * 2.0 - 1.0;
        let mut hits = 0;
        for _ in 0..10_000 {
            let s = Sphere {
                center: DVec3::new(u(), u(), u()) * 5.0,
                radius: 0.1 + u().abs() * 3.0,
            };
            // Aim near the sphere so that about half the rays hit.
            let origin = DVec3::new(u(), u(), u()) * 10.0;
            let target = s.center + DVec3::new(u(), u(), u()) * s.radius * 1.5;
            let ray = Ray::new(origin, target - origin);
            let dist_to_line = (s.center - ray.origin).reject_from(ray.direction).length();
            match s.intersect(&ray, 0.0, INF) {
                Some(h) => {
                    hits += 1;
                    let p = ray.at(h.t);
                    assert!(((p - s.center).length() - s.radius).abs() < 1e-10);
                    assert!((h.normal.length() - 1.0).abs() < 1e-10);
                }
                None => {
                    let inside = (ray.origin - s.center).length() < s.radius;
                    let ahead = (s.center - ray.origin).dot(ray.direction) > 0.0;
                    assert!(!inside && (dist_to_line > s.radius - 1e-9 || !ahead));
                }
            }
        }
        assert!(hits > 3000, "{hits} hits");
    }

    #[test]
    fn ellipsoid_normal_uses_the_inverse_transpose() {
        // Unit sphere stretched ×2 along x: the ellipse x²/4 + y² = 1.
        let t = Transform::from_affine(DAffine3::from_scale(DVec3::new(2.0, 1.0, 1.0))).unwrap();
        let e = Ellipsoid { transform: t };
        // At the point (√2, 1/√2, 0) the gradient is (x/2, 2y, 0) ∝ (1/√2, √2, 0).
        let p = DVec3::new(2f64.sqrt(), 1.0 / 2f64.sqrt(), 0.0);
        let expected = DVec3::new(1.0 / 2f64.sqrt(), 2f64.sqrt(), 0.0).normalize();
        let ray = Ray::new(p + 3.0 * expected, -expected);
        let h = e.intersect(&ray, 0.0, INF).unwrap();
        assert!((ray.at(h.t) - p).length() < 1e-12);
        assert!((h.normal - expected).length() < 1e-12, "{:?}", h.normal);
        let b = e.bounds();
        assert_eq!(b.max, DVec3::new(2.0, 1.0, 1.0));
    }
}
