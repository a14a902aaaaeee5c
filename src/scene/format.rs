//! The scene file format: these serde structs *are* the format (TOML).
//! Unknown keys are refused; values keep their source spans so the
//! validation pass can point at them. docs/scene-format.md documents every key.

use std::collections::{BTreeMap, BTreeSet};
use std::ops::Range;

use serde::Deserialize;
use toml::Spanned;

use super::animation::{Animated, AnimationDesc};

/// Three numbers: a point, a vector or an RGB colour.
pub type Triple = Spanned<[f64; 3]>;
/// A number with its span.
pub type Number = Spanned<f64>;
/// A point, direction or colour that may be keyed per frame.
pub type AnimatedTriple = Spanned<Animated<[f64; 3]>>;
/// A number that may be keyed per frame.
pub type AnimatedNumber = Spanned<Animated<f64>>;

/// The whole file, section by section.
#[derive(Debug, Default)]
pub struct SceneFile {
    /// `[render]`.
    pub render: RenderDesc,
    /// `[animation]`.
    pub animation: Option<Spanned<AnimationDesc>>,
    /// `[camera]`.
    pub camera: Option<Spanned<CameraDesc>>,
    /// `[materials.NAME]`.
    pub materials: BTreeMap<String, Spanned<MaterialDesc>>,
    /// Entries present in the file that failed to parse and are already
    /// reported (`camera`, `materials.NAME`): what refers to them gets no
    /// second error.
    pub unparsed: BTreeSet<String>,
    /// `[lights.NAME]`.
    pub lights: BTreeMap<String, Spanned<LightDesc>>,
    /// Objects given inline (`objects = [{ ... }]`), parsed with the rest.
    pub objects: Vec<Spanned<ObjectDesc>>,
    /// The byte ranges of the `[[objects]]` tables in the source: each is
    /// parsed (by `load::object`) only when the builder reaches it, so a
    /// million objects never stand as a million syntax trees at once.
    pub object_tables: Vec<Range<usize>>,
}

/// `adaptive = { threshold = …, depth = …, jitter = … }` in `[render]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AdaptiveDesc {
    /// Largest corner difference left without a cut.
    pub threshold: Option<Number>,
    /// Most levels of cuts.
    pub depth: Option<Spanned<u32>>,
    /// Jittered sample points.
    pub jitter: Option<bool>,
}

/// `[render]`: image and tracing settings.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderDesc {
    /// Image width in pixels.
    pub width: Option<Spanned<u32>>,
    /// Image height in pixels.
    pub height: Option<Spanned<u32>>,
    /// Samples per pixel.
    pub spp: Option<Spanned<u32>>,
    /// Longest ray path, counting the camera ray.
    pub max_depth: Option<Spanned<u32>>,
    /// Adaptive depth threshold.
    pub min_weight: Option<Number>,
    /// Colour of rays that hit nothing.
    pub background: Option<Triple>,
    /// Ambient light Ia.
    pub ambient: Option<Triple>,
    /// Random seed.
    pub seed: Option<Spanned<u64>>,
    /// Let transparent objects pass light to shadow feelers.
    pub transparent_shadows: Option<bool>,
    /// Exposure in stops for 8-bit images.
    pub exposure: Option<Number>,
    /// Adaptive anti-aliasing.
    pub adaptive: Option<Spanned<AdaptiveDesc>>,
    /// Motion blur: when the shutter opens and closes, in frames.
    pub shutter: Option<Spanned<[f64; 2]>>,
    /// Instants the shutter is sampled at.
    pub shutter_samples: Option<Spanned<u32>>,
}

/// Camera projections.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "lowercase")]
pub enum CameraKind {
    /// Pinhole.
    #[default]
    Perspective,
    /// Parallel rays.
    Orthographic,
}

/// Which axis `fov` spans.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum FovAxisDesc {
    /// Image height.
    Vertical,
    /// Image width.
    Horizontal,
}

/// `[camera]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraDesc {
    /// Projection.
    #[serde(rename = "type", default)]
    pub kind: CameraKind,
    /// Eye position.
    pub position: AnimatedTriple,
    /// Point looked at.
    pub look_at: AnimatedTriple,
    /// Up direction.
    pub up: Option<AnimatedTriple>,
    /// Field of view in degrees (perspective).
    pub fov: Option<AnimatedNumber>,
    /// Axis of `fov`.
    pub fov_axis: Option<Spanned<FovAxisDesc>>,
    /// Height of the view in world units (orthographic).
    pub view_height: Option<Number>,
    /// Thin lens radius in world units (0: a pinhole).
    pub aperture: Option<AnimatedNumber>,
    /// Distance along the view direction to the plane in focus.
    pub focus_distance: Option<AnimatedNumber>,
    /// A point whose depth along the view direction is the focus distance.
    pub focus_on: Option<AnimatedTriple>,
    /// Lens shift (right, up) in extents of the fov axis or view heights.
    pub shift: Option<Spanned<[f64; 2]>>,
}

/// `fresnel = ...`.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum FresnelDesc {
    /// Classic kr/kt.
    Off,
    /// Exact dielectric Fresnel.
    Exact,
    /// Schlick's approximation.
    Schlick,
}

/// `highlight = ...`.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum HighlightDesc {
    /// Phong (R·V).
    Phong,
    /// Blinn-Phong (N·H).
    Blinn,
}

/// `checker = { color = [...], size = ... }`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CheckerDesc {
    /// Colour of the odd cells (the material's `color` fills the even ones).
    pub color: Triple,
    /// Cell side in world units (or texture-coordinate units with `uv`).
    pub size: Option<Number>,
    /// `"world"` (a solid checkerboard in space, the default) or `"uv"`
    /// (squares in texture coordinates).
    pub mapping: Option<CheckerMapping>,
    /// `"none"` (the colour at the hit point, as POV-Ray; the default) or
    /// `"box"` (a camera ray sees the checker's mean over its footprint).
    pub filter: Option<CheckerFilter>,
}

/// How a checkerboard is sampled.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum CheckerFilter {
    /// The colour at the point.
    None,
    /// The mean over the box around the camera ray's footprint.
    Box,
}

/// Where a checkerboard lives.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum CheckerMapping {
    /// Cubes in world space.
    World,
    /// Squares in texture coordinates.
    Uv,
}

/// `[materials.NAME]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialDesc {
    /// Surface colour Od.
    pub color: Option<Triple>,
    /// Checkerboard texture.
    pub checker: Option<Spanned<CheckerDesc>>,
    /// Image texture file for the colour (by texture coordinates),
    /// relative to the scene file.
    pub texture: Option<Spanned<String>>,
    /// Ambient coefficient.
    pub ka: Option<Number>,
    /// Diffuse coefficient.
    pub kd: Option<Number>,
    /// Specular coefficient.
    pub ks: Option<Number>,
    /// Phong exponent.
    pub shininess: Option<Number>,
    /// Reflection weight: a number (grey) or an RGB colour (tinted
    /// reflection, e.g. gold).
    pub kr: Option<Spanned<OneOrThree>>,
    /// Transmission weight: a number or an RGB colour (tinted glass).
    pub kt: Option<Spanned<OneOrThree>>,
    /// Index of refraction.
    pub ior: Option<Number>,
    /// Fresnel mode.
    pub fresnel: Option<FresnelDesc>,
    /// Highlight model.
    pub highlight: Option<HighlightDesc>,
    /// Light the surface gives off itself.
    pub emission: Option<Triple>,
    /// Glossy lobe: perceptual roughness in [0, 1].
    pub roughness: Option<Number>,
    /// Rays per glossy lobe.
    pub samples: Option<Spanned<u32>>,
}

/// Light kinds.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum LightKind {
    /// A point.
    Point,
    /// Parallel light.
    Directional,
    /// A sphere with volume.
    Sphere,
    /// A point lighting a cone.
    Spot,
    /// A uniform Lambertian rectangle.
    Rectangle,
    /// A uniform Lambertian disk.
    Disk,
}

impl LightKind {
    /// The name as written in scene files.
    pub fn name(self) -> &'static str {
        match self {
            LightKind::Point => "point",
            LightKind::Directional => "directional",
            LightKind::Sphere => "sphere",
            LightKind::Spot => "spot",
            LightKind::Rectangle => "rectangle",
            LightKind::Disk => "disk",
        }
    }
}

/// `falloff = ...`.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum FalloffDesc {
    /// Constant with distance.
    None,
    /// 1/d².
    InverseSquare,
}

/// `cone_falloff = ...` (spot lights).
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum ConeFalloffDesc {
    /// KHR_lights_punctual's t² between the cones.
    Gltf,
    /// Blender Cycles': cos θ × smoothstep between the cones.
    Cycles,
}

/// `[lights.NAME]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightDesc {
    /// Kind of light.
    #[serde(rename = "type")]
    pub kind: Spanned<LightKind>,
    /// Position (point) or centre (sphere, rectangle, disk).
    pub position: Option<AnimatedTriple>,
    /// Direction the light travels (directional).
    pub direction: Option<Triple>,
    /// Radius (sphere, disk).
    pub radius: Option<Number>,
    /// Rectangle: the full first edge.
    pub edge_u: Option<Triple>,
    /// Rectangle: the full second edge (it emits toward edge_u × edge_v).
    pub edge_v: Option<Triple>,
    /// Disk: the normal of its emitting side.
    pub normal: Option<Triple>,
    /// Rectangle, disk: whether both sides emit.
    pub two_sided: Option<Spanned<bool>>,
    /// Shadow feelers per shading point (sphere, rectangle, disk).
    pub samples: Option<Spanned<u32>>,
    /// Colour.
    pub color: Option<AnimatedTriple>,
    /// Multiplier of the colour.
    pub intensity: Option<AnimatedNumber>,
    /// Distance falloff.
    pub falloff: Option<FalloffDesc>,
    /// Spot: half-angle in degrees of the full-intensity cone.
    pub inner_angle: Option<Number>,
    /// Spot: half-angle in degrees beyond which nothing is lit.
    pub outer_angle: Option<Number>,
    /// Spot: how the intensity falls off across the cone.
    pub cone_falloff: Option<Spanned<ConeFalloffDesc>>,
}

/// Object kinds.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum ObjectKind {
    /// Sphere (ellipsoid when non-uniformly scaled).
    Sphere,
    /// Infinite plane.
    Plane,
    /// Planar polygon.
    Polygon,
    /// Triangle mesh from a model file.
    Mesh,
    /// Box between two corners (POV-Ray's `box`).
    Box,
    /// Cylinder between two end points, capped or open.
    Cylinder,
    /// Truncated cone between two end points with a radius at each.
    Cone,
    /// Flat disc or ring.
    Disc,
    /// Torus around the y axis, centred at the origin.
    Torus,
    /// CSG: every child (POV-Ray's `union`).
    Union,
    /// CSG: where all children are.
    Intersection,
    /// CSG: the first child less the others.
    Difference,
    /// CSG: the union without inner surfaces.
    Merge,
}

impl ObjectKind {
    /// The name as written in scene files.
    pub fn name(self) -> &'static str {
        match self {
            ObjectKind::Sphere => "sphere",
            ObjectKind::Plane => "plane",
            ObjectKind::Polygon => "polygon",
            ObjectKind::Mesh => "mesh",
            ObjectKind::Box => "box",
            ObjectKind::Cylinder => "cylinder",
            ObjectKind::Cone => "cone",
            ObjectKind::Disc => "disc",
            ObjectKind::Torus => "torus",
            ObjectKind::Union => "union",
            ObjectKind::Intersection => "intersection",
            ObjectKind::Difference => "difference",
            ObjectKind::Merge => "merge",
        }
    }

    /// The CSG operation this kind names, if it names one.
    pub fn csg(self) -> Option<crate::geometry::CsgOp> {
        use crate::geometry::CsgOp;
        match self {
            ObjectKind::Union => Some(CsgOp::Union),
            ObjectKind::Intersection => Some(CsgOp::Intersection),
            ObjectKind::Difference => Some(CsgOp::Difference),
            ObjectKind::Merge => Some(CsgOp::Merge),
            _ => None,
        }
    }
}

/// `[[objects]]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectDesc {
    /// Kind of object.
    #[serde(rename = "type")]
    pub kind: Spanned<ObjectKind>,
    /// Optional name used in messages.
    pub name: Option<String>,
    /// Name of a material (for meshes: overrides the model's own).
    pub material: Option<Spanned<String>>,
    /// Model file (meshes), relative to the scene file.
    pub file: Option<Spanned<String>>,
    /// Meshes: the factor on the lights the model brings (0 drops them).
    pub light_scale: Option<Number>,
    /// Meshes: the name of the model's camera to use.
    pub camera: Option<Spanned<String>>,
    /// Sphere centre.
    pub center: Option<Triple>,
    /// Sphere radius.
    pub radius: Option<Number>,
    /// Plane normal.
    pub normal: Option<Triple>,
    /// Plane distance from the origin along the normal.
    pub distance: Option<Number>,
    /// A point on the plane (instead of `distance`).
    pub point: Option<Triple>,
    /// Polygon vertices.
    pub vertices: Option<Spanned<Vec<[f64; 3]>>>,
    /// Box: one corner.
    pub corner1: Option<Triple>,
    /// Box: the opposite corner.
    pub corner2: Option<Triple>,
    /// Cylinder, cone: the centre of the base end.
    pub base: Option<Triple>,
    /// Cylinder, cone: the centre of the cap end.
    pub cap: Option<Triple>,
    /// Cone: the radius at `base`.
    pub base_radius: Option<Number>,
    /// Cone: the radius at `cap` (0: a tip).
    pub cap_radius: Option<Number>,
    /// Cylinder, cone: without the end discs.
    pub open: Option<Spanned<bool>>,
    /// Disc: the radius of the hole in its middle.
    pub hole_radius: Option<Number>,
    /// Torus: the radius of the tube's centre circle.
    pub major_radius: Option<Number>,
    /// Torus: the tube's radius.
    pub minor_radius: Option<Number>,
    /// Transform, applied first to last.
    pub transform: Option<Vec<Spanned<TransformOp>>>,
    /// CSG: the operands (`[[objects.children]]`), any kind of object.
    pub children: Option<Vec<Spanned<ObjectDesc>>>,
    /// Inside a CSG: the complement of the solid (POV-Ray's `inverse`).
    pub inverse: Option<Spanned<bool>>,
}

/// One step of an object transform.
#[derive(Debug, Deserialize)]
#[serde(rename_all = "lowercase", deny_unknown_fields)]
pub enum TransformOp {
    /// `{ translate = [x, y, z] }`.
    Translate(Animated<[f64; 3]>),
    /// `{ rotate = { axis = [x, y, z], degrees = a } }`.
    Rotate {
        /// Rotation axis.
        axis: [f64; 3],
        /// Angle, counter-clockwise looking down the axis.
        degrees: Animated<f64>,
    },
    /// `{ scale = s }` or `{ scale = [x, y, z] }`.
    Scale(Animated<OneOrThree>),
    /// `{ matrix = [[...], [...], [...], [...]] }`: row-major 4×4 acting on
    /// column vectors; the last row must be [0, 0, 0, 1].
    Matrix([[f64; 4]; 4]),
}

/// A number that stands for three equal ones, or three numbers: a uniform
/// or per-axis scale, a grey or coloured weight.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OneOrThree(pub [f64; 3]);

impl<'de> Deserialize<'de> for OneOrThree {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = OneOrThree;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a number or an array of 3 numbers")
            }
            fn visit_f64<E>(self, v: f64) -> Result<OneOrThree, E> {
                Ok(OneOrThree([v; 3]))
            }
            fn visit_i64<E>(self, v: i64) -> Result<OneOrThree, E> {
                Ok(OneOrThree([v as f64; 3]))
            }
            fn visit_u64<E>(self, v: u64) -> Result<OneOrThree, E> {
                Ok(OneOrThree([v as f64; 3]))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                seq: A,
            ) -> Result<OneOrThree, A::Error> {
                let v = <[f64; 3]>::deserialize(serde::de::value::SeqAccessDeserializer::new(seq))?;
                Ok(OneOrThree(v))
            }
        }
        d.deserialize_any(V)
    }
}
