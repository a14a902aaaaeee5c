//! Primitives and their ray intersections, one file per shape. Each file
//! carries the formula from the lecture notes it implements.

pub mod aabb;
pub mod cone;
pub mod csg;
pub mod cuboid;
pub mod disc;
pub mod hit;
pub mod instance;
pub mod mesh;
pub mod nearest;
pub mod plane;
pub mod polygon;
pub mod span;
pub mod sphere;
pub mod steps;
pub mod terminator;
pub mod torus;
pub mod triangle;

pub use aabb::Aabb;
pub use cone::Cone;
pub use csg::{Csg, CsgChild, CsgOp};
pub use cuboid::Cuboid;
pub use disc::Disc;
pub use hit::{Hit, ShapeHit};
pub use instance::MeshInstance;
pub use mesh::{Mesh, MeshData, MeshError};
pub use plane::Plane;
pub use polygon::{Polygon, PolygonError};
pub use sphere::{Ellipsoid, Sphere};
pub use torus::Torus;
