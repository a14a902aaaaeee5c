//! Light sources: points, directions, spots, spheres and area lights
//! (rectangles and disks); the last three have volume or extent and cast
//! soft shadows. A light is sampled into directions towards it; the
//! shading code sends one shadow feeler along each.
//!
//! Area lights are uniform Lambertian emitters: their `radiance` is the
//! radiance L leaving every point of the emitting side, so a point sees
//! the irradiance E = ∫ L cos θ dω over the area (Lambert's formula), and
//! the light's power is π·A·L. They are sampled by area, one stratum of
//! the rectangle (or, by the concentric map, of the disk) per feeler, each
//! weighted by A·cos θ′/d² (θ′ at the light): an unbiased estimate of that
//! integral.

use arrayvec::ArrayVec;
use glam::{DVec2, DVec3};

use crate::accel::simd;
use crate::math::Frame;
use crate::math::rng::PixelRng;
use crate::math::sampling::{Strata, concentric_disk, cone_direction, cone_polar, uniform_cone};
use crate::math::transcendental::sin_cos_turns;

/// How many samples [`LightSampler::sample_batch`] draws at once.
pub const SAMPLE_BATCH: usize = 16;

/// The random numbers a sample of a sphere or area light draws: its
/// jitter within its stratum, x then y.
const SAMPLE_DRAWS: usize = 2;

// A batch's draws come from one `fill_uniform`.
const _: () = assert!(SAMPLE_DRAWS * SAMPLE_BATCH <= crate::math::rng::FILL_MAX);

/// Where light comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightShape {
    /// All light leaves one point.
    Point {
        /// Position.
        position: DVec3,
    },
    /// Parallel light from infinitely far away.
    Directional {
        /// Unit direction the light travels in.
        direction: DVec3,
    },
    /// A point that lights a cone (glTF's and POV-Ray's spot light): full
    /// intensity within the inner cone, fading smoothly to nothing at the
    /// outer one.
    Spot {
        /// Position.
        position: DVec3,
        /// Unit direction of the cone's axis (the way the light travels).
        direction: DVec3,
        /// Cosine of the inner cone's half-angle.
        cos_inner: f64,
        /// Cosine of the outer cone's half-angle (≤ `cos_inner`).
        cos_outer: f64,
        /// How the intensity falls between the cones.
        cone: SpotCone,
    },
    /// A glowing sphere, sampled with `samples` feelers per shading point.
    Sphere {
        /// Centre.
        center: DVec3,
        /// Radius (> 0; radius 0 is a point light).
        radius: f64,
        /// Shadow feelers per shading point.
        samples: u32,
    },
    /// A flat uniform Lambertian emitter (see [`AreaLight`]), sampled
    /// with `samples` feelers per shading point.
    Area {
        /// Its geometry.
        emitter: AreaLight,
        /// Shadow feelers per shading point.
        samples: u32,
    },
}

/// The geometry of an area light: a rectangle (a parallelogram when its
/// edges are not perpendicular) or a disk (an ellipse when its axes
/// differ), `center + x·axis_u + y·axis_v` for (x, y) in the square
/// [−1, 1]² or the unit disk.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AreaLight {
    /// Centre.
    pub center: DVec3,
    /// Half the first edge (rectangle) or the first radius (disk).
    pub axis_u: DVec3,
    /// Half the second edge, or the second radius.
    pub axis_v: DVec3,
    /// Unit normal of the emitting side, along axis_u × axis_v.
    pub normal: DVec3,
    /// The outline.
    pub outline: AreaOutline,
    /// Whether both sides emit (else only the side `normal` faces).
    pub two_sided: bool,
}

impl AreaLight {
    /// The area: |axis_u × axis_v| times 4 (rectangle) or π (disk).
    pub fn area(&self) -> f64 {
        let scale = match self.outline {
            AreaOutline::Rectangle => 4.0,
            AreaOutline::Disk => std::f64::consts::PI,
        };
        scale * self.axis_u.cross(self.axis_v).length()
    }

    /// The point at (x, y) of the square [−1, 1]² (rectangle) or the unit
    /// disk (through the concentric map), from a point `u` of the unit square.
    #[inline]
    pub fn point(&self, u: DVec2) -> DVec3 {
        let p = match self.outline {
            AreaOutline::Rectangle => 2.0 * u - DVec2::ONE,
            AreaOutline::Disk => concentric_disk(u),
        };
        self.center + p.x * self.axis_u + p.y * self.axis_v
    }

    /// The radius of a ball about the centre that holds the whole light:
    /// the farther corner of a parallelogram; for a disk (an ellipse, its
    /// axes possibly not perpendicular) the farthest point of the outline,
    /// |u·cos t + v·sin t| at most |u| + |v|, and the longer axis when they
    /// are perpendicular.
    pub fn bounding_radius(&self) -> f64 {
        let (u, v) = (self.axis_u, self.axis_v);
        match self.outline {
            AreaOutline::Rectangle => (u + v).length().max((u - v).length()),
            AreaOutline::Disk if u.dot(v).abs() <= 1e-12 * u.length() * v.length() => {
                u.length().max(v.length())
            }
            AreaOutline::Disk => u.length() + v.length(),
        }
    }
}

/// How a spot light's intensity falls off across its cone.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SpotCone {
    /// KHR_lights_punctual's: see [`spot_attenuation`].
    #[default]
    Gltf,
    /// Blender Cycles': see [`cycles_spot_attenuation`].
    Cycles,
}

impl SpotCone {
    /// The share of the intensity that leaves at cos θ from the axis.
    #[inline]
    pub fn attenuation(self, cos_angle: f64, cos_inner: f64, cos_outer: f64) -> f64 {
        match self {
            SpotCone::Gltf => spot_attenuation(cos_angle, cos_inner, cos_outer),
            SpotCone::Cycles => cycles_spot_attenuation(cos_angle, cos_inner, cos_outer),
        }
    }
}

/// The outline of an area light.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AreaOutline {
    /// The parallelogram of the two axes.
    Rectangle,
    /// The ellipse of the two axes (a disk when they are equal).
    Disk,
}

impl LightShape {
    /// The kind as the scene format names it.
    pub fn kind(&self) -> &'static str {
        match self {
            LightShape::Point { .. } => "point",
            LightShape::Directional { .. } => "directional",
            LightShape::Spot { .. } => "spot",
            LightShape::Sphere { .. } => "sphere",
            LightShape::Area { emitter, .. } => match emitter.outline {
                AreaOutline::Rectangle => "rectangle",
                AreaOutline::Disk => "disk",
            },
        }
    }

    /// Shadow feelers the light sends from each shading point it lights.
    pub fn feelers(&self) -> u32 {
        match *self {
            LightShape::Sphere { samples, .. } | LightShape::Area { samples, .. } => samples,
            _ => 1,
        }
    }

    /// An area light's area; 0 for the other shapes.
    pub fn area(&self) -> f64 {
        match self {
            LightShape::Area { emitter, .. } => emitter.area(),
            _ => 0.0,
        }
    }
}

/// A light source.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    /// Geometry of the emitter.
    pub shape: LightShape,
    /// Il: colour × intensity.
    pub radiance: DVec3,
    /// Divide by the squared distance to the light (point and sphere only).
    pub inverse_square: bool,
}

/// One direction towards a light from a shading point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    /// Unit direction L from the point towards the light.
    pub direction: DVec3,
    /// How far the shadow feeler goes (to the light's surface; ∞ for
    /// directional lights).
    pub distance: f64,
    /// Distance falloff factor (1 without inverse-square falloff).
    pub falloff: f64,
}

impl LightSample {
    /// Whether the sample gives a point of normal `n` nothing, so that no
    /// feeler need go: the light lies behind the surface (N·L ≤ 0) or the
    /// point sees the back of a one-sided area light (weight 0). NaN is
    /// not unlit: it is traced, and shows.
    #[inline]
    pub fn unlit(&self, n: DVec3) -> bool {
        n.dot(self.direction) <= 0.0 || self.falloff == 0.0
    }
}

/// The samples of one light as seen from one shading point: the set-up
/// (direction, cone, falloff) is done once per point, not once per feeler.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightSampler {
    /// A single fixed direction (point and directional lights, or a point
    /// inside a sphere light).
    Fixed(LightSample),
    /// Directions uniform over the cone a sphere light subtends.
    Cone {
        /// Frame around the axis towards the light's centre.
        frame: Frame,
        /// Cosine of the cone's half-angle: √(1 − r²/d²).
        cos_max: f64,
        /// Vector from the shading point to the centre.
        to_center: DVec3,
        /// The light's radius.
        radius: f64,
        /// The point's power with respect to the sphere, (d − r)(d + r):
        /// the same for every feeler, so worked out once.
        power: f64,
        /// Distance falloff factor.
        falloff: f64,
        /// One stratum of directions per sample.
        strata: Strata,
    },
    /// Points on an area light, one per stratum of its parameter square.
    Area {
        /// The shading point.
        point: DVec3,
        /// The light.
        emitter: AreaLight,
        /// Its area.
        area: f64,
        /// One stratum of the square per sample.
        strata: Strata,
    },
}

/// The weight of a feeler from a point to a point of an area light, d
/// away in unit direction `towards`: A·cos θ′/d² (the solid angle a piece
/// of the area covers, per unit of the area's share; θ′ between the
/// light's normal and the way back), 0 where the point sees the back of a
/// one-sided light. d² is bounded below as for point lights.
#[inline]
pub fn area_weight(
    area: f64,
    normal: DVec3,
    towards: DVec3,
    distance_squared: f64,
    two_sided: bool,
) -> f64 {
    let cos = -normal.dot(towards);
    let cos = if two_sided { cos.abs() } else { cos.max(0.0) };
    const NEAREST: f64 = crate::limits::MIN_LENGTH * crate::limits::MIN_LENGTH;
    area * cos / distance_squared.max(NEAREST)
}

impl Light {
    /// The sampler of this light from `point`.
    ///
    /// Sphere lights are sampled uniformly over the cone of directions the
    /// sphere subtends from `point`, one stratum of the unit square per
    /// sample, so the visible fraction of the light is estimated with
    /// stratified, equal-solid-angle samples: a smooth penumbra with few rays.
    pub fn sampler(&self, point: DVec3) -> LightSampler {
        match self.shape {
            LightShape::Point { position } => {
                LightSampler::Fixed(self.towards_point(point, position))
            }
            LightShape::Spot {
                position,
                direction,
                cos_inner,
                cos_outer,
                cone,
            } => {
                let mut s = self.towards_point(point, position);
                s.falloff *= cone.attenuation(direction.dot(-s.direction), cos_inner, cos_outer);
                LightSampler::Fixed(s)
            }
            LightShape::Directional { direction } => LightSampler::Fixed(LightSample {
                direction: -direction,
                distance: f64::INFINITY,
                falloff: 1.0,
            }),
            LightShape::Sphere {
                center,
                radius,
                samples,
            } => {
                let to_center = center - point;
                let d2 = to_center.length_squared();
                if d2 <= radius * radius {
                    // Inside the light: lit from everywhere, nothing can block.
                    let mut s = self.towards_point(point, center);
                    s.distance = 0.0;
                    return LightSampler::Fixed(s);
                }
                LightSampler::Cone {
                    frame: Frame::from_z(to_center / d2.sqrt()),
                    cos_max: (1.0 - radius * radius / d2).max(0.0).sqrt(),
                    to_center,
                    radius,
                    power: sphere_power(to_center, radius),
                    falloff: self.falloff(d2),
                    strata: Strata::new(samples as usize),
                }
            }
            LightShape::Area { emitter, samples } => LightSampler::Area {
                point,
                emitter,
                area: emitter.area(),
                strata: Strata::new(samples as usize),
            },
        }
    }

    fn towards_point(&self, point: DVec3, position: DVec3) -> LightSample {
        let to_light = position - point;
        let d2 = to_light.length_squared();
        let distance = d2.sqrt();
        LightSample {
            // A point at the light itself has no direction towards it: the
            // zero vector, which the shading skips (N·L = 0), not NaN.
            direction: to_light.try_normalize().unwrap_or(DVec3::ZERO),
            distance,
            falloff: self.falloff(d2),
        }
    }

    #[inline]
    fn falloff(&self, distance_squared: f64) -> f64 {
        if self.inverse_square {
            // Bounded as the point nears the light: 1/d² stays finite.
            const NEAREST: f64 = crate::limits::MIN_LENGTH * crate::limits::MIN_LENGTH;
            1.0 / distance_squared.max(NEAREST)
        } else {
            1.0
        }
    }
}

impl LightSampler {
    /// How many feelers the point sends to this light.
    pub fn count(&self) -> usize {
        match self {
            LightSampler::Fixed(_) => 1,
            LightSampler::Cone { strata, .. } | LightSampler::Area { strata, .. } => strata.len(),
        }
    }

    /// How many numbers the samples draw from the stream, all of them
    /// ([`sample_batch`](Self::sample_batch) over the whole count).
    pub fn draws(&self) -> usize {
        match self {
            LightSampler::Fixed(_) => 0,
            LightSampler::Cone { .. } | LightSampler::Area { .. } => SAMPLE_DRAWS * self.count(),
        }
    }

    /// Whether the whole light lies behind the plane through the point
    /// with unit normal `n`, so that every sample is unlit there (see
    /// [`LightSample::unlit`]): its ball (see
    /// [`light_sphere`](Self::light_sphere)) lies beyond that plane by a
    /// billionth of its distance, far more than the rounding of a
    /// sample's direction.
    pub fn behind(&self, n: DVec3) -> bool {
        self.light_sphere().is_some_and(|(to_center, radius)| {
            n.dot(to_center) < -(radius + 1e-9 * to_center.length())
        })
    }

    /// For a sphere light, the vector from the shading point to its
    /// centre and its radius: every feeler lies in their convex hull. For
    /// an area light, the same for the smallest ball about its centre
    /// that holds it.
    pub fn light_sphere(&self) -> Option<(DVec3, f64)> {
        match *self {
            LightSampler::Fixed(_) => None,
            LightSampler::Cone {
                to_center, radius, ..
            } => Some((to_center, radius)),
            LightSampler::Area { point, emitter, .. } => {
                Some((emitter.center - point, emitter.bounding_radius()))
            }
        }
    }

    /// Sample `index` of [`count`](Self::count).
    #[inline]
    pub fn sample(&self, index: usize, rng: &mut PixelRng) -> LightSample {
        match *self {
            LightSampler::Fixed(s) => s,
            LightSampler::Cone {
                frame,
                cos_max,
                to_center,
                radius,
                power,
                falloff,
                strata,
            } => {
                let direction = uniform_cone(&frame, cos_max, strata.point(index, rng));
                let distance = feeler_length(direction, to_center, radius, power);
                LightSample {
                    direction,
                    distance,
                    falloff,
                }
            }
            LightSampler::Area { .. } => {
                let jitter = DVec2::new(rng.uniform(), rng.uniform());
                self.area_sample(index, jitter)
            }
        }
    }

    /// Area light sample `index` at `jitter` across its stratum.
    #[inline(always)]
    fn area_sample(&self, index: usize, jitter: DVec2) -> LightSample {
        let LightSampler::Area {
            point,
            emitter,
            area,
            strata,
        } = *self
        else {
            unreachable!("area_sample of an area light only");
        };
        let on_light = emitter.point(strata.point_at(index, jitter));
        let to_light = on_light - point;
        let distance_squared = to_light.length_squared();
        let distance = distance_squared.sqrt();
        // A point on the light itself has no direction towards it: zero,
        // which the shading skips, as for point lights.
        let direction = if distance > 0.0 {
            to_light / distance
        } else {
            DVec3::ZERO
        };
        LightSample {
            direction,
            distance,
            falloff: area_weight(
                area,
                emitter.normal,
                direction,
                distance_squared,
                emitter.two_sided,
            ),
        }
    }

    /// Samples `first`, `first + 1`, … of [`count`](Self::count), at most
    /// [`SAMPLE_BATCH`] of them, into `out`: the same samples, bit for bit
    /// and from the same random numbers, as [`sample`](Self::sample) one
    /// by one. The random numbers are drawn first; the directions and
    /// distances (square roots, a sine and cosine, a division each) then
    /// go through one straight loop over the batch, which the compiler
    /// turns into vector code, where one sample at a time was a chain of
    /// dependent latencies.
    pub fn sample_batch(
        &self,
        first: usize,
        rng: &mut PixelRng,
        out: &mut ArrayVec<LightSample, SAMPLE_BATCH>,
    ) {
        simd::kernel().vectorize(|| self.sample_batch_here(first, rng, out));
    }

    /// [`sample_batch`](Self::sample_batch), compiled into its caller.
    #[inline(always)]
    fn sample_batch_here(
        &self,
        first: usize,
        rng: &mut PixelRng,
        out: &mut ArrayVec<LightSample, SAMPLE_BATCH>,
    ) {
        out.clear();
        let wanted = self.count().saturating_sub(first).min(SAMPLE_BATCH);
        match *self {
            LightSampler::Fixed(s) => out.extend(std::iter::repeat_n(s, wanted)),
            LightSampler::Area { .. } => {
                let mut draws = [0.0; SAMPLE_DRAWS * SAMPLE_BATCH];
                rng.fill_uniform(&mut draws[..SAMPLE_DRAWS * wanted]);
                out.extend((0..wanted).map(|k| {
                    let jitter = DVec2::new(draws[SAMPLE_DRAWS * k], draws[SAMPLE_DRAWS * k + 1]);
                    self.area_sample(first + k, jitter)
                }));
            }
            LightSampler::Cone {
                frame,
                cos_max,
                to_center,
                radius,
                power,
                falloff,
                strata,
            } => {
                // Every point's draws, x then y, all at once.
                let mut draws = [0.0; SAMPLE_DRAWS * SAMPLE_BATCH];
                rng.fill_uniform(&mut draws[..SAMPLE_DRAWS * wanted]);
                let mut u = [DVec2::ZERO; SAMPLE_BATCH];
                for (k, u) in u.iter_mut().enumerate().take(wanted) {
                    let jitter = DVec2::new(draws[SAMPLE_DRAWS * k], draws[SAMPLE_DRAWS * k + 1]);
                    *u = strata.point_at(first + k, jitter);
                }
                // Structure of arrays, every lane computed (the unused ones
                // from u = 0), so each loop has a fixed count and no branch;
                // one loop per stage of `uniform_cone` and `feeler_length`,
                // so each has short chains that overlap across the batch.
                const N: usize = SAMPLE_BATCH;
                let (mut sin_phi, mut cos_phi) = ([0.0; N], [0.0; N]);
                for k in 0..N {
                    (sin_phi[k], cos_phi[k]) = sin_cos_turns(u[k].y);
                }
                let (mut sin_theta, mut cos_theta) = ([0.0; N], [0.0; N]);
                for k in 0..N {
                    (sin_theta[k], cos_theta[k]) = cone_polar(cos_max, u[k].x);
                }
                let (mut x, mut y, mut z) = ([0.0; N], [0.0; N], [0.0; N]);
                for k in 0..N {
                    let d =
                        cone_direction(&frame, sin_theta[k], cos_theta[k], sin_phi[k], cos_phi[k]);
                    (x[k], y[k], z[k]) = (d.x, d.y, d.z);
                }
                let mut distance = [0.0; N];
                for k in 0..N {
                    let d = DVec3::new(x[k], y[k], z[k]);
                    distance[k] = feeler_length(d, to_center, radius, power);
                }
                out.extend((0..wanted).map(|k| LightSample {
                    direction: DVec3::new(x[k], y[k], z[k]),
                    distance: distance[k],
                    falloff,
                }));
            }
        }
    }
}

/// The share of a spot light's intensity that leaves it at angle θ from
/// its axis (`cos_angle` = cos θ): the KHR_lights_punctual falloff, 1
/// within the inner cone, 0 beyond the outer, and between them t² with t
/// running linearly in cos θ from 0 at the outer cone to 1 at the inner.
pub fn spot_attenuation(cos_angle: f64, cos_inner: f64, cos_outer: f64) -> f64 {
    // The specification's guard: equal cones give a hard edge, not 0/0.
    let scale = 1.0 / (cos_inner - cos_outer).max(1e-3);
    let t = ((cos_angle - cos_outer) * scale).clamp(0.0, 1.0);
    t * t
}

/// The share of a spot light's intensity that leaves it at angle θ from
/// its axis in Blender's Cycles (its kernel's `spot_attenuation`, 2.8 to
/// 3.x): cos θ × smoothstep(t), smoothstep(t) = 3t² − 2t³, with t running
/// linearly in cos θ from 0 at the outer cone to 1 at the inner and
/// clamped to [0, 1]; 0 on and beyond the outer cone. Cycles writes the
/// band as spot_smooth = (1 − cos(size/2))·blend, so its inner cone is
/// cos_inner = cos_outer + spot_smooth. Equal cones (blend 0): a hard edge.
pub fn cycles_spot_attenuation(cos_angle: f64, cos_inner: f64, cos_outer: f64) -> f64 {
    if cos_angle <= cos_outer {
        return 0.0;
    }
    let band = cos_inner - cos_outer;
    let t = if band > 0.0 {
        ((cos_angle - cos_outer) / band).min(1.0)
    } else {
        1.0
    };
    cos_angle * t * t * (3.0 - 2.0 * t)
}

/// How far a feeler from the shading point in unit `direction` travels to
/// the light's sphere (centre at `to_center` from the point, `radius`; the
/// point outside): the nearer root of |t·D − C|² = r². With b = D·C and
/// h² = r² − |C − b·D|² (the distance of the line from the centre, which
/// does not cancel), t = (|C|² − r²)/(b + h), the product form that does not
/// cancel when the point is close to the light either; one division where
/// the general quadratic takes three. At the cone's rim rounding may put
/// the line outside the sphere: then the tangent point, t = b.
#[inline]
pub fn distance_to_sphere(direction: DVec3, to_center: DVec3, radius: f64) -> f64 {
    feeler_length(
        direction,
        to_center,
        radius,
        sphere_power(to_center, radius),
    )
}

/// The power of a point with respect to a sphere, |C|² − r² = (d − r)(d + r)
/// (d = |C|, C the vector to the centre), in the product form that does not
/// cancel near the sphere.
#[inline]
pub fn sphere_power(to_center: DVec3, radius: f64) -> f64 {
    let d = to_center.length();
    (d - radius) * (d + radius)
}

/// [`distance_to_sphere`] with the point's [`sphere_power`] given, for the
/// feelers of one point, which share it.
#[inline]
pub fn feeler_length(direction: DVec3, to_center: DVec3, radius: f64, power: f64) -> f64 {
    let b = direction.dot(to_center);
    let h2 = radius * radius - (to_center - b * direction).length_squared();
    if h2 <= 0.0 {
        return b;
    }
    power / (b + h2.sqrt())
}

#[cfg(test)]
mod distance_tests {
    use super::*;
    use crate::geometry::sphere::sphere_roots;

    /// A batch is the samples one by one, bit for bit, whatever the count
    /// and wherever the batch starts, and it leaves the random numbers
    /// where they would be.
    #[test]
    fn a_batch_is_the_samples_one_by_one() {
        for samples in [1, 3, 16, 17, 36, 64, 100] {
            let light = Light {
                shape: LightShape::Sphere {
                    center: DVec3::new(1.0, 5.0, -2.0),
                    radius: 0.7,
                    samples,
                },
                radiance: DVec3::ONE,
                inverse_square: true,
            };
            let sampler = light.sampler(DVec3::new(0.3, -0.2, 0.1));
            let count = sampler.count();
            let (mut one, mut many) = (PixelRng::new(3, 1, 4), PixelRng::new(3, 1, 4));
            let mut batch = ArrayVec::new();
            let mut first = 0;
            while first < count {
                sampler.sample_batch(first, &mut many, &mut batch);
                assert_eq!(batch.len(), (count - first).min(SAMPLE_BATCH));
                for (k, s) in batch.iter().enumerate() {
                    assert_eq!(*s, sampler.sample(first + k, &mut one), "{samples}: {k}");
                }
                first += batch.len();
            }
            assert_eq!(one.uniform(), many.uniform());
            sampler.sample_batch(count, &mut many, &mut batch);
            assert!(batch.is_empty());
        }
        let point = Light {
            shape: LightShape::Point { position: DVec3::Y },
            radiance: DVec3::ONE,
            inverse_square: false,
        };
        let mut rng = PixelRng::new(1, 0, 0);
        let mut batch = ArrayVec::new();
        point
            .sampler(DVec3::ZERO)
            .sample_batch(0, &mut rng, &mut batch);
        assert_eq!(batch.len(), 1);
        assert_eq!(batch[0].direction, DVec3::Y);
    }

    /// Where `behind` says the light lies behind a point's plane, every
    /// sample is unlit, and the draws are `draws` numbers: what `direct`
    /// skips there leaves the stream and the sum where the samples would.
    /// Planes from far behind to just past the margin, tangent to the
    /// light's ball or nearly (the samples at its rim the closest calls).
    #[test]
    fn a_light_behind_the_plane_has_no_lit_sample() {
        let mut rng = PixelRng::new(21, 0, 0);
        let (mut behind, mut lit_near_miss, mut cut_lit) = (0, 0, 0);
        for round in 0..3_000 {
            let mut u = || rng.uniform();
            let center = DVec3::new(u() - 0.5, u() - 0.5, u() - 0.5) * 20.0;
            let point = DVec3::new(u() - 0.5, u() - 0.5, u() - 0.5) * 20.0;
            let radius = 0.05 + u() * 2.0;
            let shape = if round % 2 == 0 {
                LightShape::Sphere {
                    center,
                    radius,
                    samples: 1 + (u() * 40.0) as u32,
                }
            } else {
                let axis_u = DVec3::new(u() - 0.5, u() - 0.5, u() - 0.5) * radius;
                let axis_v = DVec3::new(u() - 0.5, u() - 0.5, u() - 0.5) * radius;
                LightShape::Area {
                    emitter: AreaLight {
                        center,
                        axis_u,
                        axis_v,
                        normal: axis_u.cross(axis_v).normalize(),
                        outline: if u() < 0.5 {
                            AreaOutline::Rectangle
                        } else {
                            AreaOutline::Disk
                        },
                        two_sided: u() < 0.5,
                    },
                    samples: 1 + (u() * 40.0) as u32,
                }
            };
            let light = Light {
                shape,
                radiance: DVec3::ONE,
                inverse_square: true,
            };
            let sampler = light.sampler(point);
            let Some((to_center, ball)) = sampler.light_sphere() else {
                continue;
            };
            let distance = to_center.length();
            if distance <= ball {
                continue;
            }
            // A normal whose plane passes the ball at `gap` (in units of
            // the ball's radius, < 0: cutting into it), the rim's samples
            // as near the plane as `gap` allows.
            let gap = [-0.5, -1e-6, 0.0, 1e-12, 1e-9, 1e-6, 0.5][round % 7];
            let axis = to_center / distance;
            let side = Frame::from_z(axis).x;
            let sin = ((ball * (1.0 + gap)) / distance).min(1.0);
            let n = -(axis * sin + side * (1.0 - sin * sin).sqrt());
            let count = sampler.count();
            let stream = || PixelRng::new(5, round as u32, 0);
            let (mut drawn, mut skipped) = (stream(), stream());
            let mut batch = ArrayVec::new();
            let mut any_lit = false;
            let mut first = 0;
            while first < count {
                sampler.sample_batch(first, &mut drawn, &mut batch);
                any_lit |= batch.iter().any(|s| !s.unlit(n));
                first += batch.len();
            }
            skipped.skip(sampler.draws());
            assert_eq!(drawn.uniform(), skipped.uniform(), "round {round}");
            if sampler.behind(n) {
                behind += 1;
                assert!(!any_lit, "round {round}: gap {gap}");
            } else if gap > 0.0 && !any_lit {
                lit_near_miss += 1;
            }
            cut_lit += usize::from(gap < -0.1 && any_lit);
        }
        // Both answers came up, the margin gave some away, and a plane
        // through the light leaves samples lit.
        assert!(
            behind > 600 && lit_near_miss > 0 && cut_lit > 100,
            "{behind} {lit_near_miss} {cut_lit}"
        );
    }

    #[test]
    fn distance_to_sphere_is_the_near_root_of_the_quadratic() {
        let mut rng = PixelRng::new(11, 2, 3);
        for _ in 0..10_000 {
            let radius = 0.01 + rng.uniform() * 2.0;
            // From just outside the light to far away.
            let d = radius * (1.0 + 1e-6 + rng.uniform() * 100.0);
            let axis = (DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()) - 0.5).normalize();
            let to_center = axis * d;
            let frame = Frame::from_z(axis);
            let cos_max = (1.0 - radius * radius / (d * d)).sqrt();
            let u = glam::DVec2::new(rng.uniform(), rng.uniform());
            let direction = uniform_cone(&frame, cos_max, u);
            let (t0, _) = sphere_roots(DVec3::ZERO, direction, to_center, radius)
                .unwrap_or((to_center.dot(direction), 0.0));
            let t = distance_to_sphere(direction, to_center, radius);
            assert!((t - t0).abs() <= 1e-9 * d, "{t} vs {t0}");
            // The end point lies on the sphere.
            let miss = ((direction * t - to_center).length() - radius).abs();
            assert!(miss <= 1e-9 * d, "{miss}");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spot_attenuation_follows_the_gltf_falloff() {
        let (inner, outer) = (
            crate::math::transcendental::sin_cos(20f64.to_radians()).1,
            crate::math::transcendental::sin_cos(40f64.to_radians()).1,
        );
        assert_eq!(spot_attenuation(1.0, inner, outer), 1.0);
        assert_eq!(spot_attenuation(inner, inner, outer), 1.0);
        assert_eq!(spot_attenuation(outer, inner, outer), 0.0);
        assert_eq!(spot_attenuation(-1.0, inner, outer), 0.0);
        // Halfway in cosine: t = ½, t² = ¼.
        let mid = 0.5 * (inner + outer);
        assert!((spot_attenuation(mid, inner, outer) - 0.25).abs() < 1e-12);
        // Equal cones: a hard edge.
        assert_eq!(spot_attenuation(inner + 0.01, inner, inner), 1.0);
        assert_eq!(spot_attenuation(inner - 0.01, inner, inner), 0.0);
    }

    #[test]
    fn cycles_spot_attenuation_is_cosine_times_smoothstep() {
        // Blender's spot of size 60° and blend 0.15: cos_outer = cos 30°,
        // spot_smooth = (1 − cos 30°)·0.15.
        let cos_outer = 0.75f64.sqrt();
        let smooth = (1.0 - cos_outer) * 0.15;
        let cos_inner = cos_outer + smooth;
        // On the axis: cos 0 = 1.
        assert_eq!(cycles_spot_attenuation(1.0, cos_inner, cos_outer), 1.0);
        // Inside the inner cone only the cosine: at 10°, cos 10°.
        let c10 = crate::math::transcendental::sin_cos(10f64.to_radians()).1;
        assert_eq!(cycles_spot_attenuation(c10, cos_inner, cos_outer), c10);
        // Halfway through the band: smoothstep(½) = ½, times cos θ.
        let mid = cos_outer + 0.5 * smooth;
        assert!((cycles_spot_attenuation(mid, cos_inner, cos_outer) - 0.5 * mid).abs() < 1e-12);
        // A quarter in: 3/16 − 2/64 = 0.15625 (by hand), times cos θ.
        let quarter = cos_outer + 0.25 * smooth;
        let want = quarter * 0.15625;
        assert!((cycles_spot_attenuation(quarter, cos_inner, cos_outer) - want).abs() < 1e-12);
        // On and beyond the outer cone: dark, and behind the light too.
        assert_eq!(
            cycles_spot_attenuation(cos_outer, cos_inner, cos_outer),
            0.0
        );
        assert_eq!(cycles_spot_attenuation(0.5, cos_inner, cos_outer), 0.0);
        assert_eq!(cycles_spot_attenuation(-1.0, cos_inner, cos_outer), 0.0);
        // Blend 0: a hard edge at the outer cone, the cosine inside it.
        assert_eq!(
            cycles_spot_attenuation(cos_outer + 1e-9, cos_outer, cos_outer),
            cos_outer + 1e-9
        );
        assert_eq!(
            cycles_spot_attenuation(cos_outer - 1e-9, cos_outer, cos_outer),
            0.0
        );
        // The glTF cone has no cosine and a t² band.
        assert_eq!(SpotCone::Gltf.attenuation(c10, cos_inner, cos_outer), 1.0);
        assert_eq!(SpotCone::Cycles.attenuation(c10, cos_inner, cos_outer), c10);
    }

    #[test]
    fn spot_light_samples_carry_the_cone() {
        let l = Light {
            shape: LightShape::Spot {
                position: DVec3::new(0.0, 4.0, 0.0),
                direction: -DVec3::Y,
                cos_inner: crate::math::transcendental::sin_cos(30f64.to_radians()).1,
                cos_outer: crate::math::transcendental::sin_cos(45f64.to_radians()).1,
                cone: SpotCone::Gltf,
            },
            radiance: DVec3::ONE,
            inverse_square: true,
        };
        let mut rng = PixelRng::new(0, 0, 0);
        // Straight below: inside the inner cone, only 1/d².
        let s = l.sampler(DVec3::ZERO).sample(0, &mut rng);
        assert!((s.falloff - 1.0 / 16.0).abs() < 1e-12);
        // 60° off the axis: dark.
        let off = DVec3::new(
            4.0 * crate::math::transcendental::tan(60f64.to_radians()),
            0.0,
            0.0,
        );
        assert_eq!(l.sampler(off).sample(0, &mut rng).falloff, 0.0);
    }

    #[test]
    fn point_light_sample() {
        let l = Light {
            shape: LightShape::Point {
                position: DVec3::new(0.0, 4.0, 0.0),
            },
            radiance: DVec3::ONE,
            inverse_square: true,
        };
        let mut rng = PixelRng::new(0, 0, 0);
        let sampler = l.sampler(DVec3::new(0.0, 2.0, 0.0));
        assert_eq!(sampler.count(), 1);
        let s = sampler.sample(0, &mut rng);
        assert_eq!(s.direction, DVec3::Y);
        assert_eq!(s.distance, 2.0);
        assert_eq!(s.falloff, 0.25);
    }

    #[test]
    fn sphere_light_samples_end_on_the_sphere_and_cover_it_evenly() {
        let center = DVec3::new(1.0, 5.0, -2.0);
        let radius = 1.5;
        let l = Light {
            shape: LightShape::Sphere {
                center,
                radius,
                samples: 64,
            },
            radiance: DVec3::ONE,
            inverse_square: false,
        };
        let mut rng = PixelRng::new(9, 1, 2);
        let mut mean = DVec3::ZERO;
        let sampler = l.sampler(DVec3::ZERO);
        assert_eq!(sampler.count(), 64);
        for i in 0..64 {
            let s = sampler.sample(i, &mut rng);
            assert!(((s.direction * s.distance - center).length() - radius).abs() < 1e-9);
            mean += s.direction;
        }
        // Stratified over the cone, the mean direction points at the centre.
        let axis = center.normalize();
        assert!(
            mean.normalize().dot(axis) > 0.9999,
            "{}",
            mean.normalize().dot(axis)
        );
    }
}
