//! The scene in outline for the inspector's 3D view: the camera, the
//! lights and each object as the page draws it (a sphere's centre and
//! radius, a polygon's corners, a plane's n and d, any other shape's
//! bounding box), at most [`OBJECTS`] of them.

use prism::Scene;
use prism::accel::Shape;
use prism::lights::LightShape;
use serde_json::{Value, json};

/// Objects sent: a scene of a million is drawn by its first few hundred.
const OBJECTS: usize = 256;

/// The camera, lights and objects as JSON.
pub fn outline(scene: &Scene) -> Value {
    let c = &scene.camera;
    let lights: Vec<Value> = scene
        .lights
        .iter()
        .map(|l| match l.shape {
            LightShape::Point { position } | LightShape::Spot { position, .. } => {
                json!({"position": position.to_array()})
            }
            LightShape::Sphere { center, radius, .. } => {
                json!({"position": center.to_array(), "radius": radius})
            }
            LightShape::Area { emitter, .. } => json!({"position": emitter.center.to_array()}),
            LightShape::Directional { direction } => json!({"direction": direction.to_array()}),
        })
        .collect();
    let primitives = scene.aggregate.primitives();
    let objects: Vec<Value> = primitives
        .iter()
        .take(OBJECTS)
        .enumerate()
        .map(|(i, p)| {
            let name = scene.names.objects.get(&(i as u32)).cloned();
            match &p.shape {
                Shape::Sphere(s) => json!({"primitive": i, "name": name, "sphere":
                    {"center": s.center.to_array(), "radius": s.radius}}),
                Shape::Polygon(poly) => json!({"primitive": i, "name": name, "polygon":
                    poly.vertices().iter().map(|v| v.to_array()).collect::<Vec<_>>()}),
                Shape::Plane(plane) => json!({"primitive": i, "name": name, "plane":
                    {"normal": plane.normal.to_array(), "d": plane.distance}}),
                other => json!({"primitive": i, "name": name, "box": other.bounds()
                    .map(|b| [b.min.to_array(), b.max.to_array()])}),
            }
        })
        .collect();
    json!({
        "camera": {"position": c.position.to_array(), "forward": c.forward.to_array(),
                   "up": c.up.to_array()},
        "lights": lights,
        "objects": objects,
        "objects_left_out": primitives.len().saturating_sub(OBJECTS),
    })
}
