//! The primitive set and the two queries shading asks of it: the closest
//! hit along a ray, and whether anything blocks a segment (any-hit, for
//! shadow feelers).
//!
//! Bounded primitives sit in a BVH; unbounded ones (planes) are tested one
//! by one beside it. Shading only sees [`Aggregate`].

pub mod bvh;
mod primitive;
mod shadow;
mod wide;

pub use primitive::{Primitive, Shape};
pub use shadow::{Blocker, ShadowCandidates};

use bvh::{BoxRay, Bvh};

use crate::geometry::{Aabb, Hit};
use crate::math::Ray;

/// All primitives of a scene, queried as one.
#[derive(Clone, Debug, Default)]
pub struct Aggregate {
    primitives: Vec<Primitive>,
    /// BVH over the bounded primitives.
    bvh: Bvh,
    /// Primitive index of each BVH item position (leaf order).
    leaf_primitives: Vec<u32>,
    /// Primitives without bounds, tested against every ray.
    unbounded: Vec<u32>,
}

impl Aggregate {
    /// Collects `primitives` and builds the BVH over the bounded ones;
    /// their indices are the `primitive` field of hits.
    pub fn new(primitives: Vec<Primitive>) -> Self {
        let (bounded, unbounded): (Vec<u32>, Vec<u32>) = (0..primitives.len() as u32)
            .partition(|&i| primitives[i as usize].shape.bounds().is_some());
        let bvh = Bvh::build(
            bounded
                .iter()
                .filter_map(|&i| primitives[i as usize].shape.bounds()),
        );
        let leaf_primitives = bvh
            .order()
            .iter()
            .map(|&item| bounded[item as usize])
            .collect();
        Aggregate {
            primitives,
            bvh,
            leaf_primitives,
            unbounded,
        }
    }

    /// The primitives, indexed as hits name them.
    pub fn primitives(&self) -> &[Primitive] {
        &self.primitives
    }

    /// Bounds of the bounded primitives.
    pub fn bounds(&self) -> Aabb {
        self.bvh.bounds()
    }

    /// The nearest hit with t in (0, t_max).
    pub fn closest_hit(&self, ray: &Ray, t_max: f64) -> Option<Hit> {
        let mut found = None;
        let mut closest = t_max;
        for &i in &self.unbounded {
            if let Some(h) = self.primitives[i as usize]
                .shape
                .intersect(ray, 0.0, closest)
            {
                closest = h.t;
                found = Some((i, h));
            }
        }
        let box_ray = BoxRay::new(ray.origin, ray.direction);
        self.bvh.closest(&box_ray, closest, |position, t_max| {
            let i = self.leaf_primitives[position];
            let h = self.primitives[i as usize]
                .shape
                .intersect(ray, 0.0, t_max)?;
            found = Some((i, h));
            Some(h.t)
        });
        found.map(|(primitive, h)| {
            let p = &self.primitives[primitive as usize];
            let point = ray.at(h.t);
            Hit {
                t: h.t,
                point,
                normal: h.normal,
                front_face: h.front_face,
                shading_normal: h.shading_normal,
                uv: p.shape.uv(point, &h),
                color: h.color,
                primitive,
                material: h.material.unwrap_or(p.material),
            }
        })
    }

    /// Whether any primitive is hit with t in (0, t_max); stops at the first
    /// blocker found, never looks for the nearest.
    pub fn any_hit(&self, ray: &Ray, t_max: f64) -> bool {
        let hits = |i: u32| self.primitives[i as usize].shape.occludes(ray, 0.0, t_max);
        self.unbounded.iter().any(|&i| hits(i))
            || self
                .bvh
                .any(&BoxRay::new(ray.origin, ray.direction), t_max, |p| {
                    hits(self.leaf_primitives[p])
                })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Plane, Sphere};
    use glam::DVec3;

    fn scene() -> Aggregate {
        let sphere = |z: f64| Primitive {
            shape: Shape::Sphere(Sphere {
                center: DVec3::new(0.0, 0.0, z),
                radius: 1.0,
            }),
            material: 0,
        };
        Aggregate::new(vec![
            sphere(-10.0),
            sphere(-4.0),
            Primitive {
                shape: Shape::Plane(Plane {
                    normal: DVec3::Z,
                    distance: -20.0,
                }),
                material: 1,
            },
        ])
    }

    #[test]
    fn closest_hit_is_the_nearest_whatever_the_order() {
        let ray = Ray::new(DVec3::ZERO, -DVec3::Z);
        let h = scene().closest_hit(&ray, f64::INFINITY).unwrap();
        assert_eq!(h.primitive, 1);
        assert_eq!(h.t, 3.0);
        assert_eq!(h.point, DVec3::new(0.0, 0.0, -3.0));
    }

    #[test]
    fn any_hit_respects_the_segment() {
        let ray = Ray::new(DVec3::ZERO, -DVec3::Z);
        assert!(!scene().any_hit(&ray, 2.9));
        assert!(scene().any_hit(&ray, 3.1));
        assert!(scene().closest_hit(&ray, 2.9).is_none());
    }
}
