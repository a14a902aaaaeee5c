//! The closed set of shapes, dispatched by `match` on the per-ray path.

use glam::{DVec2, DVec3};

use crate::geometry::span::{Intervals, Surface};
use crate::geometry::{
    Aabb, Cone, Csg, Cuboid, Disc, Ellipsoid, MeshInstance, Plane, Polygon, ShapeHit, Sphere, Torus,
};
use crate::math::Frame;
use crate::math::Ray;
use crate::math::transcendental;

/// Every kind of shape Prism can intersect. The variants that carry a
/// transform or vertex lists are boxed so that a primitive stays 48 bytes:
/// a scene of a million spheres is a million of these.
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// An analytic sphere.
    Sphere(Sphere),
    /// A sphere under a non-uniform transform.
    Ellipsoid(Box<Ellipsoid>),
    /// An infinite plane.
    Plane(Plane),
    /// A planar polygon.
    Polygon(Box<Polygon>),
    /// A placed triangle mesh.
    Mesh(Box<MeshInstance>),
    /// A box (POV-Ray's `box`), placed by a transform.
    Cuboid(Box<Cuboid>),
    /// A truncated cone or cylinder, capped or open.
    Cone(Box<Cone>),
    /// A flat disc or ring.
    Disc(Box<Disc>),
    /// A torus (its quartic solved by root isolation).
    Torus(Box<Torus>),
    /// Constructive solid geometry over other shapes.
    Csg(Box<Csg>),
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
            Shape::Mesh(m) => m.intersect(ray, t_min, t_max),
            Shape::Cuboid(b) => b.intersect(ray, t_min, t_max),
            Shape::Cone(c) => c.intersect(ray, t_min, t_max),
            Shape::Disc(d) => d.intersect(ray, t_min, t_max),
            Shape::Torus(t) => t.intersect(ray, t_min, t_max),
            Shape::Csg(c) => c.intersect(ray, t_min, t_max),
        }
    }

    /// Whether the shape encloses a solid that CSG can combine: one with
    /// an inside, told by [`inside`](Self::inside) (or, for meshes and
    /// CSG, by their own interval queries). Polygons, discs, open
    /// cylinders and cones and meshes with holes have none.
    pub fn is_solid(&self) -> bool {
        match self {
            Shape::Polygon(_) | Shape::Disc(_) => false,
            Shape::Cone(c) => !c.open,
            Shape::Mesh(m) => m.mesh.is_closed(),
            _ => true,
        }
    }

    /// Where the whole line of `ray` is inside an analytic solid (see
    /// `geometry/span.rs`); `None` for shapes without an inside and for
    /// meshes and CSG, which answer with richer intervals of their own.
    pub fn inside(&self, ray: &Ray) -> Option<Intervals> {
        match self {
            Shape::Cone(c) if c.open => None,
            Shape::Cone(_) | Shape::Sphere(_) | Shape::Ellipsoid(_) => Some(self.intervals(ray)),
            Shape::Plane(_) | Shape::Cuboid(_) | Shape::Torus(_) => Some(self.intervals(ray)),
            Shape::Polygon(_) | Shape::Disc(_) | Shape::Mesh(_) | Shape::Csg(_) => None,
        }
    }

    /// [`inside`](Self::inside) with no intervals for the shapes that
    /// have none of their own: the form CSG's inner loop reads, the list
    /// built where the caller keeps it (an `Option` around it costs a copy).
    #[inline(always)]
    pub(crate) fn intervals(&self, ray: &Ray) -> Intervals {
        match self {
            Shape::Sphere(s) => s.inside(ray),
            Shape::Ellipsoid(e) => e.inside(ray),
            Shape::Plane(p) => p.inside(ray),
            Shape::Cuboid(b) => b.inside(ray),
            Shape::Cone(c) if !c.open => c.inside(ray),
            Shape::Torus(t) => t.inside(ray),
            Shape::Cone(_) | Shape::Polygon(_) | Shape::Disc(_) => Intervals::new(),
            Shape::Mesh(_) | Shape::Csg(_) => Intervals::new(),
        }
    }

    /// The outward unit normal where `ray` crosses the surface of an
    /// analytic solid at `s`, one of the ends [`inside`](Self::inside)
    /// gave for the same ray; zero at a half-space's open end and for
    /// shapes without intervals of their own.
    pub fn surface_normal(&self, ray: &Ray, s: Surface) -> DVec3 {
        if !s.t.is_finite() {
            return DVec3::ZERO;
        }
        match self {
            Shape::Sphere(sphere) => sphere.surface_normal(ray, s),
            Shape::Ellipsoid(e) => e.surface_normal(ray, s),
            Shape::Plane(p) => p.normal,
            Shape::Cuboid(b) => b.surface_normal(ray, s),
            Shape::Cone(c) => c.surface_normal(ray, s),
            Shape::Torus(t) => t.surface_normal(ray, s),
            Shape::Polygon(_) | Shape::Disc(_) | Shape::Mesh(_) | Shape::Csg(_) => DVec3::ZERO,
        }
    }

    /// The nearest hit with t in (t_min, t_max) as a shadow feeler needs
    /// it: distance, geometric normal and the material there (`None`: the
    /// primitive's), without the texture coordinates CSG finds last.
    #[inline]
    pub fn feeler_hit(
        &self,
        ray: &Ray,
        t_min: f64,
        t_max: f64,
    ) -> Option<(f64, DVec3, Option<u32>)> {
        match self {
            Shape::Csg(c) => c
                .nearest_boundary(ray, t_min, t_max)
                .map(|b| (b.t, b.normal(ray), Some(b.material))),
            other => other
                .intersect(ray, t_min, t_max)
                .map(|h| (h.t, h.normal, h.material)),
        }
    }

    /// Whether a line going along `direction` that crosses the surface
    /// where its outward normal is `normal` meets the shape nowhere further
    /// on: it leaves a convex solid there, or the shape is flat. A feeler
    /// continued through glass skips a shape it has passed for good.
    #[inline]
    pub fn passed_for_good(&self, direction: DVec3, normal: DVec3) -> bool {
        match self {
            Shape::Sphere(_) | Shape::Ellipsoid(_) | Shape::Cuboid(_) => {
                direction.dot(normal) > 0.0
            }
            Shape::Cone(c) => !c.open && direction.dot(normal) > 0.0,
            Shape::Plane(_) | Shape::Polygon(_) | Shape::Disc(_) => true,
            Shape::Mesh(_) | Shape::Torus(_) | Shape::Csg(_) => false,
        }
    }

    /// Whether the shape is hit with t in (t_min, t_max) (any-hit: meshes
    /// stop at the first triangle found).
    #[inline]
    pub fn occludes(&self, ray: &Ray, t_min: f64, t_max: f64) -> bool {
        match self {
            Shape::Mesh(m) => m.any_hit(ray, t_min, t_max),
            Shape::Sphere(s) => s.occludes(ray, t_min, t_max),
            Shape::Csg(c) => c.nearest_boundary(ray, t_min, t_max).is_some(),
            other => other.intersect(ray, t_min, t_max).is_some(),
        }
    }

    /// Texture coordinates at `point` of `hit`: spheres and ellipsoids by
    /// longitude and latitude (u = 0.5 + atan2(z, x)/2π, v = 0.5 + asin(y)/π
    /// on the unit sphere), planes and polygons by coordinates in the plane,
    /// meshes by what the hit carries; boxes, cones and discs as their
    /// files say.
    pub fn uv(&self, point: DVec3, hit: &ShapeHit) -> DVec2 {
        let spherical = |p: DVec3| {
            DVec2::new(
                0.5 + transcendental::atan2(p.z, p.x) / std::f64::consts::TAU,
                0.5 + transcendental::asin(p.y.clamp(-1.0, 1.0)) / std::f64::consts::PI,
            )
        };
        let planar = |normal: DVec3| {
            let f = Frame::from_z(normal);
            DVec2::new(point.dot(f.x), point.dot(f.y))
        };
        match self {
            Shape::Sphere(s) => spherical((point - s.center) / s.radius),
            Shape::Ellipsoid(e) => spherical(e.transform.to_object.transform_point3(point)),
            Shape::Plane(p) => planar(p.normal),
            Shape::Polygon(p) => planar(p.plane.normal),
            Shape::Mesh(_) => hit.uv,
            Shape::Cuboid(b) => b.uv(point),
            Shape::Cone(c) => c.uv(point, hit.normal),
            Shape::Disc(d) => d.uv(point),
            Shape::Torus(t) => t.uv(point),
            // The leaf hit gave its own.
            Shape::Csg(_) => hit.uv,
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
            Shape::Mesh(m) => Some(m.bounds()),
            Shape::Cuboid(b) => Some(b.bounds()),
            Shape::Cone(c) => Some(c.bounds()),
            Shape::Disc(d) => Some(d.bounds()),
            Shape::Torus(t) => Some(t.bounds()),
            Shape::Csg(c) => c.bounds(),
        }
    }
}
