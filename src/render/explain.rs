//! Why is this pixel this colour? One sample of one pixel traced again
//! with a recorder: the ray tree, what each ray hit, and the terms of the
//! Whitted formula at each hit with their values,
//!
//! I = ka·Od·Ia + Σⱼ visⱼ·Ilⱼ·(kd·Od·max(0, N·Lⱼ) + ks·max(0, Rⱼ·V)ⁿ) + kr·I_r + kt·I_t,
//!
//! which add up to the sample's radiance. The sample is traced exactly as
//! the render traces it (same random stream, same code), so with one
//! sample per pixel the tree's radiance is the rendered pixel.

use glam::DVec3;
use serde::Serialize;

use super::{RayStats, RenderSettings, render_pixel_recorded};
use crate::geometry::Hit;
use crate::lights::{LightSample, LightShape};
use crate::math::Ray;
use crate::math::ray::SpawnOrigins;
use crate::scene::Scene;
use crate::shading::whitted::{RayKind, Recorder, Stop, Whitted, WhittedSettings};

pub mod steps;
pub use steps::{
    EdgeStep, IntersectionSteps, PlaneSteps, PolygonSteps, ReflectionSteps, RefractionSteps,
    SphereSteps, TriangleSteps,
};

/// One ray of the tree and everything at its end.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct RayNode {
    /// `camera`, `reflected` or `refracted`.
    pub kind: &'static str,
    /// 1 for the camera ray.
    pub depth: u32,
    /// Product of the kr/kt weights from the camera to this ray.
    pub weight: [f64; 3],
    /// Where the ray starts.
    pub origin: [f64; 3],
    /// Its unit direction.
    pub direction: [f64; 3],
    /// What it hit; `None`: it brings the background.
    pub hit: Option<HitInfo>,
    /// The test of the object hit, step by step as the notes work it
    /// (`None` on a miss, and for a moving scene).
    pub intersection: Option<IntersectionSteps>,
    /// The other objects' tests and why each was rejected: the nearest
    /// few (see `steps::REJECTED`)…
    pub rejected: Vec<IntersectionSteps>,
    /// …and how many more objects the ray was tested against.
    pub rejected_left_out: usize,
    /// R = I − 2N(I·N) at the hit, where a mirror reflection is possible
    /// (kr > 0, a smooth surface).
    pub reflection: Option<ReflectionSteps>,
    /// Snell's law at the hit, for transparent objects: θi, the critical
    /// angle, total internal reflection, T.
    pub refraction: Option<RefractionSteps>,
    /// ka·Od·Ia.
    pub ambient: [f64; 3],
    /// The surface's own emission.
    pub emission: [f64; 3],
    /// Each light's terms.
    pub lights: Vec<LightTerms>,
    /// Weight of the reflected ray (after Fresnel and total internal
    /// reflection).
    pub kr: [f64; 3],
    /// Weight of the refracted ray.
    pub kt: [f64; 3],
    /// Total internal reflection: the refracted weight went to reflection.
    pub total_internal_reflection: bool,
    /// kr·I_reflected.
    pub reflected_term: [f64; 3],
    /// kt·I_refracted.
    pub refracted_term: [f64; 3],
    /// The reflected ray, if traced.
    pub reflected: Option<Box<RayNode>>,
    /// The refracted ray, if traced.
    pub refracted: Option<Box<RayNode>>,
    /// Why branches end here: `miss`, `depth limit`, `reflected weight
    /// below min_weight`, `refracted weight below min_weight`.
    pub stopped: Vec<&'static str>,
    /// This ray's colour: the sum of the terms above (or the background).
    pub radiance: [f64; 3],
}

/// What a ray hit.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct HitInfo {
    /// The object's name in the scene file (`unnamed` if it has none).
    pub object: String,
    /// Its primitive index.
    pub primitive: u32,
    /// The material's name.
    pub material: String,
    /// Distance along the ray (the direction is unit).
    pub distance: f64,
    /// The hit point.
    pub point: [f64; 3],
    /// Unit shading normal, facing the ray.
    pub normal: [f64; 3],
    /// The ray arrives from outside the object.
    pub entering: bool,
    /// Index of refraction on the incoming side and beyond (transparent
    /// objects only).
    pub eta_incoming: Option<f64>,
    /// Index beyond the surface.
    pub eta_beyond: Option<f64>,
    /// Surface colour Od at the hit.
    pub od: [f64; 3],
}

/// One light's terms at a hit.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct LightTerms {
    /// The light's name.
    pub light: String,
    /// Samples taken (1 for point and directional lights).
    pub samples: usize,
    /// Shadow feelers sent (samples behind the surface need none).
    pub feelers: usize,
    /// Mean visibility over the samples, per channel.
    pub visible_fraction: [f64; 3],
    /// Il · mean(vis · falloff · kd·Od·max(0, N·L)).
    pub diffuse: [f64; 3],
    /// Il · mean(vis · falloff · ks·max(0, R·V)ⁿ).
    pub specular: [f64; 3],
    /// The light's whole contribution (diffuse + specular).
    pub contribution: [f64; 3],
    /// A spot light: the mean share of its intensity its cone sends
    /// towards the point (1 inside the inner cone, 0 outside the outer).
    pub spot_cone: Option<f64>,
    /// The first feelers one by one (at most 64).
    pub feeler_points: Vec<FeelerPoint>,
    /// Feelers sent beyond those listed.
    pub feeler_points_left_out: usize,
}

/// A pixel's sample explained.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Explanation {
    /// The pixel.
    pub pixel: [u32; 2],
    /// Which sample (0-based).
    pub sample: usize,
    /// Samples per pixel.
    pub samples: u32,
    /// The sample's radiance: with one sample per pixel, the pixel's.
    pub radiance: [f64; 3],
    /// The pixel's value (the mean of its samples).
    pub pixel_radiance: [f64; 3],
    /// With a thin lens, where the sample's camera ray leaves the lens: in
    /// world units along the camera's right and up from the lens centre
    /// (within the aperture); `None` for a pinhole.
    pub lens_point: Option<[f64; 2]>,
    /// With an open shutter on a moving scene, the instant the sample sees,
    /// in frames after the frame's start; `None` otherwise.
    pub time: Option<f64>,
    /// The camera ray and its subtree.
    pub tree: RayNode,
}

/// Traces sample `sample` of pixel (x, y) as `render` does, recording
/// its ray tree.
pub fn explain(
    scene: &Scene,
    settings: &RenderSettings,
    x: u32,
    y: u32,
    sample: usize,
) -> Result<Explanation, String> {
    settings.check()?;
    if x >= settings.width || y >= settings.height {
        return Err(format!(
            "pixel {x},{y} is outside the {}x{} image",
            settings.width, settings.height
        ));
    }
    let samples = crate::math::sampling::Strata::new(settings.spp as usize).len();
    // Under adaptive anti-aliasing the count is known once the pixel is
    // traced (below).
    if settings.adaptive.is_none() && sample >= samples {
        return Err(format!(
            "sample {sample}: the pixel has {samples} samples (0 to {})",
            samples - 1
        ));
    }
    let tracer = Whitted::new(
        scene,
        WhittedSettings {
            max_depth: settings.max_depth.max(1),
            min_weight: settings.min_weight,
        },
    );
    let mut recorder = TreeRecorder {
        scene,
        // A moving scene is traced at an instant of its own, whose objects
        // these steps would not see.
        steps: scene.motion.is_empty(),
        stack: Vec::new(),
        root: None,
    };
    let mut stats = RayStats::default();
    let recorded = render_pixel_recorded(
        scene,
        &tracer,
        settings,
        x,
        y,
        &mut stats,
        Some(sample),
        &mut recorder,
    );
    if sample >= recorded.samples {
        return Err(format!(
            "sample {sample}: under adaptive anti-aliasing the pixel traced {} samples \
             (0 to {}: its corners and centres, in the order the subdivision reached them)",
            recorded.samples,
            recorded.samples - 1
        ));
    }
    Ok(Explanation {
        pixel: [x, y],
        sample,
        samples: recorded.samples as u32,
        radiance: recorded.sample.to_array(),
        pixel_radiance: recorded.pixel.to_array(),
        lens_point: recorded.lens.map(|p| p.to_array()),
        time: recorded.time,
        tree: recorder.root.unwrap_or_default(),
    })
}

/// Builds the tree from the tracer's steps: a stack of the rays under way.
struct TreeRecorder<'s> {
    scene: &'s Scene,
    /// Whether to record the intersection tests' steps.
    steps: bool,
    stack: Vec<(RayNode, Shading)>,
    root: Option<RayNode>,
}

/// What the light terms need at the current hit.
#[derive(Clone, Default)]
struct Shading {
    /// The ray as traced.
    ray: Option<Ray>,
    /// The hit point, where feelers start from (the point moved by the
    /// hit's shadow-terminator offset) and the geometric normal.
    point: DVec3,
    feeler_base: DVec3,
    geometric_normal: DVec3,
    n: DVec3,
    view: DVec3,
    od: DVec3,
    material: u32,
    /// Running sums per light: (vis, diffuse, specular, feelers, spot
    /// cone share).
    sums: Option<(DVec3, DVec3, DVec3, usize, f64)>,
    /// The current light's first feelers, and how many more it sent.
    points: Vec<FeelerPoint>,
    points_left_out: usize,
}

/// Feelers listed one by one per light and hit; the rest are counted.
const FEELER_POINTS: usize = 64;

/// One shadow feeler: where it went and what came back.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct FeelerPoint {
    /// Unit direction from the hit towards the light's sample.
    pub direction: [f64; 3],
    /// The sample's point on the light (on a sphere light's surface, on an
    /// area light); `None` for a directional light.
    pub on_light: Option<[f64; 3]>,
    /// Its weight: the distance falloff (an area light's A·cos θ′/d²,
    /// a spot's cone share included).
    pub weight: f64,
    /// What got through, per channel (0: blocked).
    pub visibility: [f64; 3],
    /// Where the feeler starts: the hit point lifted off the surface.
    pub origin: [f64; 3],
    /// The nearest object on the feeler short of the light, if any (the
    /// render asks only whether there is one; with transparent shadows it
    /// passes through those that let light through).
    pub blocked_by: Option<String>,
    /// The distance to it along the feeler.
    pub blocker_distance: Option<f64>,
}

impl Recorder for TreeRecorder<'_> {
    fn ray(&mut self, kind: RayKind, depth: u32, weight: DVec3, ray: &Ray) {
        let node = RayNode {
            kind: match kind {
                RayKind::Camera => "camera",
                RayKind::Reflection => "reflected",
                RayKind::Refraction => "refracted",
            },
            depth,
            weight: weight.to_array(),
            origin: ray.origin.to_array(),
            direction: ray.direction.to_array(),
            ..RayNode::default()
        };
        let shading = Shading {
            ray: Some(*ray),
            view: -ray.direction,
            ..Shading::default()
        };
        self.stack.push((node, shading));
    }

    fn hit(&mut self, hit: &Hit, entering: bool, n: DVec3, od: DVec3) {
        let names = &self.scene.names;
        let Some((node, shading)) = self.stack.last_mut() else {
            return;
        };
        node.hit = Some(HitInfo {
            object: names
                .objects
                .get(&hit.primitive)
                .cloned()
                .unwrap_or_else(|| "unnamed".into()),
            primitive: hit.primitive,
            material: names
                .materials
                .get(hit.material as usize)
                .cloned()
                .unwrap_or_default(),
            distance: hit.t,
            point: hit.point.to_array(),
            normal: n.to_array(),
            entering,
            eta_incoming: None,
            eta_beyond: None,
            od: od.to_array(),
        });
        shading.n = n;
        shading.od = od;
        shading.material = hit.material;
        shading.point = hit.point;
        shading.feeler_base = hit.point + hit.feeler_offset;
        shading.geometric_normal = hit.normal;
        if let (true, Some(ray)) = (self.steps, shading.ray) {
            node.intersection = Some(steps::intersection_steps(
                self.scene,
                hit.primitive,
                &ray,
                Some(hit),
            ));
            (node.rejected, node.rejected_left_out) = steps::rejected(self.scene, &ray, Some(hit));
        }
    }

    fn ambient(&mut self, term: DVec3) {
        if let Some((node, _)) = self.stack.last_mut() {
            node.ambient = term.to_array();
        }
    }

    fn emission(&mut self, term: DVec3) {
        if let Some((node, _)) = self.stack.last_mut() {
            node.emission = term.to_array();
        }
    }

    fn feeler(&mut self, light: usize, sample: &LightSample, visibility: DVec3) {
        let (direction, falloff) = (sample.direction, sample.falloff);
        let scene = self.scene;
        let Some((_, s)) = self.stack.last_mut() else {
            return;
        };
        if s.points.len() < FEELER_POINTS {
            let point = s.point;
            // The feeler as the render spawns it (ShadingPoint::
            // feeler_origins), and the nearest object on it short of the
            // light.
            let (feeler, gap) =
                SpawnOrigins::new(s.feeler_base, s.geometric_normal).spawn(direction);
            let blocker = scene.aggregate.closest_hit(&feeler, sample.distance - gap);
            s.points.push(FeelerPoint {
                origin: feeler.origin.to_array(),
                blocked_by: blocker.map(|b| {
                    scene
                        .names
                        .objects
                        .get(&b.primitive)
                        .cloned()
                        .unwrap_or_else(|| "unnamed".into())
                }),
                blocker_distance: blocker.map(|b| b.t),
                direction: direction.to_array(),
                on_light: sample
                    .distance
                    .is_finite()
                    .then(|| (point + direction * sample.distance).to_array()),
                weight: falloff,
                visibility: visibility.to_array(),
            });
        } else {
            s.points_left_out += 1;
        }
        let material = &scene.materials[s.material as usize];
        let (diffuse, specular) = material.phong_terms(s.od, s.n, direction, s.view);
        let sums = s
            .sums
            .get_or_insert((DVec3::ZERO, DVec3::ZERO, DVec3::ZERO, 0, 0.0));
        if let LightShape::Spot {
            direction: axis,
            cos_inner,
            cos_outer,
            cone,
            ..
        } = scene.lights[light].shape
        {
            sums.4 += cone.attenuation(axis.dot(-direction), cos_inner, cos_outer);
        }
        sums.0 += visibility;
        sums.1 += visibility * falloff * diffuse;
        sums.2 += visibility * falloff * specular;
        sums.3 += 1;
    }

    fn light(&mut self, light: usize, radiance: DVec3, samples: usize, contribution: DVec3) {
        let scene = self.scene;
        let Some((node, s)) = self.stack.last_mut() else {
            return;
        };
        let (vis, diffuse, specular, feelers, cone) =
            s.sums
                .take()
                .unwrap_or((DVec3::ZERO, DVec3::ZERO, DVec3::ZERO, 0, 0.0));
        let n = samples.max(1) as f64;
        node.lights.push(LightTerms {
            light: scene.names.lights.get(light).cloned().unwrap_or_default(),
            samples,
            feelers,
            visible_fraction: (vis / n).to_array(),
            diffuse: (radiance * diffuse / n).to_array(),
            specular: (radiance * specular / n).to_array(),
            contribution: contribution.to_array(),
            spot_cone: matches!(scene.lights[light].shape, LightShape::Spot { .. })
                .then(|| cone / feelers.max(1) as f64),
            feeler_points: std::mem::take(&mut s.points),
            feeler_points_left_out: std::mem::take(&mut s.points_left_out),
        });
    }

    fn split(&mut self, kr: DVec3, kt: DVec3, eta: Option<(f64, f64)>, tir: bool) {
        let scene = self.scene;
        let Some((node, s)) = self.stack.last_mut() else {
            return;
        };
        // The renderer's own calls: reflect(I, N) and refract(I, N, ηi/ηt),
        // I = −V.
        let smooth = scene
            .materials
            .get(s.material as usize)
            .is_some_and(|m| m.roughness == 0.0);
        if smooth && kr != DVec3::ZERO {
            node.reflection = Some(steps::reflection_steps(-s.view, s.n));
        }
        if let Some((eta_i, eta_t)) = eta {
            node.refraction = Some(steps::refraction_steps(-s.view, s.n, eta_i, eta_t));
        }
        node.kr = kr.to_array();
        node.kt = kt.to_array();
        node.total_internal_reflection = tir;
        if let (Some(h), Some((incoming, beyond))) = (node.hit.as_mut(), eta) {
            h.eta_incoming = Some(incoming);
            h.eta_beyond = Some(beyond);
        }
    }

    fn stop(&mut self, why: Stop) {
        let scene = self.scene;
        let Some((node, s)) = self.stack.last_mut() else {
            return;
        };
        if let (Stop::Miss, true, Some(ray)) = (why, self.steps, s.ray) {
            (node.rejected, node.rejected_left_out) = steps::rejected(scene, &ray, None);
        }
        node.stopped.push(match why {
            Stop::Miss => "miss: the background",
            Stop::Depth => "depth limit (max_depth)",
            Stop::ReflectionWeight => "reflected weight below min_weight",
            Stop::RefractionWeight => "refracted weight below min_weight",
        });
    }

    fn done(&mut self, color: DVec3) {
        let Some((mut node, _)) = self.stack.pop() else {
            return;
        };
        node.radiance = color.to_array();
        match self.stack.last_mut() {
            None => self.root = Some(node),
            Some((parent, _)) => {
                let k = |w: [f64; 3]| DVec3::from_array(w);
                let term = |weights: [f64; 3]| (k(weights) * k(node.radiance)).to_array();
                if node.kind == "reflected" {
                    parent.reflected_term = term(parent.kr);
                    parent.reflected = Some(Box::new(node));
                } else {
                    parent.refracted_term = term(parent.kt);
                    parent.refracted = Some(Box::new(node));
                }
            }
        }
    }
}

impl RayNode {
    /// The sum of the node's terms: ambient + emission + lights + kr·I_r + kt·I_t (or
    /// the background on a miss). Equals `radiance` up to the rounding of
    /// the order of additions.
    pub fn sum_of_terms(&self) -> DVec3 {
        if self.hit.is_none() {
            return DVec3::from_array(self.radiance);
        }
        let v = DVec3::from_array;
        v(self.ambient)
            + v(self.emission)
            + self.lights.iter().map(|l| v(l.contribution)).sum::<DVec3>()
            + v(self.reflected_term)
            + v(self.refracted_term)
    }

    /// Every node of the tree, depth first.
    pub fn nodes(&self) -> Vec<&RayNode> {
        let mut all = vec![self];
        for child in [&self.reflected, &self.refracted].into_iter().flatten() {
            all.extend(child.nodes());
        }
        all
    }
}
