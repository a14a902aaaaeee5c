//! What a shape reports about a ray hit.

use glam::DVec3;

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
    /// Index of the primitive hit.
    pub primitive: u32,
}
