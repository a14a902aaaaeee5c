//! The nearest surface point: for each query point, the point of the
//! scene's meshes nearest it (in world space), with the triangle it lies
//! on, its barycentric weights and the triangle's normal (see `geometry::nearest` for one
//! triangle). Each mesh's tree is walked nearest box first, every box
//! farther than the nearest point found so far left out. Of points
//! equally near, the one on the first mesh (by id), then on its first
//! triangle (by index), is given, so the answer depends only on the point
//! and the scene: not on the thread count or the order the tree is
//! walked.

use glam::DVec3;
use rayon::prelude::*;

use super::QueryError;
use super::rays::{Coordinates, QueryOptions, check_points};
use super::scene::RayScene;

/// Points per task, and between checks of the cancel flag.
const CHUNK: usize = 256;

/// The answers of [`RayScene::closest_point`], one per query point.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NearestPoints {
    /// The nearest surface point, `x, y, z` per query point (NaN where
    /// the scene has no mesh).
    pub point: Vec<f64>,
    /// Its distance from the query point (∞ where the scene has no mesh).
    pub distance: Vec<f64>,
    /// Id of the mesh it lies on (−1: none).
    pub mesh_id: Vec<i64>,
    /// Index of its triangle in that mesh's face list (−1: none).
    pub triangle_id: Vec<i64>,
    /// Barycentric weight of the triangle's second vertex: the point is
    /// (1 − u − v)·a + u·b + v·c (through the mesh's transform).
    pub u: Vec<f64>,
    /// Barycentric weight of the third vertex.
    pub v: Vec<f64>,
    /// Unit geometric normal of its triangle (right-hand rule of the
    /// face's vertex order, through the mesh's transform; zero for a
    /// degenerate triangle and where the scene has no mesh), `x, y, z` per
    /// query point.
    pub normal: Vec<f64>,
}

/// One query point's answer.
#[derive(Clone, Copy, Debug)]
struct Nearest {
    point: DVec3,
    distance_squared: f64,
    mesh_id: i64,
    triangle_id: i64,
    u: f64,
    v: f64,
    normal: DVec3,
}

const NONE: Nearest = Nearest {
    point: DVec3::NAN,
    distance_squared: f64::INFINITY,
    mesh_id: -1,
    triangle_id: -1,
    u: 0.0,
    v: 0.0,
    normal: DVec3::ZERO,
};

impl RayScene {
    /// The point of the scene's meshes nearest each of `points` (`x, y, z`
    /// of each, in double or single precision: [`Coordinates`]), in world
    /// space: see the [module](self) for which of points equally near is
    /// given.
    pub fn closest_point<'p>(
        &self,
        points: impl Into<Coordinates<'p>>,
        options: &QueryOptions,
    ) -> Result<NearestPoints, QueryError> {
        let points = points.into();
        let n = check_points("points", points)?;
        let mut answers = vec![NONE; n];
        options.run(|| {
            answers.par_chunks_mut(CHUNK).enumerate().try_for_each_init(
                Vec::new,
                |stack, (c, out)| {
                    if options.cancelled() {
                        return Err(QueryError::Cancelled);
                    }
                    for (k, answer) in out.iter_mut().enumerate() {
                        *answer = self.nearest(points.point(c * CHUNK + k), stack);
                    }
                    Ok(())
                },
            )
        })?;
        let mut out = NearestPoints {
            point: Vec::with_capacity(3 * n),
            distance: Vec::with_capacity(n),
            mesh_id: Vec::with_capacity(n),
            triangle_id: Vec::with_capacity(n),
            u: Vec::with_capacity(n),
            v: Vec::with_capacity(n),
            normal: Vec::with_capacity(3 * n),
        };
        for a in answers {
            out.point.extend(a.point.to_array());
            out.distance.push(a.distance_squared.sqrt());
            out.mesh_id.push(a.mesh_id);
            out.triangle_id.push(a.triangle_id);
            out.u.push(a.u);
            out.v.push(a.v);
            out.normal.extend(a.normal.to_array());
        }
        Ok(out)
    }

    /// The nearest point of any mesh to `p`: each mesh asked within the
    /// distance of the nearest found on the meshes before it, a later
    /// mesh's point kept only when strictly nearer.
    fn nearest(&self, p: DVec3, stack: &mut Vec<(f64, u32, u16)>) -> Nearest {
        let mut best = NONE;
        for (id, placed) in self.meshes.iter().enumerate() {
            let to_world = placed.transform.as_ref().map(|t| &t.to_world);
            let Some((triangle, near, normal)) =
                placed
                    .mesh
                    .nearest_point(p, best.distance_squared, to_world, stack)
            else {
                continue;
            };
            if near.distance_squared < best.distance_squared || best.mesh_id < 0 {
                best = Nearest {
                    point: near.point,
                    distance_squared: near.distance_squared,
                    mesh_id: id as i64,
                    triangle_id: i64::from(triangle),
                    u: near.u,
                    v: near.v,
                    // As `intersect`'s normal, but zero rather than NaN
                    // for a degenerate triangle (which a ray never hits).
                    normal: match &placed.transform {
                        None => normal,
                        Some(t) => (t.normal_to_world * normal).normalize_or_zero(),
                    },
                };
            }
        }
        best
    }
}
