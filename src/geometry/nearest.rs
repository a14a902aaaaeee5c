//! The point of a triangle nearest a given point: the closest-point query
//! of the ray scene (`RayScene::closest_points`), one triangle at a time.
//!
//! The plane of the triangle splits into seven regions by which feature
//! is nearest: the face, one of three edges, one of three vertices. The
//! point's region is found from dot products with the edges (Ericson,
//! *Real-Time Collision Detection*, §5.1.5), each answer a convex
//! combination of the corners, so it lies on the triangle whatever the
//! rounding. A degenerate triangle (its corners on a line or a point) has
//! no face region; its nearest point is the nearest of its three edges'.

use glam::DVec3;

/// A triangle's point nearest some point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NearestOnTriangle {
    /// The point: (1 − u − v)·a + u·b + v·c.
    pub point: DVec3,
    /// Barycentric weight of the second corner.
    pub u: f64,
    /// Barycentric weight of the third corner.
    pub v: f64,
    /// Squared distance from the point asked about.
    pub distance_squared: f64,
}

/// The point of triangle `[a, b, c]` nearest `p`.
#[inline]
pub fn nearest_on_triangle(p: DVec3, [a, b, c]: [DVec3; 3]) -> NearestOnTriangle {
    let (u, v) = nearest_weights(p, [a, b, c]);
    let point = a + (b - a) * u + (c - a) * v;
    NearestOnTriangle {
        point,
        u,
        v,
        distance_squared: (p - point).length_squared(),
    }
}

/// The barycentric weights (of b and c) of the point of `[a, b, c]`
/// nearest `p`, by region.
#[inline]
fn nearest_weights(p: DVec3, [a, b, c]: [DVec3; 3]) -> (f64, f64) {
    let (ab, ac) = (b - a, c - a);
    // Beyond a: both edges from a point away from p.
    let ap = p - a;
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return (0.0, 0.0);
    }
    // Beyond b.
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return (1.0, 0.0);
    }
    // Over edge ab: p's projection falls between a and b, outside the face.
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return (fraction(d1, d1 - d3), 0.0);
    }
    // Beyond c.
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return (0.0, 1.0);
    }
    // Over edge ac.
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return (0.0, fraction(d2, d2 - d6));
    }
    // Over edge bc.
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        let w = fraction(d4 - d3, (d4 - d3) + (d5 - d6));
        return (1.0 - w, w);
    }
    // Over the face: the weights are its sub-areas, positive unless the
    // triangle is degenerate (then every region test above may fail to
    // rounding, and the nearest edge decides).
    let area = va + vb + vc;
    if area > 0.0 && area.is_finite() {
        let (u, v) = (vb / area, vc / area);
        if u >= 0.0 && v >= 0.0 && u + v <= 1.0 {
            return (u, v);
        }
    }
    nearest_on_edges(p, [a, b, c])
}

/// `part / whole` clamped to [0, 1], 0 where the whole is 0 (an edge of
/// zero length).
#[inline]
fn fraction(part: f64, whole: f64) -> f64 {
    if whole > 0.0 {
        (part / whole).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// The weights of the nearest point to `p` on the three edges of
/// `[a, b, c]` (for a degenerate triangle): the first edge's of those
/// equally near.
fn nearest_on_edges(p: DVec3, [a, b, c]: [DVec3; 3]) -> (f64, f64) {
    let on_segment = |from: DVec3, to: DVec3| {
        let e = to - from;
        fraction((p - from).dot(e), e.length_squared())
    };
    let s = on_segment(a, b);
    let t = on_segment(a, c);
    let r = on_segment(b, c);
    let candidates = [(s, 0.0), (0.0, t), (1.0 - r, r)];
    let distance = |(u, v): (f64, f64)| (p - (a + (b - a) * u + (c - a) * v)).length_squared();
    let mut best = candidates[0];
    for &w in &candidates[1..] {
        if distance(w) < distance(best) {
            best = w;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::PixelRng;

    const A: DVec3 = DVec3::new(0.0, 0.0, 0.0);
    const B: DVec3 = DVec3::new(2.0, 0.0, 0.0);
    const C: DVec3 = DVec3::new(0.0, 2.0, 0.0);

    #[test]
    fn each_region_by_hand() {
        let near = |p: [f64; 3]| nearest_on_triangle(DVec3::from_array(p), [A, B, C]);
        // Over the face: straight down, weights from the coordinates.
        let h = near([0.5, 0.25, 3.0]);
        assert_eq!(
            (h.point, h.u, h.v),
            (DVec3::new(0.5, 0.25, 0.0), 0.25, 0.125)
        );
        assert_eq!(h.distance_squared, 9.0);
        // Beyond each corner.
        assert_eq!(near([-1.0, -1.0, 0.0]).point, A);
        assert_eq!(near([3.0, -1.0, 1.0]).point, B);
        assert_eq!(near([-0.5, 3.0, 0.0]).point, C);
        assert_eq!(
            (near([3.0, -1.0, 1.0]).u, near([3.0, -1.0, 1.0]).v),
            (1.0, 0.0)
        );
        // Over edge ab (below the x axis), ac (left of the y axis) and the
        // hypotenuse bc.
        let h = near([1.5, -2.0, 0.0]);
        assert_eq!(
            (h.point, h.u, h.v, h.distance_squared),
            (DVec3::new(1.5, 0.0, 0.0), 0.75, 0.0, 4.0)
        );
        let h = near([-3.0, 0.5, 4.0]);
        assert_eq!(
            (h.point, h.u, h.v, h.distance_squared),
            (DVec3::new(0.0, 0.5, 0.0), 0.0, 0.25, 25.0)
        );
        let h = near([2.0, 2.0, 0.0]);
        assert_eq!(
            (h.point, h.u, h.v, h.distance_squared),
            (DVec3::new(1.0, 1.0, 0.0), 0.5, 0.5, 2.0)
        );
    }

    #[test]
    fn degenerate_triangles_give_their_nearest_edge_point() {
        // Corners on a line, and all three at one point.
        let line = [A, DVec3::new(1.0, 0.0, 0.0), B];
        let h = nearest_on_triangle(DVec3::new(1.5, 1.0, 0.0), line);
        assert_eq!(
            (h.point, h.distance_squared),
            (DVec3::new(1.5, 0.0, 0.0), 1.0)
        );
        let h = nearest_on_triangle(DVec3::new(5.0, 1.0, 0.0), line);
        assert_eq!(h.point, B);
        let dot = [C, C, C];
        let h = nearest_on_triangle(DVec3::new(1.0, 2.0, 0.0), dot);
        assert_eq!((h.point, h.distance_squared), (C, 1.0));
    }

    /// Against the minimum over a dense grid of the triangle's points, and
    /// the optimality condition: no point of the triangle is nearer.
    #[test]
    fn no_point_of_the_triangle_is_nearer_on_random_inputs() {
        let mut rng = PixelRng::new(0x5eed_7a11, 0, 0);
        let mut v = || DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 4.0 - 2.0;
        for _ in 0..2000 {
            let tri = [v(), v(), v()];
            let p = v() * 1.5;
            let h = nearest_on_triangle(p, tri);
            assert!(h.u >= 0.0 && h.v >= 0.0 && h.u + h.v <= 1.0 + 1e-12);
            let [a, b, c] = tri;
            let q = a + (b - a) * h.u + (c - a) * h.v;
            assert!((q - h.point).length() < 1e-12);
            let n = 40;
            for i in 0..=n {
                for j in 0..=n - i {
                    let (s, t) = (f64::from(i) / f64::from(n), f64::from(j) / f64::from(n));
                    let x = a + (b - a) * s + (c - a) * t;
                    assert!(
                        (p - x).length_squared() >= h.distance_squared - 1e-9,
                        "{tri:?} {p:?}: {x:?} nearer than {:?}",
                        h.point
                    );
                }
            }
            // Moving along the triangle from the answer gets no nearer
            // (first-order): (p − q)·(x − q) ≤ 0 for every corner x.
            for x in tri {
                assert!((p - h.point).dot(x - h.point) <= 1e-9 * (1.0 + (p - h.point).length()));
            }
        }
    }
}
