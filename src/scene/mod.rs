//! Scene loading: the TOML format ([`format`]), parsing section by section
//! ([`load`]), validation and construction of the runtime [`Scene`]
//! ([`build`]), errors located by line and column ([`error`]).

pub mod build;
pub mod error;
pub mod format;
pub mod load;

pub use error::{Diagnostic, SceneError};

use std::path::Path;

use glam::DVec3;

use crate::accel::Aggregate;
use crate::camera::Camera;
use crate::lights::Light;
use crate::render::RenderSettings;
use crate::shading::Material;

/// The built-in demo scene (Whitted's 1980 picture), used when no scene
/// file is given.
pub const DEFAULT_SCENE: &str = include_str!("../../scenes/whitted.toml");

/// A scene ready to render.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The camera.
    pub camera: Camera,
    /// All primitives.
    pub aggregate: Aggregate,
    /// Materials, indexed by `Primitive::material`.
    pub materials: Vec<Material>,
    /// Light sources.
    pub lights: Vec<Light>,
    /// Colour of rays that hit nothing.
    pub background: DVec3,
    /// Ambient light Ia.
    pub ambient: DVec3,
    /// Transparent objects let light through to shadow feelers (scaled by kt).
    pub transparent_shadows: bool,
    /// The render settings the file asks for.
    pub settings: RenderSettings,
}

impl Scene {
    /// Parses and validates scene text; `origin` names it in messages.
    /// Every problem found is reported, not just the first.
    pub fn from_toml(source: &str, origin: &str) -> Result<Scene, SceneError> {
        let mut diags = error::Diagnostics::new(source);
        let scene = load::parse(source, &mut diags)
            .and_then(|file| build::build(file, 0..source.len(), &mut diags));
        match scene {
            Some(scene) if diags.is_empty() => Ok(scene),
            _ => Err(SceneError::Invalid {
                origin: origin.to_string(),
                diagnostics: diags.into_diagnostics(),
            }),
        }
    }

    /// Reads and builds the scene file at `path`.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let source = std::fs::read_to_string(path).map_err(|source| SceneError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Scene::from_toml(&source, &path.display().to_string())
    }

    /// The built-in demo scene.
    pub fn demo() -> Scene {
        Scene::from_toml(DEFAULT_SCENE, "<built-in scene>").expect("the built-in scene is valid")
    }
}
