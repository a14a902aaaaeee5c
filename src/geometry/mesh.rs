//! Triangle meshes: shared vertex data, watertight triangle tests, a BVH
//! over the triangles, smooth (interpolated) or flat normals, texture
//! coordinates and per-triangle materials.

use glam::{DVec2, DVec3};
use thiserror::Error;

use super::Aabb;
use super::triangle::{WatertightRay, triangle_hit};
use crate::accel::bvh::{BoxRay, Bvh};

/// What a loader hands over to build a mesh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshData {
    /// Vertex positions.
    pub positions: Vec<DVec3>,
    /// Per-vertex normals (empty: flat shading).
    pub normals: Vec<DVec3>,
    /// Per-vertex texture coordinates (empty: none).
    pub uvs: Vec<DVec2>,
    /// Vertex indices of each triangle, counter-clockwise seen from the front.
    pub triangles: Vec<[u32; 3]>,
    /// Per-triangle material slot (empty: all slot 0).
    pub materials: Vec<u32>,
}

/// Why mesh data is unusable.
#[derive(Debug, Error, PartialEq)]
pub enum MeshError {
    /// No triangles.
    #[error("the mesh has no triangles")]
    Empty,
    /// A triangle refers past the vertex list.
    #[error("triangle {triangle} refers to vertex {index}, but there are only {count} vertices")]
    IndexOutOfRange {
        /// The triangle.
        triangle: usize,
        /// The bad index.
        index: u32,
        /// Number of vertices.
        count: usize,
    },
    /// A position, normal or texture coordinate is NaN or infinite.
    #[error("{what} {index} is not finite")]
    NotFinite {
        /// "vertex", "normal" or "texture coordinate".
        what: &'static str,
        /// Its index.
        index: usize,
    },
    /// Normal or texture coordinate count differs from the vertex count.
    #[error("{what}: {got} given for {expected} vertices")]
    CountMismatch {
        /// "normals" or "texture coordinates".
        what: &'static str,
        /// How many there are.
        got: usize,
        /// How many vertices.
        expected: usize,
    },
    /// More than 2³² − 1 of something.
    #[error("the mesh is too large")]
    TooLarge,
}

/// A triangle mesh with its BVH, in object space.
#[derive(Clone, Debug, PartialEq)]
pub struct Mesh {
    positions: Vec<DVec3>,
    normals: Vec<DVec3>,
    uvs: Vec<DVec2>,
    /// Triangles in BVH leaf order.
    triangles: Vec<[u32; 3]>,
    /// Material slot per triangle (BVH order; empty: slot 0).
    materials: Vec<u32>,
    bvh: Bvh,
}

/// A ray-mesh hit with the surface at it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshHit {
    /// Ray parameter.
    pub t: f64,
    /// Unit geometric normal (right-hand rule of the vertex order).
    pub normal: DVec3,
    /// Unit shading normal: interpolated vertex normals, or `normal`.
    pub shading_normal: DVec3,
    /// Interpolated texture coordinates (zero without any).
    pub uv: DVec2,
    /// Material slot of the triangle.
    pub material: u32,
}

impl Mesh {
    /// Checks `data` and builds the BVH.
    pub fn new(data: MeshData) -> Result<Mesh, MeshError> {
        let MeshData {
            positions,
            normals,
            uvs,
            triangles,
            materials,
        } = data;
        if triangles.is_empty() {
            return Err(MeshError::Empty);
        }
        if positions.len() > u32::MAX as usize || triangles.len() > u32::MAX as usize {
            return Err(MeshError::TooLarge);
        }
        for (what, values) in [("vertex", &positions), ("normal", &normals)] {
            if let Some(index) = values.iter().position(|v| !v.is_finite()) {
                return Err(MeshError::NotFinite { what, index });
            }
        }
        if let Some(index) = uvs.iter().position(|v| !v.is_finite()) {
            return Err(MeshError::NotFinite {
                what: "texture coordinate",
                index,
            });
        }
        for (what, got) in [
            ("normals", normals.len()),
            ("texture coordinates", uvs.len()),
        ] {
            if got != 0 && got != positions.len() {
                return Err(MeshError::CountMismatch {
                    what,
                    got,
                    expected: positions.len(),
                });
            }
        }
        for (triangle, t) in triangles.iter().enumerate() {
            if let Some(&index) = t.iter().find(|&&i| i as usize >= positions.len()) {
                return Err(MeshError::IndexOutOfRange {
                    triangle,
                    index,
                    count: positions.len(),
                });
            }
        }
        let bvh = Bvh::build(
            triangles
                .iter()
                .map(|t| Aabb::from_points(t.iter().map(|&i| positions[i as usize]))),
        );
        // Store triangles in leaf order, so leaves index them directly.
        let ordered: Vec<[u32; 3]> = bvh.order().iter().map(|&i| triangles[i as usize]).collect();
        let materials = if materials.is_empty() {
            materials
        } else {
            bvh.order()
                .iter()
                .map(|&i| materials.get(i as usize).copied().unwrap_or(0))
                .collect()
        };
        Ok(Mesh {
            positions,
            normals,
            uvs,
            triangles: ordered,
            materials,
            bvh,
        })
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Bounds in object space.
    pub fn bounds(&self) -> Aabb {
        self.bvh.bounds()
    }

    /// Approximate heap memory in bytes.
    pub fn memory_bytes(&self) -> usize {
        self.positions.len() * 24
            + self.normals.len() * 24
            + self.uvs.len() * 16
            + self.triangles.len() * 12
            + self.materials.len() * 4
            + self.bvh.memory_bytes()
    }

    #[inline]
    fn corners(&self, triangle: usize) -> [DVec3; 3] {
        let [a, b, c] = self.triangles[triangle];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// The nearest hit of `origin + t·direction` (direction need not be
    /// unit) with t in (t_min, t_max).
    pub fn intersect(
        &self,
        origin: DVec3,
        direction: DVec3,
        t_min: f64,
        t_max: f64,
    ) -> Option<MeshHit> {
        let ray = WatertightRay::new(origin, direction);
        let mut best = None;
        self.bvh
            .closest(&BoxRay::new(origin, direction), t_max, |position, t_max| {
                let [a, b, c] = self.corners(position);
                let h = triangle_hit(&ray, a, b, c, t_min, t_max)?;
                best = Some((position, h));
                Some(h.t)
            });
        let (triangle, h) = best?;
        Some(self.surface(triangle, h.barycentric, h.t))
    }

    /// Whether any triangle is hit with t in (t_min, t_max).
    pub fn any_hit(&self, origin: DVec3, direction: DVec3, t_min: f64, t_max: f64) -> bool {
        let ray = WatertightRay::new(origin, direction);
        self.bvh
            .any(&BoxRay::new(origin, direction), t_max, |position| {
                let [a, b, c] = self.corners(position);
                triangle_hit(&ray, a, b, c, t_min, t_max).is_some()
            })
    }

    fn surface(&self, triangle: usize, bary: DVec3, t: f64) -> MeshHit {
        let [ia, ib, ic] = self.triangles[triangle].map(|i| i as usize);
        let [a, b, c] = self.corners(triangle);
        let normal = (b - a).cross(c - a).normalize_or_zero();
        let interpolate3 = |v: &[DVec3]| bary.x * v[ia] + bary.y * v[ib] + bary.z * v[ic];
        let shading_normal = if self.normals.is_empty() {
            normal
        } else {
            interpolate3(&self.normals)
                .try_normalize()
                .unwrap_or(normal)
        };
        let uv = if self.uvs.is_empty() {
            DVec2::ZERO
        } else {
            bary.x * self.uvs[ia] + bary.y * self.uvs[ib] + bary.z * self.uvs[ic]
        };
        MeshHit {
            t,
            normal,
            shading_normal,
            uv,
            material: self.materials.get(triangle).copied().unwrap_or(0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit cube from (0,0,0) to (1,1,1), 12 triangles, outward winding.
    pub fn cube() -> MeshData {
        let positions = (0..8)
            .map(|i| DVec3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64))
            .collect();
        let quads = [
            [0, 2, 3, 1],
            [4, 5, 7, 6], // z = 0, z = 1
            [0, 1, 5, 4],
            [2, 6, 7, 3], // y = 0, y = 1
            [0, 4, 6, 2],
            [1, 3, 7, 5], // x = 0, x = 1
        ];
        let triangles = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        MeshData {
            positions,
            triangles,
            ..Default::default()
        }
    }

    #[test]
    fn cube_hits_have_outward_normals_and_distances() {
        let m = Mesh::new(cube()).unwrap();
        assert_eq!(m.triangle_count(), 12);
        let h = m
            .intersect(DVec3::new(0.3, 0.6, 5.0), -DVec3::Z, 0.0, f64::INFINITY)
            .unwrap();
        assert!((h.t - 4.0).abs() < 1e-12);
        assert!((h.normal - DVec3::Z).length() < 1e-12, "{}", h.normal);
        // From inside, the far wall.
        let h = m
            .intersect(DVec3::splat(0.5), DVec3::X, 0.0, f64::INFINITY)
            .unwrap();
        assert!((h.t - 0.5).abs() < 1e-12 && (h.normal - DVec3::X).length() < 1e-12);
        assert!(m.any_hit(DVec3::splat(0.5), DVec3::X, 0.0, 0.6));
        assert!(!m.any_hit(DVec3::splat(0.5), DVec3::X, 0.0, 0.4));
        // Along the cube's diagonal edge between two triangles of a face.
        let h = m
            .intersect(DVec3::new(0.5, 0.5, -3.0), DVec3::Z, 0.0, f64::INFINITY)
            .unwrap();
        assert!((h.t - 3.0).abs() < 1e-12);
    }

    #[test]
    fn smooth_normals_and_uvs_interpolate() {
        let data = MeshData {
            positions: vec![DVec3::ZERO, DVec3::X, DVec3::Y],
            normals: vec![DVec3::Z, DVec3::Z, DVec3::new(0.0, 1.0, 1.0)],
            uvs: vec![DVec2::ZERO, DVec2::X, DVec2::Y],
            triangles: vec![[0, 1, 2]],
            materials: vec![3],
        };
        let m = Mesh::new(data).unwrap();
        let h = m
            .intersect(DVec3::new(0.25, 0.5, 1.0), -DVec3::Z, 0.0, f64::INFINITY)
            .unwrap();
        assert!((h.uv - DVec2::new(0.25, 0.5)).length() < 1e-12);
        let expected = (0.5 * DVec3::Z + 0.5 * DVec3::new(0.0, 1.0, 1.0)).normalize();
        assert!((h.shading_normal - expected).length() < 1e-12);
        assert_eq!(h.normal, DVec3::Z);
        assert_eq!(h.material, 3);
    }

    #[test]
    fn bad_data_is_refused() {
        let mut d = cube();
        d.triangles[5] = [0, 1, 8];
        assert_eq!(
            Mesh::new(d),
            Err(MeshError::IndexOutOfRange {
                triangle: 5,
                index: 8,
                count: 8
            })
        );
        let mut d = cube();
        d.positions[2].y = f64::NAN;
        assert_eq!(
            Mesh::new(d),
            Err(MeshError::NotFinite {
                what: "vertex",
                index: 2
            })
        );
        let mut d = cube();
        d.normals = vec![DVec3::Z; 3];
        assert!(matches!(Mesh::new(d), Err(MeshError::CountMismatch { .. })));
        assert_eq!(Mesh::new(MeshData::default()), Err(MeshError::Empty));
    }
}
