//! POV-Ray's `torus`: the surface at distance `minor_radius` r from a
//! circle of radius `major_radius` R around the y axis, centred at the
//! origin (placed by a transform).
//!
//! A point p lies on it where f(p) = (|p|² + R² − r²)² − 4R²(px² + pz²) = 0.
//! Along the ray p = o + s·d (|d| = 1, o moved to the point of the ray
//! nearest the centre, so o·d = 0) f is the quartic
//!   s⁴ + (2G − 4R²(dx² + dz²))·s² + (4G·0 − 8R²(ox·dx + oz·dz))·s
//!     + G² − 4R²(ox² + oz²),  with G = |o|² + R² − r².
//! Its real roots are found without a closed form: they lie in the ray's
//! interval inside the bounding sphere |s| ≤ √((R + r)² − |o|²); between
//! consecutive roots of f′ (a cubic), f is monotone, so each piece holds
//! at most one root, found by safeguarded Newton steps (bisection when a
//! step would leave the bracket) on f evaluated in its geometric
//! form (no cancellation of expanded coefficients); the roots of f′ are
//! found the same way between the roots of f″ (a quadratic, closed form).
//! No root is lost where f changes sign, none is invented where it does
//! not; a tangent touch (a double root, a grazing ray) is a root where
//! |f| at a critical point is within rounding of 0. Each root is bracketed
//! until a Newton step inside the bracket leaves an error (|f″/2f′|·step²)
//! below 1e-14·(R + r) (or the bracket is two adjacent doubles), so the
//! point lies on the surface to within 1e-12·(R + r) (`ROOT_TOLERANCE`).
//!
//! A closest hit or a feeler needs the first root only, and mostly finds it
//! without any critical point: f is convex or concave between the roots of
//! f″, and on each such piece the signs of f at its ends say whether it
//! holds one root (reached by Newton steps from the end where they cannot
//! pass it), none, or two or none (Newton steps from its start either reach
//! the first or show, by two tangents, that f turns clear of 0). Grazing
//! rays and values within rounding of 0 go to the bracketing search
//! (`first_root_by_pieces`). On `bench/solids.toml` 99.6 % of the hits are
//! found so, and every miss.
//!
//! Normal: from the tube's centre circle to the point. Texture
//! coordinates: u = ½ + atan2(z, x)/2π around the y axis, v = ½ +
//! atan2(y, ρ − R)/2π around the tube (ρ = √(x² + z²)).

use arrayvec::ArrayVec;
use glam::{DVec2, DVec3};

use super::cuboid::placed_bounds;
use super::span::{Intervals, Surface, classify_between_roots};
use super::{Aabb, ShapeHit};
use crate::accel::simd::{self, Job};
use crate::math::{Ray, Transform, transcendental};

/// The most a reported point lies off the surface, relative to R + r.
pub const ROOT_TOLERANCE: f64 = 1e-12;

/// A torus around its own y axis, placed by `transform`.
#[derive(Clone, Debug, PartialEq)]
pub struct Torus {
    /// R: the radius of the tube's centre circle.
    pub major_radius: f64,
    /// r: the tube's radius.
    pub minor_radius: f64,
    /// Object to world.
    pub transform: Transform,
}

impl Torus {
    /// f(p): negative inside the tube, positive outside.
    #[inline]
    pub fn implicit(&self, p: DVec3) -> f64 {
        let (big, small) = (self.major_radius, self.minor_radius);
        let q = p.length_squared() + big * big - small * small;
        q * q - 4.0 * big * big * (p.x * p.x + p.z * p.z)
    }

    /// Every crossing of the object-space ray (o, d) as a parameter of
    /// that ray, ascending.
    pub fn crossings(&self, o: DVec3, d: DVec3) -> ArrayVec<f64, 4> {
        self.roots(o, d, true, (f64::NEG_INFINITY, f64::INFINITY), false)
    }

    /// The roots along (o, d) with t strictly inside `window`, ascending:
    /// those where f changes sign, and with `touches` the double roots of
    /// a grazing ray too; with `first`, only the first. Only the part of
    /// the ray inside the window is searched (f is monotone between its
    /// critical points there too), so a shadow feeler or a closest-hit
    /// query pays for the roots it can use.
    fn roots(
        &self,
        o: DVec3,
        d: DVec3,
        touches: bool,
        window: (f64, f64),
        first: bool,
    ) -> ArrayVec<f64, 4> {
        // The search is most of a torus query's time: compiled for AVX2
        // where the CPU has it (the same operations, so the same bits).
        simd::kernel().vectorize_job(RootSearch {
            torus: self,
            o,
            d,
            touches,
            window,
            first,
        })
    }

    /// [`roots`](Self::roots), compiled into its caller.
    #[inline(always)]
    fn roots_here(
        &self,
        o: DVec3,
        d: DVec3,
        touches: bool,
        window: (f64, f64),
        first: bool,
    ) -> ArrayVec<f64, 4> {
        let mut out = ArrayVec::new();
        let len = d.length();
        if len == 0.0 || !len.is_finite() {
            return out;
        }
        let u = d / len;
        // The point of the ray nearest the centre: s counts from there.
        let tc = -o.dot(u);
        let c = o + tc * u;
        let (big, small) = (self.major_radius, self.minor_radius);
        let reach = (big + small) * (big + small) - c.length_squared();
        if reach <= 0.0 {
            return out;
        }
        let half = reach.sqrt() * (1.0 + 1e-12);
        // The window in s, within the bounding sphere.
        let (lo, hi) = (
            (window.0 * len - tc).max(-half),
            (window.1 * len - tc).min(half),
        );
        if lo.is_nan() || hi.is_nan() || lo >= hi {
            return out;
        }
        let f = |s: f64| self.implicit(c + s * u);
        // f(s) = s⁴ + a2·s² + a1·s + a0 (o·d = 0 removes s³).
        let g = c.length_squared() + big * big - small * small;
        let a2 = 2.0 * g - 4.0 * big * big * (u.x * u.x + u.z * u.z);
        let a1 = -8.0 * big * big * (c.x * u.x + c.z * u.z);
        let f1 = |s: f64| 4.0 * s * s * s + 2.0 * a2 * s + a1;
        let f2 = |s: f64| 12.0 * s * s + 2.0 * a2;
        // A Newton step whose error is below this ends a root's search (see
        // ROOT_TOLERANCE).
        let step = 1e-14 * (big + small);
        let mut lo = lo;
        let scale = (big + small).powi(4);
        // A tangent touch (a double root) within this of 0 counts as a root.
        let touch = 1e-13 * scale;
        if first {
            // The first root is reached by Newton steps from a piece's end
            // that cannot pass it, without a critical point (see
            // `first_root_by_pieces`); the bracketing search below takes
            // over where that cannot decide.
            match first_root_by_pieces(lo, hi, a2, &f, &f1, &f2, step, touch) {
                FirstRoot::At(s) => {
                    let t = (tc + s) / len;
                    if t > window.0 && t < window.1 {
                        out.push(t);
                        return out;
                    }
                    // Within rounding of the window's edge: the search
                    // below decides.
                }
                FirstRoot::None => return out,
                FirstRoot::Search(from) => lo = from,
            }
        }
        // f″(s) = 12s² + 2·a2: its roots split f′ into monotone pieces.
        let mut cuts: ArrayVec<f64, 8> = ArrayVec::new();
        cuts.push(lo);
        if a2 < 0.0 {
            let r = (-a2 / 6.0).sqrt();
            for s in [-r, r] {
                if s > lo && s < hi {
                    cuts.push(s);
                }
            }
        }
        cuts.push(hi);
        let mut roots: ArrayVec<f64, 4> = ArrayVec::new();
        // A root on a piece's end is met from both pieces: kept once; one
        // on the window's edge is outside it.
        let keep = |s: f64, roots: &mut ArrayVec<f64, 4>| {
            let t = (tc + s) / len;
            let fresh = roots
                .last()
                .is_none_or(|&last| s - last > 1e-9 * (big + small));
            if fresh && t > window.0 && t < window.1 {
                let _ = roots.try_push(s);
            }
        };
        // f is monotone from one critical point (a root of f′, one at most
        // per piece between the cuts) to the next: each such piece holds at
        // most one root. Taken in order, found as they are needed, so a
        // query for the first root stops early.
        let mut from = lo;
        // The next piece between cuts to search for a critical point (a
        // plain loop, not an iterator's closure, so that it is compiled
        // into the search).
        let mut piece = 0;
        loop {
            let mut critical = None;
            while critical.is_none() && piece + 1 < cuts.len() {
                critical = sign_change_root(
                    &f1,
                    &f2,
                    &|s: f64| 24.0 * s,
                    cuts[piece],
                    cuts[piece + 1],
                    step,
                )
                .filter(|&s| s > lo && s < hi);
                piece += 1;
            }
            let to = critical.unwrap_or(hi);
            if let Some(s) =
                sign_change_root(&f, &f1, &|s: f64| 12.0 * s * s + 2.0 * a2, from, to, step)
            {
                keep(s, &mut roots);
            }
            // A touch at an inner critical point: a double root, kept once.
            if touches && critical.is_some() && f(to).abs() <= touch {
                keep(to, &mut roots);
            }
            if critical.is_none() || (first && !roots.is_empty()) {
                break;
            }
            from = to;
        }
        for s in roots {
            out.push((tc + s) / len);
        }
        out
    }

    /// The nearest hit in (t_min, t_max), from outside or inside.
    pub fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<ShapeHit> {
        let (o, d) = self.transform.ray_to_object(ray);
        let t = *self.roots(o, d, true, (t_min, t_max), true).first()?;
        let p = o + t * d;
        let normal = self.transform.normal(self.object_normal(p));
        Some(ShapeHit::geometric(
            t,
            normal,
            ray.direction.dot(normal) < 0.0,
        ))
    }

    /// Where the whole line of `ray` is inside the tube: between the roots
    /// where f changes sign (a grazing touch encloses nothing), each stretch
    /// judged by the sign of f at its middle.
    pub fn inside(&self, ray: &Ray) -> Intervals {
        let (o, d) = self.transform.ray_to_object(ray);
        let roots = self.roots(o, d, false, (f64::NEG_INFINITY, f64::INFINITY), false);
        classify_between_roots(&roots, |t| self.implicit(o + t * d) < 0.0)
    }

    /// The outward unit normal where `ray` crosses the surface at `s`.
    pub fn surface_normal(&self, ray: &Ray, s: Surface) -> DVec3 {
        let (o, d) = self.transform.ray_to_object(ray);
        self.transform.normal(self.object_normal(o + s.t * d))
    }

    /// The outward normal at an object-space point on the surface.
    pub fn object_normal(&self, p: DVec3) -> DVec3 {
        let around = DVec3::new(p.x, 0.0, p.z);
        let centre = around.try_normalize().unwrap_or(DVec3::X) * self.major_radius;
        p - centre
    }

    /// Texture coordinates at the world point `point` (see the module).
    pub fn uv(&self, point: DVec3) -> DVec2 {
        let p = self.transform.to_object.transform_point3(point);
        let rho = (p.x * p.x + p.z * p.z).sqrt();
        let turn = std::f64::consts::TAU;
        DVec2::new(
            0.5 + transcendental::atan2(p.z, p.x) / turn,
            0.5 + transcendental::atan2(p.y, rho - self.major_radius) / turn,
        )
    }

    /// The bounding box of the placed torus.
    pub fn bounds(&self) -> Aabb {
        let (big, small) = (self.major_radius, self.minor_radius);
        let e = DVec3::new(big + small, small, big + small);
        placed_bounds(&self.transform, -e, e)
    }
}

/// [`Torus::roots`] as a [`Job`], so that its search is compiled into
/// the job's runner.
struct RootSearch<'a> {
    torus: &'a Torus,
    o: DVec3,
    d: DVec3,
    touches: bool,
    window: (f64, f64),
    first: bool,
}

impl Job for RootSearch<'_> {
    type Output = ArrayVec<f64, 4>;

    #[inline(always)]
    fn run(self) -> ArrayVec<f64, 4> {
        self.torus
            .roots_here(self.o, self.d, self.touches, self.window, self.first)
    }
}

/// What [`first_root_by_pieces`] found.
enum FirstRoot {
    /// The first root.
    At(f64),
    /// No root and no touch in the window.
    None,
    /// Undecided from here on (f kept its sign and stayed clear of 0 up to
    /// here): the bracketing search goes on from this point.
    Search(f64),
}

/// The first root of the quartic f in [lo, hi], without its critical
/// points. Between the roots of f″ (±√(−a2/6)) f is convex or concave,
/// and on such a piece [a, b]:
/// - where f(a) and f(b) differ in sign there is exactly one root, and
///   Newton steps from the end where f·f″ > 0 approach it from that side
///   and never pass it (Fourier's condition: the tangent stays on that
///   end's side of the curve until it meets 0);
/// - where they share the sign of f″ (a convex piece above 0, a concave
///   one below), the piece holds two roots or none: Newton steps from a,
///   if f runs towards 0 there, reach the first or show that f turns before
///   meeting 0 (two tangents bound it from below, or above, clear of a
///   touch);
/// - where they have the other sign, f lies beyond its chord: no root.
///
/// A step ends the search below `tolerance` with the error bound of
/// [`sign_change_root`]. A value exactly 0, a turn within `touch` of 0 (a
/// grazing ray, whose double root the bracketing search judges), a step
/// count past 64 or rounding against the piece's shape hand the rest to
/// the bracketing search.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn first_root_by_pieces(
    lo: f64,
    hi: f64,
    a2: f64,
    f: &impl Fn(f64) -> f64,
    df: &impl Fn(f64) -> f64,
    d2f: &impl Fn(f64) -> f64,
    tolerance: f64,
    touch: f64,
) -> FirstRoot {
    let mut ends = [hi; 3];
    if a2 < 0.0 {
        let r = (-a2 / 6.0).sqrt();
        ends = [(-r).clamp(lo, hi), r.clamp(lo, hi), hi];
    }
    // Newton steps from x while they stay inside (lo, hi) and keep the
    // sign of f; the root once a step is below the tolerance.
    // Where a Newton step from x (f = fx) lands: the root once the step's
    // error is below the tolerance (or f is 0 there), the bracketing search
    // from `a` when rounding gave the other sign, else f at the new point.
    let land = |a: f64, x: f64, fx: f64, newton: f64, dfx: f64, curve: f64| {
        let stepped = (newton - x).abs();
        if stepped <= 1e6 * tolerance
            && curve.abs() * stepped * stepped <= 2.0 * dfx.abs() * tolerance
        {
            return Err(FirstRoot::At(newton));
        }
        let next = f(newton);
        if next == 0.0 {
            return Err(FirstRoot::At(newton));
        }
        if (next < 0.0) != (fx < 0.0) {
            return Err(FirstRoot::Search(a));
        }
        Ok(next)
    };
    let mut a = lo;
    let mut fa = f(a);
    for &b in &ends {
        if b <= a {
            continue;
        }
        let fb = f(b);
        if fa == 0.0 || fb == 0.0 {
            return FirstRoot::Search(a);
        }
        // The sign of f″ on the piece: at its middle (0 only at the ends).
        let curve_sign = d2f(0.5 * (a + b));
        if (fa < 0.0) != (fb < 0.0) {
            // One root: from the end where f has the sign of f″.
            let (mut x, mut fx) = if (fa < 0.0) == (curve_sign < 0.0) {
                (a, fa)
            } else {
                (b, fb)
            };
            for _ in 0..64 {
                let (dfx, curve) = (df(x), d2f(x));
                let newton = x - fx / dfx;
                if !(newton > a && newton < b) {
                    return FirstRoot::Search(a);
                }
                match land(a, x, fx, newton, dfx, curve) {
                    Ok(next) => (x, fx) = (newton, next),
                    Err(found) => return found,
                }
            }
            return FirstRoot::Search(a);
        }
        if (fa < 0.0) == (curve_sign < 0.0) {
            // Two roots or none: f must run towards 0 from a, and turn
            // back clear of 0 if it does not meet it.
            let (mut x, mut fx) = (a, fa);
            let mut dfx = df(x);
            let mut clear = false;
            for _ in 0..64 {
                if fx * dfx >= 0.0 {
                    // Running away from 0 (convex above 0 rising, or
                    // concave below falling): no root up to b.
                    if fx.abs() > touch {
                        clear = true;
                        break;
                    }
                    return FirstRoot::Search(a);
                }
                let newton = x - fx / dfx;
                let curve = d2f(x);
                if newton >= b {
                    // The tangent does not meet 0 before b, and f lies
                    // beyond it on [x, b].
                    let bound = fx + dfx * (b - x);
                    if bound.abs() > touch && (bound < 0.0) == (fx < 0.0) {
                        clear = true;
                        break;
                    }
                    return FirstRoot::Search(a);
                }
                if newton.is_nan() || newton <= x {
                    return FirstRoot::Search(a);
                }
                let next = match land(a, x, fx, newton, dfx, curve) {
                    Ok(next) => next,
                    Err(found) => return found,
                };
                let dnext = df(newton);
                if next * dnext >= 0.0 {
                    // f turned between x and newton: it lies beyond both
                    // tangents there, whose crossing bounds it.
                    let cross = (next - fx + dfx * x - dnext * newton) / (dfx - dnext);
                    let bound = fx + dfx * (cross - x);
                    if bound.abs() > touch && (bound < 0.0) == (fx < 0.0) && next.abs() > touch {
                        clear = true;
                        break;
                    }
                    return FirstRoot::Search(a);
                }
                x = newton;
                fx = next;
                dfx = dnext;
            }
            if !clear {
                // Out of steps while still running towards 0.
                return FirstRoot::Search(a);
            }
        }
        // Otherwise f lies beyond its chord, on the far side from 0.
        a = b;
        fa = fb;
    }
    FirstRoot::None
}

/// The root of `f` in [lo, hi] where f has opposite signs at the ends
/// (a piece where it is monotone), bracketed until a Newton step inside
/// it leaves an error below `tolerance` (Newton's error after a step of h
/// is about |f″/2f′|·h², `d2f` giving f″; the step itself at most 1e6
/// times the tolerance, so that estimate holds) or the bracket is two
/// adjacent doubles: Newton steps on `df` while they land inside the
/// bracket and it keeps narrowing, bisection otherwise. Every value of f only narrows
/// the bracket by its sign, so the answer is as safe as bisection's, in a
/// handful of evaluations instead of sixty. `None` without a sign change.
#[inline(always)]
fn sign_change_root(
    f: &impl Fn(f64) -> f64,
    df: &impl Fn(f64) -> f64,
    d2f: &impl Fn(f64) -> f64,
    mut lo: f64,
    mut hi: f64,
    tolerance: f64,
) -> Option<f64> {
    let (flo, fhi) = (f(lo), f(hi));
    if flo == 0.0 {
        return Some(lo);
    }
    if fhi == 0.0 {
        return Some(hi);
    }
    if (flo < 0.0) == (fhi < 0.0) {
        return None;
    }
    let rising = flo < 0.0;
    let mut x = 0.5 * (lo + hi);
    let mut width_before = f64::INFINITY;
    for _ in 0..200 {
        let fx = f(x);
        if fx == 0.0 {
            return Some(x);
        }
        if (fx < 0.0) == rising {
            lo = x;
        } else {
            hi = x;
        }
        if lo.next_up() >= hi {
            break;
        }
        let width = hi - lo;
        let dfx = df(x);
        let newton = x - fx / dfx;
        let stepped = (newton - x).abs();
        if stepped <= 1e6 * tolerance
            && newton > lo
            && newton < hi
            && d2f(x).abs() * stepped * stepped <= 2.0 * dfx.abs() * tolerance
        {
            return Some(newton);
        }
        let mut next = if newton > lo && newton < hi && width < 0.5 * width_before {
            newton
        } else {
            0.5 * (lo + hi)
        };
        width_before = 2.0 * width;
        // At the root to within rounding, a step may not move: step one
        // double towards the other end instead, which settles the bracket.
        if next == x {
            next = if x == lo { x.next_up() } else { x.next_down() };
        }
        if next <= lo || next >= hi {
            next = 0.5 * (lo + hi);
            if next <= lo || next >= hi {
                break;
            }
        }
        x = next;
    }
    // The end where f is nearer 0 (both are adjacent doubles by now).
    Some(if f(lo).abs() <= f(hi).abs() { lo } else { hi })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::PixelRng;

    fn torus(big: f64, small: f64) -> Torus {
        Torus {
            major_radius: big,
            minor_radius: small,
            transform: Transform::default(),
        }
    }

    #[test]
    fn hand_worked_crossings() {
        let t = torus(2.0, 0.5);
        // Along the x axis from x = 5: the tube at x = 2.5, 1.5, −1.5, −2.5.
        let c = t.crossings(DVec3::new(5.0, 0.0, 0.0), DVec3::NEG_X);
        let want = [2.5, 3.5, 6.5, 7.5];
        assert_eq!(c.len(), 4);
        for (a, b) in c.iter().zip(want) {
            assert!((a - b).abs() < 1e-12, "{c:?}");
        }
        // Down the y axis through the hole: no crossing.
        assert!(
            t.crossings(DVec3::new(0.0, 5.0, 0.0), DVec3::NEG_Y)
                .is_empty()
        );
        // Down through the tube's centre circle at x = 2: y = ±0.5.
        let c = t.crossings(DVec3::new(2.0, 5.0, 0.0), DVec3::NEG_Y);
        assert_eq!(c.len(), 2);
        assert!(
            (c[0] - 4.5).abs() < 1e-12 && (c[1] - 5.5).abs() < 1e-12,
            "{c:?}"
        );
        // The eye inside the tube: the line meets the tube on both sides
        // of the hole; the nearest ahead is 0.5 away, leaving the tube.
        let c = t.crossings(DVec3::new(2.0, 0.0, 0.0), DVec3::X);
        let want = [-4.5, -3.5, -0.5, 0.5];
        assert_eq!(c.len(), 4, "{c:?}");
        for (a, b) in c.iter().zip(want) {
            assert!((a - b).abs() < 1e-12, "{c:?}");
        }
        let h = t
            .intersect(
                &Ray::new(DVec3::new(2.0, 0.0, 0.0), DVec3::X),
                0.0,
                f64::INFINITY,
            )
            .unwrap();
        assert!(!h.front_face && (h.normal - DVec3::X).length() < 1e-12);
    }

    #[test]
    fn grazing_rays_neither_lose_nor_invent_roots() {
        let t = torus(2.0, 0.5);
        // Along x at height y just below, at and just above the top of
        // the tube (y = 0.5): four roots (two pairs close together), the
        // tangent touches, none.
        let below = t.crossings(DVec3::new(5.0, 0.5 - 1e-6, 0.0), DVec3::NEG_X);
        assert_eq!(below.len(), 4, "{below:?}");
        let at = t.crossings(DVec3::new(5.0, 0.5, 0.0), DVec3::NEG_X);
        assert!(!at.is_empty() && at.len() <= 2, "{at:?}");
        for s in &at {
            assert!((s - 3.0).abs() < 1e-4 || (s - 7.0).abs() < 1e-4, "{at:?}");
        }
        let above = t.crossings(DVec3::new(5.0, 0.5 + 1e-6, 0.0), DVec3::NEG_X);
        assert!(above.is_empty(), "{above:?}");
        // Along z beside the inner equator (x = R − r = 1.5): just inside
        // the tube, one chord (z = ±2); just outside, the chord splits in
        // two around z = 0 (a gap of 2√(2·1.5·1e-7) ≈ 1.1e-3).
        let inside = t.crossings(DVec3::new(1.5 + 1e-7, 0.0, -5.0), DVec3::Z);
        assert_eq!(inside.len(), 2, "{inside:?}");
        assert!((inside[0] - 3.0).abs() < 1e-6 && (inside[1] - 7.0).abs() < 1e-6);
        let split = t.crossings(DVec3::new(1.5 - 1e-7, 0.0, -5.0), DVec3::Z);
        assert_eq!(split.len(), 4, "{split:?}");
        let gap = split[2] - split[1];
        assert!((gap - 2.0 * (3e-7f64).sqrt()).abs() < 1e-6, "{split:?}");
    }

    /// A closest-hit query searches only its window; it must find the
    /// root the whole line's list has first in that window.
    #[test]
    fn a_windowed_search_finds_the_first_root_of_the_whole_line_in_it() {
        let mut rng = PixelRng::new(4, 2, 9);
        let mut u = || 2.0 * rng.uniform() - 1.0;
        let t = torus(1.5, 0.5);
        let mut compared = 0;
        for _ in 0..5000 {
            let o = DVec3::new(u(), u(), u()) * 3.0;
            let d = DVec3::new(u(), u(), u());
            let all = t.crossings(o, d);
            let (a, b) = (u() * 4.0, u() * 4.0);
            let window = (a.min(b), a.max(b));
            let want = all.iter().copied().find(|&x| x > window.0 && x < window.1);
            let got = t.roots(o, d, true, window, true).first().copied();
            match (want, got) {
                (Some(w), Some(g)) => {
                    compared += 1;
                    assert!((w - g).abs() < 1e-9, "{w} vs {g}");
                }
                (None, None) => {}
                other => panic!("{o} {d} {window:?}: {other:?} in {all:?}"),
            }
        }
        assert!(compared > 500, "{compared}");
    }

    /// The first root of a closest-hit query (Newton steps from a piece's
    /// end, `first_root_by_pieces`) against the whole line's roots (the
    /// bracketing search between critical points): rays leaving points on
    /// the surface, into the tube and out of it (as feelers and refracted
    /// rays do), and rays grazing the top of the tube and its inner
    /// equator ever closer, above and below. The same root (or none), on
    /// the surface to the documented tolerance. The windows of rays from
    /// the surface start 1e-6·(R + r) out: nearer, a ray leaving almost
    /// tangentially meets its own origin's crossing within f's rounding,
    /// which either search may report (3 such cases in 1 M hits with
    /// windows from 1e-9; none from 1e-6 in 2 M rays).
    #[test]
    fn the_first_root_by_newton_steps_is_the_first_of_the_whole_line() {
        let mut rng = PixelRng::new(7, 3, 21);
        let mut u = || 2.0 * rng.uniform() - 1.0;
        // (torus, origin, direction, window, how near the two searches'
        // roots must agree, relative to R + r)
        type Case = (Torus, DVec3, DVec3, (f64, f64), f64);
        let mut cases: Vec<Case> = Vec::new();
        for _ in 0..4000 {
            let big = 1.0 + u().abs() * 3.0;
            let small = (0.05 + u().abs()) * big * 0.9;
            let t = torus(big, small);
            // A point on the surface, a direction either way.
            let (around, tube) = (std::f64::consts::PI * u(), std::f64::consts::PI * u());
            let ((around_sin, around_cos), (tube_sin, tube_cos)) = (
                transcendental::sin_cos(around),
                transcendental::sin_cos(tube),
            );
            let rho = big + small * tube_cos;
            let p = DVec3::new(rho * around_cos, small * tube_sin, rho * around_sin);
            let d = DVec3::new(u(), u(), u()).normalize();
            let far = if u() > 0.0 {
                f64::INFINITY
            } else {
                4.0 * u().abs() * (big + small)
            };
            cases.push((t, p, d, (1e-6 * (big + small), far), 1e-9));
        }
        let t = torus(2.0, 0.5);
        for k in 1..=15 {
            let gap = 10f64.powi(-k);
            for sign in [-1.0, 1.0] {
                // Along x past the top of the tube (y = 0.5), and along z
                // beside the inner equator (x = 1.5).
                let top = DVec3::new(5.0, 0.5 + sign * gap, 0.0);
                let equator = DVec3::new(1.5 + sign * gap, 0.0, -5.0);
                // Near a double root f is flat to within its rounding
                // (~1e-16·(R + r)⁴), so a root is only defined to about
                // the square root of that: 1e-8·(R + r).
                let agree = if gap < 1e-12 { 1e-7 } else { 1e-9 };
                cases.push((t.clone(), top, DVec3::NEG_X, (0.0, f64::INFINITY), agree));
                cases.push((t.clone(), equator, DVec3::Z, (0.0, f64::INFINITY), agree));
            }
        }
        let mut hits = 0;
        for (t, o, d, window, agree) in &cases {
            let scale = t.major_radius + t.minor_radius;
            let all = t.crossings(*o, *d);
            let want = all.iter().copied().find(|&x| x > window.0 && x < window.1);
            let got = t.roots(*o, *d, true, *window, true).first().copied();
            match (want, got) {
                (Some(w), Some(g)) => {
                    hits += 1;
                    assert!(
                        (w - g).abs() < agree * scale,
                        "{o} {d}: {w} vs {g} in {all:?}"
                    );
                    let p = *o + g * *d;
                    let distance = (DVec3::new(p.x, 0.0, p.z).length() - t.major_radius).hypot(p.y)
                        - t.minor_radius;
                    assert!(
                        distance.abs() <= ROOT_TOLERANCE * 10.0 * scale,
                        "{distance:e}"
                    );
                }
                (None, None) => {}
                other => panic!("{o} {d} {window:?}: {other:?} in {all:?}"),
            }
        }
        assert!(hits > 1500, "{hits}");
    }

    /// Plain bisection of a sign change of f in [lo, hi], to adjacent doubles.
    fn bisect(f: &impl Fn(f64) -> f64, mut lo: f64, mut hi: f64) -> f64 {
        let rising = f(lo) < 0.0;
        loop {
            let mid = 0.5 * (lo + hi);
            if mid <= lo || mid >= hi {
                return mid;
            }
            if (f(mid) < 0.0) == rising {
                lo = mid;
            } else {
                hi = mid;
            }
        }
    }

    /// Every root against a brute force: f sampled densely along the ray,
    /// each sign change bisected, on random rays and tori (seeded), with
    /// the eye outside, inside the tube and in the hole.
    #[test]
    fn roots_agree_with_bisection_on_the_implicit_function() {
        let mut rng = PixelRng::new(11, 5, 6);
        let mut u = || 2.0 * rng.uniform() - 1.0;
        let mut total = 0;
        for i in 0..1000 {
            let big = 1.0 + u().abs() * 3.0;
            let small = (0.05 + u().abs()) * big * 0.9;
            let t = torus(big, small);
            let o = match i % 3 {
                0 => DVec3::new(u(), u(), u()) * 3.0 * (big + small),
                1 => DVec3::new(big, 0.0, 0.0) + DVec3::new(u(), u(), u()) * 0.5 * small,
                _ => DVec3::new(u(), u(), u()) * 0.5 * (big - small),
            };
            let d = DVec3::new(u(), u(), u()).normalize();
            let got = t.crossings(o, d);
            // Brute force over the ray's reach through the bounding sphere.
            let span = 2.0 * (o.length() + big + small);
            let n = 100_000;
            let f = |s: f64| t.implicit(o + s * d);
            let mut want = Vec::new();
            let mut prev = (-span, f(-span));
            for k in 1..=n {
                let s = -span + 2.0 * span * k as f64 / n as f64;
                let fs = f(s);
                if (fs < 0.0) != (prev.1 < 0.0) {
                    want.push(bisect(&f, prev.0, s));
                }
                prev = (s, fs);
            }
            total += want.len();
            // Roots closer than the sampling step may be one pair missed by
            // the brute force; every brute root is found.
            for w in &want {
                assert!(
                    got.iter().any(|g| (g - w).abs() < 1e-9 * (big + small)),
                    "ray {i}: brute root {w} not in {got:?}"
                );
            }
            // Every root found lies on the surface.
            for g in &got {
                let p = o + *g * d;
                let distance = (DVec3::new(p.x, 0.0, p.z).length() - big).hypot(p.y) - small;
                assert!(
                    distance.abs() <= ROOT_TOLERANCE * 10.0 * (big + small),
                    "{distance:e}"
                );
            }
        }
        assert!(total > 600, "{total}");
    }
}
