//! Watertight ray-triangle intersection (Woop, Benthin, Wald, "Watertight
//! Ray/Triangle Intersection", JCGT 2013).
//!
//! The ray is sheared and scaled into a space where it runs along +z from
//! the origin; the three edge functions U, V, W are then 2D cross products
//! of the projected vertices. Two triangles sharing an edge evaluate that
//! edge's function from the same two vertices, so a ray can never slip
//! between them: it hits one, or both.

use glam::DVec3;

use super::steps::Steps;

/// A ray prepared for the watertight test: the axis permutation and shear
/// depend only on the direction, so they are computed once per ray.
#[derive(Clone, Copy, Debug)]
pub struct WatertightRay {
    origin: DVec3,
    /// Axes (kx, ky, kz): kz is the direction's largest |component|.
    axes: [Axis; 3],
    /// Which of the six (kx, ky, kz) it is: 2·kz, plus 1 where kx and ky
    /// are swapped (see [`triangle_hit`]).
    permutation: u8,
    /// Shear constants Sx = Dx/Dz, Sy = Dy/Dz, Sz = 1/Dz.
    sx: f64,
    sy: f64,
    sz: f64,
}

/// A coordinate axis. An enum rather than an index, so that a coordinate
/// picked by a ray's axis at run time is one load from the vertex, with no
/// bounds check: the compiler knows the value lies in 0..3.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
enum Axis {
    X = 0,
    Y = 1,
    Z = 2,
}

impl Axis {
    /// The coordinate of `p` on this axis.
    #[inline(always)]
    fn of(self, p: &DVec3) -> f64 {
        let p: &[f64; 3] = p.as_ref();
        p[self as usize]
    }
}

/// The axes (kx, ky, kz) of each permutation the watertight test uses:
/// 2·kz, plus 1 where the ray runs towards −kz (kx and ky swapped).
const AXES: [[Axis; 3]; 6] = {
    use Axis::{X, Y, Z};
    [
        [Y, Z, X],
        [Z, Y, X],
        [Z, X, Y],
        [X, Z, Y],
        [X, Y, Z],
        [Y, X, Z],
    ]
};

impl WatertightRay {
    /// Which of the six axis permutations the test uses for this ray
    /// (0 to 5).
    #[inline(always)]
    pub fn permutation(&self) -> u8 {
        self.permutation
    }

    /// Prepares a ray with the given origin and (not necessarily unit)
    /// direction.
    #[inline]
    pub fn new(origin: DVec3, direction: DVec3) -> Self {
        let permutation = axis_permutation(direction);
        let axes = AXES[usize::from(permutation)];
        // The direction's components on axes kx, ky and kz.
        let [dx, dy, dz] = axes.map(|k| k.of(&direction));
        WatertightRay {
            origin,
            axes,
            permutation,
            sx: dx / dz,
            sy: dy / dz,
            sz: 1.0 / dz,
        }
    }
}

/// The axis permutation (index into `AXES`) of the watertight test for
/// rays along `direction`: kz its largest component's axis, and kx, ky
/// following kz in cyclic order, swapped where the ray runs towards −kz so
/// that the projected triangle keeps its winding.
#[inline]
pub fn axis_permutation(direction: DVec3) -> u8 {
    let a = direction.abs();
    // x where it is the largest, else y where it is at least z, else z;
    // in arithmetic on the comparisons, not branches: for scattered rays
    // those mispredicted (6 % of a bunny query's mispredictions).
    let not_x = 1 - u8::from(a.x >= a.y && a.x >= a.z);
    let kz = not_x * (2 - u8::from(a.y >= a.z));
    let d = [direction.x, direction.y, direction.z];
    2 * kz + u8::from(d[usize::from(kz)] < 0.0)
}

/// A ray-triangle hit: parameter and barycentric coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleHit {
    /// Ray parameter.
    pub t: f64,
    /// Barycentric weights of vertices a, b, c (sum 1).
    pub barycentric: DVec3,
}

/// The watertight test of `ray` against triangle (a, b, c), keeping hits
/// with t in (t_min, t_max). Both faces count.
#[inline(always)]
pub fn triangle_hit(
    ray: &WatertightRay,
    a: DVec3,
    b: DVec3,
    c: DVec3,
    t_min: f64,
    t_max: f64,
) -> Option<TriangleHit> {
    permuted_test(ray, ray.axes, [&a, &b, &c], t_min, t_max, &mut ())
}

/// [`triangle_hit`] of the triangle whose corners `corners` point at: each
/// coordinate the test uses is read straight from its vertex (a value
/// passed in is first written out to be read so).
#[inline(always)]
pub fn triangle_hit_at(
    ray: &WatertightRay,
    corners: [&DVec3; 3],
    t_min: f64,
    t_max: f64,
) -> Option<TriangleHit> {
    permuted_test(ray, ray.axes, corners, t_min, t_max, &mut ())
}

/// [`triangle_hit`], telling `steps` the axes, the edge functions U, V,
/// W, their sum and t.
#[inline(always)]
pub fn triangle_hit_steps<S: Steps>(
    ray: &WatertightRay,
    [a, b, c]: [DVec3; 3],
    t_min: f64,
    t_max: f64,
    steps: &mut S,
) -> Option<TriangleHit> {
    permuted_test(ray, ray.axes, [&a, &b, &c], t_min, t_max, steps)
}

/// [`triangle_hit`] for a ray of permutation `P` (see
/// [`WatertightRay::permutation`]): the same operations, with the axes as
/// constants, so each coordinate is read directly. A run-time index into
/// the coordinates goes through memory (a store and a load per
/// coordinate); a traversal compiled for one permutation (see
/// `Mesh::any_hit`) does without. Crate-private: a ray of another
/// permutation would get a wrong answer (checked in debug builds only);
/// [`triangle_hit_dispatched`] is the public form.
#[inline(always)]
pub(crate) fn triangle_hit_as<const P: u8>(
    ray: &WatertightRay,
    corners: [&DVec3; 3],
    t_min: f64,
    t_max: f64,
) -> Option<TriangleHit> {
    debug_assert_eq!(ray.permutation, P);
    permuted_test(ray, AXES[usize::from(P)], corners, t_min, t_max, &mut ())
}

/// [`triangle_hit`] by a branch per test to the form compiled for the
/// ray's permutation (see `triangle_hit_as`). For the rays of a packet
/// tested one by one: they share one permutation as a rule, so the branch
/// goes the same way test after test.
#[inline(always)]
pub fn triangle_hit_dispatched(
    ray: &WatertightRay,
    a: DVec3,
    b: DVec3,
    c: DVec3,
    t_min: f64,
    t_max: f64,
) -> Option<TriangleHit> {
    match ray.permutation {
        0 => triangle_hit_as::<0>(ray, [&a, &b, &c], t_min, t_max),
        1 => triangle_hit_as::<1>(ray, [&a, &b, &c], t_min, t_max),
        2 => triangle_hit_as::<2>(ray, [&a, &b, &c], t_min, t_max),
        3 => triangle_hit_as::<3>(ray, [&a, &b, &c], t_min, t_max),
        4 => triangle_hit_as::<4>(ray, [&a, &b, &c], t_min, t_max),
        _ => triangle_hit_as::<5>(ray, [&a, &b, &c], t_min, t_max),
    }
}

/// The watertight test with the ray's axes given: at run time, or as
/// constants, which the compiler then folds into direct reads.
#[inline(always)]
fn permuted_test<S: Steps>(
    ray: &WatertightRay,
    [kx, ky, kz]: [Axis; 3],
    [a, b, c]: [&DVec3; 3],
    t_min: f64,
    t_max: f64,
    steps: &mut S,
) -> Option<TriangleHit> {
    // The vertices relative to the origin, permuted to (kx, ky, kz): each
    // coordinate read from the vertex by its axis, rather than the vertex
    // read, its difference written out and read back by index.
    // (The origin too: permuted here, not stored so, as the searches read
    // the prepared ray their caller has just written: a pair of its values
    // read as one vector from two scalar stores waits for them to reach
    // the cache.)
    let [ox, oy, oz] = [kx, ky, kz].map(|k| k.of(&ray.origin));
    let permute = |p: &DVec3| (kx.of(p) - ox, ky.of(p) - oy, kz.of(p) - oz);
    let (ax, ay, az) = permute(a);
    let (bx, by, bz) = permute(b);
    let (cx, cy, cz) = permute(c);
    let [kx, ky, kz] = [kx, ky, kz].map(|k| k as usize);
    // Shear the vertices so the ray runs along +z.
    let ax = ax - ray.sx * az;
    let ay = ay - ray.sy * az;
    let bx = bx - ray.sx * bz;
    let by = by - ray.sy * bz;
    let cx = cx - ray.sx * cz;
    let cy = cy - ray.sy * cz;
    // Scaled barycentrics: 2D edge functions.
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    // Signs both ways: the ray passes outside. Non-short-circuit `|` and
    // `&`, so one branch rather than six that mispredict.
    let negative = (u < 0.0) | (v < 0.0) | (w < 0.0);
    let positive = (u > 0.0) | (v > 0.0) | (w > 0.0);
    if negative & positive {
        steps.triangle([kx, ky, kz], DVec3::new(u, v, w), None, None);
        return None;
    }
    let det = u + v + w;
    if det == 0.0 {
        steps.triangle([kx, ky, kz], DVec3::new(u, v, w), Some(det), None);
        return None;
    }
    // Scaled distance, compared before the division.
    let az = ray.sz * az;
    let bz = ray.sz * bz;
    let cz = ray.sz * cz;
    let t_scaled = u * az + v * bz + w * cz;
    let t = t_scaled / det;
    steps.triangle([kx, ky, kz], DVec3::new(u, v, w), Some(det), Some(t));
    if !(t > t_min && t < t_max) {
        return None;
    }
    Some(TriangleHit {
        t,
        barycentric: DVec3::new(u, v, w) / det,
    })
}

/// Up to eight rays prepared for [`triangle_hit_lanes`]: rays whose
/// largest direction component lies on the same axis with the same sign,
/// so that they share the watertight test's axis permutation and each
/// lane's arithmetic is [`triangle_hit`]'s for that ray.
#[derive(Clone, Copy, Debug)]
pub struct WatertightLanes {
    /// The origins' coordinates on axes kx, ky, kz, lane by lane.
    origin: [[f64; LANES]; 3],
    sx: [f64; LANES],
    sy: [f64; LANES],
    sz: [f64; LANES],
    /// The shared permutation.
    axes: [usize; 3],
}

/// Rays per [`WatertightLanes`].
pub const LANES: usize = 8;

impl WatertightLanes {
    /// The lanes of `rays` (lanes past the last repeat ray 0), or `None`
    /// when the rays do not share one permutation.
    #[inline(always)]
    pub fn new(rays: &[WatertightRay; LANES]) -> Option<Self> {
        let first = &rays[0];
        let axes = first.axes.map(|k| k as usize);
        let mut lanes = WatertightLanes {
            origin: [[0.0; LANES]; 3],
            sx: [0.0; LANES],
            sy: [0.0; LANES],
            sz: [0.0; LANES],
            axes,
        };
        // Loops and `&`, not `map` and `any`: this runs once per packet.
        let mut shared = true;
        for (k, r) in rays.iter().enumerate() {
            shared &= r.axes == first.axes;
            for (row, axis) in lanes.origin.iter_mut().zip(r.axes) {
                row[k] = axis.of(&r.origin);
            }
            (lanes.sx[k], lanes.sy[k], lanes.sz[k]) = (r.sx, r.sy, r.sz);
        }
        shared.then_some(lanes)
    }
}

/// What [`triangle_hit_lanes`] finds: a mask of the lanes that hit, and
/// each lane's scaled barycentrics, their sum and the distance (meaningful
/// only in a lane that hits).
#[derive(Clone, Copy, Debug)]
pub struct LaneHits {
    /// Bit k set when lane k hits with t in (`t_min`, `t_max[k]`).
    pub mask: u32,
    u: [f64; LANES],
    v: [f64; LANES],
    w: [f64; LANES],
    det: [f64; LANES],
    t: [f64; LANES],
}

impl LaneHits {
    /// Lane `k`'s hit, as [`triangle_hit`] gives it for that ray.
    #[inline(always)]
    pub fn hit(&self, k: usize) -> TriangleHit {
        TriangleHit {
            t: self.t[k],
            barycentric: DVec3::new(self.u[k], self.v[k], self.w[k]) / self.det[k],
        }
    }
}

/// [`triangle_hit`] of triangle (a, b, c) for each lane of `rays` in mask
/// `active`, lane `k` keeping hits with t in (`t_min`, `t_max[k]`): the same
/// operations, lane by lane, in a form the compiler turns into vector code
/// (no early exit: every lane runs to the end and the conditions become a
/// mask), so each lane's answer is the scalar one to the bit.
#[inline(always)]
pub fn triangle_hit_lanes(
    rays: &WatertightLanes,
    active: u32,
    a: DVec3,
    b: DVec3,
    c: DVec3,
    t_min: f64,
    t_max: &[f64; LANES],
) -> LaneHits {
    let [kx, ky, kz] = rays.axes.map(|k| k & 3);
    let pick = |p: DVec3| {
        let p = [p.x, p.y, p.z, 0.0];
        (p[kx], p[ky], p[kz])
    };
    let (a, b, c) = (pick(a), pick(b), pick(c));
    let [ox, oy, oz] = &rays.origin;
    let mut out = LaneHits {
        mask: 0,
        u: [0.0; LANES],
        v: [0.0; LANES],
        w: [0.0; LANES],
        det: [0.0; LANES],
        t: [0.0; LANES],
    };
    let mut hit = [false; LANES];
    for k in 0..LANES {
        let (ax, ay, az) = (a.0 - ox[k], a.1 - oy[k], a.2 - oz[k]);
        let (bx, by, bz) = (b.0 - ox[k], b.1 - oy[k], b.2 - oz[k]);
        let (cx, cy, cz) = (c.0 - ox[k], c.1 - oy[k], c.2 - oz[k]);
        let (sx, sy, sz) = (rays.sx[k], rays.sy[k], rays.sz[k]);
        let ax = ax - sx * az;
        let ay = ay - sy * az;
        let bx = bx - sx * bz;
        let by = by - sy * bz;
        let cx = cx - sx * cz;
        let cy = cy - sy * cz;
        let u = cx * by - cy * bx;
        let v = ax * cy - ay * cx;
        let w = bx * ay - by * ax;
        let negative = (u < 0.0) | (v < 0.0) | (w < 0.0);
        let positive = (u > 0.0) | (v > 0.0) | (w > 0.0);
        let det = u + v + w;
        let t_scaled = u * (sz * az) + v * (sz * bz) + w * (sz * cz);
        let t = t_scaled / det;
        hit[k] = !(negative & positive) & (det != 0.0) & (t > t_min) & (t < t_max[k]);
        out.u[k] = u;
        out.v[k] = v;
        out.w[k] = w;
        out.det[k] = det;
        out.t[k] = t;
    }
    for (k, &h) in hit.iter().enumerate() {
        out.mask |= u32::from(h) << k;
    }
    out.mask &= active;
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::PixelRng;

    fn hit(o: DVec3, d: DVec3, tri: [DVec3; 3]) -> Option<TriangleHit> {
        triangle_hit(
            &WatertightRay::new(o, d),
            tri[0],
            tri[1],
            tri[2],
            0.0,
            f64::INFINITY,
        )
    }

    #[test]
    fn each_permutation_is_the_textbook_choice_of_axes() {
        // Woop et al.: kz the largest |component| (the first on ties), kx
        // and ky the next two in cyclic order, swapped where d[kz] < 0.
        let mut corners = PixelRng::new(41, 0, 0);
        let mut seen = [false; 6];
        let special = [
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(-1.0, 1.0, 0.0),
            DVec3::new(0.0, -2.0, 2.0),
            DVec3::new(-0.0, 0.0, -3.0),
        ];
        let mut directions = PixelRng::new(43, 0, 0);
        let random = (0..2000).map(|_| {
            DVec3::new(
                directions.uniform(),
                directions.uniform(),
                directions.uniform(),
            ) * 2.0
                - DVec3::ONE
        });
        for d in special.into_iter().chain(random) {
            let ray = WatertightRay::new(DVec3::ZERO, d);
            let a = d.abs().to_array();
            let kz = (0..3).fold(0, |k, i| if a[i] > a[k] { i } else { k });
            let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
            if d[kz] < 0.0 {
                std::mem::swap(&mut kx, &mut ky);
            }
            assert_eq!(ray.axes.map(|k| k as usize), [kx, ky, kz], "{d}");
            let p = usize::from(ray.permutation());
            assert_eq!(AXES[p].map(|k| k as usize), [kx, ky, kz], "{d}");
            seen[p] = true;
            // The test compiled for the ray's permutation is the one that
            // reads it at run time.
            let tri = [
                DVec3::new(corners.uniform(), corners.uniform(), corners.uniform()),
                DVec3::new(corners.uniform(), corners.uniform(), corners.uniform()),
                DVec3::new(corners.uniform(), corners.uniform(), corners.uniform()),
            ]
            .map(|v| v * 2.0 - DVec3::ONE + d);
            let any = triangle_hit(&ray, tri[0], tri[1], tri[2], 0.0, f64::INFINITY);
            let fixed = match p {
                0 => triangle_hit_as::<0>,
                1 => triangle_hit_as::<1>,
                2 => triangle_hit_as::<2>,
                3 => triangle_hit_as::<3>,
                4 => triangle_hit_as::<4>,
                _ => triangle_hit_as::<5>,
            }(&ray, [&tri[0], &tri[1], &tri[2]], 0.0, f64::INFINITY);
            assert_eq!(any, fixed, "{d}");
            let at = triangle_hit_at(&ray, [&tri[0], &tri[1], &tri[2]], 0.0, f64::INFINITY);
            assert_eq!(any, at, "{d}");
            let dispatched =
                triangle_hit_dispatched(&ray, tri[0], tri[1], tri[2], 0.0, f64::INFINITY);
            assert_eq!(any, dispatched, "{d}");
        }
        assert!(seen.iter().all(|&s| s));
    }

    #[test]
    fn hand_worked_hit_and_barycentrics() {
        let tri = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let h = hit(DVec3::new(0.25, 0.5, 2.0), -DVec3::Z, tri).unwrap();
        assert!((h.t - 2.0).abs() < 1e-15);
        // Point = 0.25·a + 0.25·b + 0.5·c.
        assert!((h.barycentric - DVec3::new(0.25, 0.25, 0.5)).length() < 1e-15);
        // From behind too.
        assert!(hit(DVec3::new(0.25, 0.5, -2.0), DVec3::Z, tri).is_some());
        // Outside, parallel, behind the origin.
        assert!(hit(DVec3::new(0.75, 0.5, 2.0), -DVec3::Z, tri).is_none());
        assert!(hit(DVec3::new(0.25, 0.25, 1.0), DVec3::X, tri).is_none());
        assert!(hit(DVec3::new(0.25, 0.25, 1.0), DVec3::Z, tri).is_none());
    }

    /// An octahedron: closed, every edge shared by two triangles, every
    /// vertex by four.
    fn octahedron() -> Vec<[DVec3; 3]> {
        let p = [
            DVec3::X,
            DVec3::Y,
            DVec3::Z,
            -DVec3::X,
            -DVec3::Y,
            -DVec3::Z,
        ];
        let faces = [
            [0, 1, 2],
            [1, 3, 2],
            [3, 4, 2],
            [4, 0, 2],
            [1, 0, 5],
            [3, 1, 5],
            [4, 3, 5],
            [0, 4, 5],
        ];
        faces.iter().map(|f| [p[f[0]], p[f[1]], p[f[2]]]).collect()
    }

    #[test]
    fn rays_at_shared_edges_and_vertices_never_slip_through() {
        let mesh = octahedron();
        let mut rng = PixelRng::new(13, 0, 0);
        let mut targets = vec![
            DVec3::X,
            DVec3::Y,
            DVec3::Z,
            -DVec3::X,
            -DVec3::Y,
            -DVec3::Z,
        ];
        // Points exactly on edges (midpoints and random points).
        for tri in &mesh {
            for i in 0..3 {
                let (p, q) = (tri[i], tri[(i + 1) % 3]);
                targets.push(0.5 * (p + q));
                let s = rng.uniform();
                targets.push(p + s * (q - p));
            }
        }
        for target in targets {
            let mut tried = 0;
            while tried < 20 {
                // From a random point outside, aimed at the target, keeping
                // rays that enter the solid there (not ones that graze it).
                let dir = DVec3::new(
                    rng.uniform() - 0.5,
                    rng.uniform() - 0.5,
                    rng.uniform() - 0.5,
                )
                .normalize();
                let origin = target + 5.0 * dir;
                let beyond = target + 1e-6 * (target - origin);
                if beyond.abs().element_sum() >= 1.0 {
                    continue;
                }
                tried += 1;
                let ray = WatertightRay::new(origin, target - origin);
                let hits = mesh
                    .iter()
                    .filter_map(|t| triangle_hit(&ray, t[0], t[1], t[2], 0.0, f64::INFINITY))
                    .count();
                assert!(hits >= 1, "ray at {target} from {origin} slipped through");
            }
        }
    }

    #[test]
    fn random_hits_match_a_plane_reference() {
        let mut rng = PixelRng::new(17, 0, 0);
        let mut u = || rng.uniform() * 2.0 - 1.0;
        let mut hits = 0;
        for _ in 0..20_000 {
            let tri = [
                DVec3::new(u(), u(), u()),
                DVec3::new(u(), u(), u()),
                DVec3::new(u(), u(), u()),
            ];
            let o = DVec3::new(u(), u(), u()) * 3.0;
            // Aim near the triangle so that about half the rays hit.
            let w = DVec3::new(u().abs(), u().abs(), u().abs());
            let aim = (w.x * tri[0] + w.y * tri[1] + w.z * tri[2]) / w.element_sum().max(1e-9);
            let d = aim + DVec3::new(u(), u(), u()) * 0.3 - o;
            if let Some(h) = hit(o, d, tri) {
                hits += 1;
                let p = o + h.t * d;
                let from_bary =
                    h.barycentric.x * tri[0] + h.barycentric.y * tri[1] + h.barycentric.z * tri[2];
                assert!((p - from_bary).length() < 1e-9, "{p} vs {from_bary}");
                assert!(h.barycentric.min_element() >= 0.0);
            } else {
                // Reference: plane hit, then inside by signed areas.
                let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
                let denom = n.dot(d);
                if denom.abs() < 1e-12 {
                    continue;
                }
                let t = n.dot(tri[0] - o) / denom;
                if t <= 0.0 {
                    continue;
                }
                let p = o + t * d;
                let inside = (0..3).all(|i| {
                    let (a, b) = (tri[i], tri[(i + 1) % 3]);
                    (b - a).cross(p - a).dot(n) > 1e-9 * n.length_squared()
                });
                assert!(!inside, "missed an inside point");
            }
        }
        assert!(hits > 5000, "{hits} hits");
    }

    #[test]
    fn lanes_are_the_scalar_test_to_the_bit() {
        // Eight rays sharing a dominant axis against random triangles,
        // aimed inside, at vertices, at edges and beside them, with limits
        // before, at and beyond the surface.
        let mut rng = PixelRng::new(31, 0, 0);
        let mut u = || rng.uniform();
        let mut hits = 0;
        for i in 0..20_000 {
            let scale = [1e-3, 1.0, 1e4][i % 3];
            let tri = [0; 3].map(|_| DVec3::new(u(), u(), u()) * scale);
            let axis = i % 3;
            let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
            let mut rays = [WatertightRay::new(DVec3::ZERO, DVec3::X); LANES];
            let mut t_max = [f64::INFINITY; LANES];
            for (k, ray) in rays.iter_mut().enumerate() {
                let (a, b, c) = (tri[0], tri[1], tri[2]);
                let target = match k % 4 {
                    0 => a,
                    1 => a + (b - a) * u(),
                    2 => a * 0.2 + b * 0.3 + c * 0.5,
                    _ => a + (c - a) * 0.5 + DVec3::splat(1e-9 * scale),
                };
                let mut offset = DVec3::new(u() - 0.5, u() - 0.5, u() - 0.5) * 0.5;
                offset[axis] = sign * (1.0 + u());
                let origin = target + offset * scale * 3.0;
                *ray = WatertightRay::new(origin, target - origin);
                t_max[k] = [f64::INFINITY, 1.0, 0.5, 1.0f64.next_up()][(i + k) % 4];
            }
            let Some(lanes) = WatertightLanes::new(&rays) else {
                continue;
            };
            let active = if i % 7 == 0 { 0b1011_0110 } else { 0xff };
            let found = triangle_hit_lanes(&lanes, active, tri[0], tri[1], tri[2], 1e-12, &t_max);
            for k in 0..LANES {
                let alone = triangle_hit(&rays[k], tri[0], tri[1], tri[2], 1e-12, t_max[k]);
                let lane = (found.mask >> k & 1 == 1).then(|| found.hit(k));
                let expected = alone.filter(|_| active >> k & 1 == 1);
                assert_eq!(
                    lane.map(|h| (h.t.to_bits(), h.barycentric.to_array().map(f64::to_bits))),
                    expected.map(|h| (h.t.to_bits(), h.barycentric.to_array().map(f64::to_bits))),
                    "case {i}, lane {k}"
                );
                hits += usize::from(lane.is_some());
            }
        }
        assert!(hits > 50_000, "{hits}");
    }
}
