//! A conservative f32 filter in front of the exact watertight test: a
//! mesh's triangles in BVH leaf order, in f32, four tested at once by the
//! same sheared edge functions as [`triangle_hit`](super::triangle::triangle_hit),
//! each widened by a proven bound on how far the f32 value can lie from the
//! value the f64 test computes. A triangle the filter rejects has, in the
//! f64 test, one edge function certainly negative and another certainly
//! positive, so the f64 test rejects it too; survivors go to the f64 test
//! in their usual order. The hit, and so every bit of an image, is the
//! same with the filter or without it (`PRISM_TRIFILTER=off`).
//!
//! ## The bound
//!
//! With u = 2⁻²⁴, T ≥ |vertex coordinate| + |origin coordinate| on every
//! axis, and |Sx|, |Sy| ≤ 1 (the shear divides by the largest direction
//! component), each sheared coordinate (ax = a_kx − Sx·a_kz with
//! a = A − O) comes out of the f32 chain (four roundings to f32 of the
//! inputs, a subtraction, a product, a subtraction) within 8.1·u·T of the
//! real value from the f64 inputs, and the f64 chain within 8·2⁻⁵³·T of it:
//! e = 10·u·T bounds the f32-to-f64 distance. An edge function
//! U = cx·by − cy·bx then differs between the two chains by at most
//! 2.01·u·2M² (the f32 roundings of two products and a difference) +
//! e·(4M + 2e) (the inputs' distance) + 2⁻⁵⁰·(M + e)² (the f64 roundings),
//! where M is the largest |sheared coordinate| in f32. The filter uses
//! E = 8uM² + 8eM + 4e² + 2⁻⁹⁰, about twice that, with an absolute term far
//! above any f32 underflow error (≤ 2⁻¹⁵⁰ per operation; e also carries
//! 2⁻¹⁰⁰). A lane with T > 2⁶⁰ (where M² could overflow), or any NaN on
//! the way, is never rejected.

use glam::{DVec3, Vec4};

use super::triangle::WatertightRay;

/// Sections of the data, each one float per triangle: a, b, c (x, y, z
/// each), then the largest |coordinate| rounded up.
const SECTIONS: usize = 10;
/// Floats of padding after each section, so that four floats can be
/// loaded from any triangle position.
const PAD: usize = 3;
/// f32 unit roundoff.
const U: f32 = 1.0 / 16_777_216.0;

/// The smallest f32 ≥ `x` (x ≥ 0; infinity above f32's range).
fn round_up(x: f64) -> f32 {
    let r = x as f32;
    if f64::from(r) < x {
        f32::from_bits(r.to_bits() + 1)
    } else {
        r
    }
}

/// A mesh's triangles in f32, in leaf order, structure of arrays: four
/// consecutive triangles' x coordinates of vertex a are one load.
#[derive(Clone, Debug, PartialEq)]
pub struct TriangleFilter {
    data: Vec<f32>,
    /// Floats per section (triangles + `PAD`).
    section: usize,
}

/// A ray prepared for the filter.
#[derive(Clone, Copy, Debug)]
pub struct FilterRay {
    /// Origin coordinates on axes kx, ky, kz.
    ox: Vec4,
    oy: Vec4,
    oz: Vec4,
    kx: usize,
    ky: usize,
    kz: usize,
    sx: Vec4,
    sy: Vec4,
    /// Largest |origin coordinate|, rounded up.
    omax: Vec4,
}

impl FilterRay {
    /// The filter's view of `ray`.
    pub fn new(ray: &WatertightRay) -> Self {
        let (origin, [kx, ky, kz], sx, sy) = ray.parts();
        FilterRay {
            ox: Vec4::splat(origin[kx] as f32),
            oy: Vec4::splat(origin[ky] as f32),
            oz: Vec4::splat(origin[kz] as f32),
            kx,
            ky,
            kz,
            sx: Vec4::splat(sx as f32),
            sy: Vec4::splat(sy as f32),
            omax: Vec4::splat(round_up(origin.abs().max_element())),
        }
    }
}

impl TriangleFilter {
    /// The filter for triangles given by their corners, in leaf order.
    pub fn new(corners: impl ExactSizeIterator<Item = [DVec3; 3]>) -> Self {
        let section = corners.len() + PAD;
        let mut data = vec![0.0; section * SECTIONS];
        for (position, tri) in corners.enumerate() {
            for (v, p) in tri.iter().enumerate() {
                for axis in 0..3 {
                    data[(3 * v + axis) * section + position] = p[axis] as f32;
                }
            }
            let m = tri
                .iter()
                .map(|p| p.abs().max_element())
                .fold(0.0, f64::max);
            data[9 * section + position] = round_up(m);
        }
        TriangleFilter { data, section }
    }

    /// Heap memory in bytes.
    pub fn memory_bytes(&self) -> usize {
        self.data.len() * 4
    }

    /// Section `section` from position `start`, four floats.
    #[inline(always)]
    fn load(&self, section: usize, start: usize) -> Vec4 {
        Vec4::from_slice(&self.data[section * self.section + start..])
    }

    /// Vertex `v` of the four triangles from `start`, sheared: one load per
    /// coordinate, the ray's axes picked by address.
    #[inline(always)]
    fn sheared(&self, ray: &FilterRay, v: usize, start: usize) -> (Vec4, Vec4) {
        let z = self.load(3 * v + ray.kz, start) - ray.oz;
        (
            (self.load(3 * v + ray.kx, start) - ray.ox) - ray.sx * z,
            (self.load(3 * v + ray.ky, start) - ray.oy) - ray.sy * z,
        )
    }

    /// Of the `count` (1 to 4) triangles from position `start`, those the
    /// exact test might hit, as a bit mask (bit i: position start + i).
    #[inline(always)]
    pub fn survivors(&self, ray: &FilterRay, start: usize, count: usize) -> u32 {
        let (ax, ay) = self.sheared(ray, 0, start);
        let (bx, by) = self.sheared(ray, 1, start);
        let (cx, cy) = self.sheared(ray, 2, start);
        let u = cx * by - cy * bx;
        let v = ax * cy - ay * cx;
        let w = bx * ay - by * ax;
        let m = ax
            .abs()
            .max(ay.abs())
            .max(bx.abs())
            .max(by.abs())
            .max(cx.abs())
            .max(cy.abs());
        let t = self.load(9, start) + ray.omax;
        let e = t * (10.0 * U) + Vec4::splat(2f32.powi(-100));
        let err = m * m * (8.0 * U) + e * m * 8.0 + e * e * 4.0 + Vec4::splat(2f32.powi(-90));
        let neg = u.cmplt(-err) | v.cmplt(-err) | w.cmplt(-err);
        let pos = u.cmpgt(err) | v.cmpgt(err) | w.cmpgt(err);
        let reject = neg & pos & t.cmple(Vec4::splat(2f32.powi(60)));
        !reject.bitmask() & ((1 << count) - 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::triangle::triangle_hit;
    use crate::math::rng::PixelRng;

    /// The filter never rejects a triangle the exact test hits: random
    /// triangles at several scales and distances, rays aimed at random
    /// inside points, exactly at edges and vertices, and a hair beside
    /// them, with a check that it does reject most misses.
    #[test]
    fn never_rejects_an_exact_hit() {
        let mut rng = PixelRng::new(41, 0, 0);
        let mut r = || rng.uniform() * 2.0 - 1.0;
        let (mut hits, mut misses, mut rejected) = (0u64, 0u64, 0u64);
        for round in 0..40_000 {
            let scale = [1e-3, 1.0, 7.0, 1e3, 1e6][round % 5];
            let offset = [0.0, 1.0, 100.0, 1e4][(round / 5) % 4] * scale;
            let centre = DVec3::new(r(), r(), r()) * offset;
            let tris: Vec<[DVec3; 3]> = (0..4)
                .map(|_| {
                    let p = centre + DVec3::new(r(), r(), r()) * scale;
                    [
                        p,
                        p + DVec3::new(r(), r(), r()) * scale * 0.1,
                        p + DVec3::new(r(), r(), r()) * scale * 0.1,
                    ]
                })
                .collect();
            let filter = TriangleFilter::new(tris.iter().copied());
            let tri = tris[round % 4];
            let (s, t) = (r().abs(), r().abs());
            let target = match (round / 20) % 5 {
                // Inside.
                0 => tri[0] + (s * (tri[1] - tri[0]) + t * (tri[2] - tri[0])) * 0.5,
                // Exactly on an edge, or at a vertex.
                1 => tri[round % 3] + s * (tri[(round + 1) % 3] - tri[round % 3]),
                2 => tri[round % 3],
                // A hair beside an edge.
                3 => {
                    tri[round % 3]
                        + s * (tri[(round + 1) % 3] - tri[round % 3])
                        + DVec3::new(r(), r(), r()) * scale * 1e-7
                }
                _ => centre + DVec3::new(r(), r(), r()) * scale,
            };
            let origin = target + DVec3::new(r(), r(), r()) * scale * [0.5, 5.0, 1e3][round % 3];
            let direction = target - origin;
            let ray = WatertightRay::new(origin, direction);
            let fray = FilterRay::new(&ray);
            for count in 1..=4 {
                let mask = filter.survivors(&fray, 0, count);
                assert_eq!(mask >> count, 0);
                for (i, t) in tris.iter().enumerate().take(count) {
                    let hit =
                        triangle_hit(&ray, t[0], t[1], t[2], f64::NEG_INFINITY, f64::INFINITY);
                    if count == 4 {
                        if hit.is_some() {
                            hits += 1;
                        } else {
                            misses += 1;
                            rejected += u64::from(mask & (1 << i) == 0);
                        }
                    }
                    assert!(
                        hit.is_none() || mask & (1 << i) != 0,
                        "round {round}: rejected a hit of {t:?} by {origin} + t·{direction}"
                    );
                }
            }
            // The same triangles from a later position in the array.
            let mut more = vec![tris[3]; 5];
            more.extend(&tris);
            let later = TriangleFilter::new(more.into_iter());
            assert_eq!(later.survivors(&fray, 5, 4), filter.survivors(&fray, 0, 4));
        }
        assert!(hits > 20_000, "{hits} hits");
        assert!(
            rejected * 10 > misses * 7,
            "rejected {rejected} of {misses} misses"
        );
    }

    #[test]
    fn huge_coordinates_and_bad_rays_are_let_through() {
        let tri = [
            DVec3::splat(1e30),
            DVec3::new(2e30, 1e30, 1e30),
            DVec3::new(1e30, 2e30, 1e30),
        ];
        let filter = TriangleFilter::new([tri; 4].into_iter());
        let ray = WatertightRay::new(DVec3::ZERO, DVec3::new(-1.0, 0.3, 0.1));
        assert_eq!(filter.survivors(&FilterRay::new(&ray), 0, 4), 0b1111);
        let small = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let filter = TriangleFilter::new([small; 4].into_iter());
        for (o, d) in [
            (DVec3::splat(f64::NAN), DVec3::Z),
            (DVec3::new(5.0, 5.0, 1.0), DVec3::ZERO),
            (DVec3::new(5.0, 5.0, 1e300), -DVec3::Z),
        ] {
            let ray = WatertightRay::new(o, d);
            assert_eq!(
                filter.survivors(&FilterRay::new(&ray), 0, 3),
                0b111,
                "{o} {d}"
            );
        }
        // A plain miss is rejected.
        let ray = WatertightRay::new(DVec3::new(5.0, 5.0, 1.0), -DVec3::Z);
        assert_eq!(filter.survivors(&FilterRay::new(&ray), 0, 4), 0);
    }
}
