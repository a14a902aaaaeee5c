//! Scene loading: the TOML format ([`format`](mod@format)), parsing section by section
//! ([`load`]), validation and construction of the runtime [`Scene`]
//! ([`build`]), errors located by line and column ([`error`]).

pub mod animation;
pub mod build;
pub mod dict;
pub mod error;
pub mod format;
pub mod load;
pub mod models;
pub mod resources;
pub mod tables;

pub use error::{Diagnostic, SceneError};
pub use resources::LoadOptions;

use std::path::Path;

use glam::DVec3;

use crate::accel::Aggregate;
use crate::camera::Camera;
use crate::lights::Light;
use crate::settings::RenderSettings;
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
    /// What loading noticed but could use anyway (ignored parts of models).
    pub warnings: Vec<String>,
    /// What loading built and what it cost.
    pub inventory: Inventory,
    /// `[animation]`, if the file has one.
    pub animation: Option<animation::Animation>,
    /// Whether any value is keyed per frame (then each frame is built
    /// anew).
    pub animated: bool,
    /// What the file calls its objects, materials and lights.
    pub names: Names,
    /// With an open shutter and something keyed: the scene at each of the
    /// shutter's instants (`RenderSettings::shutter`), in order; camera
    /// sample at time t looks at the instant whose share holds t. Empty
    /// otherwise: nothing moves.
    pub motion: Vec<Scene>,
}

/// Names from the scene file, for messages and `prism explain`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Names {
    /// Named objects' primitives, by primitive index (unnamed ones are
    /// absent).
    pub objects: std::collections::BTreeMap<u32, String>,
    /// Material names, by material index.
    pub materials: Vec<String>,
    /// Light names, by light index.
    pub lights: Vec<String>,
}

/// What a scene holds beyond its primitives, and what building it cost.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Inventory {
    /// Time spent building the acceleration structure over the primitives
    /// (after files were read and checked).
    pub build_time: std::time::Duration,
    /// Textures decoded (each file once).
    pub textures: usize,
    /// Bytes of decoded texels.
    pub texture_bytes: u64,
    /// Every file the scene read besides its own text (models, MTL,
    /// textures), resolved, with the SHA-256 of its bytes.
    pub files_read: Vec<resources::FileRead>,
    /// SHA-256 (hex) over the scene text and every file it read, in read
    /// order: equal hashes mean equal input, wherever the files lie.
    pub content_hash: String,
    /// The model camera chosen by name when loading (`--camera NAME`,
    /// `LoadOptions::camera`): not in the scene's text, yet it changes
    /// every pixel, so a part or checkpoint records it.
    pub camera: Option<String>,
}

/// Counts of what a scene holds, for `prism check` and the summary line.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Census {
    /// Spheres (and ellipsoids), planes, polygons, mesh placements.
    pub spheres: usize,
    /// Infinite planes.
    pub planes: usize,
    /// Polygons.
    pub polygons: usize,
    /// Boxes.
    pub boxes: usize,
    /// Cones and cylinders.
    pub cones: usize,
    /// Discs.
    pub discs: usize,
    /// Tori.
    pub tori: usize,
    /// Mesh placements (instances).
    pub mesh_instances: usize,
    /// Distinct meshes (each stored once however often placed).
    pub meshes: usize,
    /// Triangles stored (over distinct meshes).
    pub triangles: usize,
    /// Triangles placed (over instances).
    pub placed_triangles: usize,
    /// CSG operations (each node of a CSG tree; a top-level union's
    /// children are placed as objects of their own and not counted here).
    pub csg: usize,
    /// Estimated bytes of geometry, acceleration structures and textures.
    pub memory_bytes: u64,
}

/// Adds `shape` (and, for CSG, its operands) to the census.
fn count_shape(
    shape: &crate::accel::Shape,
    c: &mut Census,
    bytes: &mut u64,
    seen: &mut Vec<*const crate::geometry::Mesh>,
) {
    use crate::accel::Shape;
    use std::mem::size_of;
    match shape {
        Shape::Sphere(_) | Shape::Ellipsoid(_) => c.spheres += 1,
        Shape::Plane(_) => c.planes += 1,
        Shape::Cuboid(_) => {
            c.boxes += 1;
            *bytes += size_of::<crate::geometry::Cuboid>() as u64;
        }
        Shape::Cone(_) => {
            c.cones += 1;
            *bytes += size_of::<crate::geometry::Cone>() as u64;
        }
        Shape::Torus(_) => {
            c.tori += 1;
            *bytes += size_of::<crate::geometry::Torus>() as u64;
        }
        Shape::Disc(_) => {
            c.discs += 1;
            *bytes += size_of::<crate::geometry::Disc>() as u64;
        }
        Shape::Polygon(poly) => {
            c.polygons += 1;
            *bytes += (poly.vertices().len() * 40) as u64;
        }
        Shape::Mesh(m) => {
            c.mesh_instances += 1;
            c.placed_triangles += m.mesh.triangle_count();
            let ptr = std::sync::Arc::as_ptr(&m.mesh);
            if !seen.contains(&ptr) {
                seen.push(ptr);
                c.meshes += 1;
                c.triangles += m.mesh.triangle_count();
                *bytes += m.mesh.memory_bytes() as u64;
            }
        }
        Shape::Csg(csg) => {
            c.csg += 1;
            let n = csg.children().len() as u64;
            // The node, its operands and their boxes (and the tree over
            // them when there are many).
            *bytes += size_of::<crate::geometry::Csg>() as u64
                + n * (size_of::<crate::geometry::CsgChild>() as u64 + 56 + 64);
            for child in csg.children() {
                count_shape(&child.shape, c, bytes, seen);
            }
        }
    }
}

impl Scene {
    /// Counts the scene's primitives by kind, its meshes and triangles, and
    /// estimates its memory.
    pub fn census(&self) -> Census {
        let mut c = Census::default();
        let mut seen: Vec<*const crate::geometry::Mesh> = Vec::new();
        let mut bytes = std::mem::size_of_val(self.aggregate.primitives()) as u64;
        for p in self.aggregate.primitives() {
            count_shape(&p.shape, &mut c, &mut bytes, &mut seen);
        }
        // The top-level tree: about two nodes' worth per primitive.
        bytes += 64 * self.aggregate.primitives().len() as u64;
        c.memory_bytes = bytes + self.inventory.texture_bytes;
        c
    }
}

impl Scene {
    /// Parses and validates scene text; `origin` names it in messages and
    /// model files are looked up from the current folder. Every problem
    /// found is reported, not just the first.
    pub fn from_toml(source: &str, origin: &str) -> Result<Scene, SceneError> {
        Scene::from_toml_in(source, origin, Path::new("."))
    }

    /// [`from_toml`](Self::from_toml) with model paths relative to `base_dir`.
    pub fn from_toml_in(source: &str, origin: &str, base_dir: &Path) -> Result<Scene, SceneError> {
        Scene::from_toml_with(source, origin, base_dir, &LoadOptions::default())
    }

    /// [`from_toml_in`](Self::from_toml_in) with `options` (the folders it
    /// may read besides `base_dir`, the texture budget).
    pub fn from_toml_with(
        source: &str,
        origin: &str,
        base_dir: &Path,
        options: &LoadOptions,
    ) -> Result<Scene, SceneError> {
        let checked = check(source, origin, base_dir, options)?;
        let at = error::line_column(source, checked.shutter_at());
        let models = checked.models();
        checked.finish().with_motion(origin, at, |offset| {
            check_at(source, origin, base_dir, options, offset, &models).map(build::Checked::finish)
        })
    }

    /// The scene with its shutter's instants built (see [`motion`](Self::motion))
    /// by `build_at(offset)`, when it has a shutter and keys.
    /// `origin` and `at` (line, column of the `shutter` key) place the
    /// refusal of too many instants.
    fn with_motion(
        mut self,
        origin: &str,
        at: (usize, usize),
        build_at: impl Fn(f64) -> Result<Scene, SceneError>,
    ) -> Result<Scene, SceneError> {
        let Some(shutter) = self.settings.shutter else {
            return Ok(self);
        };
        if !self.animated {
            return Ok(self);
        }
        self.motion_fits().map_err(|message| SceneError::Invalid {
            origin: origin.to_string(),
            diagnostics: vec![Diagnostic {
                line: at.0,
                column: at.1,
                message,
            }],
        })?;
        self.motion = (0..shutter.samples)
            .map(|k| build_at(shutter.instant(k)))
            .collect::<Result<_, _>>()?;
        Ok(self)
    }

    /// Whether the instants of this scene's open shutter fit in
    /// [`MAX_SHUTTER_BYTES`](crate::limits::MAX_SHUTTER_BYTES), each
    /// counted as a copy of the scene; the message says what to lower.
    pub fn motion_fits(&self) -> Result<(), String> {
        let Some(shutter) = self.settings.shutter else {
            return Ok(());
        };
        let each = self.census().memory_bytes.max(1);
        let total = each.saturating_mul(u64::from(shutter.samples));
        if total > crate::limits::MAX_SHUTTER_BYTES {
            return Err(format!(
                "`shutter_samples` = {} builds the scene {} times, about {:.1} GiB of {:.1} MiB each, \
                 more than the {} GiB an open shutter may take; lower `shutter_samples`",
                shutter.samples,
                shutter.samples,
                total as f64 / (1u64 << 30) as f64,
                each as f64 / (1u64 << 20) as f64,
                crate::limits::MAX_SHUTTER_BYTES >> 30
            ));
        }
        Ok(())
    }

    /// Reads and builds the scene file at `path`.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        Scene::load_with(path, &LoadOptions::default())
    }

    /// [`load`](Self::load) with `options`.
    pub fn load_with(path: &Path, options: &LoadOptions) -> Result<Scene, SceneError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        if let Some("gltf" | "glb") = ext.as_deref() {
            return Scene::load_gltf(path, options);
        }
        if let Some(ext @ ("obj" | "ply")) = ext.as_deref() {
            // A model given where a scene belongs: say how to use it rather
            // than report its bytes as hundreds of TOML errors.
            let name = path
                .file_name()
                .map_or(String::new(), |n| n.to_string_lossy().into_owned());
            return Err(SceneError::Invalid {
                origin: path.display().to_string(),
                diagnostics: vec![Diagnostic {
                    line: 1,
                    column: 1,
                    message: format!(
                        "this is a .{ext} model, not a scene; a model goes in a scene file as \
                         [[objects]] with type = \"mesh\" and file = \"{name}\" (see docs/scene-format.md)"
                    ),
                }],
            });
        }
        let bytes = resources::read_regular(
            path,
            resources::Extent::Whole(crate::limits::MAX_SCENE_FILE_BYTES),
        )
        .map_err(|source| SceneError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        let origin = path.display().to_string();
        match String::from_utf8(bytes) {
            Ok(source) => {
                let base_dir = path
                    .parent()
                    .filter(|p| !p.as_os_str().is_empty())
                    .unwrap_or(Path::new("."));
                let checked = check(&source, &origin, base_dir, options)?;
                let wants_motion = checked.shutter_open();
                if !wants_motion {
                    // The text can be large (a million objects): let it go
                    // before the BVH is built.
                    drop(source);
                    return Ok(checked.finish());
                }
                let at = error::line_column(&source, checked.shutter_at());
                // The instants read no model file again.
                let models = checked.models();
                checked.finish().with_motion(&origin, at, |offset| {
                    check_at(&source, &origin, base_dir, options, offset, &models)
                        .map(build::Checked::finish)
                })
            }
            Err(e) => {
                let valid = std::str::from_utf8(&e.as_bytes()[..e.utf8_error().valid_up_to()])
                    .unwrap_or_default();
                let (line, column) = error::line_column(valid, valid.len());
                Err(SceneError::Invalid {
                    origin,
                    diagnostics: vec![Diagnostic {
                        line,
                        column,
                        message: "the file is not valid UTF-8 text; expected a TOML scene".into(),
                    }],
                })
            }
        }
    }

    /// A glTF file as a whole scene: its meshes, cameras and lights, the
    /// default settings, a neutral grey background (Blender's default
    /// world colour) and no ambient term; it reads below its own folder.
    /// Errors are the model's, at 1:1 (the file has no lines to point at).
    fn load_gltf(path: &Path, options: &LoadOptions) -> Result<Scene, SceneError> {
        let name = path
            .file_name()
            .map_or(String::new(), |n| n.to_string_lossy().into_owned());
        let source = gltf_scene_text(&name);
        let base_dir = path
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        let origin = path.display().to_string();
        check(&source, &origin, base_dir, options)
            .map(build::Checked::finish)
            .map_err(|e| match e {
                SceneError::Invalid {
                    origin,
                    diagnostics,
                } => SceneError::Invalid {
                    origin,
                    diagnostics: diagnostics
                        .into_iter()
                        .map(|d| Diagnostic {
                            line: 1,
                            column: 1,
                            message: if d.message.starts_with("missing [camera]") {
                                "the file has no camera: add one in Blender (or place the file \
                                 in a scene file, type = \"mesh\", with a [camera])"
                                    .to_string()
                            } else {
                                d.message
                                    .strip_prefix("objects[0]: ")
                                    .map_or(d.message.clone(), str::to_string)
                            },
                        })
                        .collect(),
                },
                other => other,
            })
    }

    /// The built-in demo scene.
    pub fn demo() -> Scene {
        Scene::from_toml(DEFAULT_SCENE, "<built-in scene>").expect("the built-in scene is valid")
    }
}

/// The scene a glTF file named `name` makes on its own (see
/// [`Scene::load_gltf`]).
fn gltf_scene_text(name: &str) -> String {
    // A TOML string, quoted and escaped whatever the file is called.
    let quoted = toml::Value::String(name.to_string()).to_string();
    format!(
        "[[objects]]\ntype = \"mesh\"\nfile = {quoted}\n\
         [render]\nbackground = [0.05, 0.05, 0.05]\nambient = [0, 0, 0]\n"
    )
}

/// SHA-256 (hex) of the scene text's digest followed by each read file's.
fn content_hash(source: &str, files: &[resources::FileRead]) -> String {
    use sha2::{Digest, Sha256};
    let mut all = Sha256::new();
    all.update(Sha256::digest(source.as_bytes()));
    for file in files {
        all.update(file.sha256);
    }
    all.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

/// Parses and checks scene text: everything but the BVH.
fn check(
    source: &str,
    origin: &str,
    base_dir: &Path,
    options: &LoadOptions,
) -> Result<build::Checked, SceneError> {
    check_at(
        source,
        origin,
        base_dir,
        options,
        0.0,
        &build::ModelCache::default(),
    )
}

/// [`check`] with keyed values `offset` frames after the frame asked for,
/// model files read through `models`.
fn check_at(
    source: &str,
    origin: &str,
    base_dir: &Path,
    options: &LoadOptions,
    offset: f64,
    models: &build::ModelCache,
) -> Result<build::Checked, SceneError> {
    let mut diags = error::Diagnostics::new(source);
    let checked = load::parse(source, &mut diags)
        .and_then(|file| build::check_with(file, base_dir, options, offset, models, &mut diags));
    match checked {
        Some(mut checked) if diags.is_empty() => {
            let inventory = checked.inventory_mut();
            inventory.content_hash = content_hash(source, &inventory.files_read);
            Ok(checked)
        }
        _ => Err(SceneError::Invalid {
            origin: origin.to_string(),
            diagnostics: diags.into_diagnostics(),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::Shape;
    use crate::lights::LightShape;

    const HEAD: &str = "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n[materials.m]\n";

    fn build(body: &str) -> Result<Scene, SceneError> {
        Scene::from_toml(&format!("{HEAD}{body}"), "t.toml")
    }

    fn shape(body: &str) -> Shape {
        let s = build(&format!("[[objects]]\nmaterial = \"m\"\n{body}"))
            .unwrap_or_else(|e| panic!("{e}"));
        s.aggregate.primitives()[0].shape.clone()
    }

    fn messages(body: &str) -> Vec<String> {
        match build(body) {
            Err(SceneError::Invalid { diagnostics, .. }) => {
                diagnostics.into_iter().map(|d| d.message).collect()
            }
            other => panic!("expected errors, got {other:?}"),
        }
    }

    #[test]
    fn transform_steps_apply_first_to_last() {
        let scaled_then_moved =
            shape("type = \"sphere\"\ntransform = [{ scale = 2 }, { translate = [1, 0, 0] }]");
        assert_eq!(
            scaled_then_moved,
            Shape::Sphere(crate::geometry::Sphere {
                center: DVec3::X,
                radius: 2.0
            })
        );
        let moved_then_scaled =
            shape("type = \"sphere\"\ntransform = [{ translate = [1, 0, 0] }, { scale = 2 }]");
        let Shape::Sphere(s) = moved_then_scaled else {
            panic!()
        };
        assert_eq!(s.center, DVec3::new(2.0, 0.0, 0.0));
        // A matrix step is the same map as the named steps.
        let by_matrix = shape(
            "type = \"sphere\"\ntransform = [{ matrix = [[2, 0, 0, 1], [0, 2, 0, 0], [0, 0, 2, 0], [0, 0, 0, 1]] }]",
        );
        assert_eq!(by_matrix, scaled_then_moved);
    }

    #[test]
    fn object_tables_parse_alone_as_they_would_in_the_whole_file() {
        // Sub-tables of an object (`[[objects.transform]]`) stay with it,
        // and sections after the objects are still read.
        let by_tables = build(
            "[[objects]]\ntype = \"sphere\"\nmaterial = \"m\"\n\
             [[objects.transform]]\nscale = 2\n[[objects.transform]]\ntranslate = [1, 0, 0]\n\
             [lights.l]\ntype = \"point\"\nposition = [0, 5, 0]\n",
        )
        .unwrap();
        // Root keys come before the first header.
        let inline = Scene::from_toml(
            &format!(
                "objects = [{{ type = \"sphere\", material = \"m\", transform = [{{ scale = 2 }}, \
                 {{ translate = [1, 0, 0] }}] }}]\n{HEAD}[lights.l]\ntype = \"point\"\nposition = [0, 5, 0]\n"
            ),
            "t.toml",
        )
        .unwrap();
        assert_eq!(
            by_tables.aggregate.primitives(),
            inline.aggregate.primitives()
        );
        assert_eq!(by_tables.lights.len(), 1);
        // Both forms at once: one error, at the inline key.
        let both = Scene::from_toml(
            &format!("objects = []\n{HEAD}[[objects]]\ntype = \"sphere\"\nmaterial = \"m\"\n"),
            "t.toml",
        )
        .unwrap_err()
        .to_string();
        assert!(
            both.contains(
                "t.toml:1:1: error: `objects` is given here and also as [[objects]] tables"
            ),
            "{both}"
        );
        assert_eq!(both.matches("error").count(), 1, "{both}");
    }

    #[test]
    fn boxes_cylinders_cones_and_discs_are_built_and_checked() {
        let Shape::Cuboid(b) = shape("type = \"box\"\ncorner1 = [1, 2, 3]\ncorner2 = [-1, 0, 0]")
        else {
            panic!("a box")
        };
        assert_eq!(
            (b.min, b.max),
            (DVec3::new(-1.0, 0.0, 0.0), DVec3::new(1.0, 2.0, 3.0))
        );
        let Shape::Cone(c) = shape(
            "type = \"cylinder\"\nbase = [0, 0, 0]\ncap = [0, 2, 0]\nradius = 0.5\nopen = true",
        ) else {
            panic!("a cylinder")
        };
        assert_eq!((c.base_radius, c.cap_radius, c.open), (0.5, 0.5, true));
        // The cap end lies at object z = 1, two units up.
        assert!((c.transform.point(DVec3::Z) - DVec3::new(0.0, 2.0, 0.0)).length() < 1e-12);
        let Shape::Cone(tip) = shape("type = \"cone\"\nbase = [0, 0, 0]\ncap = [1, 0, 0]") else {
            panic!("a cone")
        };
        assert_eq!((tip.base_radius, tip.cap_radius), (1.0, 0.0));
        assert!(matches!(
            shape("type = \"disc\"\nnormal = [0, 1, 0]\nradius = 2\nhole_radius = 1"),
            Shape::Disc(_)
        ));
        let Shape::Torus(t) = shape("type = \"torus\"\nmajor_radius = 2\nminor_radius = 0.5")
        else {
            panic!("a torus")
        };
        assert_eq!((t.major_radius, t.minor_radius), (2.0, 0.5));
        let head = "[[objects]]\nmaterial = \"m\"\n";
        for (body, wanted) in [
            (
                "type = \"box\"\ncorner1 = [0, 0, 0]\ncorner2 = [1, 1, 0]",
                "differ along every axis",
            ),
            (
                "type = \"box\"\ncorner1 = [0, 0, 0]",
                "needs `corner1` and `corner2`",
            ),
            (
                "type = \"cylinder\"\nbase = [1, 1, 1]\ncap = [1, 1, 1]",
                "`cap` must differ",
            ),
            (
                "type = \"cone\"\nbase = [0, 0, 0]\ncap = [0, 1, 0]\nbase_radius = 0",
                "a radius above 0",
            ),
            (
                "type = \"disc\"\nnormal = [0, 0, 1]\nradius = 1\nhole_radius = 1",
                "less than `radius`",
            ),
            ("type = \"disc\"\nradius = 1", "needs `normal`"),
            (
                "type = \"torus\"\nmajor_radius = 1\nminor_radius = 1",
                "less than `major_radius`",
            ),
            ("type = \"torus\"\nradius = 1", "does not apply to a torus"),
            (
                "type = \"cylinder\"\nbase = [0, 0, 0]\ncap = [0, 1, 0]\nhole_radius = 1",
                "does not apply to a cylinder",
            ),
            (
                "type = \"box\"\ncorner1 = [0, 0, 0]\ncorner2 = [1, 1, 1]\nopen = true",
                "does not apply to a box",
            ),
        ] {
            let m = messages(&format!("{head}{body}"));
            assert!(m.iter().any(|m| m.contains(wanted)), "{body}: {m:?}");
        }
    }

    #[test]
    fn non_uniform_scale_makes_an_ellipsoid_and_rotation_keeps_a_sphere() {
        assert!(matches!(
            shape("type = \"sphere\"\ntransform = [{ scale = [1, 2, 1] }]"),
            Shape::Ellipsoid(_)
        ));
        let Shape::Sphere(s) = shape(
            "type = \"sphere\"\ncenter = [1, 0, 0]\nradius = 0.5\ntransform = [{ rotate = { axis = [0, 0, 1], degrees = 90 } }]",
        ) else {
            panic!("a rotated sphere is a sphere")
        };
        assert!((s.center - DVec3::Y).length() < 1e-12);
        assert!((s.radius - 0.5).abs() < 1e-12);
    }

    #[test]
    fn planes_by_distance_or_point_and_under_transforms() {
        let Shape::Plane(p) = shape("type = \"plane\"\nnormal = [0, 2, 0]\ndistance = -1") else {
            panic!()
        };
        assert_eq!((p.normal, p.distance), (DVec3::Y, -1.0));
        let Shape::Plane(q) = shape("type = \"plane\"\nnormal = [0, 1, 0]\npoint = [5, -1, 3]")
        else {
            panic!()
        };
        assert_eq!(p, q);
        // Turned -90° about z, the floor y = -1 becomes the wall x = -1.
        let Shape::Plane(r) = shape(
            "type = \"plane\"\nnormal = [0, 1, 0]\ndistance = -1\ntransform = [{ rotate = { axis = [0, 0, 1], degrees = -90 } }]",
        ) else {
            panic!()
        };
        assert!((r.normal - DVec3::X).length() < 1e-12);
        assert!((r.distance - -1.0).abs() < 1e-12);
    }

    #[test]
    fn sphere_light_of_radius_zero_is_a_point_light() {
        let s = build("[lights.a]\ntype = \"sphere\"\nposition = [0, 1, 0]\nradius = 0").unwrap();
        assert_eq!(s.lights[0].shape, LightShape::Point { position: DVec3::Y });
    }

    #[test]
    fn spot_cone_falloff_is_gltf_unless_cycles_is_asked() {
        let spot = "[lights.a]\ntype = \"spot\"\nposition = [0, 4, 0]\ndirection = [0, -1, 0]\n\
                    inner_angle = 20\nouter_angle = 30\n";
        let cone = |text: &str| match build(text).unwrap().lights[0].shape {
            LightShape::Spot { cone, .. } => cone,
            other => panic!("{other:?}"),
        };
        assert_eq!(cone(spot), crate::lights::SpotCone::Gltf);
        assert_eq!(
            cone(&format!("{spot}cone_falloff = \"gltf\"")),
            crate::lights::SpotCone::Gltf
        );
        assert_eq!(
            cone(&format!("{spot}cone_falloff = \"cycles\"")),
            crate::lights::SpotCone::Cycles
        );
        let m = messages(&format!("{spot}cone_falloff = \"eevee\""));
        assert!(m[0].contains("unknown variant `eevee`"), "{m:?}");
        let m = messages(
            "[lights.a]\ntype = \"point\"\nposition = [0, 1, 0]\ncone_falloff = \"cycles\"",
        );
        assert!(
            m[0].contains("`cone_falloff` does not apply to a point light"),
            "{m:?}"
        );
    }

    #[test]
    fn camera_shift_is_read_and_bounded() {
        let camera = |shift: &str| {
            Scene::from_toml(
                &format!("[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n{shift}"),
                "t.toml",
            )
        };
        assert_eq!(camera("").unwrap().camera.shift, glam::DVec2::ZERO);
        let s = camera("shift = [0.25, -0.5]").unwrap();
        assert_eq!(s.camera.shift, glam::DVec2::new(0.25, -0.5));
        let e = camera("shift = [1e9, 0]").unwrap_err().to_string();
        assert!(
            e.contains("`shift` ([1000000000, 0]) must be finite"),
            "{e}"
        );
    }

    #[test]
    fn keys_of_other_kinds_are_refused() {
        let m = messages(
            "[lights.a]\ntype = \"point\"\nposition = [0, 1, 0]\nradius = 2\n[[objects]]\ntype = \"plane\"\nmaterial = \"m\"\nnormal = [0, 1, 0]\nradius = 1",
        );
        assert_eq!(m.len(), 2, "{m:?}");
        assert!(m[0].contains("`radius` does not apply to a point light"));
        assert!(m[1].contains("`radius` does not apply to a plane"));
    }

    #[test]
    fn degenerate_transforms_and_cameras_are_refused() {
        let m = messages(
            "[[objects]]\ntype = \"sphere\"\nmaterial = \"m\"\ntransform = [{ scale = [1, 0, 1] }]",
        );
        assert!(m[0].contains("invalid transform step"), "{m:?}");
        let m = messages(
            "[[objects]]\ntype = \"sphere\"\nmaterial = \"m\"\ntransform = [{ matrix = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1]] }]",
        );
        assert!(m[0].contains("last row is [0, 0, 0, 1]"), "{m:?}");
        let bad_camera =
            Scene::from_toml("[camera]\nposition = [0, 0, 0]\nlook_at = [0, 5, 0]", "t");
        assert!(
            bad_camera
                .unwrap_err()
                .to_string()
                .contains("not parallel to `up`")
        );
    }

    #[test]
    fn unknown_sections_are_refused() {
        let m = messages("[lightz.a]\ntype = \"point\"");
        assert!(m[0].contains("unknown section `lightz`"), "{m:?}");
    }
}
