//! The closed set of shapes, dispatched by `match` on the per-ray path.

use crate::geometry::{Aabb, Ellipsoid, Plane, Polygon, ShapeHit, Sphere};
use crate::math::Ray;

/// Every kind of shape Prism can intersect.
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// An analytic sphere.
    Sphere(Sphere),
    /// A sphere under a non-uniform transform.
    Ellipsoid(Ellipsoid),
    /// An infinite plane.
    Plane(Plane),
    /// A planar polygon.
    Polygon(Polygon),
}

/// A shape with its material.
#[derive(Clone, Debug, PartialEq)]
pub struct Primitive {
    /// The geometry.
    pub shape: Shape,
    /// Index into the scene's materials.
    pub material: u32,
}

impl Shape {
    /// The nearest hit with t in (t_min, t_max).
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<ShapeHit> {
        match self {
            Shape::Sphere(s) => s.intersect(ray, t_min, t_max),
            Shape::Ellipsoid(e) => e.intersect(ray, t_min, t_max),
            Shape::Plane(p) => p.intersect(ray, t_min, t_max),
            Shape::Polygon(p) => p.intersect(ray, t_min, t_max),
        }
    }

    /// The bounding box; `None` for unbounded shapes (planes), which an
    /// acceleration structure must keep outside its tree.
    pub fn bounds(&self) -> Option<Aabb> {
        match self {
            Shape::Sphere(s) => Some(s.bounds()),
            Shape::Ellipsoid(e) => Some(e.bounds()),
            Shape::Plane(_) => None,
            Shape::Polygon(p) => Some(p.bounds()),
        }
    }
}
