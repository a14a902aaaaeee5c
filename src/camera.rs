//! Cameras: from a point on the film to a primary ray.

use glam::DVec3;

use crate::math::Ray;
use crate::math::transcendental;

/// Which film axis the field of view spans.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum FovAxis {
    /// The angle spans the image height (POV-Ray's `angle` spans the width,
    /// pbrt's `fov` the shorter side; this is the OpenGL convention).
    #[default]
    Vertical,
    /// The angle spans the image width.
    Horizontal,
}

/// How the film maps to rays.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// Pinhole camera: all rays leave the eye.
    Perspective {
        /// Full field of view in radians.
        fov: f64,
        /// The axis `fov` spans.
        axis: FovAxis,
    },
    /// Parallel rays from a film `view_height` world units tall.
    Orthographic {
        /// Height of the viewed region in world units.
        view_height: f64,
    },
}

/// A camera placed in the scene, independent of the image resolution.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position (centre of the film for orthographic cameras).
    pub position: DVec3,
    /// Unit viewing direction.
    pub forward: DVec3,
    /// Unit film x axis (to the right in the image).
    pub right: DVec3,
    /// Unit film y axis (up in the image).
    pub up: DVec3,
    /// Projection.
    pub projection: Projection,
}

impl Camera {
    /// A camera at `position` looking at `look_at`, with `up` defining the
    /// image's vertical. `None` if the view direction is zero or parallel to up.
    pub fn look_at(
        position: DVec3,
        look_at: DVec3,
        up: DVec3,
        projection: Projection,
    ) -> Option<Self> {
        let forward = (look_at - position).try_normalize()?;
        let right = forward.cross(up).try_normalize()?;
        Some(Camera {
            position,
            forward,
            right,
            up: right.cross(forward),
            projection,
        })
    }

    /// The ray through film point (x, y), in pixels from the top-left corner
    /// of a `width` × `height` image: pixel (i, j) covers [i, i+1) × [j, j+1),
    /// so its centre is (i + 0.5, j + 0.5).
    #[inline]
    pub fn ray(&self, x: f64, y: f64, width: u32, height: u32) -> Ray {
        let (w, h) = (f64::from(width), f64::from(height));
        let aspect = w / h;
        // Film coordinates in [-1, 1], y up.
        let sx = 2.0 * x / w - 1.0;
        let sy = 1.0 - 2.0 * y / h;
        match self.projection {
            Projection::Perspective { fov, axis } => {
                let half = transcendental::tan(0.5 * fov);
                let (half_w, half_h) = match axis {
                    FovAxis::Vertical => (half * aspect, half),
                    FovAxis::Horizontal => (half, half / aspect),
                };
                let dir = self.forward + sx * half_w * self.right + sy * half_h * self.up;
                Ray::new(self.position, dir)
            }
            Projection::Orthographic { view_height } => {
                let half_h = 0.5 * view_height;
                let origin =
                    self.position + sx * half_h * aspect * self.right + sy * half_h * self.up;
                Ray {
                    origin,
                    direction: self.forward,
                }
            }
        }
    }
}

impl Camera {
    /// Where `point` appears on the film of a `width` × `height` image, in
    /// pixels from the top-left corner: the inverse of [`ray`](Self::ray).
    /// `None` for points behind a perspective camera.
    pub fn project(&self, point: DVec3, width: u32, height: u32) -> Option<(f64, f64)> {
        let (w, h) = (f64::from(width), f64::from(height));
        let aspect = w / h;
        let d = point - self.position;
        let (sx, sy) = match self.projection {
            Projection::Perspective { fov, axis } => {
                let z = d.dot(self.forward);
                if z <= 0.0 {
                    return None;
                }
                let half = transcendental::tan(0.5 * fov);
                let (half_w, half_h) = match axis {
                    FovAxis::Vertical => (half * aspect, half),
                    FovAxis::Horizontal => (half, half / aspect),
                };
                (
                    d.dot(self.right) / (z * half_w),
                    d.dot(self.up) / (z * half_h),
                )
            }
            Projection::Orthographic { view_height } => {
                let half_h = 0.5 * view_height;
                (
                    d.dot(self.right) / (half_h * aspect),
                    d.dot(self.up) / half_h,
                )
            }
        };
        Some((0.5 * (sx + 1.0) * w, 0.5 * (1.0 - sy) * h))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn project_inverts_ray() {
        for camera in [
            perspective(FovAxis::Vertical),
            perspective(FovAxis::Horizontal),
        ] {
            for (x, y) in [(0.5, 0.5), (123.25, 77.0), (639.0, 479.5)] {
                let r = camera.ray(x, y, 640, 480);
                let (px, py) = camera.project(r.at(3.7), 640, 480).unwrap();
                assert!((px - x).abs() < 1e-9 && (py - y).abs() < 1e-9, "{px},{py}");
            }
            assert_eq!(camera.project(DVec3::new(0.0, 0.0, 9.0), 640, 480), None);
        }
    }

    fn perspective(axis: FovAxis) -> Camera {
        Camera::look_at(
            DVec3::new(0.0, 0.0, 5.0),
            DVec3::ZERO,
            DVec3::Y,
            Projection::Perspective {
                fov: 90f64.to_radians(),
                axis,
            },
        )
        .unwrap()
    }

    #[test]
    fn centre_pixel_looks_forward() {
        let c = perspective(FovAxis::Vertical);
        // 3×3 image: the centre pixel (1, 1) has its centre at (1.5, 1.5).
        let r = c.ray(1.5, 1.5, 3, 3);
        assert!((r.direction - -DVec3::Z).length() < 1e-15);
    }

    #[test]
    fn field_of_view_spans_the_chosen_axis() {
        let c = perspective(FovAxis::Vertical);
        // Top edge of a 200×100 image at 90° vertical: 45° up.
        let top = c.ray(100.0, 0.0, 200, 100);
        assert!((top.direction.angle_between(-DVec3::Z) - 45f64.to_radians()).abs() < 1e-12);
        assert!(top.direction.y > 0.0);
        let c = perspective(FovAxis::Horizontal);
        let right = c.ray(200.0, 50.0, 200, 100);
        assert!((right.direction.angle_between(-DVec3::Z) - 45f64.to_radians()).abs() < 1e-12);
        assert!(right.direction.x > 0.0);
    }

    #[test]
    fn orthographic_rays_are_parallel_and_span_the_view() {
        let c = Camera::look_at(
            DVec3::new(0.0, 0.0, 5.0),
            DVec3::ZERO,
            DVec3::Y,
            Projection::Orthographic { view_height: 4.0 },
        )
        .unwrap();
        let a = c.ray(0.0, 0.0, 20, 10);
        let b = c.ray(20.0, 10.0, 20, 10);
        assert_eq!(a.direction, -DVec3::Z);
        assert_eq!(a.origin, DVec3::new(-4.0, 2.0, 5.0));
        assert_eq!(b.origin, DVec3::new(4.0, -2.0, 5.0));
    }

    #[test]
    fn degenerate_views_are_refused() {
        let p = Projection::Orthographic { view_height: 1.0 };
        assert!(Camera::look_at(DVec3::ZERO, DVec3::ZERO, DVec3::Y, p).is_none());
        assert!(Camera::look_at(DVec3::ZERO, DVec3::Y, DVec3::Y, p).is_none());
    }
}
