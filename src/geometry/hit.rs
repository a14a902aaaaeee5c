//! What a shape reports about a ray hit.

use glam::{DVec2, DVec3};

/// A ray-shape intersection, before the aggregate adds which primitive it was.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShapeHit {
    /// Ray parameter of the hit.
    pub t: f64,
    /// Unit geometric normal on the shape's outside (for planes and
    /// polygons: the side their normal points to).
    pub normal: DVec3,
    /// True when the ray arrives from the outside (D·N < 0); false for a
    /// back-face hit or a hit from inside a closed shape.
    pub front_face: bool,
    /// Unit normal for shading (interpolated on smooth meshes; else `normal`).
    pub shading_normal: DVec3,
    /// Texture coordinates, where the shape computes them during the test
    /// (meshes, CSG); analytic shapes give theirs when shading asks for
    /// them (`Aggregate::uv`).
    pub uv: DVec2,
    /// Vertex colour at the hit (white where the shape has none).
    pub color: DVec3,
    /// A material chosen by the shape itself (a mesh's per-triangle
    /// material), overriding the primitive's.
    pub material: Option<u32>,
    /// Where shadow feelers start, relative to the hit point: the shadow
    /// terminator's lift on smooth-shaded meshes, else zero.
    pub feeler_offset: DVec3,
}

impl ShapeHit {
    /// A hit on a shape with one normal and no material of its own.
    #[inline]
    pub fn geometric(t: f64, normal: DVec3, front_face: bool) -> Self {
        ShapeHit {
            t,
            normal,
            front_face,
            shading_normal: normal,
            uv: DVec2::ZERO,
            color: DVec3::ONE,
            material: None,
            feeler_offset: DVec3::ZERO,
        }
    }
}

/// The closest hit along a ray, as the aggregate reports it to shading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter.
    pub t: f64,
    /// The hit point O + tD.
    pub point: DVec3,
    /// Unit geometric normal on the shape's outside.
    pub normal: DVec3,
    /// The ray arrives from the outside (D·N < 0).
    pub front_face: bool,
    /// Unit normal for shading, on the same side as `normal`.
    pub shading_normal: DVec3,
    /// Texture coordinates the shape's hit carried: a mesh's interpolated
    /// ones, a CSG part's own. Other shapes' are worked out only when
    /// shading asks for them ([`Aggregate::uv`](crate::accel::Aggregate::uv)):
    /// a sphere's longitude costs two arcs per hit, wasted on an untextured
    /// material.
    pub shape_uv: DVec2,
    /// Vertex colour (glTF COLOR_0), multiplied into the surface colour;
    /// white without one.
    pub color: DVec3,
    /// Index of the primitive hit.
    pub primitive: u32,
    /// Index of the material at the hit.
    pub material: u32,
    /// The material whose index of refraction fills the solid behind the
    /// surface: the hit's own, but for a CSG that names a material that
    /// one (a part's material paints its part of the surface; the medium
    /// is the CSG's).
    pub medium: u32,
    /// Where shadow feelers start, relative to `point` (see
    /// [`ShapeHit::feeler_offset`]).
    pub feeler_offset: DVec3,
}
