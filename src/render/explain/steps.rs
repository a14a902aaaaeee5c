//! The lecture worked on a pixel: each intersection test, reflection and
//! refraction of the ray tree step by step, with the values the render's
//! own functions compute. Nothing here repeats a formula: the tests are the
//! geometry's `intersect_steps` and the optics' `reflect_steps` /
//! `refract_steps` (the functions the renderer calls, with `()` there),
//! run on the recorded ray with a [`StepLog`] listening; what is added is
//! presentation (names of axes, angles in degrees, Snell's construction
//! split into the vectors the notes draw).

use glam::{DVec2, DVec3};
use serde::Serialize;

use crate::accel::Shape;
use crate::geometry::steps::{EdgeCase, Steps};
use crate::geometry::triangle::{WatertightRay, triangle_hit_steps};
use crate::geometry::{Hit, MeshInstance, ShapeHit};
use crate::math::Ray;
use crate::math::transcendental;
use crate::scene::Scene;
use crate::shading::optics::{critical_angle, reflect_steps, refract_steps};

/// Edges of a polygon listed one by one; the rest are counted.
const EDGES: usize = 64;
/// Objects a ray did not take, listed with their reasons; the rest are
/// counted.
pub const REJECTED: usize = 8;

/// Everything a test told its listener.
#[derive(Clone, Debug, Default)]
pub struct StepLog {
    plane: Option<(f64, Option<f64>)>,
    projection: Option<(usize, DVec3, DVec2)>,
    edges: Vec<(DVec2, DVec2, EdgeCase)>,
    edges_left_out: usize,
    crossings: Option<usize>,
    quadratic: Option<(f64, f64, f64, f64)>,
    roots: Option<Option<(f64, f64)>>,
    root_taken: Option<Option<f64>>,
    reflection: Option<(f64, DVec3)>,
    refraction: Option<(f64, f64, Option<DVec3>)>,
    triangle: Option<WatertightSteps>,
}

/// What the watertight test told: axes, U V W, det, t.
type WatertightSteps = ([usize; 3], DVec3, Option<f64>, Option<f64>);

impl Steps for StepLog {
    fn plane(&mut self, n_dot_d: f64, t: Option<f64>) {
        self.plane = Some((n_dot_d, t));
    }
    fn projection(&mut self, principal_axis: usize, point: DVec3, projected: DVec2) {
        self.projection = Some((principal_axis, point, projected));
    }
    fn edge(&mut self, from: DVec2, to: DVec2, case: EdgeCase) {
        if self.edges.len() < EDGES {
            self.edges.push((from, to, case));
        } else {
            self.edges_left_out += 1;
        }
    }
    fn crossings(&mut self, count: usize) {
        self.crossings = Some(count);
    }
    fn quadratic(&mut self, a: f64, half_b: f64, c: f64, discriminant: f64) {
        self.quadratic = Some((a, half_b, c, discriminant));
    }
    fn roots(&mut self, roots: Option<(f64, f64)>) {
        self.roots = Some(roots);
    }
    fn root_taken(&mut self, t: Option<f64>) {
        self.root_taken = Some(t);
    }
    fn reflection(&mut self, i_dot_n: f64, r: DVec3) {
        self.reflection = Some((i_dot_n, r));
    }
    fn refraction(&mut self, cos_i: f64, radicand: f64, t: Option<DVec3>) {
        self.refraction = Some((cos_i, radicand, t));
    }
    fn triangle(&mut self, axes: [usize; 3], uvw: DVec3, det: Option<f64>, t: Option<f64>) {
        self.triangle = Some((axes, uvw, det, t));
    }
}

/// One object's intersection test against a ray, as the notes work it.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct IntersectionSteps {
    /// The object's name (`unnamed` if it has none).
    pub object: String,
    /// Its primitive index.
    pub primitive: u32,
    /// `plane`, `polygon`, `sphere`, `ellipsoid`, `mesh`, `box`, `cone`,
    /// `disc`, `torus` or `csg` (steps are listed for the first four).
    pub shape: &'static str,
    /// The test's answer: t of its nearest hit in (0, ∞), or none.
    pub t: Option<f64>,
    /// What became of it: `hit` (the nearest), or why it was rejected.
    pub verdict: String,
    /// The plane test (planes and polygons).
    pub plane: Option<PlaneSteps>,
    /// The point-in-polygon test (polygons whose plane is hit ahead).
    pub polygon: Option<PolygonSteps>,
    /// The quadratic (spheres; ellipsoids in their unit sphere's space).
    pub sphere: Option<SphereSteps>,
    /// The watertight test of the mesh's triangle hit (the object hit).
    pub triangle: Option<TriangleSteps>,
}

/// The watertight ray-triangle test (Woop, Benthin, Wald 2013) of the
/// triangle a mesh was hit on, in the mesh's own space.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct TriangleSteps {
    /// The triangle's index in the model file's list.
    pub triangle: u32,
    /// Its corners a, b, c.
    pub vertices: [[f64; 3]; 3],
    /// The mesh is placed by a transform: corners, ray and edge functions
    /// are in its own space (t the same in both).
    pub object_space: bool,
    /// The axes (kx, ky, kz): kz the direction's largest component, the
    /// ray sheared to run along it.
    pub axes: [&'static str; 3],
    /// U, V, W: the 2D edge functions of the sheared corners (for the
    /// edges bc, ca, ab).
    pub edge_functions: [f64; 3],
    /// `all ≥ 0` or `all ≤ 0` (the ray passes inside) or `mixed`.
    pub signs: &'static str,
    /// U + V + W (0: the ray runs in the triangle's plane).
    pub det: Option<f64>,
    /// t = (U·z_a + V·z_b + W·z_c)/det.
    pub t: Option<f64>,
    /// The hit's barycentric weights U/det, V/det, W/det of a, b, c.
    pub barycentric: Option<[f64; 3]>,
}

/// The ray against the plane n·v = d.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct PlaneSteps {
    /// The plane's unit normal n.
    pub normal: [f64; 3],
    /// Its distance d from the origin.
    pub d: f64,
    /// n·d, the normal against the ray's direction.
    pub n_dot_d: f64,
    /// `parallel` (n·d = 0: no intersection), `back face` (n·d > 0) or
    /// `front face` (n·d < 0).
    pub verdict: &'static str,
    /// t = (d − n·O)/(n·d); none when parallel.
    pub t: Option<f64>,
    /// P = O + tD, where the test computed it (t ahead of the ray).
    pub point: Option<[f64; 3]>,
}

/// One edge of the translated 2D polygon.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct EdgeStep {
    /// First end (x, z).
    pub from: [f64; 2],
    /// Second end.
    pub to: [f64; 2],
    /// `both z positive`, `both z negative`, `both x negative` (no
    /// crossing), or `x_int` (computed).
    pub case: &'static str,
    /// x_int = x₁ − z₁(x₂ − x₁)/(z₂ − z₁).
    pub x_int: Option<f64>,
    /// x_int > 0: the edge crosses the positive x axis.
    pub crosses: bool,
}

/// The point-in-polygon test of the notes: project along the principal
/// axis, translate the hit to the origin, count the edges crossing the
/// positive x axis.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct PolygonSteps {
    /// The normal's largest component: `x`, `y` or `z`.
    pub principal_axis: &'static str,
    /// The plane projected onto (the other two axes): `yz`, `zx`, `xy`.
    pub projected_onto: &'static str,
    /// The world axis of the 2D x (the direction of the test ray).
    pub x_axis: &'static str,
    /// The world axis of the 2D z.
    pub z_axis: &'static str,
    /// The hit point projected, before the translation.
    pub point: [f64; 2],
    /// The polygon's vertices projected and translated by −point.
    pub translated_polygon: Vec<[f64; 2]>,
    /// Each edge, from the last vertex to the first and on in order.
    pub edges: Vec<EdgeStep>,
    /// Edges beyond those listed (at most 64 are).
    pub edges_left_out: usize,
    /// Edges crossing the positive x axis.
    pub crossings: usize,
    /// `odd` (inside, by the Jordan curve theorem) or `even` (outside).
    pub parity: &'static str,
    /// The verdict.
    pub inside: bool,
}

/// The sphere's quadratic |O + tD − C|² = r²: a·t² + b·t + c = 0.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct SphereSteps {
    /// The centre (an ellipsoid: the origin of its unit sphere).
    pub center: [f64; 3],
    /// The radius (an ellipsoid: 1).
    pub radius: f64,
    /// An ellipsoid: the quadratic is the unit sphere's, with the ray in
    /// the object's own space (t the same in both).
    pub object_space: bool,
    /// a = D·D.
    pub a: f64,
    /// b = 2(O − C)·D.
    pub b: f64,
    /// c = |O − C|² − r².
    pub c: f64,
    /// b² − 4ac (negative: the line misses the sphere), computed as
    /// 4a(r² − |f − (f·D/a)D|²), f = O − C, which does not cancel.
    pub discriminant: f64,
    /// The roots t₀ ≤ t₁.
    pub roots: Option<[f64; 2]>,
    /// `t0`, `t1` (the nearest ahead of the ray), or none (both behind).
    pub taken: Option<&'static str>,
}

/// R = I − 2N(I·N) at a hit.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct ReflectionSteps {
    /// I, the incoming unit direction.
    pub i: [f64; 3],
    /// N, the unit normal facing I.
    pub n: [f64; 3],
    /// I·N.
    pub i_dot_n: f64,
    /// R.
    pub r: [f64; 3],
    /// The angle of incidence (= of reflection), degrees.
    pub theta: f64,
}

/// Snell's law at a hit, and the notes' construction T = w + ηu.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct RefractionSteps {
    /// I, the incoming unit direction.
    pub i: [f64; 3],
    /// N, the unit normal facing I.
    pub n: [f64; 3],
    /// Index on the incoming side.
    pub eta_i: f64,
    /// Index beyond.
    pub eta_t: f64,
    /// η = ηi/ηt.
    pub eta: f64,
    /// cos θi = −I·N.
    pub cos_i: f64,
    /// θi, degrees.
    pub theta_i: f64,
    /// θc = asin(ηt/ηi), degrees; none when ηi ≤ ηt (no TIR possible).
    pub critical_angle: Option<f64>,
    /// cos² θt = 1 − η²(1 − cos² θi); negative: total internal reflection.
    pub radicand: f64,
    /// Total internal reflection: θi past the critical angle, no T.
    pub total_internal_reflection: bool,
    /// θt, degrees.
    pub theta_t: Option<f64>,
    /// u = I + N cos θi: I's part along the surface (|u| = sin θi).
    pub u: [f64; 3],
    /// w = −N cos θt.
    pub w: Option<[f64; 3]>,
    /// T = w + ηu.
    pub t: Option<[f64; 3]>,
}

/// What the steps of a test say about `hit` (the ray's nearest hit, if
/// any) and this object.
fn verdict(log: &StepLog, found: Option<&ShapeHit>, primitive: u32, hit: Option<&Hit>) -> String {
    if let (Some(h), Some(nearest)) = (found, hit) {
        if nearest.primitive == primitive {
            return "hit: the nearest".into();
        }
        if h.t > nearest.t {
            return format!("hit farther than the nearest (t = {} > {})", h.t, nearest.t);
        }
        return format!(
            "hit as near as the nearest (t = {}), which has a lower index",
            h.t
        );
    }
    if found.is_some() {
        return "hit".into();
    }
    if let Some((n_dot_d, t)) = log.plane {
        match t {
            None => return format!("parallel: n·d = {n_dot_d:e}"),
            Some(t) if t <= 0.0 => return format!("the plane is behind the ray (t = {t})"),
            _ => {}
        }
    }
    if let Some(count) = log.crossings {
        return format!("outside the polygon: {count} crossings, even");
    }
    match (log.roots, log.root_taken) {
        (Some(None), _) => "the discriminant is negative: the line misses the sphere".into(),
        (Some(Some(_)), Some(None)) => "both roots lie behind the ray".into(),
        _ => "no intersection".into(),
    }
}

fn axis_name(axis: usize) -> &'static str {
    ["x", "y", "z"][axis.min(2)]
}

fn pair(v: DVec2) -> [f64; 2] {
    v.to_array()
}

/// Primitive `primitive`'s own test against `ray`, with t in (0, ∞) as
/// the closest-hit query asks, its steps recorded; `hit` is the ray's
/// nearest hit, for the verdict.
pub fn intersection_steps(
    scene: &Scene,
    primitive: u32,
    ray: &Ray,
    hit: Option<&Hit>,
) -> IntersectionSteps {
    let shape = &scene.aggregate.primitives()[primitive as usize].shape;
    let mut log = StepLog::default();
    let (far, near) = (f64::INFINITY, 0.0);
    let mut triangle = None;
    let (kind, found) = match shape {
        Shape::Plane(p) => ("plane", p.intersect_steps(ray, near, far, &mut log)),
        Shape::Polygon(p) => ("polygon", p.intersect_steps(ray, near, far, &mut log)),
        Shape::Sphere(s) => ("sphere", s.intersect_steps(ray, near, far, &mut log)),
        Shape::Ellipsoid(e) => ("ellipsoid", e.intersect_steps(ray, near, far, &mut log)),
        Shape::Mesh(instance) => {
            let found = shape.intersect(ray, near, far);
            if found.is_some() {
                triangle = triangle_steps(instance, ray, &mut log);
            }
            ("mesh", found)
        }
        Shape::Cuboid(_) => ("box", shape.intersect(ray, near, far)),
        Shape::Cone(_) => ("cone", shape.intersect(ray, near, far)),
        Shape::Disc(_) => ("disc", shape.intersect(ray, near, far)),
        Shape::Torus(_) => ("torus", shape.intersect(ray, near, far)),
        Shape::Csg(_) => ("csg", shape.intersect(ray, near, far)),
    };
    let plane = match (shape, log.plane) {
        (Shape::Plane(_) | Shape::Polygon(_), Some((n_dot_d, t))) => {
            let (normal, d) = match shape {
                Shape::Plane(p) => (p.normal, p.distance),
                Shape::Polygon(p) => (p.plane.normal, p.plane.distance),
                _ => (DVec3::ZERO, 0.0),
            };
            Some(PlaneSteps {
                normal: normal.to_array(),
                d,
                n_dot_d,
                verdict: if t.is_none() {
                    "parallel"
                } else if n_dot_d > 0.0 {
                    "back face"
                } else {
                    "front face"
                },
                t,
                // A polygon's test computes P; a plane's is the hit's point
                // (O + tD, computed once the plane is the nearest).
                point: log.projection.map(|(_, p, _)| p.to_array()).or_else(|| {
                    hit.filter(|h| h.primitive == primitive)
                        .map(|h| h.point.to_array())
                }),
            })
        }
        _ => None,
    };
    let polygon = match (log.projection, log.crossings) {
        (Some((axis, _, point)), Some(crossings)) => Some(PolygonSteps {
            principal_axis: axis_name(axis),
            projected_onto: ["yz", "zx", "xy"][axis.min(2)],
            x_axis: axis_name((axis + 1) % 3),
            z_axis: axis_name((axis + 2) % 3),
            point: pair(point),
            translated_polygon: log.edges.iter().map(|e| pair(e.1)).collect(),
            edges: log
                .edges
                .iter()
                .map(|&(from, to, case)| {
                    let (name, x_int) = match case {
                        EdgeCase::BothZPositive => ("both z positive", None),
                        EdgeCase::BothZNegative => ("both z negative", None),
                        EdgeCase::BothXNegative => ("both x negative", None),
                        EdgeCase::Intersects { x_int } => ("x_int", Some(x_int)),
                    };
                    EdgeStep {
                        from: pair(from),
                        to: pair(to),
                        case: name,
                        x_int,
                        crosses: x_int.is_some_and(|x| x > 0.0),
                    }
                })
                .collect(),
            edges_left_out: log.edges_left_out,
            crossings,
            parity: if crossings % 2 == 1 { "odd" } else { "even" },
            inside: crossings % 2 == 1,
        }),
        _ => None,
    };
    let sphere = log.quadratic.map(|(a, half_b, c, discriminant)| {
        let (center, radius, object_space) = match shape {
            Shape::Sphere(s) => (s.center, s.radius, false),
            _ => (DVec3::ZERO, 1.0, true),
        };
        let roots = log.roots.flatten();
        let taken = match (roots, log.root_taken.flatten()) {
            (Some((t0, _)), Some(t)) if t == t0 => Some("t0"),
            (Some(_), Some(_)) => Some("t1"),
            _ => None,
        };
        SphereSteps {
            center: center.to_array(),
            radius,
            object_space,
            a,
            // The code keeps b′ = b/2 and b′² − ac = (b² − 4ac)/4; the
            // notes' b and discriminant are these times 2 and 4, exactly.
            b: 2.0 * half_b,
            c,
            discriminant: 4.0 * discriminant,
            roots: roots.map(|(t0, t1)| [t0, t1]),
            taken,
        }
    });
    IntersectionSteps {
        object: scene
            .names
            .objects
            .get(&primitive)
            .cloned()
            .unwrap_or_else(|| "unnamed".into()),
        primitive,
        shape: kind,
        t: found.map(|h| h.t),
        verdict: verdict(&log, found.as_ref(), primitive, hit),
        plane,
        polygon,
        sphere,
        triangle,
    }
}

/// The watertight test of the triangle `instance` is hit on by `ray`, run
/// again by `triangle_hit_steps` on that triangle with the ray in the
/// mesh's space (as `MeshInstance::intersect` hands it to the mesh).
fn triangle_steps(instance: &MeshInstance, ray: &Ray, log: &mut StepLog) -> Option<TriangleSteps> {
    let (origin, direction) = match &instance.transform {
        None => (ray.origin, ray.direction),
        Some(t) => t.ray_to_object(ray),
    };
    let hit = instance
        .mesh
        .intersect(origin, direction, 0.0, f64::INFINITY)?;
    // The triangle's corners: from the leaves whose boxes hold the hit.
    let point = origin + hit.t * direction;
    let slack = 1e-9 * point.abs().max_element().max(1.0);
    let mut corners = None;
    instance.mesh.visit_triangles(
        |b| (point.cmpge(b.min - slack) & point.cmple(b.max + slack)).all(),
        |index, c| {
            if index == hit.triangle {
                corners = Some(c);
            }
        },
    );
    let corners = corners?;
    triangle_hit_steps(
        &WatertightRay::new(origin, direction),
        corners,
        0.0,
        f64::INFINITY,
        log,
    );
    let (axes, uvw, det, t) = log.triangle?;
    let (negative, positive) = (uvw.min_element() < 0.0, uvw.max_element() > 0.0);
    Some(TriangleSteps {
        triangle: hit.triangle,
        vertices: corners.map(|c| c.to_array()),
        object_space: instance.transform.is_some(),
        axes: axes.map(axis_name),
        edge_functions: uvw.to_array(),
        signs: match (negative, positive) {
            (true, true) => "mixed",
            (true, false) => "all ≤ 0",
            _ => "all ≥ 0",
        },
        det,
        t,
        barycentric: Some(hit.barycentric.to_array()),
    })
}

/// Every other primitive's test against `ray` (whose nearest hit is `hit`),
/// the nearest [`REJECTED`] with their steps, and how many more there are.
/// Each object is tested on its own, as the notes test every object; the
/// render's BVH passes over those whose boxes the ray misses without a test.
pub fn rejected(scene: &Scene, ray: &Ray, hit: Option<&Hit>) -> (Vec<IntersectionSteps>, usize) {
    let primitives = scene.aggregate.primitives();
    // Nearest first: an object hit farther by its t, any other by how near
    // its bounds' centre passes the ray (planes, unbounded, first of all).
    let mut order: Vec<(f64, u32)> = (0..primitives.len() as u32)
        .filter(|&i| hit.is_none_or(|h| h.primitive != i))
        .map(|i| {
            let key = match primitives[i as usize].shape.bounds() {
                None => 0.0,
                Some(b) => {
                    let to = b.centroid() - ray.origin;
                    let along = to.dot(ray.direction).max(0.0);
                    (to - along * ray.direction).length()
                }
            };
            (key, i)
        })
        .collect();
    // The nearest few first (a partial selection: a scene of a million
    // objects is not sorted for eight), then those in order.
    let nearest = |a: &(f64, u32), b: &(f64, u32)| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1));
    if order.len() > REJECTED {
        order.select_nth_unstable_by(REJECTED, nearest);
    }
    let listed = order.len().min(REJECTED);
    order[..listed].sort_by(nearest);
    let left_out = order.len().saturating_sub(REJECTED);
    let listed = order
        .iter()
        .take(REJECTED)
        .map(|&(_, i)| intersection_steps(scene, i, ray, hit))
        .collect();
    (listed, left_out)
}

/// Degrees of the angle whose cosine is `cos` (clamped to [−1, 1]).
fn degrees_of_cos(cos: f64) -> f64 {
    let cos = cos.clamp(-1.0, 1.0);
    transcendental::atan2((1.0 - cos * cos).max(0.0).sqrt(), cos).to_degrees()
}

/// `reflect` (the renderer's call, R = reflect(I, N)) with its steps.
pub fn reflection_steps(incident: DVec3, n: DVec3) -> ReflectionSteps {
    let mut log = StepLog::default();
    reflect_steps(incident, n, &mut log);
    let (i_dot_n, r) = log.reflection.unwrap_or_default();
    ReflectionSteps {
        i: incident.to_array(),
        n: n.to_array(),
        i_dot_n,
        r: r.to_array(),
        theta: degrees_of_cos(-i_dot_n),
    }
}

/// `refract` (the renderer's call, T = refract(I, N, ηi/ηt)) with its
/// steps, and the construction's vectors.
pub fn refraction_steps(incident: DVec3, n: DVec3, eta_i: f64, eta_t: f64) -> RefractionSteps {
    let mut log = StepLog::default();
    let eta = eta_i / eta_t;
    refract_steps(incident, n, eta, &mut log);
    let (cos_i, radicand, t) = log.refraction.unwrap_or_default();
    let cos_t = (radicand >= 0.0).then(|| radicand.sqrt());
    RefractionSteps {
        i: incident.to_array(),
        n: n.to_array(),
        eta_i,
        eta_t,
        eta,
        cos_i,
        theta_i: degrees_of_cos(cos_i),
        critical_angle: critical_angle(eta_i, eta_t).map(f64::to_degrees),
        radicand,
        total_internal_reflection: t.is_none(),
        theta_t: cos_t.map(degrees_of_cos),
        u: (incident + n * cos_i).to_array(),
        w: cos_t.map(|c| (-n * c).to_array()),
        t: t.map(|t| t.to_array()),
    }
}
