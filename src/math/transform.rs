//! Affine object-to-world transforms, with the inverse and the
//! inverse-transpose that normals need.

use glam::{DAffine3, DMat3, DVec3};

/// An invertible affine map from object space to world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    /// Object to world.
    pub to_world: DAffine3,
    /// World to object.
    pub to_object: DAffine3,
    /// (M⁻¹)ᵀ of the linear part: maps object normals to world normals.
    pub normal_to_world: DMat3,
}

impl Default for Transform {
    fn default() -> Self {
        Transform::from_affine(DAffine3::IDENTITY).expect("identity is invertible")
    }
}

impl Transform {
    /// Wraps `to_world`; `None` when it is singular (determinant ~ 0 relative
    /// to its scale) or not finite.
    pub fn from_affine(to_world: DAffine3) -> Option<Self> {
        let m = to_world.matrix3;
        let scale = m.x_axis.length() * m.y_axis.length() * m.z_axis.length();
        let det = m.determinant();
        if !to_world.is_finite() || scale == 0.0 || det.abs() <= 1e-12 * scale {
            return None;
        }
        let to_object = to_world.inverse();
        // Scale factors within the supported range along every axis, both
        // ways (a map that stretches by 1e300 along one axis and shrinks by
        // 1e-300 along another has determinant 1 but is no usable map).
        use crate::limits::{MAX_COORDINATE, MIN_LENGTH};
        let columns = |m: DMat3| [m.x_axis.length(), m.y_axis.length(), m.z_axis.length()];
        if columns(m).iter().any(|&l| l > MAX_COORDINATE)
            || columns(to_object.matrix3)
                .iter()
                .any(|&l| l > 1.0 / MIN_LENGTH)
            || to_world.translation.abs().max_element() > MAX_COORDINATE
        {
            return None;
        }
        Some(Transform {
            to_world,
            to_object,
            normal_to_world: to_object.matrix3.transpose(),
        })
    }

    /// Maps an object-space point to world space.
    #[inline]
    pub fn point(&self, p: DVec3) -> DVec3 {
        self.to_world.transform_point3(p)
    }

    /// `ray` in object space as (origin, direction): the direction is
    /// mapped but not renormalised, so t means the same in both spaces.
    #[inline]
    pub fn ray_to_object(&self, ray: &crate::math::Ray) -> (DVec3, DVec3) {
        (
            self.to_object.transform_point3(ray.origin),
            self.to_object.transform_vector3(ray.direction),
        )
    }

    /// Maps an object-space normal to a unit world-space normal.
    #[inline]
    pub fn normal(&self, n: DVec3) -> DVec3 {
        (self.normal_to_world * n).normalize()
    }

    /// `Some(s)` when the map is a similarity (rotation, translation and a
    /// uniform scale `s`), so spheres stay spheres.
    pub fn uniform_scale(&self) -> Option<f64> {
        let m = self.to_world.matrix3;
        let s = m.x_axis.length();
        let gram = m.transpose() * m;
        let expected = DMat3::from_diagonal(DVec3::splat(s * s));
        gram.abs_diff_eq(expected, 1e-12 * s * s).then_some(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normals_stay_perpendicular_under_non_uniform_scale() {
        let t = Transform::from_affine(DAffine3::from_scale(DVec3::new(1.0, 3.0, 1.0))).unwrap();
        // Plane x + y = 0 in object space, tangent (1, -1, 0), normal (1, 1, 0).
        let tangent = t.to_world.transform_vector3(DVec3::new(1.0, -1.0, 0.0));
        let n = t.normal(DVec3::new(1.0, 1.0, 0.0));
        assert!(tangent.dot(n).abs() < 1e-12);
        assert!(t.uniform_scale().is_none());
    }

    #[test]
    fn similarity_is_detected() {
        let a = DAffine3::from_scale_rotation_translation(
            DVec3::splat(2.0),
            glam::DQuat::from_axis_angle(DVec3::new(1.0, 1.0, 0.0).normalize(), 0.7),
            DVec3::new(1.0, 2.0, 3.0),
        );
        let t = Transform::from_affine(a).unwrap();
        assert!((t.uniform_scale().unwrap() - 2.0).abs() < 1e-12);
        assert!((t.to_object.transform_point3(t.point(DVec3::ONE)) - DVec3::ONE).length() < 1e-12);
    }

    #[test]
    fn singular_maps_are_refused() {
        let a = DAffine3::from_scale(DVec3::new(1.0, 0.0, 1.0));
        assert!(Transform::from_affine(a).is_none());
    }
}
