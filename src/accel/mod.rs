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
pub use shadow::{Blocker, FeelerBatch, FirstBlockers, MAX_CANDIDATES, ShadowCandidates};
pub(crate) use simd::prefetch;
pub use simd::{NodePacket, NodeRay, PACKET, SimdPath, simd_path};

use bvh::Bvh;
use glam::{DVec2, DVec3};
use packet::PacketClosestTest;

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
        let mut found = None;
        let mut consider = |i: u32, t_max: f64| {
            let shape = &self.primitives[i as usize].shape;
            let h = shape.intersect(ray, 0.0, reach(&found, t_max))?;
            keep(&mut found, i, h)
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
        found.map(|(primitive, h)| self.hit(ray, primitive, h))
    }

    /// [`closest_hit`](Self::closest_hit) for each of up to [`PACKET`] rays,
    /// traced together: coherent rays (neighbouring camera rays) share
    /// their node visits, and those that reach a mesh go through its tree
    /// as a packet too. `hits[k]` is, to the bit, what `closest_hit` gives
    /// ray k alone (the same tests, each with the ray's own limit, and a
    /// tie-break that does not depend on the order of visits).
    ///
    /// # Panics
    /// If there are more than [`PACKET`] rays, or `hits` is not as long as
    /// `rays`.
    pub fn closest_hit_packet(&self, rays: &[Ray], t_max: f64, hits: &mut [Option<Hit>]) {
        let n = rays.len();
        assert!(n <= PACKET && hits.len() == n);
        let mut pairs = [(DVec3::ZERO, DVec3::ZERO); PACKET];
        for (pair, ray) in pairs.iter_mut().zip(rays) {
            *pair = (ray.origin, ray.direction);
        }
        let Some(packet) = NodePacket::new(&pairs[..n]) else {
            for (hit, ray) in hits.iter_mut().zip(rays) {
                *hit = self.closest_hit(ray, t_max);
            }
            return;
        };
        let mut test = PrimitivesTest {
            aggregate: self,
            rays,
            found: [None; PACKET],
        };
        // Lanes past the last ray hold none.
        let mut closest = [f64::NEG_INFINITY; PACKET];
        for (k, closest) in closest.iter_mut().enumerate().take(n) {
            *closest = t_max;
            for &i in &self.unbounded {
                if let Some(t) = test.consider(k, i, *closest) {
                    *closest = t;
                }
            }
        }
        self.bvh
            .closest_packet_on(simd::kernel(), &packet, &mut closest, &mut test);
        for ((hit, found), ray) in hits.iter_mut().zip(&test.found).zip(rays) {
            *hit = found.map(|(primitive, h)| self.hit(ray, primitive, h));
        }
    }

    /// Texture coordinates at `hit`, as its shape defines them
    /// ([`Shape::uv`]); asked for by textures that use them.
    pub fn uv(&self, hit: &Hit) -> DVec2 {
        let shape = &self.primitives[hit.primitive as usize].shape;
        let carried = ShapeHit {
            uv: hit.shape_uv,
            ..ShapeHit::geometric(hit.t, hit.normal, hit.front_face)
        };
        shape.uv(hit.point, &carried)
    }

    /// The hit of `ray` on primitive `primitive` at `h`.
    #[inline]
    fn hit(&self, ray: &Ray, primitive: u32, h: ShapeHit) -> Hit {
        let p = &self.primitives[primitive as usize];
        let point = ray.at(h.t);
        Hit {
            t: h.t,
            point,
            normal: h.normal,
            front_face: h.front_face,
            shading_normal: h.shading_normal,
            shape_uv: h.uv,
            color: h.color,
            primitive,
            material: h.material.unwrap_or(p.material),
            medium: match &p.shape {
                Shape::Csg(c) => c.medium().unwrap_or(h.material.unwrap_or(p.material)),
                _ => h.material.unwrap_or(p.material),
            },
            feeler_offset: h.feeler_offset,
        }
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

/// What a closest-hit query holds for a ray: the primitive hit nearest so
/// far and its hit.
type Held = Option<(u32, ShapeHit)>;

/// How far a query holding `found` looks: up to `t_max`, or just past it
/// once a hit is held (a later one at the same t is looked for too).
#[inline(always)]
fn reach(found: &Held, t_max: f64) -> f64 {
    if found.is_some() {
        t_max.next_up()
    } else {
        t_max
    }
}

/// Keeps hit `h` of primitive `i` unless the hit held is as near and of a
/// lower primitive index; returns its distance when it is kept.
#[inline(always)]
fn keep(found: &mut Held, i: u32, h: ShapeHit) -> Option<f64> {
    if found
        .as_ref()
        .is_some_and(|(j, held)| h.t == held.t && *j < i)
    {
        return None;
    }
    *found = Some((i, h));
    Some(h.t)
}

/// The leaf test of [`Aggregate::closest_hit_packet`]: `closest_hit`'s, ray
/// by ray, or for a mesh met by two rays or more, the mesh's packet query.
struct PrimitivesTest<'a> {
    aggregate: &'a Aggregate,
    rays: &'a [Ray],
    found: [Held; PACKET],
}

impl PrimitivesTest<'_> {
    /// `closest_hit`'s test of primitive `i` for ray `k`.
    #[inline(always)]
    fn consider(&mut self, k: usize, i: u32, t_max: f64) -> Option<f64> {
        let shape = &self.aggregate.primitives[i as usize].shape;
        let h = shape.intersect(&self.rays[k], 0.0, reach(&self.found[k], t_max))?;
        keep(&mut self.found[k], i, h)
    }
}

impl PacketClosestTest for &mut PrimitivesTest<'_> {
    #[inline(always)]
    fn test(&mut self, rays: u32, position: usize, t_max: &mut [f64; PACKET]) -> u32 {
        let i = self.aggregate.leaf_primitives[position];
        let mut closer = 0;
        if let Shape::Mesh(mesh) = &self.aggregate.primitives[i as usize].shape
            && rays.count_ones() >= 2
        {
            // The rays that reach it, with the limits `consider` would use.
            let mut lanes = [0; PACKET];
            let mut sub = [self.rays[0]; PACKET];
            let mut limits = [0.0; PACKET];
            let mut len = 0;
            let mut scan = rays;
            while scan != 0 {
                let k = scan.trailing_zeros() as usize;
                scan &= scan - 1;
                (lanes[len], sub[len]) = (k, self.rays[k]);
                limits[len] = reach(&self.found[k], t_max[k]);
                len += 1;
            }
            let mut found = [None; PACKET];
            mesh.intersect_packet(&sub[..len], 0.0, &limits[..len], &mut found[..len]);
            for (&k, h) in lanes.iter().zip(found).take(len) {
                if let Some(t) = h.and_then(|h| keep(&mut self.found[k], i, h)) {
                    t_max[k] = t;
                    closer |= 1 << k;
                }
            }
            return closer;
        }
        let mut scan = rays;
        while scan != 0 {
            let k = scan.trailing_zeros() as usize;
            scan &= scan - 1;
            if let Some(t) = self.consider(k, i, t_max[k]) {
                t_max[k] = t;
                closer |= 1 << k;
            }
        }
        closer
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

    /// Every value of a hit, as bits.
    fn bits(h: &Option<Hit>) -> Option<(Vec<u64>, u32, u32, bool)> {
        h.map(|h| {
            let v = [h.point, h.normal, h.shading_normal, h.color]
                .iter()
                .flat_map(|v| v.to_array())
                .chain([h.t, h.shape_uv.x, h.shape_uv.y])
                .map(f64::to_bits)
                .collect();
            (v, h.primitive, h.material, h.front_face)
        })
    }

    #[test]
    fn packets_answer_each_ray_as_it_is_answered_alone() {
        use crate::geometry::{Mesh, MeshInstance};
        use crate::math::Transform;
        use crate::math::rng::PixelRng;
        use std::sync::Arc;
        let mut rng = PixelRng::new(41, 0, 0);
        // A bumpy 12×12 grid over [0, 12]² at y ≈ 0.
        let mesh = Arc::new(Mesh::new(crate::geometry::mesh::tests::bumpy_grid(12, 41)).unwrap());
        let placed = |transform: Option<Transform>, material: u32| Primitive {
            shape: Shape::Mesh(Box::new(MeshInstance {
                mesh: mesh.clone(),
                transform,
                materials: Arc::from([material]),
            })),
            material,
        };
        let tilted = glam::DAffine3::from_scale_rotation_translation(
            DVec3::new(0.5, 1.5, 0.7),
            glam::DQuat::from_euler(glam::EulerRot::XYZ, 0.4, 0.3, -0.2),
            DVec3::new(-3.0, 2.0, 1.0),
        );
        let mut primitives = vec![
            placed(None, 0),
            // The same placement again: every hit on it ties with the first.
            placed(None, 1),
            placed(Transform::from_affine(tilted), 2),
            Primitive {
                shape: Shape::Plane(Plane {
                    normal: DVec3::Y,
                    distance: -0.1,
                }),
                material: 3,
            },
        ];
        for i in 0..30 {
            let center = DVec3::new(
                rng.uniform() * 12.0,
                rng.uniform() * 3.0,
                rng.uniform() * 12.0,
            );
            let sphere = Shape::Sphere(Sphere {
                center,
                radius: 0.2 + rng.uniform(),
            });
            primitives.push(Primitive {
                shape: sphere.clone(),
                material: 4,
            });
            if i % 5 == 0 {
                // A twin: ties again.
                primitives.push(Primitive {
                    shape: sphere,
                    material: 5,
                });
            }
        }
        let scene = Aggregate::new(primitives);
        let (mut packets, mut hits) = (0, 0);
        for case in 0..3_000 {
            // Eight rays through neighbouring pixels of a camera looking at
            // the grid from above, one tilted row, or anywhere.
            let eye = DVec3::new(
                rng.uniform() * 16.0 - 2.0,
                4.0 + rng.uniform() * 6.0,
                rng.uniform() * 16.0 - 2.0,
            );
            let target = DVec3::new(rng.uniform() * 12.0, 0.0, rng.uniform() * 12.0);
            let pixel = [1e-3, 2e-2, 0.3][case % 3];
            let t_max = [f64::INFINITY, (target - eye).length(), 3.0][case % 5 % 3];
            let rays: Vec<Ray> = (0..1 + case % 8)
                .map(|k| {
                    let (dx, dy) = ((k % 4) as f64, (k / 4) as f64);
                    let aim = if case % 7 == 6 {
                        DVec3::new(
                            rng.uniform() - 0.5,
                            rng.uniform() - 0.5,
                            rng.uniform() - 0.5,
                        )
                    } else {
                        target - eye + DVec3::new(dx * pixel, 0.0, dy * pixel)
                    };
                    Ray::new(eye, aim.normalize())
                })
                .collect();
            let mut together = vec![None; rays.len()];
            scene.closest_hit_packet(&rays, t_max, &mut together);
            for (ray, got) in rays.iter().zip(&together) {
                let alone = scene.closest_hit(ray, t_max);
                assert_eq!(bits(got), bits(&alone), "case {case}");
                hits += usize::from(alone.is_some_and(|h| h.primitive < 3));
            }
            packets += 1;
        }
        assert!(packets == 3_000 && hits > 5_000, "{hits} mesh hits");
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
