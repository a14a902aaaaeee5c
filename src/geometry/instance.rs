//! A mesh placed in the scene: shared mesh data (loaded and built once,
//! however many times it is placed) plus this placement's transform and
//! materials. Together with the scene BVH over instances this is a
//! two-level BVH.

use std::sync::Arc;

use super::mesh::MeshHit;
use super::{Aabb, Mesh, ShapeHit};
use crate::accel::PACKET;
use crate::math::{Ray, Transform};

/// One placement of a mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshInstance {
    /// The shared mesh, in object space.
    pub mesh: Arc<Mesh>,
    /// Object to world; `None` when the mesh is placed as it is.
    pub transform: Option<Transform>,
    /// Scene material index for each of the mesh's material slots (at
    /// least one; slots past the end use the first).
    pub materials: Arc<[u32]>,
}

impl MeshInstance {
    /// The ray in object space: the direction is mapped but not
    /// renormalised, so t means the same in both spaces.
    #[inline]
    fn local(&self, ray: &Ray) -> (glam::DVec3, glam::DVec3) {
        match &self.transform {
            None => (ray.origin, ray.direction),
            Some(t) => t.ray_to_object(ray),
        }
    }

    /// The nearest hit with t in (t_min, t_max).
    pub fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<ShapeHit> {
        let (origin, direction) = self.local(ray);
        let h = self.mesh.intersect(origin, direction, t_min, t_max)?;
        Some(self.world_hit(ray, h))
    }

    /// [`intersect`](Self::intersect) for each of up to eight rays, traced
    /// together (see [`Mesh::intersect_packet`]): `hits[k]` is, to the bit,
    /// what `intersect` gives ray k alone with limit `t_max[k]`. Panics as
    /// `Mesh::intersect_packet` does.
    pub fn intersect_packet(
        &self,
        rays: &[Ray],
        t_min: f64,
        t_max: &[f64],
        hits: &mut [Option<ShapeHit>],
    ) {
        const NONE: Option<MeshHit> = None;
        let n = rays.len();
        assert!(n <= PACKET && hits.len() == n);
        let mut local = [(glam::DVec3::ZERO, glam::DVec3::ZERO); PACKET];
        for (l, ray) in local.iter_mut().zip(rays) {
            *l = self.local(ray);
        }
        let mut found = [NONE; PACKET];
        self.mesh
            .intersect_packet(&local[..n], t_min, t_max, &mut found[..n]);
        for ((hit, h), ray) in hits.iter_mut().zip(found).zip(rays) {
            *hit = h.map(|h| self.world_hit(ray, h));
        }
    }

    /// The hit of world-space `ray` from the mesh's hit of its object-space
    /// form: normals back to world space, the material slot to the scene's.
    #[inline]
    fn world_hit(&self, ray: &Ray, h: MeshHit) -> ShapeHit {
        let (normal, shading_normal, feeler_offset) = match &self.transform {
            None => (h.normal, h.shading_normal, h.feeler_offset),
            Some(t) => (
                t.normal(h.normal),
                t.normal(h.shading_normal),
                t.to_world.transform_vector3(h.feeler_offset),
            ),
        };
        let material = self
            .materials
            .get(h.material as usize)
            .or(self.materials.first())
            .copied();
        ShapeHit {
            t: h.t,
            normal,
            front_face: ray.direction.dot(normal) < 0.0,
            shading_normal,
            feeler_offset,
            uv: h.uv,
            color: h.color,
            material,
        }
    }

    /// Whether any triangle is hit with t in (t_min, t_max).
    pub fn any_hit(&self, ray: &Ray, t_min: f64, t_max: f64) -> bool {
        let (origin, direction) = self.local(ray);
        self.mesh.any_hit(origin, direction, t_min, t_max)
    }

    /// [`any_hit`](Self::any_hit) for each of up to eight rays, traced
    /// together (see [`Mesh::any_hit_packet`]): bit k set when ray k is
    /// blocked within `t_max[k]`. Panics as `Mesh::any_hit_packet` does.
    pub fn any_hit_packet(&self, rays: &[Ray], t_min: f64, t_max: &[f64]) -> u32 {
        let mut local = [(glam::DVec3::ZERO, glam::DVec3::ZERO); PACKET];
        for (l, ray) in local.iter_mut().zip(rays) {
            *l = self.local(ray);
        }
        self.mesh.any_hit_packet(&local[..rays.len()], t_min, t_max)
    }

    /// Where the whole line of `ray` is inside the (closed) mesh, as
    /// (enter, exit) hits in world space; see [`Mesh::inside`].
    pub fn inside(&self, ray: &Ray) -> Vec<(ShapeHit, ShapeHit)> {
        let (origin, direction) = self.local(ray);
        self.mesh
            .inside(origin, direction)
            .into_iter()
            .map(|(a, b)| (self.world_hit(ray, a), self.world_hit(ray, b)))
            .collect()
    }

    /// World-space bounds.
    pub fn bounds(&self) -> Aabb {
        let b = self.mesh.bounds();
        match &self.transform {
            None => b,
            Some(t) => b.transformed(|p| t.point(p)),
        }
    }
}
