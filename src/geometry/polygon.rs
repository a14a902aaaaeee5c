//! Planar polygons: the ray meets the polygon's plane, then the hit is
//! tested against the outline by the Jordan curve theorem (lecture notes,
//! "Ray Polygon Intersections").

use glam::{DVec2, DVec3};
use thiserror::Error;

use super::plane::plane_hit_steps;
use super::steps::{EdgeCase, Steps};
use super::{Aabb, Plane, ShapeHit};
use crate::math::Ray;

/// Why a vertex list is not a usable polygon.
#[derive(Debug, Error, PartialEq)]
pub enum PolygonError {
    /// Fewer than three vertices.
    #[error("a polygon needs at least 3 vertices, got {0}")]
    TooFewVertices(usize),
    /// A non-finite coordinate.
    #[error("vertex {0} is not finite")]
    NotFinite(usize),
    /// Two neighbouring vertices coincide (a zero-length edge).
    #[error("vertices {0} and {1} coincide (a zero-length edge)")]
    RepeatedVertex(usize, usize),
    /// All vertices on one line (or one point): no area, no normal.
    #[error("the vertices are collinear: the polygon has zero area")]
    ZeroArea,
    /// A coordinate outside the supported range.
    #[error("vertex {0} lies outside the supported range (coordinates within ±{max:e})", max = crate::limits::MAX_COORDINATE)]
    OutOfRange(usize),
    /// A vertex lies off the polygon's plane.
    #[error(
        "vertex {vertex} lies {distance:.3e} off the polygon's plane (tolerance {tolerance:.3e})"
    )]
    NotPlanar {
        /// Index of the worst vertex.
        vertex: usize,
        /// Its distance from the plane.
        distance: f64,
        /// The allowed distance, relative to the polygon's size.
        tolerance: f64,
    },
}

/// Vertices closer than this fraction of the polygon's size coincide.
const REPEAT_TOLERANCE: f64 = 1e-9;
/// Vertices further than this fraction of the size from the plane make the
/// polygon non-planar.
const PLANARITY_TOLERANCE: f64 = 1e-6;

/// A planar polygon, convex or concave, with its projection precomputed.
#[derive(Clone, Debug, PartialEq)]
pub struct Polygon {
    /// The supporting plane (normal by Newell's method, following the
    /// vertex order counter-clockwise).
    pub plane: Plane,
    /// The dropped (principal) axis: 0, 1 or 2 for x, y, z.
    pub principal_axis: usize,
    /// Vertices projected along the principal axis.
    projected: Box<[DVec2]>,
    /// The 3D vertices, kept for bounds and transforms.
    vertices: Box<[DVec3]>,
}

/// Newell's method: the polygon normal as the sum over edges of
/// (yᵢ − yⱼ)(zᵢ + zⱼ), (zᵢ − zⱼ)(xᵢ + xⱼ), (xᵢ − xⱼ)(yᵢ + yⱼ), j = i + 1.
/// Its length is twice the area; it is robust for concave and nearly
/// degenerate polygons where one cross product is not.
pub fn newell_normal(vertices: &[DVec3]) -> DVec3 {
    let mut n = DVec3::ZERO;
    for (i, a) in vertices.iter().enumerate() {
        let b = vertices[(i + 1) % vertices.len()];
        n += DVec3::new(
            (a.y - b.y) * (a.z + b.z),
            (a.z - b.z) * (a.x + b.x),
            (a.x - b.x) * (a.y + b.y),
        );
    }
    n
}

/// The normal of the largest triangle of vertices found in linear time:
/// from vertex 0, the vertex b farthest from it, then the vertex c farthest
/// from the line through both; (b − a) × (c − a). Unlike the Newell sum it
/// does not cancel for self-intersecting outlines (a bow-tie's two lobes
/// have opposite signed areas), so it gives the plane of any outline that
/// is not collinear.
pub fn widest_triangle_normal(vertices: &[DVec3]) -> DVec3 {
    let a = vertices[0];
    let b = vertices
        .iter()
        .copied()
        .max_by(|p, q| {
            (*p - a)
                .length_squared()
                .total_cmp(&(*q - a).length_squared())
        })
        .unwrap_or(a);
    let ab = b - a;
    vertices
        .iter()
        .map(|&c| ab.cross(c - a))
        .max_by(|m, n| m.length_squared().total_cmp(&n.length_squared()))
        .unwrap_or(DVec3::ZERO)
}

/// The polygon's plane normal (unnormalised): the Newell sum, which is
/// exact and orientation-true for simple outlines; but where the net signed
/// area it measures is small beside the widest vertex triangle (a
/// self-intersecting outline whose lobes nearly cancel), its direction is
/// mostly rounding, and the triangle's normal is used, turned to agree with
/// the Newell sum's side where that has one.
pub fn robust_normal(vertices: &[DVec3]) -> DVec3 {
    let newell = newell_normal(vertices);
    let triangle = widest_triangle_normal(vertices);
    if newell.length() >= 0.25 * triangle.length() {
        newell
    } else if newell.dot(triangle) < 0.0 {
        -triangle
    } else {
        triangle
    }
}

/// The principal axis: the index of the normal's largest |component|.
/// Projecting along it preserves the polygon's topology and loses the least
/// area. For n = [0.2, 0.96, 0.3] it is y (1): project onto the zx plane.
pub fn principal_axis(normal: DVec3) -> usize {
    let a = normal.abs();
    if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    }
}

/// Drops `axis` from `p`, keeping the other two coordinates in cyclic order
/// (x → (y, z), y → (z, x), z → (x, y)) so the projection keeps handedness.
#[inline]
pub fn project(p: DVec3, axis: usize) -> DVec2 {
    match axis {
        0 => DVec2::new(p.y, p.z),
        1 => DVec2::new(p.z, p.x),
        _ => DVec2::new(p.x, p.y),
    }
}

/// Where the edge (u1, v1)–(u2, v2) meets the u axis:
/// u_int = u1 − v1·(u2 − u1)/(v2 − v1).
#[inline]
pub fn axis_crossing(a: DVec2, b: DVec2) -> f64 {
    a.x - a.y * (b.x - a.x) / (b.y - a.y)
}

/// Counts the edges of the closed outline `vertices` that cross the positive
/// u axis from `point`, after translating `point` to the origin.
///
/// Quick rejects as in the notes: both v positive, both v negative, both u
/// negative. The half-open rule counts v = 0 as negative, so an outline
/// passing exactly through a vertex on the axis crosses it once, not twice.
pub fn crossing_count(point: DVec2, vertices: &[DVec2]) -> usize {
    crossing_count_steps(point, vertices, &mut ())
}

/// [`crossing_count`], telling `steps` each translated edge, its case (in
/// the notes' letters: x along the test axis, z across it) and the count.
#[inline(always)]
pub fn crossing_count_steps<S: Steps>(point: DVec2, vertices: &[DVec2], steps: &mut S) -> usize {
    let mut crossings = 0;
    let mut a = vertices[vertices.len() - 1] - point;
    for &vertex in vertices {
        let b = vertex - point;
        let (a_up, b_up) = (a.y > 0.0, b.y > 0.0);
        if a_up == b_up {
            steps.edge(
                a,
                b,
                if a_up {
                    EdgeCase::BothZPositive
                } else {
                    EdgeCase::BothZNegative
                },
            );
        } else if a.x < 0.0 && b.x < 0.0 {
            steps.edge(a, b, EdgeCase::BothXNegative);
        } else {
            let x_int = axis_crossing(a, b);
            steps.edge(a, b, EdgeCase::Intersects { x_int });
            if x_int > 0.0 {
                crossings += 1;
            }
        }
        a = b;
    }
    steps.crossings(crossings);
    crossings
}

/// Jordan curve theorem: inside when the crossing count is odd.
#[inline]
pub fn point_in_polygon(point: DVec2, vertices: &[DVec2]) -> bool {
    crossing_count(point, vertices) % 2 == 1
}

impl Polygon {
    /// Builds a polygon, checking that the vertices describe one: at least
    /// three, no two neighbours equal, not all collinear, all on one plane.
    /// Linear in the number of vertices.
    pub fn new(vertices: Vec<DVec3>) -> Result<Self, PolygonError> {
        if vertices.len() < 3 {
            return Err(PolygonError::TooFewVertices(vertices.len()));
        }
        if let Some(i) = vertices.iter().position(|v| !v.is_finite()) {
            return Err(PolygonError::NotFinite(i));
        }
        if let Some(i) = vertices
            .iter()
            .position(|v| v.abs().max_element() > crate::limits::MAX_COORDINATE)
        {
            return Err(PolygonError::OutOfRange(i));
        }
        let size = Aabb::from_points(vertices.iter().copied()).diagonal();
        // Neighbours that coincide make a zero-length edge: a vertex typed
        // twice, or the first vertex repeated at the end to "close" the
        // outline. (Coincident vertices that are not neighbours are allowed:
        // outlines that touch themselves, or bridge to a hole, need them.)
        for i in 0..vertices.len() {
            let j = (i + 1) % vertices.len();
            if (vertices[i] - vertices[j]).length() <= REPEAT_TOLERANCE * size {
                return Err(PolygonError::RepeatedVertex(i.min(j), i.max(j)));
            }
        }
        let n = robust_normal(&vertices);
        if n.length() <= 1e-12 * size * size {
            return Err(PolygonError::ZeroArea);
        }
        let normal = n.normalize();
        let centroid = vertices.iter().sum::<DVec3>() / vertices.len() as f64;
        let plane = Plane::through(centroid, normal);
        let tolerance = PLANARITY_TOLERANCE * size;
        let (vertex, distance) = vertices
            .iter()
            .map(|v| plane.signed_distance(*v).abs())
            .enumerate()
            .fold(
                (0, 0.0),
                |best, (i, d)| if d > best.1 { (i, d) } else { best },
            );
        if distance > tolerance {
            return Err(PolygonError::NotPlanar {
                vertex,
                distance,
                tolerance,
            });
        }
        let principal_axis = principal_axis(normal);
        let projected = vertices
            .iter()
            .map(|v| project(*v, principal_axis))
            .collect();
        Ok(Polygon {
            plane,
            principal_axis,
            projected,
            vertices: vertices.into_boxed_slice(),
        })
    }

    /// The vertices in order.
    pub fn vertices(&self) -> &[DVec3] {
        &self.vertices
    }

    /// The bounding box.
    pub fn bounds(&self) -> Aabb {
        Aabb::from_points(self.vertices.iter().copied())
    }

    /// The plane hit, kept only if its projection lies inside the outline.
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<ShapeHit> {
        self.intersect_steps(ray, t_min, t_max, &mut ())
    }

    /// [`intersect`](Self::intersect), telling `steps` each step: the
    /// plane test, the projection along the principal axis, each edge and
    /// the crossing count.
    #[inline(always)]
    pub fn intersect_steps<S: Steps>(
        &self,
        ray: &Ray,
        t_min: f64,
        t_max: f64,
        steps: &mut S,
    ) -> Option<ShapeHit> {
        let h = plane_hit_steps(
            self.plane.normal,
            self.plane.distance,
            ray,
            t_min,
            t_max,
            steps,
        )?;
        let point = ray.at(h.t);
        let p = project(point, self.principal_axis);
        steps.projection(self.principal_axis, point, p);
        // Jordan curve theorem: inside when the count is odd.
        (crossing_count_steps(p, &self.projected, steps) % 2 == 1).then_some(ShapeHit::geometric(
            h.t,
            self.plane.normal,
            !h.back_face,
        ))
    }
}

#[cfg(test)]
#[allow(clippy::disallowed_methods)] // hand-worked values use the platform's functions
mod tests {
    use super::*;
    use crate::math::rng::PixelRng;

    fn square() -> Vec<DVec2> {
        vec![
            DVec2::new(0.0, 0.0),
            DVec2::new(1.0, 0.0),
            DVec2::new(1.0, 1.0),
            DVec2::new(0.0, 1.0),
        ]
    }

    #[test]
    fn principal_axis_of_the_notes_example_is_y() {
        assert_eq!(principal_axis(DVec3::new(0.2, 0.96, 0.3)), 1);
        assert_eq!(principal_axis(DVec3::new(-0.9, 0.1, 0.3)), 0);
        assert_eq!(principal_axis(DVec3::new(0.1, 0.1, -0.99)), 2);
        // y dropped: the projection is onto the zx plane.
        assert_eq!(project(DVec3::new(1.0, 2.0, 3.0), 1), DVec2::new(3.0, 1.0));
    }

    #[test]
    fn axis_crossing_hand_worked() {
        // Edge from (1, -1) to (3, 1) meets v = 0 at u = 2.
        assert_eq!(
            axis_crossing(DVec2::new(1.0, -1.0), DVec2::new(3.0, 1.0)),
            2.0
        );
        // Edge from (-3, 2) to (1, -2) meets v = 0 at u = -1.
        assert_eq!(
            axis_crossing(DVec2::new(-3.0, 2.0), DVec2::new(1.0, -2.0)),
            -1.0
        );
    }

    #[test]
    fn square_inside_and_outside() {
        let s = square();
        assert!(point_in_polygon(DVec2::new(0.5, 0.5), &s));
        assert_eq!(crossing_count(DVec2::new(-0.5, 0.5), &s), 2);
        assert!(!point_in_polygon(DVec2::new(1.5, 0.5), &s));
        assert!(!point_in_polygon(DVec2::new(0.5, 1.5), &s));
    }

    #[test]
    fn axis_through_a_vertex_counts_once() {
        // A diamond whose right vertex (2, 0) lies on the test axis of the
        // centre: without the half-open rule both edges there would count.
        let diamond = [
            DVec2::new(0.0, -1.0),
            DVec2::new(2.0, 0.0),
            DVec2::new(0.0, 1.0),
            DVec2::new(-2.0, 0.0),
        ];
        assert_eq!(crossing_count(DVec2::ZERO, &diamond), 1);
        // A vertex touching the axis from above only (a spike) counts 0 or 2.
        let spike = [
            DVec2::new(-1.0, 1.0),
            DVec2::new(1.0, 0.0),
            DVec2::new(3.0, 1.0),
            DVec2::new(3.0, 2.0),
            DVec2::new(-1.0, 2.0),
        ];
        assert_eq!(crossing_count(DVec2::ZERO, &spike) % 2, 0);
        // A horizontal edge lying on the axis.
        let step = [
            DVec2::new(1.0, -1.0),
            DVec2::new(1.0, 0.0),
            DVec2::new(2.0, 0.0),
            DVec2::new(2.0, 1.0),
            DVec2::new(-1.0, 1.0),
            DVec2::new(-1.0, -1.0),
        ];
        assert_eq!(crossing_count(DVec2::new(0.0, 0.0), &step), 1);
    }

    /// A random star-shaped (generally concave) polygon around the origin.
    fn random_star(rng: &mut PixelRng) -> Vec<DVec2> {
        let n = 3 + rng.below(12);
        let mut angles: Vec<f64> = (0..n)
            .map(|_| rng.uniform() * std::f64::consts::TAU)
            .collect();
        angles.sort_by(f64::total_cmp);
        angles
            .iter()
            .map(|a| (0.2 + rng.uniform()) * DVec2::new(a.cos(), a.sin()))
            .collect()
    }

    /// Independent reference for star-shaped polygons: inside iff inside one
    /// of the fan triangles (origin, vᵢ, vᵢ₊₁), by signed areas.
    fn inside_fan(p: DVec2, poly: &[DVec2]) -> bool {
        let cross = |a: DVec2, b: DVec2| a.x * b.y - a.y * b.x;
        (0..poly.len()).any(|i| {
            let a = poly[i];
            let b = poly[(i + 1) % poly.len()];
            let total = cross(a, b);
            if total.abs() < 1e-12 {
                return false;
            }
            let s = total.signum();
            cross(a, p) * s > 0.0 && cross(p, b) * s > 0.0 && cross(b - a, p - a) * s > 0.0
        })
    }

    #[test]
    fn crossing_test_matches_brute_force_on_random_concave_polygons() {
        let mut rng = PixelRng::new(2024, 0, 0);
        let mut checked = 0;
        for _ in 0..300 {
            let poly = random_star(&mut rng);
            // Angular gaps above π make the fan reference wrong; skip those.
            let mut angles: Vec<f64> = poly.iter().map(|v| v.y.atan2(v.x)).collect();
            angles.sort_by(f64::total_cmp);
            let wrap = angles[0] + std::f64::consts::TAU - angles[angles.len() - 1];
            if angles.windows(2).any(|w| w[1] - w[0] >= 3.1) || wrap >= 3.1 {
                continue;
            }
            for _ in 0..100 {
                let p = DVec2::new(rng.uniform() * 3.0 - 1.5, rng.uniform() * 3.0 - 1.5);
                assert_eq!(
                    point_in_polygon(p, &poly),
                    inside_fan(p, &poly),
                    "{p:?} in {poly:?}"
                );
                checked += 1;
            }
        }
        assert!(checked > 10_000, "only {checked} points checked");
    }

    #[test]
    fn concave_polygon_ray_hits_only_inside_the_notch() {
        // An L shape in the plane z = 2, seen along -z.
        let l = Polygon::new(vec![
            DVec3::new(0.0, 0.0, 2.0),
            DVec3::new(2.0, 0.0, 2.0),
            DVec3::new(2.0, 1.0, 2.0),
            DVec3::new(1.0, 1.0, 2.0),
            DVec3::new(1.0, 2.0, 2.0),
            DVec3::new(0.0, 2.0, 2.0),
        ])
        .unwrap();
        assert_eq!(l.principal_axis, 2);
        let shoot = |x: f64, y: f64| {
            l.intersect(
                &Ray::new(DVec3::new(x, y, 5.0), -DVec3::Z),
                0.0,
                f64::INFINITY,
            )
        };
        let h = shoot(0.5, 1.5).expect("inside the upper arm");
        assert!((h.t - 3.0).abs() < 1e-12 && h.front_face);
        assert!(shoot(1.5, 0.5).is_some());
        assert!(shoot(1.5, 1.5).is_none(), "the notch is outside");
        assert!(shoot(2.5, 0.5).is_none());
    }

    #[test]
    fn tilted_polygon_matches_its_plane() {
        let n = DVec3::new(0.2, 0.96, 0.3).normalize();
        let frame = crate::math::Frame::from_z(n);
        let verts: Vec<DVec3> = (0..5)
            .map(|i| {
                let a = i as f64 * std::f64::consts::TAU / 5.0;
                DVec3::new(1.0, 2.0, 3.0) + frame.to_world(DVec3::new(a.cos(), a.sin(), 0.0))
            })
            .collect();
        let p = Polygon::new(verts).unwrap();
        assert_eq!(p.principal_axis, 1);
        assert!((p.plane.normal - n).length() < 1e-12);
        let ray = Ray::new(DVec3::new(1.0, 2.0, 3.0) + 4.0 * n, -n);
        let h = p.intersect(&ray, 0.0, f64::INFINITY).unwrap();
        assert!((h.t - 4.0).abs() < 1e-12);
    }

    #[test]
    fn bad_vertex_lists_are_refused() {
        let v = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
        assert_eq!(
            Polygon::new(vec![v(0., 0., 0.), v(1., 0., 0.)]),
            Err(PolygonError::TooFewVertices(2))
        );
        assert_eq!(
            Polygon::new(vec![
                v(0., 0., 0.),
                v(1., 0., 0.),
                v(1., 0., 0.),
                v(0., 1., 0.)
            ]),
            Err(PolygonError::RepeatedVertex(1, 2))
        );
        assert_eq!(
            Polygon::new(vec![
                v(0., 0., 0.),
                v(1., 0., 0.),
                v(0., 1., 0.),
                v(0., 0., 0.)
            ]),
            Err(PolygonError::RepeatedVertex(0, 3)),
            "closing the loop by repeating the first vertex"
        );
        assert_eq!(
            Polygon::new(vec![v(0., 0., 0.), v(1., 1., 1.), v(2., 2., 2.)]),
            Err(PolygonError::ZeroArea)
        );
        assert!(matches!(
            Polygon::new(vec![
                v(0., 0., 0.),
                v(1., 0., 0.),
                v(1., 1., 0.1),
                v(0., 1., 0.)
            ]),
            Err(PolygonError::NotPlanar { .. })
        ));
        assert_eq!(
            Polygon::new(vec![v(0., 0., 0.), v(f64::NAN, 0., 0.), v(0., 1., 0.)]),
            Err(PolygonError::NotFinite(1))
        );
    }

    #[test]
    fn self_intersecting_outlines_are_accepted_with_even_odd_coverage() {
        let v = |x: f64, y: f64| DVec3::new(x, y, 0.0);
        // A symmetric bow-tie: the Newell sum is exactly zero.
        let bow = vec![v(-1., -1.), v(1., 1.), v(1., -1.), v(-1., 1.)];
        assert_eq!(newell_normal(&bow), DVec3::ZERO);
        let p = Polygon::new(bow).unwrap();
        assert_eq!(p.plane.normal.abs(), DVec3::Z);
        let hits = |p: &Polygon, x: f64, y: f64| {
            let n = p.plane.normal;
            let ray = Ray::new(DVec3::new(x, y, 0.0) + n * 5.0, -n);
            p.intersect(&ray, 0.0, f64::INFINITY).is_some()
        };
        // Both lobes (left and right) are covered; above and below are not.
        assert!(hits(&p, 0.8, 0.0) && hits(&p, -0.8, 0.0));
        assert!(!hits(&p, 0.0, 0.8) && !hits(&p, 0.0, -0.8));
        // A nearly cancelling one (lobes of area 2 and 2.02), tilted 75°:
        // its plane is found, not refused as non-planar.
        let tilt = glam::DQuat::from_rotation_x(75f64.to_radians());
        let lopsided: Vec<DVec3> = [v(-1., -1.), v(1.01, 1.), v(1.01, -1.), v(-1., 1.)]
            .iter()
            .map(|&p| tilt * p)
            .collect();
        let q = Polygon::new(lopsided).unwrap();
        assert!((q.plane.normal.abs() - (tilt * DVec3::Z).abs()).length() < 1e-12);
        // Collinear outlines are still refused, by their real defect.
        assert_eq!(
            Polygon::new(vec![v(0., 0.), v(1., 0.), v(3., 0.), v(2., 0.)]),
            Err(PolygonError::ZeroArea)
        );
        // Too large to compute with: said so, not "vertices coincide".
        assert_eq!(
            Polygon::new(vec![v(0., 0.), v(2e300, 0.), v(0., 1.)]),
            Err(PolygonError::OutOfRange(1))
        );
    }

    #[test]
    fn newell_normal_length_is_twice_the_area() {
        let n = newell_normal(&[
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(2.0, 3.0, 0.0),
            DVec3::new(0.0, 3.0, 0.0),
        ]);
        assert_eq!(n, DVec3::new(0.0, 0.0, 12.0));
    }
}
