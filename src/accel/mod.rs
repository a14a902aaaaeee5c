//! The primitive set and the two queries shading asks of it: the closest
//! hit along a ray, and whether anything blocks a segment (any-hit, for
//! shadow feelers).
//!
//! Bounded primitives sit in a BVH; unbounded ones (planes) are tested one
//! by one beside it. Shading only sees [`Aggregate`].

pub mod bvh;
pub(crate) mod packet;
mod primitive;
mod shadow;
pub(crate) mod simd;
mod wide;

pub use primitive::{Primitive, Shape};
pub use shadow::{Blocker, FeelerBatch, ShadowCandidates};
pub use simd::{NodePacket, NodeRay, PACKET, SimdPath, simd_path};

use bvh::Bvh;

use crate::geometry::{Aabb, Hit, ShapeHit};
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

    /// The nearest hit with t in (0, t_max); of hits at the same t, the
    /// one of the lowest primitive index, so the answer does not depend on
    /// the order the tree visits them in.
    pub fn closest_hit(&self, ray: &Ray, t_max: f64) -> Option<Hit> {
        let mut found: Option<(u32, ShapeHit)> = None;
        // Once a hit is held, a later one at the same t is looked for too.
        let mut consider = |i: u32, t_max: f64| {
            let limit = if found.is_some() {
                t_max.next_up()
            } else {
                t_max
            };
            let h = self.primitives[i as usize]
                .shape
                .intersect(ray, 0.0, limit)?;
            if found
                .as_ref()
                .is_some_and(|(j, held)| h.t == held.t && *j < i)
            {
                return None;
            }
            found = Some((i, h));
            Some(h.t)
        };
        let mut closest = t_max;
        for &i in &self.unbounded {
            if let Some(t) = consider(i, closest) {
                closest = t;
            }
        }
        self.bvh.closest(
            &NodeRay::new(ray.origin, ray.direction),
            closest,
            |position, t_max| consider(self.leaf_primitives[position], t_max),
        );
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
                .any(&NodeRay::new(ray.origin, ray.direction), t_max, |p| {
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

    #[test]
    fn a_tie_goes_to_the_lowest_primitive_index() {
        // Two spheres touching at the point a ray meets first (radius 1 and
        // 2, tangent inside at z = -3), among others: the same t exactly, so
        // the lower index wins however the tree orders them.
        let sphere = |x: f64, radius: f64, material: u32| Primitive {
            shape: Shape::Sphere(Sphere {
                center: DVec3::new(x, 0.0, -3.0 - radius),
                radius,
            }),
            material,
        };
        for (twin, first) in [0usize, 7, 19]
            .into_iter()
            .flat_map(|t| [(t, false), (t, true)])
        {
            let mut primitives: Vec<Primitive> =
                (0..20).map(|i| sphere(3.0 * i as f64, 1.0, 0)).collect();
            primitives.insert(
                twin + usize::from(!first),
                sphere(3.0 * twin as f64, 2.0, 1),
            );
            let scene = Aggregate::new(primitives);
            let ray = Ray::new(DVec3::new(3.0 * twin as f64, 0.0, 0.0), -DVec3::Z);
            let h = scene.closest_hit(&ray, f64::INFINITY).unwrap();
            assert_eq!(h.t, 3.0);
            let material = u32::from(first);
            assert_eq!(
                (h.primitive, h.material),
                (twin as u32, material),
                "{twin} {first}"
            );
        }
    }
}
