//! The ray scene: meshes with ids and transforms, each built once (its
//! BVH) and shared by every query.

use std::path::Path;
use std::sync::{Arc, OnceLock};

use glam::{DAffine3, DMat4, DVec3};

use super::QueryError;
use super::rays::{Coordinates, check_points};
use crate::geometry::{Aabb, Mesh, MeshData, MeshError};
use crate::math::Transform;
use crate::scene::LoadOptions;
use crate::scene::models::load_model;
use crate::scene::resources::Resources;

/// A mesh built for a file, shared by its placements, with whether it is
/// closed (found once for all of them).
type Shared = (Arc<Mesh>, Arc<OnceLock<bool>>);

/// One mesh of a [`RayScene`], placed.
#[derive(Clone, Debug)]
pub(crate) struct Placed {
    pub mesh: Arc<Mesh>,
    /// Object to world; `None`: placed as it is.
    pub transform: Option<Transform>,
    /// World-space bounds.
    pub bounds: Aabb,
    /// Whether the mesh is closed (asked by `contains`, found once).
    closed: Arc<OnceLock<bool>>,
}

impl Placed {
    /// `origin`, `direction` in the mesh's own space: the direction mapped
    /// but not renormalised, so t is the same in both (as the renderer's
    /// `MeshInstance` does it).
    #[inline]
    pub fn local(&self, origin: DVec3, direction: DVec3) -> (DVec3, DVec3) {
        match &self.transform {
            None => (origin, direction),
            Some(t) => (
                t.to_object.transform_point3(origin),
                t.to_object.transform_vector3(direction),
            ),
        }
    }

    /// An object-space geometric normal in world space.
    #[inline]
    pub fn world_normal(&self, normal: DVec3) -> DVec3 {
        match &self.transform {
            None => normal,
            Some(t) => t.normal(normal),
        }
    }

    /// Whether object-space point `p` lies in the mesh's bounds.
    pub fn bounds_contain_local(&self, p: DVec3) -> bool {
        let b = self.mesh.bounds();
        p.cmpge(b.min).all() && p.cmple(b.max).all()
    }

    pub fn is_closed(&self) -> bool {
        *self.closed.get_or_init(|| self.mesh.is_closed())
    }
}

/// Triangle meshes for ray queries, each with an id (0, 1, … in the order
/// they were added) and an optional transform; see the [module](super).
/// A clone shares the meshes (their trees are built once).
#[derive(Clone, Debug, Default)]
pub struct RayScene {
    pub(crate) meshes: Vec<Placed>,
}

impl RayScene {
    /// An empty scene.
    pub fn new() -> Self {
        RayScene::default()
    }

    /// Adds a mesh of `vertices` (`x, y, z` of each, in double or single
    /// precision: [`Coordinates`]) and `faces` (three
    /// vertex indices per triangle, counter-clockwise seen from the
    /// outside), placed by `transform` (object to world, an affine 4×4
    /// matrix: last row 0, 0, 0, 1), and builds its BVH. Returns its id.
    pub fn add_mesh<'v>(
        &mut self,
        vertices: impl Into<Coordinates<'v>>,
        faces: &[u32],
        transform: Option<DMat4>,
    ) -> Result<u32, QueryError> {
        let vertices = vertices.into();
        let n = check_points("vertices", vertices)?;
        if faces.is_empty() {
            return Err(QueryError::invalid("faces", "is empty"));
        }
        if !faces.len().is_multiple_of(3) {
            return Err(QueryError::invalid(
                "faces",
                format!("{} indices are not rows of 3", faces.len()),
            ));
        }
        let data = MeshData {
            positions: (0..n).map(|k| vertices.point(k)).collect(),
            triangles: faces.chunks_exact(3).map(|f| [f[0], f[1], f[2]]).collect(),
            ..MeshData::default()
        };
        let transform = transform.map(affine).transpose()?;
        let mesh = Mesh::new(data).map_err(mesh_error)?;
        self.place(Arc::new(mesh), transform, Arc::default())
    }

    /// Every mesh of the model file at `path` (OBJ, PLY, glTF/GLB: what a
    /// scene's `model` reads), each placement as a mesh of its own (a glTF
    /// mesh placed by several nodes is built once). The file is read under
    /// `options`' read policy and limits, as a scene reads it: the file's
    /// own folder and `allow_read`. Returns the new meshes' ids.
    pub fn add_file(&mut self, path: &Path, options: &LoadOptions) -> Result<Vec<u32>, QueryError> {
        let dir = path.parent().unwrap_or(Path::new("."));
        let mut res = Resources::new(dir, options);
        let model = load_model(path, &mut res).map_err(|e| QueryError::Load(e.to_string()))?;
        let mut built: Vec<Option<Shared>> = vec![None; model.meshes.len()];
        let mut meshes: Vec<Option<MeshData>> = model.meshes.into_iter().map(Some).collect();
        let mut ids = Vec::new();
        for (index, matrix) in model.placements {
            let slot = built.get_mut(index).ok_or_else(|| {
                QueryError::Load(format!("{}: a placement names no mesh", path.display()))
            })?;
            if slot.is_none() {
                let data = meshes[index].take().unwrap_or_default();
                let mesh = Mesh::new(data)
                    .map_err(|e| QueryError::Load(format!("{}: {e}", path.display())))?;
                *slot = Some((Arc::new(mesh), Arc::default()));
            }
            let Some((mesh, closed)) = slot.clone() else {
                continue;
            };
            let transform = if matrix == DMat4::IDENTITY {
                None
            } else {
                Some(
                    affine(matrix)
                        .map_err(|e| QueryError::Load(format!("{}: {e}", path.display())))?,
                )
            };
            ids.push(self.place(mesh, transform, closed)?);
        }
        Ok(ids)
    }

    /// A scene of the model file at `path` (see [`add_file`](Self::add_file)).
    pub fn from_file(path: &Path, options: &LoadOptions) -> Result<Self, QueryError> {
        let mut scene = RayScene::new();
        scene.add_file(path, options)?;
        Ok(scene)
    }

    fn place(
        &mut self,
        mesh: Arc<Mesh>,
        transform: Option<Transform>,
        closed: Arc<OnceLock<bool>>,
    ) -> Result<u32, QueryError> {
        let id = u32::try_from(self.meshes.len())
            .map_err(|_| QueryError::invalid("vertices", "too many meshes"))?;
        let b = mesh.bounds();
        let bounds = match &transform {
            None => b,
            Some(t) => b.transformed(|p| t.point(p)),
        };
        self.meshes.push(Placed {
            mesh,
            transform,
            bounds,
            closed,
        });
        Ok(id)
    }

    /// Number of meshes.
    pub fn mesh_count(&self) -> usize {
        self.meshes.len()
    }

    /// Number of triangles, a mesh placed twice counted twice.
    pub fn triangle_count(&self) -> usize {
        self.meshes.iter().map(|m| m.mesh.triangle_count()).sum()
    }

    /// Heap memory of the meshes and their BVHs in bytes (a mesh placed
    /// several times counted once).
    pub fn memory_bytes(&self) -> usize {
        let mut seen: Vec<*const Mesh> = Vec::new();
        let mut bytes = 0;
        for m in &self.meshes {
            let p = Arc::as_ptr(&m.mesh);
            if !seen.contains(&p) {
                seen.push(p);
                bytes += m.mesh.memory_bytes();
            }
        }
        bytes
    }

    /// World-space bounds of all meshes (empty scene: an empty box).
    pub fn bounds(&self) -> Aabb {
        self.meshes
            .iter()
            .fold(Aabb::EMPTY, |acc, m| acc.union(&m.bounds))
    }

    /// Whether mesh `id` is closed (every edge shared by two triangles that
    /// run it in opposite directions): what [`contains`](Self::contains)
    /// needs of every mesh; `None` for an unknown id.
    pub fn is_closed(&self, id: u32) -> Option<bool> {
        self.meshes.get(id as usize).map(Placed::is_closed)
    }
}

/// A 4×4 object-to-world matrix as a transform: affine, finite and
/// invertible, or an error naming `transform`.
fn affine(m: DMat4) -> Result<Transform, QueryError> {
    if m.row(3) != glam::DVec4::new(0.0, 0.0, 0.0, 1.0) {
        return Err(QueryError::invalid(
            "transform",
            "is not affine (its last row must be 0, 0, 0, 1)",
        ));
    }
    Transform::from_affine(DAffine3::from_mat4(m)).ok_or_else(|| {
        QueryError::invalid(
            "transform",
            "is singular, not finite, or scales beyond the supported range",
        )
    })
}

fn mesh_error(e: MeshError) -> QueryError {
    let argument = match e {
        MeshError::NotFinite { .. } | MeshError::CountMismatch { .. } => "vertices",
        MeshError::Empty | MeshError::IndexOutOfRange { .. } | MeshError::TooLarge => "faces",
    };
    QueryError::invalid(argument, e.to_string())
}
