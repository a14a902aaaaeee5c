//! The shadow terminator of smooth-shaded meshes (Hanika, "Hacking the
//! Shadow Terminator", Ray Tracing Gems II, 2021).
//!
//! A triangle shaded with interpolated vertex normals is lit as if it
//! were the curved surface those normals describe, but its shadow feelers
//! leave the flat triangle: near the terminator a feeler toward a light
//! the smooth normal still sees dives under the facet and is blocked by
//! the mesh itself, and the light ends in stair-steps along the facets.
//! Hanika's remedy starts the feelers at a point P′ lifted off the facet
//! towards the curved surface: P projected onto the tangent plane of each
//! vertex (where it lies below that plane), the three projections blended
//! with the hit's barycentric weights. On a flat-shaded triangle (vertex
//! normals equal to the face normal) every projection is P itself, and on
//! a fine mesh the lift shrinks with the square of the triangle's size.

use glam::DVec3;

/// Hanika's offset P′ − P of the shadow-feeler origin at the point
/// `bary`·`corners` of a triangle with unit vertex normals `normals`
/// (turned to the side the shading point is seen from).
///
/// P′ = Σ wᵢ (P − min(0, (P − Vᵢ)·Nᵢ) Nᵢ): each vertex's tangent plane
/// lifts P only where P lies below it, so the offset never moves a point
/// under the facet and is zero where the normals are the face's.
#[inline]
pub fn terminator_offset(corners: [DVec3; 3], normals: [DVec3; 3], bary: DVec3) -> DVec3 {
    let p = bary.x * corners[0] + bary.y * corners[1] + bary.z * corners[2];
    let lift = |corner: DVec3, normal: DVec3, weight: f64| {
        let below = (p - corner).dot(normal).min(0.0);
        -weight * below * normal
    };
    lift(corners[0], normals[0], bary.x)
        + lift(corners[1], normals[1], bary.y)
        + lift(corners[2], normals[2], bary.z)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flat_normals_give_no_offset() {
        let corners = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let bary = DVec3::new(0.2, 0.3, 0.5);
        assert_eq!(terminator_offset(corners, [DVec3::Z; 3], bary), DVec3::ZERO);
    }

    #[test]
    fn vertices_are_not_moved() {
        let corners = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let normals = [
            DVec3::new(-1.0, -1.0, 1.0).normalize(),
            DVec3::new(1.0, 0.0, 1.0).normalize(),
            DVec3::new(0.0, 1.0, 1.0).normalize(),
        ];
        for k in 0..3 {
            let mut bary = DVec3::ZERO;
            bary[k] = 1.0;
            assert_eq!(terminator_offset(corners, normals, bary), DVec3::ZERO);
        }
    }

    /// Hand-worked: an edge from (−1, 0, 0) to (1, 0, 0) whose normals
    /// lean out by 45° (a circle's chord), at its midpoint. Each tangent
    /// plane passes through its vertex with normal (∓1, 0, 1)/√2; the
    /// midpoint lies 1/√2 below each, so each lifts it by ½ along its
    /// normal: P′ = ½(−½, 0, ½) + ½(½, 0, ½) = (0, 0, ½), the height of
    /// the two tangent lines' crossing halfway (they meet at z = 1).
    #[test]
    fn a_chord_midpoint_rises_halfway_to_the_tangents_meeting() {
        let s = std::f64::consts::FRAC_1_SQRT_2;
        let corners = [
            DVec3::new(-1.0, 0.0, 0.0),
            DVec3::X,
            DVec3::new(0.0, 5.0, 0.0),
        ];
        let normals = [DVec3::new(-s, 0.0, s), DVec3::new(s, 0.0, s), DVec3::Z];
        let offset = terminator_offset(corners, normals, DVec3::new(0.5, 0.5, 0.0));
        assert!(
            (offset - DVec3::new(0.0, 0.0, 0.5)).length() < 1e-15,
            "{offset}"
        );
    }

    /// On a concave patch (normals leaning in) P lies above every tangent
    /// plane: no offset.
    #[test]
    fn concave_patches_are_not_lifted() {
        let s = std::f64::consts::FRAC_1_SQRT_2;
        let corners = [
            DVec3::new(-1.0, 0.0, 0.0),
            DVec3::X,
            DVec3::new(0.0, 5.0, 0.0),
        ];
        let normals = [DVec3::new(s, 0.0, s), DVec3::new(-s, 0.0, s), DVec3::Z];
        let offset = terminator_offset(corners, normals, DVec3::new(0.5, 0.5, 0.0));
        assert_eq!(offset, DVec3::ZERO);
    }

    /// On a triangle inscribed in the unit sphere with the sphere's normals,
    /// P′ lies above the facet and nearer the sphere than P (it may pass
    /// the sphere a little: the blend of tangent planes is not the
    /// sphere) (seeded random triangles and points).
    #[test]
    fn inscribed_triangles_lift_towards_the_sphere() {
        let mut rng = crate::math::rng::PixelRng::new(7, 1, 2);
        let mut unit = || {
            loop {
                let v = DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 2.0 - DVec3::ONE;
                if v.length_squared() > 0.01 && v.length_squared() <= 1.0 {
                    return v.normalize();
                }
            }
        };
        for _ in 0..1000 {
            let centre = unit();
            let corners = [0; 3].map(|_| (centre + 0.2 * unit()).normalize());
            let (a, b) = (rng_weight(&mut unit), rng_weight(&mut unit));
            let bary = if a + b <= 1.0 {
                DVec3::new(a, b, 1.0 - a - b)
            } else {
                DVec3::new(1.0 - a, 1.0 - b, a + b - 1.0)
            };
            let p = bary.x * corners[0] + bary.y * corners[1] + bary.z * corners[2];
            let lifted = p + terminator_offset(corners, corners, bary);
            assert!(lifted.length() >= p.length() - 1e-15, "{lifted} under {p}");
            let gap = |q: DVec3| (q.length() - 1.0).abs();
            assert!(
                gap(lifted) <= gap(p) + 1e-15,
                "{lifted} no nearer the sphere than {p}"
            );
        }
    }

    fn rng_weight(unit: &mut impl FnMut() -> DVec3) -> f64 {
        unit().x.abs()
    }
}
