//! Model files → mesh data and materials: OBJ + MTL (tobj), PLY (ply-rs-bw)
//! and glTF 2.0 (gltf). Errors name the file and, where the format has
//! them, the line or element.

mod gltf;
pub mod keyframes;
mod obj;
mod ply;

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{DMat4, DVec3};

use super::resources::Resources;
use crate::geometry::MeshData;
use crate::lights::Light;
use crate::shading::Material;

/// A model file, read: its meshes, where they are placed, and the
/// materials their triangles use.
#[derive(Debug)]
pub struct Model {
    /// The meshes (material slots index `materials`), each in its own space.
    pub meshes: Vec<MeshData>,
    /// Placements: (index into `meshes`, mesh to model space). A mesh placed
    /// by several glTF nodes is stored once.
    pub placements: Vec<(usize, DMat4)>,
    /// Materials by slot; empty when the file brings none.
    pub materials: Vec<Material>,
    /// Things read but not used, for the user to know.
    pub warnings: Vec<String>,
    /// Lights the file brings (glTF), in model space.
    pub lights: Vec<Light>,
    /// The file's cameras (glTF), in model space, in node order.
    pub cameras: Vec<ModelCamera>,
    /// The file's node animations (glTF), if any channel moves a node:
    /// placements, lights and cameras at another time. The fields above
    /// are its pose at time 0.
    pub motion: Option<Arc<ModelMotion>>,
}

pub use gltf::Motion as ModelMotion;

/// Where a model's meshes, lights and cameras are at one time (see
/// [`ModelMotion::pose`]); the fields mean what [`Model`]'s do.
#[derive(Debug, Default)]
pub struct Pose {
    /// (index into the model's meshes, mesh to model space).
    pub placements: Vec<(usize, DMat4)>,
    /// Lights in model space.
    pub lights: Vec<Light>,
    /// Cameras in model space, in node order.
    pub cameras: Vec<ModelCamera>,
}

/// How a model's camera projects.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ModelProjection {
    /// Vertical field of view in radians.
    Perspective {
        /// The angle.
        yfov: f64,
    },
    /// Parallel rays over a film `2·ymag` tall.
    Orthographic {
        /// Half the film's height.
        ymag: f64,
    },
}

/// A camera found in a model file.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelCamera {
    /// What `camera = "NAME"` and `--camera NAME` match: the node's name,
    /// else the camera's, else `cameras[i]`.
    pub name: String,
    /// The camera's own name, also matched.
    pub alias: Option<String>,
    /// Width over height of the image it was made for, if it says.
    pub aspect_ratio: Option<f64>,
    /// How it projects.
    pub projection: ModelProjection,
    /// Eye position.
    pub position: DVec3,
    /// Unit viewing direction.
    pub forward: DVec3,
    /// Unit up direction.
    pub up: DVec3,
}

impl ModelCamera {
    /// Whether `name` names this camera (its node's name or its own).
    pub fn is_named(&self, name: &str) -> bool {
        self.name == name || self.alias.as_deref() == Some(name)
    }
}

/// Why a model file could not be used.
#[derive(Debug, PartialEq, Eq)]
pub struct ModelError {
    /// The file.
    pub path: PathBuf,
    /// The line (text formats), when known.
    pub line: Option<usize>,
    /// What is wrong, naming the element where the format has no lines.
    pub message: String,
}

impl fmt::Display for ModelError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(line) => write!(f, "{}:{line}: {}", self.path.display(), self.message),
            None => write!(f, "{}: {}", self.path.display(), self.message),
        }
    }
}

impl ModelError {
    fn new(path: &Path, line: Option<usize>, message: impl Into<String>) -> Self {
        ModelError {
            path: path.to_path_buf(),
            line,
            message: message.into(),
        }
    }
}

/// Reads the model at `path`, choosing the format by extension; every file
/// it reads (the model, material libraries, buffers, textures) goes through
/// `res`'s read policy, textures through its cache.
pub fn load_model(path: &Path, res: &mut Resources) -> Result<Model, ModelError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("obj") => obj::load(path, res),
        Some("ply") => ply::load(path, res),
        Some("gltf" | "glb") => gltf::load(path, res),
        _ => Err(ModelError::new(
            path,
            None,
            "unknown model format; expected a .obj, .ply, .gltf or .glb file",
        )),
    }
}

impl Model {
    /// A model of one mesh placed as it is (OBJ, PLY).
    pub fn single(mesh: MeshData, materials: Vec<Material>, warnings: Vec<String>) -> Model {
        Model {
            meshes: vec![mesh],
            placements: vec![(0, DMat4::IDENTITY)],
            materials,
            warnings,
            lights: Vec::new(),
            cameras: Vec::new(),
            motion: None,
        }
    }
}

/// `s` cut to at most `max` characters (with an ellipsis), so that a huge
/// value in a file is not echoed whole.
pub(crate) fn cut(s: &str, max: usize) -> String {
    match s.char_indices().nth(max) {
        None => s.to_string(),
        Some((end, _)) => format!("{}…", &s[..end]),
    }
}

/// Splits each polygon (vertex indices in order) into a fan of triangles,
/// which is exact for the convex polygons models are made of.
pub(crate) fn fan(polygon: &[u32]) -> impl Iterator<Item = [u32; 3]> + '_ {
    (1..polygon.len().saturating_sub(1)).map(move |i| [polygon[0], polygon[i], polygon[i + 1]])
}
