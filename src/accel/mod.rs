//! The primitive set and the two queries shading asks of it: the closest
//! hit along a ray, and whether anything blocks a segment (any-hit, for
//! shadow feelers).
//!
//! Shading only sees [`Aggregate`]; how it finds hits (a linear scan today,
//! a BVH over the bounded primitives next) is its own business.

mod primitive;

pub use primitive::{Primitive, Shape};

use crate::geometry::Hit;
use crate::math::Ray;

/// All primitives of a scene, queried as one.
#[derive(Clone, Debug, Default)]
pub struct Aggregate {
    primitives: Vec<Primitive>,
}

impl Aggregate {
    /// Collects `primitives`; their indices are the `primitive` field of hits.
    pub fn new(primitives: Vec<Primitive>) -> Self {
        Aggregate { primitives }
    }

    /// The primitives, indexed as hits name them.
    pub fn primitives(&self) -> &[Primitive] {
        &self.primitives
    }

    /// The nearest hit with t in (0, t_max).
    pub fn closest_hit(&self, ray: &Ray, t_max: f64) -> Option<Hit> {
        let mut closest = t_max;
        let mut found = None;
        for (index, primitive) in self.primitives.iter().enumerate() {
            if let Some(h) = primitive.shape.intersect(ray, 0.0, closest) {
                closest = h.t;
                found = Some((index, h));
            }
        }
        found.map(|(index, h)| Hit {
            t: h.t,
            point: ray.at(h.t),
            normal: h.normal,
            front_face: h.front_face,
            primitive: index as u32,
        })
    }

    /// Whether any primitive is hit with t in (0, t_max); stops at the first
    /// blocker found, never looks for the nearest.
    pub fn any_hit(&self, ray: &Ray, t_max: f64) -> bool {
        self.primitives
            .iter()
            .any(|p| p.shape.intersect(ray, 0.0, t_max).is_some())
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
