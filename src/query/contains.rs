//! Inside or outside: crossing parity along a ray (the Jordan curve
//! theorem in three dimensions, as the notes use it for polygons), with
//! every sign the answer rests on certified, so that it is exact.
//!
//! The ray from point p is sheared so it runs along +z from the origin,
//! as the watertight triangle test does it; each vertex is mapped once,
//! so the sheared vertices form a closed mesh M' of the same triangles,
//! each vertex moved by the shear's rounding (a few units in the last
//! place of its distance from p). A triangle is crossed when its three
//! 2D edge functions (cross products of the sheared corners) have one
//! sign, at t = Σ eᵢzᵢ / Σ eᵢ. Each edge function and that numerator is
//! computed with a forward error bound (Shewchuk's for a 2×2 determinant:
//! 3ε·(|a·d| + |b·c|)); where every value that decides a triangle is
//! farther from zero than its bound, the signs are the exact signs of M',
//! so the count of crossings ahead is the exact crossing count of M', and
//! its parity tells inside from outside exactly for every point farther
//! from the surface than the rounding moved it (about 1e-15 of the mesh's
//! size; points 1e-12 from it are told apart, see tests/ray_queries.rs).
//!
//! A ray that passes within rounding of an edge or a vertex of a triangle
//! (a graze, where the watertight test may see both triangles of an edge,
//! or none of a fold) leaves some sign uncertain: the whole ray is set
//! aside, never guessed, and the next of eight fixed directions is cast.
//! When every direction is uncertain the point lies within rounding of
//! the surface (every ray from it starts on it); it is reported inside,
//! as a closed solid holds its boundary. The answer depends only on the
//! point and the mesh: not on the thread count or the order the tree is
//! walked.

use glam::DVec3;
use rayon::prelude::*;

use super::QueryError;
use super::rays::{Coordinates, QueryOptions, check_points};
use super::scene::RayScene;
use super::trace::meets;
use crate::geometry::Mesh;

/// The directions cast from a point, in turn, until one is certain: fixed
/// (so answers do not depend on anything but the point), none in a
/// coordinate plane (where grid meshes have their edges).
const DIRECTIONS: [[f64; 3]; 8] = [
    [0.3713, 0.7201, 0.5862],
    [-0.6541, 0.2297, 0.7206],
    [0.5127, -0.8019, 0.3066],
    [-0.2883, -0.4510, -0.8447],
    [0.8124, 0.3347, -0.4774],
    [-0.7315, 0.6188, -0.2866],
    [0.1991, -0.2741, 0.9409],
    [-0.4617, -0.8731, 0.1563],
];

/// Points per task, and between checks of the cancel flag.
const CHUNK: usize = 256;

/// The unit roundoff 2⁻⁵³.
const EPS: f64 = f64::EPSILON / 2.0;

impl RayScene {
    /// Whether each of `points` (`x, y, z` of each, in double or single
    /// precision: [`Coordinates`]) lies inside one of the
    /// scene's meshes, all of which must be closed
    /// ([`QueryError::NotClosed`] otherwise): see the [module](self) for
    /// how it is exact and what a point on the surface gets.
    pub fn contains<'p>(
        &self,
        points: impl Into<Coordinates<'p>>,
        options: &QueryOptions,
    ) -> Result<Vec<bool>, QueryError> {
        let points = points.into();
        let n = check_points("points", points)?;
        if let Some(id) = (0..self.meshes.len()).find(|&i| !self.meshes[i].is_closed()) {
            return Err(QueryError::NotClosed { mesh: id as u32 });
        }
        let mut inside = vec![false; n];
        options.run(|| {
            inside
                .par_chunks_mut(CHUNK)
                .enumerate()
                .try_for_each(|(c, out)| {
                    if options.cancelled() {
                        return Err(QueryError::Cancelled);
                    }
                    for (k, answer) in out.iter_mut().enumerate() {
                        let p = points.point(c * CHUNK + k);
                        *answer = self.meshes.iter().any(|placed| {
                            let (p, _) = placed.local(p, DVec3::Z);
                            placed.bounds_contain_local(p) && mesh_contains(&placed.mesh, p)
                        });
                    }
                    Ok(())
                })
        })?;
        Ok(inside)
    }
}

/// Whether closed `mesh` holds point `p` (object space).
pub fn mesh_contains(mesh: &Mesh, p: DVec3) -> bool {
    DIRECTIONS
        .iter()
        .find_map(|&d| crossing_parity(mesh, p, DVec3::from_array(d)))
        .unwrap_or(true)
}

/// The parity of the crossings of the ray from `p` along `d` with
/// `mesh` (true: odd, inside), or `None` when a sign it rests on is
/// uncertain.
pub fn crossing_parity(mesh: &Mesh, p: DVec3, d: DVec3) -> Option<bool> {
    let shear = Shear::new(p, d);
    let mut odd = false;
    let certain = std::cell::Cell::new(true);
    mesh.visit_triangles(
        |b| certain.get() && meets(b, p, d, 0.0, f64::INFINITY),
        |_, corners| match shear.crossing(corners) {
            Crossing::Miss | Crossing::Behind => {}
            Crossing::Ahead => odd = !odd,
            Crossing::Unsure => certain.set(false),
        },
    );
    certain.get().then_some(odd)
}

/// What a triangle is to the ray, as far as the rounding lets it be told.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Crossing {
    /// Certainly not crossed.
    Miss,
    /// Certainly crossed at t > 0.
    Ahead,
    /// Certainly crossed at t < 0.
    Behind,
    /// Within rounding of an edge, a vertex, or the point.
    Unsure,
}

/// The watertight test's shear for one ray: the axes and constants.
#[derive(Clone, Copy, Debug)]
pub struct Shear {
    origin: DVec3,
    axes: [usize; 3],
    sx: f64,
    sy: f64,
    sz: f64,
}

impl Shear {
    /// The shear that makes the ray from `origin` along `direction` run
    /// along +z (kz the direction's largest component).
    pub fn new(origin: DVec3, direction: DVec3) -> Self {
        let kz = direction.abs().max_position();
        let (kx, ky) = ((kz + 1) % 3, (kz + 2) % 3);
        let d = direction.to_array();
        Shear {
            origin,
            axes: [kx, ky, kz],
            sx: d[kx] / d[kz],
            sy: d[ky] / d[kz],
            sz: 1.0 / d[kz],
        }
    }

    /// A vertex in the sheared frame: a function of the vertex alone, so
    /// every triangle that shares it sees the same point.
    #[inline]
    fn map(&self, v: DVec3) -> [f64; 3] {
        let r = (v - self.origin).to_array();
        let [kx, ky, kz] = self.axes;
        [
            r[kx] - self.sx * r[kz],
            r[ky] - self.sy * r[kz],
            self.sz * r[kz],
        ]
    }

    /// Triangle `[a, b, c]` against the ray, each deciding sign certified.
    pub fn crossing(&self, [a, b, c]: [DVec3; 3]) -> Crossing {
        let [a, b, c] = [self.map(a), self.map(b), self.map(c)];
        // Edge function opposite each corner, with its error bound.
        let edge = |p: [f64; 3], q: [f64; 3]| {
            let (l, r) = (p[0] * q[1], p[1] * q[0]);
            let e = l - r;
            (
                e,
                3.0 * EPS * (1.0 + 4.0 * EPS) * (l.abs() + r.abs()) + f64::MIN_POSITIVE,
            )
        };
        let es = [edge(c, b), edge(a, c), edge(b, a)];
        let sign = |(e, bound): (f64, f64)| {
            if e > bound {
                1
            } else if e < -bound {
                -1
            } else {
                0
            }
        };
        let signs = es.map(sign);
        if signs.contains(&1) && signs.contains(&-1) {
            return Crossing::Miss;
        }
        if signs.contains(&0) {
            return Crossing::Unsure;
        }
        // All one sign s, so Σ eᵢ has it too; t's sign is T's times s.
        let z = [a[2], b[2], c[2]];
        let t_scaled = es[0].0 * z[0] + es[1].0 * z[1] + es[2].0 * z[2];
        let bound = (0..3)
            .map(|i| (es[i].1 + 4.0 * EPS * es[i].0.abs()) * z[i].abs())
            .sum::<f64>()
            * (1.0 + 8.0 * EPS)
            + f64::MIN_POSITIVE;
        if t_scaled.abs() <= bound {
            return Crossing::Unsure;
        }
        if (t_scaled > 0.0) == (signs[0] > 0) {
            Crossing::Ahead
        } else {
            Crossing::Behind
        }
    }
}
