//! Cameras: from a point on the film (and, with a thin lens, a point on
//! the lens) to a primary ray.

use glam::{DVec2, DVec3};

use crate::math::transcendental;
use crate::math::{Ray, RayDifferential};

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
    /// A thin lens (depth of field); `None`: a pinhole.
    pub lens: Option<ThinLens>,
    /// Lens shift: the film moved across the view, off centre, by
    /// (right, up) times its extent along the fov axis (perspective) or
    /// times `view_height` (orthographic); Blender's shift_x and shift_y.
    /// The view direction and the focus plane stay; the frustum leans.
    pub shift: DVec2,
}

/// A thin lens in front of the film (pbrt's `lensradius` and
/// `focaldistance`, Ray Tracing in One Weekend's defocus disk): points on
/// the plane `focus_distance` along the view direction are sharp, others
/// spread over a circle of confusion.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThinLens {
    /// Radius of the lens in world units (> 0).
    pub radius: f64,
    /// Distance from the lens to the plane in focus, along the view
    /// direction (> 0).
    pub focus_distance: f64,
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
            lens: None,
            shift: DVec2::ZERO,
        })
    }

    /// The ray through film point (x, y), in pixels from the top-left corner
    /// of a `width` × `height` image: pixel (i, j) covers [i, i+1) × [j, j+1),
    /// so its centre is (i + 0.5, j + 0.5).
    #[inline]
    pub fn ray(&self, x: f64, y: f64, width: u32, height: u32) -> Ray {
        self.film(width, height).ray(x, y)
    }

    /// The film of a `width` × `height` image, its extents worked out once
    /// for all the rays through it.
    #[inline]
    pub fn film(&self, width: u32, height: u32) -> FilmRays {
        let (w, h) = (f64::from(width), f64::from(height));
        let aspect = w / h;
        let (half_w, half_h, ox, oy) = match self.projection {
            Projection::Perspective { fov, axis } => {
                let half = transcendental::tan(0.5 * fov);
                let (half_w, half_h) = match axis {
                    FovAxis::Vertical => (half * aspect, half),
                    FovAxis::Horizontal => (half, half / aspect),
                };
                // The shift is in extents along the fov axis, 2·half.
                (
                    half_w,
                    half_h,
                    2.0 * half * self.shift.x,
                    2.0 * half * self.shift.y,
                )
            }
            Projection::Orthographic { view_height } => {
                let half_h = 0.5 * view_height;
                (
                    half_h * aspect,
                    half_h,
                    view_height * self.shift.x,
                    view_height * self.shift.y,
                )
            }
        };
        FilmRays {
            camera: *self,
            w,
            h,
            aspect,
            half_w,
            half_h,
            ox,
            oy,
        }
    }
}

/// A camera's film at one image size: the rays through its points, with
/// the tangent of the field of view taken once rather than per ray (the
/// same bits as [`Camera::ray`], which goes through it).
#[derive(Clone, Copy, Debug)]
pub struct FilmRays {
    camera: Camera,
    w: f64,
    h: f64,
    aspect: f64,
    /// Half the film's extents, at unit distance (perspective) or in
    /// world units (orthographic: the width is half_h·aspect).
    half_w: f64,
    half_h: f64,
    /// The lens shift, in the same units.
    ox: f64,
    oy: f64,
}

impl FilmRays {
    /// The camera the film belongs to.
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    /// The ray through film point (x, y), in pixels (see [`Camera::ray`]).
    #[inline]
    pub fn ray(&self, x: f64, y: f64) -> Ray {
        let c = &self.camera;
        // Film coordinates in [-1, 1], y up.
        let sx = 2.0 * x / self.w - 1.0;
        let sy = 1.0 - 2.0 * y / self.h;
        match c.projection {
            Projection::Perspective { .. } => {
                let dir = c.forward
                    + (sx * self.half_w + self.ox) * c.right
                    + (sy * self.half_h + self.oy) * c.up;
                Ray::new(c.position, dir)
            }
            Projection::Orthographic { .. } => {
                // sx·half_h·aspect in that order: the bits of the rays
                // from before the film was cached.
                let origin = c.position
                    + (sx * self.half_h * self.aspect + self.ox) * c.right
                    + (sy * self.half_h + self.oy) * c.up;
                Ray {
                    origin,
                    direction: c.forward,
                }
            }
        }
    }

    /// The ray through film point (x, y) and point `disk` of the unit disk
    /// on the lens (see [`Camera::ray_through_lens`]).
    #[inline]
    pub fn ray_through_lens(&self, x: f64, y: f64, disk: DVec2) -> Ray {
        let pinhole = self.ray(x, y);
        let c = &self.camera;
        let Some(lens) = c.lens else {
            return pinhole;
        };
        // The pinhole ray's direction is unit: it reaches the plane in
        // focus after focus_distance / cos θ.
        let focus = pinhole.at(lens.focus_distance / pinhole.direction.dot(c.forward));
        let origin = pinhole.origin + lens.radius * (disk.x * c.right + disk.y * c.up);
        Ray::new(origin, focus - origin)
    }

    /// The differential of the ray through film point (x, y) and lens
    /// point `disk`: the rays `spacing.x` pixels to the right and
    /// `spacing.y` below, through the same lens point.
    pub fn differential(&self, x: f64, y: f64, disk: DVec2, spacing: DVec2) -> RayDifferential {
        RayDifferential {
            right: self.ray_through_lens(x + spacing.x, y, disk),
            below: self.ray_through_lens(x, y + spacing.y, disk),
        }
    }

    /// [`ray_through_lens`](Self::ray_through_lens) of `N` film points
    /// and lens points at once (`disks` is ignored without a lens), to the
    /// bit: the same operations in the same order, written lane by lane so
    /// that the batch's divisions and square roots, a chain of them per
    /// ray, run side by side instead of one ray waiting on the last (in
    /// vector code where the caller is compiled for it).
    #[inline(always)]
    pub fn rays_through_lens<const N: usize>(
        &self,
        points: &[DVec2; N],
        disks: &[DVec2; N],
        out: &mut RayLanes<N>,
    ) {
        let c = &self.camera;
        if !matches!(c.projection, Projection::Perspective { .. }) {
            for (k, (p, disk)) in points.iter().zip(disks).enumerate() {
                out.set(k, &self.ray_through_lens(p.x, p.y, *disk));
            }
            return;
        }
        // The coordinates apart first, as the lanes below read them.
        let (px, py) = (lanes::<N>(|k| points[k].x), lanes::<N>(|k| points[k].y));
        // The pinhole ray's direction, as in `ray`, then normalised as
        // `Ray::new` does: times the reciprocal of its length.
        let a = lanes::<N>(|k| (2.0 * px[k] / self.w - 1.0) * self.half_w + self.ox);
        let b = lanes::<N>(|k| (1.0 - 2.0 * py[k] / self.h) * self.half_h + self.oy);
        let dx = lanes::<N>(|k| c.forward.x + a[k] * c.right.x + b[k] * c.up.x);
        let dy = lanes::<N>(|k| c.forward.y + a[k] * c.right.y + b[k] * c.up.y);
        let dz = lanes::<N>(|k| c.forward.z + a[k] * c.right.z + b[k] * c.up.z);
        let recip = lanes::<N>(|k| 1.0 / (dx[k] * dx[k] + dy[k] * dy[k] + dz[k] * dz[k]).sqrt());
        let (dx, dy, dz) = (
            lanes::<N>(|k| dx[k] * recip[k]),
            lanes::<N>(|k| dy[k] * recip[k]),
            lanes::<N>(|k| dz[k] * recip[k]),
        );
        let p = c.position;
        let Some(lens) = c.lens else {
            out.origin = [[p.x; N], [p.y; N], [p.z; N]];
            out.direction = [dx, dy, dz];
            return;
        };
        let f = c.forward;
        let t = lanes::<N>(|k| lens.focus_distance / (dx[k] * f.x + dy[k] * f.y + dz[k] * f.z));
        let u = lanes::<N>(|k| disks[k].x);
        let v = lanes::<N>(|k| disks[k].y);
        let ox = lanes::<N>(|k| p.x + lens.radius * (u[k] * c.right.x + v[k] * c.up.x));
        let oy = lanes::<N>(|k| p.y + lens.radius * (u[k] * c.right.y + v[k] * c.up.y));
        let oz = lanes::<N>(|k| p.z + lens.radius * (u[k] * c.right.z + v[k] * c.up.z));
        let ex = lanes::<N>(|k| (p.x + t[k] * dx[k]) - ox[k]);
        let ey = lanes::<N>(|k| (p.y + t[k] * dy[k]) - oy[k]);
        let ez = lanes::<N>(|k| (p.z + t[k] * dz[k]) - oz[k]);
        let recip = lanes::<N>(|k| 1.0 / (ex[k] * ex[k] + ey[k] * ey[k] + ez[k] * ez[k]).sqrt());
        out.origin = [ox, oy, oz];
        out.direction = [
            lanes::<N>(|k| ex[k] * recip[k]),
            lanes::<N>(|k| ey[k] * recip[k]),
            lanes::<N>(|k| ez[k] * recip[k]),
        ];
    }
}

/// `N` rays, coordinate by coordinate (`origin[axis][k]` of ray k): what
/// [`FilmRays::rays_through_lens`] fills. Apart from the rays, because
/// writing each lane's `Ray` where the lanes are computed turned the
/// compiler's vector code back into one lane at a time.
#[derive(Clone, Copy, Debug)]
pub struct RayLanes<const N: usize> {
    /// Origins, by axis then lane.
    pub origin: [[f64; N]; 3],
    /// Unit directions, by axis then lane.
    pub direction: [[f64; N]; 3],
}

impl<const N: usize> Default for RayLanes<N> {
    fn default() -> Self {
        RayLanes {
            origin: [[0.0; N]; 3],
            direction: [[0.0; N]; 3],
        }
    }
}

impl<const N: usize> RayLanes<N> {
    /// Ray `k`.
    #[inline]
    pub fn ray(&self, k: usize) -> Ray {
        let (o, d) = (&self.origin, &self.direction);
        Ray {
            origin: DVec3::new(o[0][k], o[1][k], o[2][k]),
            direction: DVec3::new(d[0][k], d[1][k], d[2][k]),
        }
    }

    /// Sets ray `k`.
    #[inline]
    pub fn set(&mut self, k: usize, ray: &Ray) {
        for axis in 0..3 {
            self.origin[axis][k] = ray.origin[axis];
            self.direction[axis][k] = ray.direction[axis];
        }
    }
}

/// `[f(0), …, f(N − 1)]`, by a plain loop over the lanes, which the
/// compiler turns into vector code once `f` is inlined.
#[inline(always)]
fn lanes<const N: usize>(f: impl Fn(usize) -> f64) -> [f64; N] {
    let mut out = [0.0; N];
    for (k, value) in out.iter_mut().enumerate() {
        *value = f(k);
    }
    out
}

impl Camera {
    /// The ray of film point (x, y) (as in [`ray`](Self::ray)) through the
    /// point `disk` of the unit disk on the lens. The pinhole ray meets the
    /// plane in focus at P; the ray leaves the lens at
    /// position + radius·(disk.x·right + disk.y·up) towards P, so
    /// everything on that plane images where the pinhole images it. An
    /// orthographic film gets the same lens in front of each film point
    /// (pbrt's way): its parallel rays converge on the plane in focus.
    /// Without a lens, the pinhole ray itself.
    #[inline]
    pub fn ray_through_lens(&self, x: f64, y: f64, width: u32, height: u32, disk: DVec2) -> Ray {
        self.film(width, height).ray_through_lens(x, y, disk)
    }

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
                    (d.dot(self.right) / z - 2.0 * half * self.shift.x) / half_w,
                    (d.dot(self.up) / z - 2.0 * half * self.shift.y) / half_h,
                )
            }
            Projection::Orthographic { view_height } => {
                let half_h = 0.5 * view_height;
                (
                    (d.dot(self.right) - view_height * self.shift.x) / (half_h * aspect),
                    (d.dot(self.up) - view_height * self.shift.y) / half_h,
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

    #[test]
    fn lens_shift_moves_the_frustum_by_extents_of_the_fov_axis() {
        // A shifted camera's pixel sees what the unshifted one sees
        // shift × (the fitted extent in pixels) to the right and up: the
        // height for a vertical fov and an orthographic view, the width
        // for a horizontal fov. Its rays still leave the same eye.
        let shift = DVec2::new(0.25, -0.1);
        let ortho = Camera::look_at(
            DVec3::new(0.0, 0.0, 5.0),
            DVec3::ZERO,
            DVec3::Y,
            Projection::Orthographic { view_height: 3.0 },
        )
        .unwrap();
        for (camera, extent) in [
            (perspective(FovAxis::Vertical), 480.0),
            (perspective(FovAxis::Horizontal), 640.0),
            (ortho, 480.0),
        ] {
            let shifted = Camera { shift, ..camera };
            for (x, y) in [(0.5, 0.5), (123.25, 77.0), (320.0, 240.0)] {
                let a = shifted.ray(x, y, 640, 480);
                let b = camera.ray(x + shift.x * extent, y - shift.y * extent, 640, 480);
                assert!((a.origin - b.origin).length() < 1e-12, "{a:?} {b:?}");
                assert!((a.direction - b.direction).length() < 1e-12, "{a:?} {b:?}");
                let (px, py) = shifted.project(a.at(3.7), 640, 480).unwrap();
                assert!((px - x).abs() < 1e-9 && (py - y).abs() < 1e-9, "{px},{py}");
            }
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

    /// `perspective` with a lens of radius 0.25 focused 4 units away.
    fn with_lens(mut camera: Camera) -> Camera {
        camera.lens = Some(ThinLens {
            radius: 0.25,
            focus_distance: 4.0,
        });
        camera
    }

    /// The batch of rays is, lane by lane and bit for bit, the rays one
    /// at a time: with and without a lens, shifted, tilted, orthographic.
    #[test]
    fn a_batch_of_rays_is_the_rays_one_by_one() {
        let mut rng = crate::math::rng::PixelRng::new(7, 1, 2);
        let tilted = Camera::look_at(
            DVec3::new(0.3, 1.6, 6.0),
            DVec3::new(-0.2, 0.7, -2.0),
            DVec3::Y,
            Projection::Perspective {
                fov: 40f64.to_radians(),
                axis: FovAxis::Horizontal,
            },
        )
        .unwrap();
        let mut shifted = with_lens(tilted);
        shifted.shift = glam::DVec2::new(0.1, -0.05);
        let ortho = Camera::look_at(
            DVec3::new(0.0, 0.0, 5.0),
            DVec3::ZERO,
            DVec3::Y,
            Projection::Orthographic { view_height: 4.0 },
        )
        .unwrap();
        for camera in [
            perspective(FovAxis::Vertical),
            with_lens(perspective(FovAxis::Vertical)),
            tilted,
            with_lens(tilted),
            shifted,
            with_lens(ortho),
        ] {
            let film = camera.film(640, 480);
            for _ in 0..50 {
                let points: [DVec2; 8] = std::array::from_fn(|_| {
                    DVec2::new(640.0 * rng.uniform(), 480.0 * rng.uniform())
                });
                let disks: [DVec2; 8] = std::array::from_fn(|_| {
                    crate::math::sampling::concentric_disk(DVec2::new(rng.uniform(), rng.uniform()))
                });
                let mut rays = RayLanes::<8>::default();
                film.rays_through_lens(&points, &disks, &mut rays);
                for k in 0..8 {
                    let one = film.ray_through_lens(points[k].x, points[k].y, disks[k]);
                    let ray = rays.ray(k);
                    assert_eq!(
                        ray.origin.to_array().map(f64::to_bits),
                        one.origin.to_array().map(f64::to_bits)
                    );
                    assert_eq!(
                        ray.direction.to_array().map(f64::to_bits),
                        one.direction.to_array().map(f64::to_bits)
                    );
                }
            }
        }
    }

    #[test]
    fn the_plane_in_focus_images_as_the_pinhole_does() {
        let ortho = Projection::Orthographic { view_height: 4.0 };
        let ortho = Camera::look_at(DVec3::new(0.0, 0.0, 5.0), DVec3::ZERO, DVec3::Y, ortho);
        for camera in [perspective(FovAxis::Vertical), ortho.unwrap()] {
            let lens = with_lens(camera);
            for (x, y) in [(0.5, 0.5), (123.25, 77.0), (320.0, 240.0)] {
                let pinhole = camera.ray(x, y, 640, 480);
                let depth = |p: DVec3| (p - camera.position).dot(camera.forward);
                let target = pinhole.at(4.0 / pinhole.direction.dot(camera.forward));
                for disk in [
                    DVec2::ZERO,
                    DVec2::X,
                    DVec2::new(-0.6, 0.8),
                    DVec2::splat(0.5),
                ] {
                    let r = lens.ray_through_lens(x, y, 640, 480, disk);
                    let offset = r.origin - pinhole.origin;
                    assert!((offset.length() - 0.25 * disk.length()).abs() < 1e-15);
                    assert!(offset.dot(camera.forward).abs() < 1e-15);
                    let p = r.at(depth(target) / r.direction.dot(camera.forward));
                    assert!((p - target).length() < 1e-13, "{p} {target}");
                }
                // No lens: the pinhole ray, to the bit.
                assert_eq!(camera.ray_through_lens(x, y, 640, 480, DVec2::X), pinhole);
            }
        }
    }

    /// A point at depth d seen through the lens's edge appears displaced
    /// from its pinhole image by the thin lens's circle of confusion,
    /// c = f·A·|1/d − 1/F| pixels (f: the focal length in pixels, h / 2
    /// tan(fov/2); A the lens radius; F the focus distance).
    #[test]
    fn a_point_off_the_plane_in_focus_spreads_over_the_circle_of_confusion() {
        let camera = with_lens(perspective(FovAxis::Vertical));
        // 90° vertical over 480 pixels: f = 240 / tan 45°.
        let f = 240.0;
        for (point, disk) in [
            (DVec3::new(0.3, -0.2, 3.0), DVec2::X),
            (DVec3::new(-1.0, 0.5, -4.0), DVec2::new(0.6, -0.8)),
        ] {
            let d = camera.position.z - point.z;
            // The ray from the lens point through the point meets the plane
            // in focus where the film point that sees it aims.
            let lens_point = camera.position + 0.25 * (disk.x * camera.right + disk.y * camera.up);
            let towards = (point - lens_point).normalize();
            let on_focus = lens_point + towards * (4.0 / towards.dot(camera.forward));
            let seen = camera.project(on_focus, 640, 480).unwrap();
            let pinhole = camera.project(point, 640, 480).unwrap();
            let spread = (seen.0 - pinhole.0).hypot(seen.1 - pinhole.1);
            let c = f * 0.25 * (1.0 / d - 1.0 / 4.0).abs();
            assert!((spread - c).abs() < 1e-9, "{spread} vs {c}");
            // And that film point's ray through that lens point passes
            // through the point.
            let r = camera.ray_through_lens(seen.0, seen.1, 640, 480, disk);
            let miss = (point - r.origin).cross(r.direction).length();
            assert!(miss < 1e-12, "{miss}");
        }
    }

    #[test]
    fn degenerate_views_are_refused() {
        let p = Projection::Orthographic { view_height: 1.0 };
        assert!(Camera::look_at(DVec3::ZERO, DVec3::ZERO, DVec3::Y, p).is_none());
        assert!(Camera::look_at(DVec3::ZERO, DVec3::Y, DVec3::Y, p).is_none());
    }
}
