//! Ray queries against triangle meshes, for callers that want hits rather
//! than pictures (lidar and sensor simulation, visibility, inside/outside
//! tests for meshing and voxelization): Prism's watertight double-precision
//! triangle test and mesh BVHs behind a batch interface.
//!
//! A [`RayScene`] holds meshes, each with an id and an optional transform,
//! built once (each mesh its BVH) and queried many times. Queries take a
//! batch of rays ([`Rays`]: origins and directions as flat `x, y, z`
//! slices, one `t_min`/`t_max` for all) and run on a rayon pool of
//! [`QueryOptions::threads`] workers; every ray's answer is computed on its
//! own, so it is the same, bit for bit, for any thread count:
//!
//! - [`RayScene::intersect`]: the nearest hit (t, mesh, triangle,
//!   barycentric u and v, geometric normal), equal to the renderer's hit of
//!   the same ray; [`RayScene::intersect_into`] writes the same into the
//!   caller's arrays ([`HitsMut`]), so that a loop of large queries can
//!   reuse one set rather than fault in new memory each time;
//! - [`RayScene::occluded`]: whether anything is hit;
//! - [`RayScene::count_intersections`], [`RayScene::all_intersections`]:
//!   every triangle the ray hits in (t_min, t_max), sorted by t;
//! - [`RayScene::contains`]: inside/outside of closed meshes by crossing
//!   parity, certified exact (see [`contains`](mod@contains));
//! - [`RayScene::closest_point`]: the nearest surface point to each point
//!   (distance, mesh, triangle, barycentric u and v; see
//!   [`closest`](mod@closest)).
//!
//! ```
//! use prism::query::{QueryOptions, RayScene, Rays};
//!
//! // A tetrahedron.
//! let vertices = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
//! let faces = [0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3];
//! let mut scene = RayScene::new();
//! let id = scene.add_mesh(&vertices, &faces, None).unwrap();
//! let rays = Rays::new(&[0.2, 0.2, -1.0], &[0.0, 0.0, 1.0], 0.0, f64::INFINITY).unwrap();
//! let hits = scene.intersect(&rays, &QueryOptions::default()).unwrap();
//! assert_eq!(hits.t[0], 1.0);
//! assert_eq!((hits.mesh_id[0], hits.triangle_id[0]), (i64::from(id), 0));
//! // Again, into arrays the caller holds (here a copy of the first answer).
//! let mut again = hits.clone();
//! scene.intersect_into(&rays, again.as_mut(), &QueryOptions::default()).unwrap();
//! assert_eq!(again, hits);
//! let inside = scene.contains(&[0.1, 0.1, 0.1, 1.0, 1.0, 1.0], &QueryOptions::default());
//! assert_eq!(inside.unwrap(), [true, false]);
//! // (1, 1, 1) is nearest the face on x + y + z = 1, at its centre.
//! let near = scene.closest_point(&[1.0, 1.0, 1.0], &QueryOptions::default()).unwrap();
//! assert_eq!(near.triangle_id[0], 3);
//! assert!((near.distance[0] - 2.0 / 3f64.sqrt()).abs() < 1e-15);
//! assert!((near.point[0] - 1.0 / 3.0).abs() < 1e-15);
//! ```

pub mod closest;
pub mod contains;
mod order;
pub mod rays;
pub mod scene;
mod tiles;
mod trace;

use thiserror::Error;

pub use closest::NearestPoints;
pub use rays::{Coordinates, Crossings, Hits, HitsMut, QueryOptions, Rays};
pub use scene::RayScene;

/// Why a ray scene or a query could not be made.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum QueryError {
    /// An argument is unusable; `argument` names it as the caller's API
    /// does (`vertices`, `faces`, `origins`, `directions`, `points`,
    /// `tmin`, `tmax`, `threads`, `transform`; for
    /// [`RayScene::intersect_into`], the array of [`HitsMut`] of the wrong
    /// length: `t`, `mesh_id`, `triangle_id`, `u`, `v`, `normal`).
    #[error("{argument}: {message}")]
    Invalid {
        /// The argument's name.
        argument: &'static str,
        /// What is wrong with it.
        message: String,
    },
    /// `contains` was asked of a scene with a mesh that is not closed.
    #[error(
        "contains: mesh {mesh} is not closed (every edge shared by two triangles that run it \
         in opposite directions), so it has no inside"
    )]
    NotClosed {
        /// The mesh's id.
        mesh: u32,
    },
    /// A model file could not be read.
    #[error("{0}")]
    Load(String),
    /// The caller's cancel flag was raised before the query finished.
    #[error("the query was cancelled")]
    Cancelled,
}

impl QueryError {
    fn invalid(argument: &'static str, message: impl Into<String>) -> Self {
        QueryError::Invalid {
            argument,
            message: message.into(),
        }
    }
}
