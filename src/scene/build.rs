//! [`SceneFile`] → runtime [`Scene`]: every value checked, every problem
//! reported with its span, object transforms applied.

use std::collections::{BTreeMap, BTreeSet};
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{DAffine3, DMat3, DMat4, DQuat, DVec2, DVec3, DVec4};
use toml::Spanned;

use super::animation::{Animated, Animation, AnimationDesc, Interpolation, Lerp};
use super::error::Diagnostics;
use super::format::*;
use super::models::{ModelCamera, ModelMotion, ModelProjection, Pose, load_model};
use super::resources::{LoadOptions, Resources};
use super::{Names, Scene};

/// How messages name the object at `path` (`objects[3]`,
/// `objects[3].children[0]`).
fn label_of(d: &ObjectDesc, path: &str) -> String {
    // A deep CSG path keeps its first and last steps.
    let steps: Vec<&str> = path.split('.').collect();
    let short;
    let path = if steps.len() > 5 {
        short = format!(
            "{}.{} … {} ({} deep)",
            steps[0],
            steps[1],
            steps[steps.len() - 1],
            steps.len() - 1
        );
        short.as_str()
    } else {
        path
    };
    match &d.name {
        Some(n) => format!("object `{n}` ({path})"),
        None => path.to_string(),
    }
}

/// What a CSG hands down to its children: its placement and material,
/// how deep they sit, and whether they are operands of a set operation
/// (rather than objects of their own, as a top-level union's are).
#[derive(Clone, Copy, Debug, Default)]
struct Parent {
    transform: Option<Transform>,
    material: Option<u32>,
    depth: usize,
    in_csg: bool,
}

/// A model file, read and built once however often it is placed.
#[derive(Clone)]
struct LoadedModel {
    meshes: Vec<Arc<Mesh>>,
    /// (index into `meshes`, mesh to model space; `None`: as it is).
    placements: Vec<(usize, Option<Transform>)>,
    /// Scene material index per material slot of the mesh.
    slots: Arc<[u32]>,
    lights: Vec<Light>,
    cameras: Vec<ModelCamera>,
}

/// Model files read by one build of a scene, for the builds of its
/// shutter's instants: each file is read, and its meshes' trees built,
/// once; an animated glTF is only posed again at each instant.
#[derive(Clone, Default)]
pub struct ModelCache(Arc<std::sync::Mutex<BTreeMap<PathBuf, Arc<ReadModel>>>>);

/// A model file as read, before its materials join a scene.
struct ReadModel {
    meshes: Vec<Arc<Mesh>>,
    /// Where its meshes, lights and cameras are at time 0.
    pose: Pose,
    materials: Vec<Material>,
    warnings: Vec<String>,
    motion: Option<Arc<ModelMotion>>,
}

impl ModelCache {
    fn get(&self, key: &Path) -> Option<Arc<ReadModel>> {
        let map = self.0.lock().unwrap_or_else(|p| p.into_inner());
        map.get(key).cloned()
    }

    fn insert(&self, key: PathBuf, model: Arc<ReadModel>) {
        let mut map = self.0.lock().unwrap_or_else(|p| p.into_inner());
        map.insert(key, model);
    }
}

/// A model's camera placed in the world, and what chose it.
#[derive(Clone)]
struct ChosenCamera {
    camera: Camera,
    name: String,
    /// The image shape it was made for (glTF `aspectRatio`).
    aspect: Option<f64>,
    /// Named by an object's `camera = "NAME"`.
    explicit: bool,
}
use crate::accel::{Aggregate, Primitive, Shape};
use crate::camera::{Camera, FovAxis, Projection, ThinLens};
use crate::geometry::{
    Cone, Csg, CsgChild, CsgOp, Cuboid, Disc, Ellipsoid, Mesh, MeshInstance, Plane, Polygon,
    Sphere, Torus,
};
use crate::lights::{AreaLight, AreaOutline, Light, LightShape, SpotCone};
use crate::limits;
use crate::math::Transform;
use crate::settings::RenderSettings;
use crate::shading::{Fresnel, Highlight, Material, Texture};

/// Checks the scene and builds everything but its acceleration structure;
/// `None` if any problem was recorded. [`Checked::finish`] builds the rest,
/// after the caller has let go of the source text.
pub fn check(
    file: SceneFile,
    base_dir: &Path,
    options: &LoadOptions,
    diags: &mut Diagnostics,
) -> Option<Checked> {
    check_at(file, base_dir, options, 0.0, diags)
}

/// [`check_at`] reading model files through `models` (those the scene's
/// first build read: see [`Checked::models`]).
pub fn check_with(
    file: SceneFile,
    base_dir: &Path,
    options: &LoadOptions,
    offset: f64,
    models: &ModelCache,
    diags: &mut Diagnostics,
) -> Option<Checked> {
    check_in(file, base_dir, options, offset, models.clone(), diags)
}

/// [`check`] with keyed values taken `offset` frames after the frame
/// `options` names (an instant of an open shutter).
pub fn check_at(
    file: SceneFile,
    base_dir: &Path,
    options: &LoadOptions,
    offset: f64,
    diags: &mut Diagnostics,
) -> Option<Checked> {
    check_in(
        file,
        base_dir,
        options,
        offset,
        ModelCache::default(),
        diags,
    )
}

fn check_in(
    file: SceneFile,
    base_dir: &Path,
    options: &LoadOptions,
    offset: f64,
    cache: ModelCache,
    diags: &mut Diagnostics,
) -> Option<Checked> {
    let mut c = Check {
        diags,
        base_dir: base_dir.to_path_buf(),
        resources: Resources::new(base_dir, options),
        materials: Vec::new(),
        models: BTreeMap::new(),
        cache,
        fps: 24.0,
        model_lights: Vec::new(),
        model_camera: None,
        camera_request: options.camera.clone(),
        requested_camera: None,
        model_camera_names: Vec::new(),
        default_material: None,
        model_failed: false,
        camera_request_failed: false,
        warnings: Vec::new(),
        frame: f64::from(options.frame) + offset,
        offset,
        interpolation: Interpolation::Linear,
        keyed: false,
    };
    let animation = file.animation.as_ref().and_then(|a| c.animation(a));
    if let Some(a) = &animation {
        c.fps = a.fps;
    }
    if let Some(desc) = &file.animation
        && let Some(i) = &desc.get_ref().interpolation
    {
        c.interpolation = *i.get_ref();
    }
    let settings = c.settings(&file.render);
    let background = file
        .render
        .background
        .as_ref()
        .map_or(DVec3::ZERO, |v| c.color(v, "background"));
    let ambient = file
        .render
        .ambient
        .as_ref()
        .map_or(DVec3::splat(0.1), |v| c.color(v, "ambient"));
    let camera = match &file.camera {
        Some(desc) => c.camera(desc),
        // Missing: a model file may bring one (checked below).
        None => None,
    };
    let mut material_index = BTreeMap::new();
    for (name, desc) in &file.materials {
        material_index.insert(name.as_str(), c.materials.len() as u32);
        let m = c.material(name, desc);
        c.materials.push(m);
    }
    let mut names = Names::default();
    let lights: Vec<Light> = file
        .lights
        .iter()
        .filter_map(|(name, d)| {
            let light = c.light(name, d)?;
            names.lights.push(name.clone());
            Some(light)
        })
        .collect();
    let mut primitives: Vec<Primitive> =
        Vec::with_capacity(file.objects.len() + file.object_tables.len());
    // Named objects' primitives (a model may bring several), for messages
    // and `prism explain`.
    let mut add =
        |primitives: &mut Vec<Primitive>, built: Vec<Primitive>, name: &Option<String>| {
            if let Some(name) = name {
                for i in primitives.len()..primitives.len() + built.len() {
                    names.objects.insert(i as u32, name.clone());
                }
            }
            primitives.extend(built);
        };
    for (i, o) in file.objects.iter().enumerate() {
        let built = c.object(i, o, &material_index, &file.unparsed);
        add(&mut primitives, built, &o.get_ref().name);
    }
    // Each table is parsed, built and its syntax tree dropped in turn.
    for (i, range) in file.object_tables.iter().enumerate() {
        c.diags.set_offset(range.start);
        if let Some(o) = super::load::object(range.clone(), c.diags) {
            let built = c.object(i, &o, &material_index, &file.unparsed);
            add(&mut primitives, built, &o.get_ref().name);
        }
        c.diags.set_offset(0);
    }
    names.materials = file.materials.keys().cloned().collect();
    for i in names.materials.len()..c.materials.len() {
        names.materials.push(format!("model material {i}"));
    }
    for i in names.lights.len()..names.lights.len() + c.model_lights.len() {
        names.lights.push(format!("model light {i}"));
    }
    let mut settings = settings;
    let chosen = match &c.camera_request {
        Some(name) => {
            if c.requested_camera.is_none() && !c.model_failed {
                // Said once: the scene's own lack of a camera is then no
                // separate fault (the request is what failed).
                c.camera_request_failed = true;
                let known = if c.model_camera_names.is_empty() {
                    "no model file brings a camera".to_string()
                } else {
                    format!("the models' cameras: {}", c.model_camera_names.join(", "))
                };
                c.diags.error(
                    0..0,
                    format!("--camera {name}: no model camera has that name ({known})"),
                );
            }
            c.requested_camera.take()
        }
        // The scene's own [camera] comes first.
        None if file.camera.is_some() => None,
        None => c.model_camera.take(),
    };
    if let Some(chosen) = &chosen {
        if c.model_camera_names.len() > 1 {
            c.warnings.push(format!(
                "the models bring {} cameras ({}); using `{}` (choose with camera = \"NAME\" in \
                 the mesh object or --camera NAME)",
                c.model_camera_names.len(),
                c.model_camera_names.join(", "),
                chosen.name
            ));
        }
        if let Some(aspect) = chosen.aspect {
            let (w, h) = (
                file.render.width.as_ref().map(|w| *w.get_ref()),
                file.render.height.as_ref().map(|h| *h.get_ref()),
            );
            (settings.width, settings.height) = match crate::settings::image_shape(aspect, w, h) {
                Ok(shape) => shape,
                // Not an error yet: the command line may set both sides.
                // A side left at 0 makes `RenderSettings::check` say why.
                Err(_) => (w.unwrap_or(0), h.unwrap_or(0)),
            };
            if w.is_some() && h.is_some() {
                let given = f64::from(settings.width) / f64::from(settings.height);
                if (given / aspect - 1.0).abs() > 0.01 {
                    c.warnings.push(format!(
                        "camera `{}` was made for an image {aspect:.4} times as wide as tall, \
                         but [render] asks for {}x{} ({given:.4}); the picture is cropped or \
                         widened",
                        chosen.name, settings.width, settings.height
                    ));
                }
            } else {
                settings.aspect = Some(aspect);
            }
        }
    }
    let camera = chosen.map(|c| c.camera).or(camera);
    // A [camera] that failed to parse is already reported; a model that
    // failed to load may have been the one to bring the camera.
    if camera.is_none()
        && file.camera.is_none()
        && !file.unparsed.contains("camera")
        && !c.model_failed
        && !c.camera_request_failed
    {
        c.diags.error(
            0..0,
            "missing [camera] section (position and look_at are required), and no model file brings a camera",
        );
    }
    let mut lights: Vec<Light> = lights;
    lights.append(&mut c.model_lights);
    if lights.is_empty() && !c.model_failed {
        // A glTF export without lights renders near-black: say why.
        c.warnings.push(
            "the scene has no lights: surfaces show only the ambient term (add [lights.NAME], \
             or lights to the model)"
                .into(),
        );
    }
    if !c.diags.is_empty() {
        return None;
    }
    let camera = camera?;
    Some(Checked {
        models: c.cache,
        shutter_at: file.render.shutter.as_ref().map(|s| s.span().start),
        primitives,
        scene: Scene {
            camera,
            aggregate: Aggregate::default(),
            inventory: super::Inventory {
                build_time: std::time::Duration::ZERO,
                textures: c.resources.texture_count(),
                texture_bytes: c.resources.texture_bytes(),
                files_read: c.resources.policy.files_read(),
                content_hash: String::new(),
                camera: c.camera_request.clone(),
            },
            materials: c.materials,
            // Warnings quote names from files: escaped once, here, for
            // every front end that shows them.
            warnings: c
                .warnings
                .iter()
                .map(|w| crate::text::escape_controls(w).into_owned())
                .collect(),
            lights,
            background,
            ambient,
            transparent_shadows: file.render.transparent_shadows.unwrap_or(false),
            settings,
            animation,
            animated: c.keyed,
            names,
            motion: Vec::new(),
        },
    })
}

/// A checked scene whose primitives still wait for their BVH.
pub struct Checked {
    primitives: Vec<Primitive>,
    /// Everything else, with an empty aggregate.
    scene: Scene,
    /// Where the `shutter` key starts in the source, if it is there.
    shutter_at: Option<usize>,
    /// The model files it read.
    models: ModelCache,
}

impl Checked {
    /// Whether the scene has an open shutter and keyed values: then its
    /// instants are built too.
    pub fn shutter_open(&self) -> bool {
        self.scene.settings.shutter.is_some() && self.scene.animated
    }

    /// The model files this build read, for [`check_with`] to build the
    /// shutter's instants without reading them again.
    pub fn models(&self) -> ModelCache {
        self.models.clone()
    }

    /// The byte offset of the `shutter` key in the source (0 without one):
    /// where a refusal of its instants points.
    pub fn shutter_at(&self) -> usize {
        self.shutter_at.unwrap_or(0)
    }

    /// What loading built and read so far.
    pub fn inventory_mut(&mut self) -> &mut super::Inventory {
        &mut self.scene.inventory
    }

    /// Builds the acceleration structure: the scene is ready to render.
    pub fn finish(self) -> Scene {
        let start = std::time::Instant::now();
        let mut scene = self.scene;
        scene.aggregate = Aggregate::new(self.primitives);
        scene.inventory.build_time = start.elapsed();
        scene
    }
}

struct Check<'d, 's> {
    diags: &'d mut Diagnostics<'s>,
    /// Model paths are relative to this (the scene file's folder).
    base_dir: PathBuf,
    /// What the scene may read; textures decoded once.
    resources: Resources,
    /// The scene's materials: the file's, then those models bring.
    materials: Vec<Material>,
    /// Models loaded so far, by path: placing a model again shares its mesh.
    models: BTreeMap<PathBuf, LoadedModel>,
    /// Model files as read, shared with the builds of other instants.
    cache: ModelCache,
    /// `[animation] fps`: a glTF's animation time is frame / fps seconds.
    fps: f64,
    /// Lights that models brought, placed in the world.
    model_lights: Vec<Light>,
    /// The first camera a model brought (or the one an object named),
    /// placed in the world.
    model_camera: Option<ChosenCamera>,
    /// `--camera NAME`.
    camera_request: Option<String>,
    /// The model camera `--camera` names, placed in the world.
    requested_camera: Option<ChosenCamera>,
    /// Every model camera's name, for messages.
    model_camera_names: Vec<String>,
    /// Index of the grey material for models that bring none.
    default_material: Option<u32>,
    /// A model file could not be loaded (already reported).
    model_failed: bool,
    /// `--camera NAME` named no model camera (already reported).
    camera_request_failed: bool,
    warnings: Vec<String>,
    /// The frame keyed values are taken at.
    frame: f64,
    /// How far `frame` lies after the frame asked for (a shutter's instant).
    offset: f64,
    interpolation: Interpolation,
    /// Whether any value is keyed.
    keyed: bool,
}

impl Check<'_, '_> {
    fn error(&mut self, span: Range<usize>, message: String) {
        self.diags.error(span, message);
    }

    /// Three finite numbers.
    fn vector(&mut self, v: &Triple, what: &str) -> DVec3 {
        let d = DVec3::from_array(*v.get_ref());
        if !d.is_finite() {
            self.error(
                v.span(),
                format!(
                    "`{what}` must be three finite numbers, got {:?}",
                    v.get_ref()
                ),
            );
            return DVec3::ZERO;
        }
        d
    }

    /// A non-zero finite vector, normalised.
    fn direction(&mut self, v: &Triple, what: &str) -> DVec3 {
        let d = self.vector(v, what);
        d.try_normalize().unwrap_or_else(|| {
            if d.is_finite() {
                self.error(v.span(), format!("`{what}` must be a non-zero vector"));
            }
            DVec3::Z
        })
    }

    /// A point in the world: three finite numbers within ±MAX_COORDINATE.
    fn point(&mut self, v: &Triple, what: &str) -> DVec3 {
        let p = self.vector(v, what);
        if p.abs().max_element() > limits::MAX_COORDINATE {
            self.error(
                v.span(),
                format!(
                    "`{what}` must lie within ±{:e} (the supported range), got {:?}",
                    limits::MAX_COORDINATE,
                    v.get_ref()
                ),
            );
            return DVec3::ZERO;
        }
        p
    }

    /// A colour: three finite, non-negative numbers.
    fn color(&mut self, v: &Triple, what: &str) -> DVec3 {
        let c = self.vector(v, what);
        if c.max_element() > limits::MAX_VALUE {
            self.error(
                v.span(),
                format!(
                    "`{what}` components must be at most {:e}, got {:?}",
                    limits::MAX_VALUE,
                    v.get_ref()
                ),
            );
        } else if c.min_element() < 0.0 {
            self.error(
                v.span(),
                format!(
                    "`{what}` components must not be negative, got {:?}",
                    v.get_ref()
                ),
            );
        }
        c
    }

    /// An optional reflection or transmission weight, 0 by default: a
    /// number is a grey, three numbers a colour; each in [0, MAX_VALUE].
    fn weight(&mut self, v: &Option<Spanned<OneOrThree>>, what: &str) -> DVec3 {
        let Some(v) = v else { return DVec3::ZERO };
        let k = DVec3::from_array(v.get_ref().0);
        let [x, y, z] = v.get_ref().0.map(f64::to_bits);
        let given = if x == y && y == z {
            readable(k.x)
        } else {
            format!("{:?}", v.get_ref().0)
        };
        if !k.to_array().into_iter().all(VALUE.0) {
            self.error(
                v.span(),
                format!(
                    "`{what}` must be {} (one number, or one per colour channel), got {given}",
                    VALUE.1
                ),
            );
            return DVec3::ZERO;
        }
        k
    }

    /// An optional number with a default, checked against `valid`.
    fn number(
        &mut self,
        v: &Option<Number>,
        default: f64,
        what: &str,
        valid: (fn(f64) -> bool, &str),
    ) -> f64 {
        let Some(v) = v else { return default };
        let x = *v.get_ref();
        if !x.is_finite() {
            self.error(
                v.span(),
                format!("`{what}` must be a finite number, got {x}"),
            );
        } else if !valid.0(x) {
            self.error(
                v.span(),
                format!("`{what}` must be {}, got {}", valid.1, readable(x)),
            );
        }
        x
    }

    /// An optional count of at least 1.
    fn count(&mut self, v: &Option<Spanned<u32>>, default: u32, what: &str, max: u32) -> u32 {
        match v {
            Some(v) if *v.get_ref() == 0 || *v.get_ref() > max => {
                self.error(
                    v.span(),
                    format!("`{what}` must be between 1 and {max}, got {}", v.get_ref()),
                );
                default
            }
            Some(v) => *v.get_ref(),
            None => default,
        }
    }

    /// `value` at the frame being built.
    fn value_at_frame<T: Lerp>(&mut self, value: &Animated<T>) -> T {
        self.keyed |= value.is_keyed();
        value.at(self.frame, self.interpolation)
    }

    /// A keyed value at the frame being built, with its span.
    fn at<T: Lerp>(&mut self, value: &Spanned<Animated<T>>) -> Spanned<T> {
        Spanned::new(value.span(), self.value_at_frame(value.get_ref()))
    }

    /// [`at`](Self::at) of an optional value.
    fn at_frame<T: Lerp>(&mut self, value: &Option<Spanned<Animated<T>>>) -> Option<Spanned<T>> {
        value.as_ref().map(|v| self.at(v))
    }

    fn animation(&mut self, desc: &Spanned<AnimationDesc>) -> Option<Animation> {
        let d = desc.get_ref();
        let frames = *d.frames.get_ref();
        if frames == 0 || frames > limits::MAX_FRAMES {
            self.error(
                d.frames.span(),
                format!(
                    "`frames` must be between 1 and {}, got {frames}",
                    limits::MAX_FRAMES
                ),
            );
            return None;
        }
        // The frame asked for (an instant of its shutter may lie past it).
        if self.frame - self.offset >= f64::from(frames) {
            self.error(
                d.frames.span(),
                format!(
                    "frame {} is past the animation's last frame {} (frames = {frames})",
                    self.frame,
                    frames - 1
                ),
            );
        }
        let fps = self.number(
            &d.fps,
            24.0,
            "fps",
            (
                |x| x > 0.0 && x <= 1000.0,
                "between 0 and 1000 (exclusive of 0)",
            ),
        );
        Some(Animation { frames, fps })
    }

    /// `shutter = [open, close]` and `shutter_samples`.
    fn shutter(&mut self, r: &RenderDesc) -> Option<crate::settings::Shutter> {
        let samples = self.count(
            &r.shutter_samples,
            16,
            "shutter_samples",
            limits::MAX_SHUTTER_SAMPLES,
        );
        let Some(times) = &r.shutter else {
            if let Some(s) = &r.shutter_samples {
                self.error(
                    s.span(),
                    "`shutter_samples` needs `shutter = [open, close]`".into(),
                );
            }
            return None;
        };
        let [open, close] = *times.get_ref();
        let bound = f64::from(limits::MAX_FRAMES);
        if !(open.abs() <= bound && close.abs() <= bound && open <= close) {
            self.error(
                times.span(),
                format!("`shutter` = [{open}, {close}]: the shutter opens before it closes, within ±{bound} frames"),
            );
            return None;
        }
        Some(crate::settings::Shutter {
            open,
            close,
            samples,
        })
    }

    fn settings(&mut self, r: &RenderDesc) -> RenderSettings {
        let defaults = RenderSettings::default();
        RenderSettings {
            width: self.count(&r.width, defaults.width, "width", limits::MAX_IMAGE_SIDE),
            height: self.count(&r.height, defaults.height, "height", limits::MAX_IMAGE_SIDE),
            spp: self.count(&r.spp, defaults.spp, "spp", limits::MAX_SPP),
            max_depth: self.count(
                &r.max_depth,
                defaults.max_depth,
                "max_depth",
                limits::MAX_DEPTH,
            ),
            min_weight: self.number(
                &r.min_weight,
                defaults.min_weight,
                "min_weight",
                UNIT_INTERVAL,
            ),
            seed: r.seed.as_ref().map_or(defaults.seed, |s| *s.get_ref()),
            frame: 0,
            threads: None,
            exposure: self.number(&r.exposure, 0.0, "exposure", EXPOSURE),
            aspect: None,
            adaptive: r.adaptive.as_ref().map(|a| {
                let a = a.get_ref();
                crate::settings::Adaptive {
                    threshold: self.number(&a.threshold, 0.3, "adaptive.threshold", VALUE),
                    depth: self.count(&a.depth, 3, "adaptive.depth", limits::MAX_ADAPTIVE_DEPTH),
                    jitter: a.jitter.unwrap_or(false),
                }
            }),
            shutter: self.shutter(r),
        }
    }

    fn camera(&mut self, desc: &Spanned<CameraDesc>) -> Option<Camera> {
        let d = desc.get_ref();
        let (position, look_at) = (self.at(&d.position), self.at(&d.look_at));
        let position = self.point(&position, "position");
        let look_at = self.point(&look_at, "look_at");
        let up = self.at_frame(&d.up);
        let up = up.as_ref().map_or(DVec3::Y, |u| self.direction(u, "up"));
        let fov = self.at_frame(&d.fov);
        let projection = match d.kind {
            CameraKind::Perspective => {
                if let Some(v) = &d.view_height {
                    self.error(
                        v.span(),
                        "`view_height` applies to orthographic cameras; use `fov`".into(),
                    );
                }
                let fov = self.number(
                    &fov,
                    45.0,
                    "fov",
                    (|x| x > 0.0 && x < 180.0, "between 0 and 180 degrees"),
                );
                Projection::Perspective {
                    fov: fov.to_radians(),
                    axis: match d.fov_axis.as_ref().map(Spanned::get_ref) {
                        Some(FovAxisDesc::Horizontal) => FovAxis::Horizontal,
                        _ => FovAxis::Vertical,
                    },
                }
            }
            CameraKind::Orthographic => {
                let misplaced = [
                    ("fov", d.fov.as_ref().map(Spanned::span)),
                    ("fov_axis", d.fov_axis.as_ref().map(Spanned::span)),
                ];
                for (key, span) in misplaced {
                    if let Some(span) = span {
                        self.error(
                            span,
                            format!("`{key}` applies to perspective cameras; use `view_height`"),
                        );
                    }
                }
                let view_height = self.number(&d.view_height, 2.0, "view_height", LENGTH);
                Projection::Orthographic { view_height }
            }
        };
        let mut camera = Camera::look_at(position, look_at, up, projection);
        if camera.is_none() && self.diags.is_empty() {
            self.error(
                d.look_at.span(),
                "the camera needs `look_at` away from `position` and a view direction not parallel to `up`".into(),
            );
        }
        if let Some(camera) = camera.as_mut() {
            camera.lens = self.lens(d, camera, look_at);
            if let Some(shift) = &d.shift {
                let [x, y] = *shift.get_ref();
                // A shift of a thousand frames is a mistake, not a view.
                if x.is_finite() && y.is_finite() && x.abs() <= 1e3 && y.abs() <= 1e3 {
                    camera.shift = DVec2::new(x, y);
                } else {
                    self.error(
                        shift.span(),
                        format!("`shift` ([{x}, {y}]) must be finite and within ±1000"),
                    );
                }
            }
        }
        camera
    }

    /// The camera's thin lens: `aperture` (its radius; 0, the default, is
    /// a pinhole) focused at `focus_distance`, at the depth of `focus_on`
    /// along the view, or, with neither, at `look_at`: the point the
    /// camera is aimed at is the one a user means to see sharp (POV-Ray's
    /// focal_point defaults to the origin, where its look_at usually is).
    fn lens(&mut self, d: &CameraDesc, camera: &Camera, look_at: DVec3) -> Option<ThinLens> {
        let aperture = self.at_frame(&d.aperture);
        let radius = self.number(&aperture, 0.0, "aperture", LENGTH_OR_ZERO);
        let distance = self.at_frame(&d.focus_distance);
        let on = self.at_frame(&d.focus_on);
        let depth = |p: DVec3| (p - camera.position).dot(camera.forward);
        let focus_distance = match (&distance, &on) {
            (Some(_), Some(on)) => {
                self.error(
                    on.span(),
                    "give `focus_distance` or `focus_on`, not both".into(),
                );
                return None;
            }
            (Some(_), None) => self.number(&distance, 1.0, "focus_distance", LENGTH),
            (None, Some(on)) => {
                let z = depth(self.point(on, "focus_on"));
                if z < limits::MIN_LENGTH {
                    self.error(
                        on.span(),
                        format!(
                            "`focus_on` must lie in front of the camera (its depth along the view \
                             direction must be positive), got depth {}",
                            readable(z)
                        ),
                    );
                    return None;
                }
                z
            }
            (None, None) => depth(look_at),
        };
        (radius > 0.0).then_some(ThinLens {
            radius,
            focus_distance,
        })
    }

    fn material(&mut self, name: &str, desc: &Spanned<MaterialDesc>) -> Material {
        let d = desc.get_ref();
        let color = d
            .color
            .as_ref()
            .map_or(DVec3::ONE, |c| self.color(c, "color"));
        let texture = match (&d.checker, &d.texture) {
            (Some(_), Some(file)) => {
                self.error(
                    file.span(),
                    format!("material `{name}`: give `checker` or `texture`, not both"),
                );
                Texture::Solid(color)
            }
            (None, None) => Texture::Solid(color),
            (Some(spanned), None) => {
                let ch = spanned.get_ref();
                if ch.mapping == Some(CheckerMapping::Uv) && ch.filter == Some(CheckerFilter::Box) {
                    self.error(
                        spanned.span(),
                        format!(
                            "material `{name}`: `filter = \"box\"` is for the world checker; \
                             a `uv` checker has no footprint in texture coordinates and is \
                             point-sampled (remove `filter`)"
                        ),
                    );
                }
                let odd = self.color(&ch.color, "checker.color");
                let size = self.number(&ch.size, 1.0, "checker.size", LENGTH);
                match ch.mapping {
                    Some(CheckerMapping::Uv) => Texture::UvChecker {
                        even: color,
                        odd,
                        size,
                    },
                    _ => Texture::Checker {
                        even: color,
                        odd,
                        size,
                        filtered: ch.filter == Some(CheckerFilter::Box),
                    },
                }
            }
            (None, Some(file)) => {
                let path = self.base_dir.join(file.get_ref());
                match self.resources.texture_file(&path) {
                    Ok(image) => Texture::Image { image, tint: color },
                    Err(e) => {
                        self.error(
                            file.span(),
                            format!("material `{name}`: texture {}: {e}", path.display()),
                        );
                        Texture::Solid(color)
                    }
                }
            }
        };
        let kr = self.weight(&d.kr, "kr");
        let kt = self.weight(&d.kt, "kt");
        let sum = (kr + kt).max_element();
        if sum > 1.0 + 1e-9 {
            let span =
                d.kt.as_ref()
                    .or(d.kr.as_ref())
                    .map_or(desc.span(), |s| s.span());
            self.error(
                span,
                format!(
                    "material `{name}`: kr + kt = {} exceeds 1, which would create light",
                    short(sum)
                ),
            );
        }
        Material {
            texture,
            ka: self.number(&d.ka, 0.1, "ka", VALUE),
            kd: self.number(&d.kd, 0.8, "kd", VALUE),
            ks: self.number(&d.ks, 0.0, "ks", VALUE),
            shininess: self.number(&d.shininess, 32.0, "shininess", VALUE),
            kr,
            kt,
            ior: self.number(&d.ior, 1.0, "ior", IOR),
            fresnel: match d.fresnel {
                None | Some(FresnelDesc::Off) => Fresnel::Off,
                Some(FresnelDesc::Exact) => Fresnel::Exact,
                Some(FresnelDesc::Schlick) => Fresnel::Schlick,
            },
            highlight: match d.highlight {
                Some(HighlightDesc::Blinn) => Highlight::Blinn,
                _ => Highlight::Phong,
            },
            emission: Texture::Solid(
                d.emission
                    .as_ref()
                    .map_or(DVec3::ZERO, |c| self.color(c, "emission")),
            ),
            roughness: self.number(&d.roughness, 0.0, "roughness", UNIT_INTERVAL),
            glossy_samples: self.count(&d.samples, 16, "samples", limits::MAX_LIGHT_SAMPLES),
        }
    }

    fn light(&mut self, name: &str, desc: &Spanned<LightDesc>) -> Option<Light> {
        let d = desc.get_ref();
        let kind = *d.kind.get_ref();
        let color = self.at_frame(&d.color);
        let intensity = self.at_frame(&d.intensity);
        let radiance = color
            .as_ref()
            .map_or(DVec3::ONE, |c| self.color(c, "color"))
            * self.number(&intensity, 1.0, "intensity", VALUE);
        let label = format!("light `{name}`");
        let needs = |this: &mut Self, present: bool, key: &str| {
            if !present {
                this.error(
                    desc.span(),
                    format!("{label}: a {} light needs `{key}`", kind.name()),
                );
            }
        };
        let reject = |this: &mut Self, span: Option<Range<usize>>, key: &str| {
            if let Some(span) = span {
                this.error(
                    span,
                    format!("{label}: `{key}` does not apply to a {} light", kind.name()),
                );
            }
        };
        let area = matches!(kind, LightKind::Rectangle | LightKind::Disk);
        if !area {
            for (span, key) in [
                (d.edge_u.as_ref().map(Spanned::span), "edge_u"),
                (d.edge_v.as_ref().map(Spanned::span), "edge_v"),
                (d.normal.as_ref().map(Spanned::span), "normal"),
                (d.two_sided.as_ref().map(Spanned::span), "two_sided"),
            ] {
                reject(self, span, key);
            }
        }
        if kind != LightKind::Spot {
            reject(
                self,
                d.inner_angle.as_ref().map(Spanned::span),
                "inner_angle",
            );
            reject(
                self,
                d.outer_angle.as_ref().map(Spanned::span),
                "outer_angle",
            );
            reject(
                self,
                d.cone_falloff.as_ref().map(Spanned::span),
                "cone_falloff",
            );
        }
        let shape = match kind {
            LightKind::Spot => {
                needs(self, d.position.is_some(), "position");
                needs(self, d.direction.is_some(), "direction");
                reject(self, d.radius.as_ref().map(Spanned::span), "radius");
                reject(self, d.samples.as_ref().map(Spanned::span), "samples");
                let outer = self.number(&d.outer_angle, 45.0, "outer_angle", HALF_ANGLE);
                let inner = self.number(&d.inner_angle, 0.0, "inner_angle", HALF_ANGLE);
                if inner > outer {
                    self.error(
                        desc.span(),
                        format!(
                            "{label}: `inner_angle` ({inner}°) is wider than `outer_angle` ({outer}°)"
                        ),
                    );
                }
                let position = self.at_frame(&d.position);
                let position = position.as_ref().map(|p| self.point(p, "position"))?;
                LightShape::Spot {
                    position,
                    direction: self.direction(d.direction.as_ref()?, "direction"),
                    cos_inner: crate::math::transcendental::sin_cos(inner.to_radians()).1,
                    cos_outer: crate::math::transcendental::sin_cos(outer.to_radians()).1,
                    cone: match d.cone_falloff.as_ref().map(|c| *c.get_ref()) {
                        None | Some(ConeFalloffDesc::Gltf) => SpotCone::Gltf,
                        Some(ConeFalloffDesc::Cycles) => SpotCone::Cycles,
                    },
                }
            }
            LightKind::Point | LightKind::Sphere => {
                needs(self, d.position.is_some(), "position");
                reject(self, d.direction.as_ref().map(Spanned::span), "direction");
                let position = self.at_frame(&d.position);
                let position = position.as_ref().map(|p| self.point(p, "position"))?;
                if kind == LightKind::Point {
                    reject(self, d.radius.as_ref().map(Spanned::span), "radius");
                    reject(self, d.samples.as_ref().map(Spanned::span), "samples");
                    LightShape::Point { position }
                } else {
                    let radius = self.number(&d.radius, 1.0, "radius", LENGTH_OR_ZERO);
                    let samples = self.count(&d.samples, 16, "samples", limits::MAX_LIGHT_SAMPLES);
                    if radius == 0.0 {
                        LightShape::Point { position }
                    } else {
                        LightShape::Sphere {
                            center: position,
                            radius,
                            samples,
                        }
                    }
                }
            }
            LightKind::Directional => {
                needs(self, d.direction.is_some(), "direction");
                for (span, key) in [
                    (d.position.as_ref().map(Spanned::span), "position"),
                    (d.radius.as_ref().map(Spanned::span), "radius"),
                    (d.samples.as_ref().map(Spanned::span), "samples"),
                ] {
                    reject(self, span, key);
                }
                if d.falloff == Some(FalloffDesc::InverseSquare) {
                    self.error(
                        desc.span(),
                        format!("{label}: a directional light has no distance falloff"),
                    );
                }
                LightShape::Directional {
                    direction: self.direction(d.direction.as_ref()?, "direction"),
                }
            }
            LightKind::Rectangle | LightKind::Disk => {
                needs(self, d.position.is_some(), "position");
                reject(self, d.direction.as_ref().map(Spanned::span), "direction");
                if d.falloff.is_some() {
                    // Radiance: the cos θ′/d² of Lambert's law is the falloff.
                    self.error(
                        desc.span(),
                        format!("{label}: `falloff` does not apply to a {} light (its intensity is radiance; Lambert's law gives the falloff)", kind.name()),
                    );
                }
                let position = self.at_frame(&d.position);
                let center = position.as_ref().map(|p| self.point(p, "position"))?;
                let samples = self.count(&d.samples, 16, "samples", limits::MAX_LIGHT_SAMPLES);
                let two_sided = d.two_sided.as_ref().is_some_and(|b| *b.get_ref());
                let (axis_u, axis_v, outline) = if kind == LightKind::Rectangle {
                    needs(self, d.edge_u.is_some(), "edge_u");
                    needs(self, d.edge_v.is_some(), "edge_v");
                    reject(self, d.radius.as_ref().map(Spanned::span), "radius");
                    reject(self, d.normal.as_ref().map(Spanned::span), "normal");
                    let edge_u = self.vector(d.edge_u.as_ref()?, "edge_u");
                    let edge_v = self.vector(d.edge_v.as_ref()?, "edge_v");
                    (0.5 * edge_u, 0.5 * edge_v, AreaOutline::Rectangle)
                } else {
                    needs(self, d.normal.is_some(), "normal");
                    for (span, key) in [
                        (d.edge_u.as_ref().map(Spanned::span), "edge_u"),
                        (d.edge_v.as_ref().map(Spanned::span), "edge_v"),
                    ] {
                        reject(self, span, key);
                    }
                    let normal = self.direction(d.normal.as_ref()?, "normal");
                    let radius = self.number(&d.radius, 1.0, "radius", LENGTH);
                    // Axes with u × v along the normal.
                    let frame = crate::math::Frame::from_z(normal);
                    (radius * frame.x, radius * frame.y, AreaOutline::Disk)
                };
                let normal = axis_u.cross(axis_v).try_normalize();
                let Some(normal) = normal.filter(|n| n.is_finite()) else {
                    self.error(
                        desc.span(),
                        format!(
                            "{label}: `edge_u` and `edge_v` span no area (zero or parallel edges)"
                        ),
                    );
                    return None;
                };
                LightShape::Area {
                    emitter: AreaLight {
                        center,
                        axis_u,
                        axis_v,
                        normal,
                        outline,
                        two_sided,
                    },
                    samples,
                }
            }
        };
        Some(Light {
            shape,
            radiance,
            inverse_square: d.falloff == Some(FalloffDesc::InverseSquare),
        })
    }

    fn object(
        &mut self,
        index: usize,
        desc: &Spanned<ObjectDesc>,
        materials: &BTreeMap<&str, u32>,
        unparsed: &BTreeSet<String>,
    ) -> Vec<Primitive> {
        let path = format!("objects[{index}]");
        self.object_in(&path, desc, materials, unparsed, &Parent::default())
    }

    /// The primitives of the object at `path` (`objects[3]`,
    /// `objects[3].children[1]`), placed under `parent`.
    fn object_in(
        &mut self,
        path: &str,
        desc: &Spanned<ObjectDesc>,
        materials: &BTreeMap<&str, u32>,
        unparsed: &BTreeSet<String>,
        parent: &Parent,
    ) -> Vec<Primitive> {
        let d = desc.get_ref();
        let kind = *d.kind.get_ref();
        let label = label_of(d, path);
        self.reject_foreign_keys(d, kind, &label);
        if let Some(inverse) = d.inverse.as_ref().filter(|_| !parent.in_csg) {
            self.error(
                inverse.span(),
                format!(
                    "{label}: `inverse` applies to a part of an intersection, difference or merge (a solid alone is drawn the same either way)"
                ),
            );
        }
        if let Some(op) = kind.csg() {
            return self.csg_object(op, path, &label, desc, materials, unparsed, parent);
        }
        if kind == ObjectKind::Mesh {
            return self.mesh_object(d, desc, &label, materials, unparsed, parent.transform);
        }
        let material = match &d.material {
            Some(name) => self.material_named(name, materials, unparsed, &label),
            None if parent.material.is_some() => parent.material,
            None => {
                self.error(
                    desc.span(),
                    format!("{label}: a {} needs `material`", kind.name()),
                );
                None
            }
        };
        let transform = self.transform(d.transform.as_deref().unwrap_or_default(), &label);
        let transform = transform.and_then(|t| self.under(parent.transform, t, desc, &label));
        let errors_before = self.diags.len();
        let Some(shape) = self.analytic_shape(kind, d, desc, &label, transform) else {
            return Vec::new();
        };
        // A value already refused is not reported again as out of range.
        if self.diags.len() == errors_before && !self.within_range(&shape, desc, &label) {
            return Vec::new();
        }
        material
            .map(|material| Primitive { shape, material })
            .into_iter()
            .collect()
    }

    /// `own` placed under a CSG's transform `parent` (parent after own).
    fn under(
        &mut self,
        parent: Option<Transform>,
        own: Transform,
        desc: &Spanned<ObjectDesc>,
        label: &str,
    ) -> Option<Transform> {
        let Some(outer) = parent else {
            return Some(own);
        };
        let placed = Transform::from_affine(outer.to_world * own.to_world);
        if placed.is_none() {
            self.error(
                desc.span(),
                format!("{label}: its transform times its CSG's is singular or out of range"),
            );
        }
        placed
    }

    /// A `union`, `intersection`, `difference` or `merge`: a union not
    /// inside another operation places its children as objects of their
    /// own (every surface kept, as POV-Ray's union); any other becomes one
    /// CSG primitive over its children, each of which must be a solid.
    #[allow(clippy::too_many_arguments)]
    fn csg_object(
        &mut self,
        op: CsgOp,
        path: &str,
        label: &str,
        desc: &Spanned<ObjectDesc>,
        materials: &BTreeMap<&str, u32>,
        unparsed: &BTreeSet<String>,
        parent: &Parent,
    ) -> Vec<Primitive> {
        let d = desc.get_ref();
        if parent.depth >= limits::MAX_CSG_DEPTH {
            self.error(
                desc.span(),
                format!(
                    "{label}: CSG nested more than {} deep; flatten it (a union of unions \
                     is one union)",
                    limits::MAX_CSG_DEPTH
                ),
            );
            return Vec::new();
        }
        let children = d.children.as_deref().unwrap_or_default();
        if children.is_empty() {
            self.error(
                desc.span(),
                format!(
                    "{label}: a {} needs `children` ([[objects.children]] tables, at least one)",
                    op.name()
                ),
            );
            return Vec::new();
        }
        let material = match &d.material {
            Some(name) => self.material_named(name, materials, unparsed, label),
            None => parent.material,
        };
        let Some(transform) = self.transform(d.transform.as_deref().unwrap_or_default(), label)
        else {
            return Vec::new();
        };
        let has_transform = d.transform.as_ref().is_some_and(|t| !t.is_empty());
        let transform = if has_transform {
            match self.under(parent.transform, transform, desc, label) {
                Some(t) => Some(t),
                None => return Vec::new(),
            }
        } else {
            parent.transform
        };
        let flatten = op == CsgOp::Union && !parent.in_csg;
        let inner = Parent {
            transform,
            material,
            depth: parent.depth + 1,
            in_csg: !flatten,
        };
        let mut primitives = Vec::new();
        let mut operands = Vec::with_capacity(if flatten { 0 } else { children.len() });
        for (i, child) in children.iter().enumerate() {
            let child_path = format!("{path}.children[{i}]");
            let errors_before = self.diags.len();
            let built = self.object_in(&child_path, child, materials, unparsed, &inner);
            if !flatten && built.is_empty() && self.diags.len() == errors_before {
                let child_label = label_of(child.get_ref(), &child_path);
                self.error(
                    child.span(),
                    format!("{child_label}: builds nothing (a model without meshes?), so the {} has a part missing", op.name()),
                );
            }
            if flatten {
                primitives.extend(built);
                continue;
            }
            let c = child.get_ref();
            let inverse = c.inverse.as_ref().is_some_and(|v| *v.get_ref());
            let child_label = label_of(c, &child_path);
            let Some(operand) = self.operand(built, inverse, child, &child_label, op) else {
                continue;
            };
            operands.push(operand);
        }
        if flatten || operands.len() != children.len() {
            return primitives;
        }
        // The CSG's own material fills it (its medium).
        let csg = Csg::new(op, operands).with_medium(material);
        let material = material.unwrap_or(csg.children()[0].material);
        vec![Primitive {
            shape: Shape::Csg(Box::new(csg)),
            material,
        }]
    }

    /// One operand of a CSG from what its object built: several primitives
    /// (a model of several meshes) become their union; each must enclose
    /// a solid.
    fn operand(
        &mut self,
        mut built: Vec<Primitive>,
        inverse: bool,
        desc: &Spanned<ObjectDesc>,
        label: &str,
        op: CsgOp,
    ) -> Option<CsgChild> {
        let kind = desc.get_ref().kind.get_ref();
        for p in &built {
            if !p.shape.is_solid() {
                let why = match &p.shape {
                    Shape::Mesh(_) => "its mesh is not closed (every edge must join exactly two \
                         triangles, wound the same way), so it has no inside"
                        .to_string(),
                    Shape::Cone(_) => format!("an open {} has no inside", kind.name()),
                    _ => format!("a {} has no inside", kind.name()),
                };
                self.error(
                    desc.span(),
                    format!(
                        "{label}: a part of a {} must be a closed solid, but {why}",
                        op.name()
                    ),
                );
                return None;
            }
        }
        let (shape, material) = match built.len() {
            0 => return None,
            1 => {
                let p = built.pop()?;
                (p.shape, p.material)
            }
            _ => {
                let material = built[0].material;
                let parts = built
                    .into_iter()
                    .map(|p| CsgChild {
                        shape: p.shape,
                        material: p.material,
                        inverse: false,
                    })
                    .collect();
                (
                    Shape::Csg(Box::new(Csg::new(CsgOp::Union, parts))),
                    material,
                )
            }
        };
        Some(CsgChild {
            shape,
            material,
            inverse,
        })
    }

    /// Whether the placed shape lies within the supported range (its
    /// bounds, or a plane's distance from the origin); reported if not.
    fn within_range(&mut self, shape: &Shape, desc: &Spanned<ObjectDesc>, label: &str) -> bool {
        let reach = match (shape, shape.bounds()) {
            (Shape::Plane(p), _) => p.distance.abs(),
            (_, Some(b)) => b.min.abs().max(b.max.abs()).max_element(),
            (_, None) => 0.0,
        };
        if reach.is_finite() && reach <= limits::MAX_COORDINATE {
            return true;
        }
        self.error(
            desc.span(),
            format!(
                "{label}: after its transform it reaches {reach:e}; the supported range is \
                 coordinates within ±1e30"
            ),
        );
        false
    }

    /// Reports the keys given that belong to other kinds of object.
    fn reject_foreign_keys(&mut self, d: &ObjectDesc, kind: ObjectKind, label: &str) {
        let allowed: &[&str] = match kind {
            ObjectKind::Sphere => &["center", "radius"],
            ObjectKind::Plane => &["normal", "distance", "point"],
            ObjectKind::Polygon => &["vertices"],
            ObjectKind::Mesh => &["file", "light_scale", "camera"],
            ObjectKind::Box => &["corner1", "corner2"],
            ObjectKind::Cylinder => &["base", "cap", "radius", "open"],
            ObjectKind::Cone => &["base", "cap", "base_radius", "cap_radius", "open"],
            ObjectKind::Disc => &["center", "normal", "radius", "hole_radius"],
            ObjectKind::Torus => &["major_radius", "minor_radius"],
            ObjectKind::Union
            | ObjectKind::Intersection
            | ObjectKind::Difference
            | ObjectKind::Merge => &["children"],
        };
        let present = [
            ("center", d.center.as_ref().map(Spanned::span)),
            ("radius", d.radius.as_ref().map(Spanned::span)),
            ("normal", d.normal.as_ref().map(Spanned::span)),
            ("distance", d.distance.as_ref().map(Spanned::span)),
            ("point", d.point.as_ref().map(Spanned::span)),
            ("vertices", d.vertices.as_ref().map(Spanned::span)),
            ("file", d.file.as_ref().map(Spanned::span)),
            ("light_scale", d.light_scale.as_ref().map(Spanned::span)),
            ("camera", d.camera.as_ref().map(Spanned::span)),
            ("corner1", d.corner1.as_ref().map(Spanned::span)),
            ("corner2", d.corner2.as_ref().map(Spanned::span)),
            ("base", d.base.as_ref().map(Spanned::span)),
            ("cap", d.cap.as_ref().map(Spanned::span)),
            ("base_radius", d.base_radius.as_ref().map(Spanned::span)),
            ("cap_radius", d.cap_radius.as_ref().map(Spanned::span)),
            ("open", d.open.as_ref().map(Spanned::span)),
            ("hole_radius", d.hole_radius.as_ref().map(Spanned::span)),
            ("major_radius", d.major_radius.as_ref().map(Spanned::span)),
            ("minor_radius", d.minor_radius.as_ref().map(Spanned::span)),
            (
                "children",
                d.children
                    .as_ref()
                    .and_then(|c| c.first())
                    .map(Spanned::span),
            ),
        ];
        for (key, span) in present {
            if let Some(span) = span.filter(|_| !allowed.contains(&key)) {
                self.error(
                    span,
                    format!("{label}: `{key}` does not apply to a {}", kind.name()),
                );
            }
        }
    }

    /// The primitives of a mesh object: one instance per placement of each
    /// of the model's meshes.
    fn mesh_object(
        &mut self,
        d: &ObjectDesc,
        desc: &Spanned<ObjectDesc>,
        label: &str,
        materials: &BTreeMap<&str, u32>,
        unparsed: &BTreeSet<String>,
        outer: Option<Transform>,
    ) -> Vec<Primitive> {
        let material = d
            .material
            .as_ref()
            .map(|name| self.material_named(name, materials, unparsed, label));
        let transform = self.transform(d.transform.as_deref().unwrap_or_default(), label);
        let Some(file) = &d.file else {
            self.error(desc.span(), format!("{label}: a mesh needs `file`"));
            return Vec::new();
        };
        let has_transform = d.transform.as_ref().is_some_and(|t| !t.is_empty());
        let (Some(transform), Some(loaded)) = (transform, self.model(file, label)) else {
            return Vec::new();
        };
        // Under a CSG's transform, the object's own first.
        let object = match (has_transform.then_some(transform), outer) {
            (own, None) => own,
            (None, Some(o)) => Some(o),
            (Some(own), Some(_)) => match self.under(outer, own, desc, label) {
                Some(t) => Some(t),
                None => return Vec::new(),
            },
        };
        let light_scale = self.number(&d.light_scale, 1.0, "light_scale", VALUE);
        self.place_model_extras(
            &loaded,
            object.as_ref(),
            light_scale,
            d.camera.as_ref(),
            label,
        );
        let materials: Arc<[u32]> = match material {
            Some(Some(m)) => Arc::new([m]),
            Some(None) => return Vec::new(),
            None => loaded.slots.clone(),
        };
        let mut primitives = Vec::with_capacity(loaded.placements.len());
        for (mesh, placement) in &loaded.placements {
            // The placement inside the model first, then the object's.
            let transform = match (placement, &object) {
                (None, None) => None,
                (Some(p), None) => Some(*p),
                (None, Some(o)) => Some(*o),
                (Some(p), Some(o)) => match Transform::from_affine(o.to_world * p.to_world) {
                    Some(t) => Some(t),
                    None => {
                        self.error(
                            desc.span(),
                            format!(
                                "{label}: the object's transform times the model's node \
                                 transform is singular or out of range"
                            ),
                        );
                        return Vec::new();
                    }
                },
            };
            let shape = Shape::Mesh(Box::new(MeshInstance {
                mesh: loaded.meshes[*mesh].clone(),
                transform,
                materials: materials.clone(),
            }));
            if !self.within_range(&shape, desc, label) {
                return Vec::new();
            }
            primitives.push(Primitive {
                shape,
                material: materials[0],
            });
        }
        primitives
    }

    /// The index of material `name`, or an error listing the known ones.
    fn material_named(
        &mut self,
        name: &Spanned<String>,
        materials: &BTreeMap<&str, u32>,
        unparsed: &BTreeSet<String>,
        label: &str,
    ) -> Option<u32> {
        match materials.get(name.get_ref().as_str()) {
            Some(&m) => Some(m),
            // Its own error is already reported.
            None if unparsed.contains(&format!("materials.{}", name.get_ref())) => None,
            None => {
                let known: Vec<_> = materials.keys().map(|k| format!("`{k}`")).collect();
                let known = if known.is_empty() {
                    "none is defined".to_string()
                } else {
                    known.join(", ")
                };
                self.error(
                    name.span(),
                    format!(
                        "{label}: unknown material `{}`; known: {known}",
                        name.get_ref()
                    ),
                );
                None
            }
        }
    }

    /// The geometry of a sphere, plane or polygon object.
    fn analytic_shape(
        &mut self,
        kind: ObjectKind,
        d: &ObjectDesc,
        desc: &Spanned<ObjectDesc>,
        label: &str,
        transform: Option<Transform>,
    ) -> Option<Shape> {
        Some(match kind {
            ObjectKind::Mesh
            | ObjectKind::Union
            | ObjectKind::Intersection
            | ObjectKind::Difference
            | ObjectKind::Merge => return None,
            ObjectKind::Sphere => {
                let center = d
                    .center
                    .as_ref()
                    .map_or(DVec3::ZERO, |c| self.point(c, "center"));
                let radius = self.number(&d.radius, 1.0, "radius", LENGTH);
                let transform = transform?;
                match transform.uniform_scale() {
                    Some(s) => Shape::Sphere(Sphere {
                        center: transform.point(center),
                        radius: radius * s,
                    }),
                    None => {
                        let local = DAffine3::from_scale_rotation_translation(
                            DVec3::splat(radius),
                            DQuat::IDENTITY,
                            center,
                        );
                        Shape::Ellipsoid(Box::new(Ellipsoid {
                            transform: Transform::from_affine(transform.to_world * local)?,
                        }))
                    }
                }
            }
            ObjectKind::Plane => {
                let Some(normal_desc) = &d.normal else {
                    self.error(desc.span(), format!("{label}: a plane needs `normal`"));
                    return None;
                };
                let normal = self.direction(normal_desc, "normal");
                let point = match (&d.distance, &d.point) {
                    (Some(dist), Some(p)) => {
                        self.error(
                            p.span(),
                            format!("{label}: give `distance` or `point`, not both"),
                        );
                        normal * *dist.get_ref()
                    }
                    (Some(_), None) => {
                        normal * self.number(&d.distance, 0.0, "distance", COORDINATE)
                    }
                    (None, Some(p)) => self.point(p, "point"),
                    (None, None) => DVec3::ZERO,
                };
                let transform = transform?;
                Shape::Plane(Plane::through(
                    transform.point(point),
                    transform.normal(normal),
                ))
            }
            ObjectKind::Box => {
                let (Some(c1), Some(c2)) = (&d.corner1, &d.corner2) else {
                    self.error(
                        desc.span(),
                        format!("{label}: a box needs `corner1` and `corner2`"),
                    );
                    return None;
                };
                let (a, b) = (self.point(c1, "corner1"), self.point(c2, "corner2"));
                let (min, max) = (a.min(b), a.max(b));
                if (max - min).min_element() < limits::MIN_LENGTH {
                    self.error(
                        c2.span(),
                        format!("{label}: the corners must differ along every axis (a flat box is a polygon)"),
                    );
                    return None;
                }
                Shape::Cuboid(Box::new(Cuboid::new(min, max, transform?)))
            }
            ObjectKind::Cylinder | ObjectKind::Cone => {
                let (Some(base), Some(cap)) = (&d.base, &d.cap) else {
                    self.error(
                        desc.span(),
                        format!("{label}: a {} needs `base` and `cap`", kind.name()),
                    );
                    return None;
                };
                let (b, c) = (self.point(base, "base"), self.point(cap, "cap"));
                let (r0, r1) = if kind == ObjectKind::Cylinder {
                    let r = self.number(&d.radius, 1.0, "radius", LENGTH);
                    (r, r)
                } else {
                    (
                        self.number(&d.base_radius, 1.0, "base_radius", LENGTH_OR_ZERO),
                        self.number(&d.cap_radius, 0.0, "cap_radius", LENGTH_OR_ZERO),
                    )
                };
                if r0 == 0.0 && r1 == 0.0 {
                    self.error(
                        desc.span(),
                        format!("{label}: a cone needs a radius above 0 at one end"),
                    );
                    return None;
                }
                let axis = c - b;
                if axis.length() < limits::MIN_LENGTH {
                    self.error(
                        cap.span(),
                        format!("{label}: `cap` must differ from `base`"),
                    );
                    return None;
                }
                // Object space: the axis along z from 0 (base) to 1 (cap).
                let placed = self.placed_along(transform?, axis, b, desc, label)?;
                Shape::Cone(Box::new(Cone {
                    base_radius: r0,
                    cap_radius: r1,
                    open: d.open.as_ref().is_some_and(|o| *o.get_ref()),
                    transform: placed,
                }))
            }
            ObjectKind::Disc => {
                let Some(normal_desc) = &d.normal else {
                    self.error(desc.span(), format!("{label}: a disc needs `normal`"));
                    return None;
                };
                let normal = self.direction(normal_desc, "normal");
                let center = d
                    .center
                    .as_ref()
                    .map_or(DVec3::ZERO, |c| self.point(c, "center"));
                let radius = self.number(&d.radius, 1.0, "radius", LENGTH);
                let hole = self.number(&d.hole_radius, 0.0, "hole_radius", LENGTH_OR_ZERO);
                if hole >= radius {
                    self.error(
                        d.hole_radius.as_ref().map_or(desc.span(), Spanned::span),
                        format!(
                            "{label}: `hole_radius` {hole} must be less than `radius` {radius}"
                        ),
                    );
                    return None;
                }
                let placed = self.placed_along(transform?, normal, center, desc, label)?;
                Shape::Disc(Box::new(Disc {
                    radius,
                    hole_radius: hole,
                    transform: placed,
                }))
            }
            ObjectKind::Torus => {
                let big = self.number(&d.major_radius, 1.0, "major_radius", LENGTH);
                let small = self.number(&d.minor_radius, 0.25, "minor_radius", LENGTH);
                if small >= big {
                    // A spindle torus (r ≥ R) intersects itself.
                    self.error(
                        d.minor_radius.as_ref().map_or(desc.span(), Spanned::span),
                        format!(
                            "{label}: `minor_radius` {small} must be less than `major_radius` {big}"
                        ),
                    );
                    return None;
                }
                Shape::Torus(Box::new(Torus {
                    major_radius: big,
                    minor_radius: small,
                    transform: transform?,
                }))
            }
            ObjectKind::Polygon => {
                let Some(vertices) = &d.vertices else {
                    self.error(desc.span(), format!("{label}: a polygon needs `vertices`"));
                    return None;
                };
                let transform = transform?;
                let world = vertices
                    .get_ref()
                    .iter()
                    .map(|v| transform.point(DVec3::from_array(*v)))
                    .collect();
                match Polygon::new(world) {
                    Ok(p) => Shape::Polygon(Box::new(p)),
                    Err(e) => {
                        self.error(vertices.span(), format!("{label}: {e}"));
                        return None;
                    }
                }
            }
        })
    }

    /// The object's own space of a shape built around an axis (cones,
    /// discs): object z runs along `axis` (its length is object z's unit)
    /// from `origin`, x and y across it, then the object's `transform`.
    fn placed_along(
        &mut self,
        transform: Transform,
        axis: DVec3,
        origin: DVec3,
        desc: &Spanned<ObjectDesc>,
        label: &str,
    ) -> Option<Transform> {
        let f = crate::math::Frame::from_z(axis.normalize());
        let local = DAffine3::from_mat3_translation(glam::DMat3::from_cols(f.x, f.y, axis), origin);
        let placed = Transform::from_affine(transform.to_world * local);
        if placed.is_none() {
            self.error(
                desc.span(),
                format!("{label}: its transform is singular or out of range"),
            );
        }
        placed
    }

    /// The mesh and material slots of the model `file`, loaded once however
    /// often it is placed.
    fn model(&mut self, file: &Spanned<String>, label: &str) -> Option<LoadedModel> {
        let path = self.base_dir.join(file.get_ref());
        let key = path.canonicalize().unwrap_or_else(|_| path.clone());
        if let Some(found) = self.models.get(&key) {
            return Some(found.clone());
        }
        let read = match self.cache.get(&key) {
            Some(read) => read,
            None => {
                let read = Arc::new(self.read_model(&path, file, label)?);
                self.cache.insert(key.clone(), read.clone());
                read
            }
        };
        let posed;
        let pose = match &read.motion {
            None => &read.pose,
            Some(motion) => {
                // Prism's frame F is the glTF's time F / fps.
                self.keyed = true;
                posed = match motion.pose(self.frame / self.fps) {
                    Ok(p) => p,
                    Err(e) => {
                        self.model_failed = true;
                        self.error(file.span(), format!("{label}: {e}"));
                        return None;
                    }
                };
                &posed
            }
        };
        let mut placements = Vec::with_capacity(pose.placements.len());
        for &(mesh, m) in &pose.placements {
            let affine = DAffine3::from_mat4(m);
            if affine == DAffine3::IDENTITY {
                placements.push((mesh, None));
                continue;
            }
            // Out of range or singular is an error, never "placed as is".
            let Some(t) = Transform::from_affine(affine) else {
                self.model_failed = true;
                self.error(
                    file.span(),
                    format!(
                        "{label}: {}: a node's transform is singular or out of range (scale \
                         factors 1e-30 to 1e30, translations within ±1e30)",
                        path.display()
                    ),
                );
                return None;
            };
            placements.push((mesh, Some(t)));
        }
        let slots: Arc<[u32]> = if read.materials.is_empty() {
            let default = *self.default_material.get_or_insert_with(|| {
                self.materials.push(Material::default());
                self.materials.len() as u32 - 1
            });
            Arc::new([default])
        } else {
            let first = self.materials.len() as u32;
            self.materials.extend(read.materials.iter().cloned());
            (first..self.materials.len() as u32).collect()
        };
        self.warnings.extend(read.warnings.iter().cloned());
        let loaded = LoadedModel {
            meshes: read.meshes.clone(),
            placements,
            slots,
            lights: pose.lights.clone(),
            cameras: pose.cameras.clone(),
        };
        self.models.insert(key, loaded.clone());
        Some(loaded)
    }

    /// Reads the model file at `path` and builds its meshes' trees.
    fn read_model(
        &mut self,
        path: &Path,
        file: &Spanned<String>,
        label: &str,
    ) -> Option<ReadModel> {
        let model = match load_model(path, &mut self.resources) {
            Ok(m) => m,
            Err(e) => {
                self.model_failed = true;
                self.error(file.span(), format!("{label}: {e}"));
                return None;
            }
        };
        let mut meshes = Vec::with_capacity(model.meshes.len());
        for data in model.meshes {
            match Mesh::new(data) {
                Ok(m) => meshes.push(Arc::new(m)),
                Err(e) => {
                    // The model failed as surely as when it could not be
                    // read: it may have brought the camera.
                    self.model_failed = true;
                    self.error(file.span(), format!("{label}: {}: {e}", path.display()));
                    return None;
                }
            }
        }
        Some(ReadModel {
            meshes,
            pose: Pose {
                placements: model.placements,
                lights: model.lights,
                cameras: model.cameras,
            },
            materials: model.materials,
            warnings: model.warnings,
            motion: model.motion,
        })
    }

    /// Puts the lights (times `light_scale`) and cameras a model brought
    /// into the world, through the placement's transform; `camera` is the
    /// object's choice among the model's cameras.
    fn place_model_extras(
        &mut self,
        model: &LoadedModel,
        transform: Option<&Transform>,
        light_scale: f64,
        camera: Option<&Spanned<String>>,
        label: &str,
    ) {
        let point = |p: DVec3| transform.map_or(p, |t| t.point(p));
        let vector = |v: DVec3| {
            transform
                .map_or(v, |t| t.to_world.transform_vector3(v))
                .normalize_or_zero()
        };
        for light in &model.lights {
            let mut light = *light;
            light.shape = match light.shape {
                LightShape::Point { position } => LightShape::Point {
                    position: point(position),
                },
                LightShape::Directional { direction } => LightShape::Directional {
                    direction: vector(direction),
                },
                LightShape::Spot {
                    position,
                    direction,
                    cos_inner,
                    cos_outer,
                    cone,
                } => LightShape::Spot {
                    position: point(position),
                    direction: vector(direction),
                    cos_inner,
                    cos_outer,
                    cone,
                },
                LightShape::Sphere {
                    center,
                    radius,
                    samples,
                } => LightShape::Sphere {
                    center: point(center),
                    radius,
                    samples,
                },
                LightShape::Area { emitter, samples } => {
                    let along = |v: DVec3| transform.map_or(v, |t| t.to_world.transform_vector3(v));
                    let (axis_u, axis_v) = (along(emitter.axis_u), along(emitter.axis_v));
                    LightShape::Area {
                        emitter: AreaLight {
                            center: point(emitter.center),
                            axis_u,
                            axis_v,
                            normal: axis_u.cross(axis_v).normalize_or_zero(),
                            ..emitter
                        },
                        samples,
                    }
                }
            };
            light.radiance *= light_scale;
            if light_scale > 0.0 {
                self.model_lights.push(light);
            }
        }
        let place = |cam: &ModelCamera, explicit: bool| {
            let position = point(cam.position);
            let projection = match cam.projection {
                ModelProjection::Perspective { yfov } => Projection::Perspective {
                    fov: yfov,
                    axis: FovAxis::Vertical,
                },
                ModelProjection::Orthographic { ymag } => Projection::Orthographic {
                    view_height: 2.0
                        * ymag
                        * transform
                            .map_or(1.0, |t| t.to_world.transform_vector3(DVec3::Y).length()),
                },
            };
            Camera::look_at(
                position,
                position + vector(cam.forward),
                vector(cam.up),
                projection,
            )
            .map(|camera| ChosenCamera {
                camera,
                name: cam.name.clone(),
                aspect: cam.aspect_ratio,
                explicit,
            })
        };
        if let Some(name) = &self.camera_request
            && self.requested_camera.is_none()
            && let Some(cam) = model.cameras.iter().find(|c| c.is_named(name))
        {
            self.requested_camera = place(cam, true);
        }
        self.model_camera_names
            .extend(model.cameras.iter().map(|c| format!("`{}`", c.name)));
        match camera {
            Some(name) => match model.cameras.iter().find(|c| c.is_named(name.get_ref())) {
                Some(cam) => {
                    if !self.model_camera.as_ref().is_some_and(|c| c.explicit) {
                        self.model_camera = place(cam, true);
                    }
                }
                None => {
                    let known: Vec<String> = model
                        .cameras
                        .iter()
                        .map(|c| format!("`{}`", c.name))
                        .collect();
                    self.error(
                        name.span(),
                        format!(
                            "{label}: the model has no camera named `{}` ({})",
                            limits_cut(name.get_ref()),
                            if known.is_empty() {
                                "it has no cameras".to_string()
                            } else {
                                format!("its cameras: {}", known.join(", "))
                            }
                        ),
                    );
                }
            },
            None => {
                if self.model_camera.is_none()
                    && let Some(cam) = model.cameras.first()
                {
                    self.model_camera = place(cam, false);
                }
            }
        }
    }

    /// The steps composed in order: the first step acts on the object first.
    fn transform(&mut self, ops: &[Spanned<TransformOp>], label: &str) -> Option<Transform> {
        let mut m = DAffine3::IDENTITY;
        let mut ok = true;
        for op in ops {
            let step = match op.get_ref() {
                TransformOp::Translate(t) => Some(DAffine3::from_translation(DVec3::from_array(
                    self.value_at_frame(t),
                ))),
                TransformOp::Rotate { axis, degrees } => {
                    let degrees = self.value_at_frame(degrees);
                    DVec3::from_array(*axis)
                        .try_normalize()
                        .map(|a| DAffine3::from_axis_angle(a, degrees.to_radians()))
                }
                TransformOp::Scale(s) => Some(DAffine3::from_scale(DVec3::from_array(
                    self.value_at_frame(s).0,
                ))),
                TransformOp::Matrix(rows) => {
                    let m4 = DMat4::from_cols_array_2d(rows).transpose();
                    (m4.row(3) == DVec4::W).then(|| DAffine3 {
                        matrix3: DMat3::from_mat4(m4),
                        translation: m4.w_axis.truncate(),
                    })
                }
            };
            match step.filter(DAffine3::is_finite) {
                Some(s) if Transform::from_affine(s).is_some() => m = s * m,
                _ => {
                    ok = false;
                    self.error(
                        op.span(),
                        format!(
                            "{label}: invalid transform step; expected finite values, a non-zero rotation axis, \
                             scale factors between 1e-30 and 1e30, translations within ±1e30 \
                             and a matrix whose last row is [0, 0, 0, 1]"
                        ),
                    );
                }
            }
        }
        if !ok {
            return None;
        }
        Transform::from_affine(m).or_else(|| {
            self.error(
                ops[0].span(),
                format!(
                    "{label}: the steps together are singular or out of range (they must scale by \
                     1e-30 to 1e30 along every axis and translate within ±1e30)"
                ),
            );
            None
        })
    }
}

/// A length (radius, size): within the supported range.
const LENGTH: (fn(f64) -> bool, &str) = (
    |x| (limits::MIN_LENGTH..=limits::MAX_COORDINATE).contains(&x),
    "between 1e-30 and 1e30 (the supported range of lengths)",
);
/// A light radius: 0 (a point) or a length.
const LENGTH_OR_ZERO: (fn(f64) -> bool, &str) = (
    |x| x == 0.0 || LENGTH.0(x),
    "0 or between 1e-30 and 1e30 (the supported range of lengths)",
);
/// A signed distance from the origin.
const COORDINATE: (fn(f64) -> bool, &str) = (
    |x| x.abs() <= limits::MAX_COORDINATE,
    "within ±1e30 (the supported range)",
);
/// A coefficient or intensity.
const VALUE: (fn(f64) -> bool, &str) = (
    |x| (0.0..=limits::MAX_VALUE).contains(&x),
    "between 0 and 1e15",
);
/// An index of refraction.
const IOR: (fn(f64) -> bool, &str) = (
    |x| x > 0.0 && x <= limits::MAX_VALUE,
    "greater than 0 and at most 1e15",
);
const UNIT_INTERVAL: (fn(f64) -> bool, &str) = (|x| (0.0..=1.0).contains(&x), "between 0 and 1");
/// A name from the file for messages, cut to a readable length.
fn limits_cut(s: &str) -> String {
    super::models::cut(s, 80)
}

/// A spot light's cone half-angle, in degrees.
const HALF_ANGLE: (fn(f64) -> bool, &str) =
    (|x| (0.0..=90.0).contains(&x), "between 0 and 90 degrees");
/// Exposure in stops: 2^±64 keeps every pixel finite.
const EXPOSURE: (fn(f64) -> bool, &str) =
    (|x| (-64.0..=64.0).contains(&x), "between -64 and 64 stops");

/// A number for messages in the form a person reads: plain for everyday
/// magnitudes, with an exponent for very large or small ones (1e39, not
/// forty digits).
fn readable(x: f64) -> String {
    if x == 0.0 || (1e-4..1e9).contains(&x.abs()) {
        x.to_string()
    } else {
        format!("{x:e}")
    }
}

/// A number for messages: at most 6 decimals, no float noise (1.3, not 1.2999999999999998).
fn short(x: f64) -> String {
    let s = format!("{x:.6}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}
