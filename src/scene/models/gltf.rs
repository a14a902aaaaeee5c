//! glTF 2.0 (.gltf and .glb): the meshes of the default scene, each stored
//! once and placed by every node that uses it (with the node's world
//! transform), the first camera, KHR_lights_punctual lights, and materials
//! mapped onto the Whitted model (see docs/scene-format.md):
//! Od = baseColorFactor × baseColorTexture, kd = 1 − metallic,
//! kr = metallic × baseColorFactor (a tinted mirror), ks = 1 − roughness with a Blinn exponent 2/α² − 2
//! (α = roughness²), kt = KHR_materials_transmission × baseColorFactor, ior =
//! KHR_materials_ior (1.5 by default); where kr or kt is not zero, the
//! material's `roughness` is glTF's, so the reflection and the transmitted
//! light spread over its GGX lobe (`shading/glossy.rs`). What is not mapped
//! is named in a warning.
//!
//! The file is read as untrusted input: the JSON is deserialized without the
//! gltf crate's validation (which indexes without checking) and nothing is
//! looked up through its wrappers; every index, buffer range, component type
//! and element type read here is checked first, and errors name the JSON
//! path (`meshes[0].primitives[0].attributes.POSITION`). The node graph is
//! checked for cycles, and the number of node instances it expands to is
//! counted before anything is expanded (nodes may be shared by several
//! parents, which makes the count exponential in the depth).

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use glam::{DMat3, DMat4, DQuat, DVec2, DVec3, DVec4};
use gltf::json::accessor::{ComponentType, GenericComponentType, Type};
use gltf::json::mesh::{Mode, Semantic};
use gltf::json::validation::Checked;
use gltf::json::{self, Index, Root};

use super::keyframes::{Interpolation, Sampler};
use super::{Model, ModelCamera, ModelError, ModelProjection, Pose};
use crate::geometry::MeshData;
use crate::lights::{Light, LightShape, SpotCone};
use crate::limits::{MAX_ANIMATION_KEYS, MAX_MODEL_PLACEMENTS, MAX_VALUE};
use crate::scene::resources::{Resources, TextureKey};
use crate::shading::texture::{Sampling, Wrap, texture_transform};
use crate::shading::{Fresnel, Highlight, Material, Texture};

/// Luminous efficacy the glTF specification converts with (lm/W), as
/// Blender's exporter does.
pub const LUMENS_PER_WATT: f64 = 683.0;

/// A KHR_lights_punctual intensity — candela (lm/sr) for point and spot
/// lights, lux (lm/m²) for directional ones — in radiometric units (W/sr,
/// W/m²), which is what Prism's light intensity Il is.
pub fn photometric_to_radiometric(intensity: f64) -> f64 {
    intensity / LUMENS_PER_WATT
}

/// The Whitted coefficient of a Lambertian term of reflectance `albedo`:
/// albedo / π, the glTF metallic-roughness model's diffuse BRDF (and
/// Cycles'), so that kd·Od·Il·N·L/d² is the radiance a Lambertian surface
/// of that albedo returns.
pub fn lambertian(albedo: f64) -> f64 {
    albedo / std::f64::consts::PI
}

const SUPPORTED: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_materials_transmission",
    "KHR_materials_ior",
    "KHR_materials_emissive_strength",
    "KHR_texture_transform",
];

/// What to change in Blender's glTF export for a required extension Prism
/// cannot read.
fn required_extension_advice(ext: &str) -> &'static str {
    match ext {
        "KHR_draco_mesh_compression" | "EXT_meshopt_compression" => {
            "compressed meshes; in Blender's glTF export untick Data > Compression"
        }
        "EXT_texture_webp" | "KHR_texture_basisu" => {
            "images Prism cannot decode; in Blender's glTF export set Material > Images to \
             Automatic or JPEG (not WebP)"
        }
        "KHR_mesh_quantization" => {
            "quantized vertex data; export without quantization (Blender writes float vertices)"
        }
        _ => "export without it (or with the feature that needs it turned off)",
    }
}

pub fn load(path: &Path, res: &mut Resources) -> Result<Model, ModelError> {
    let err = |message: String| ModelError::new(path, None, message);
    let bytes = res.policy.read(path).map_err(err)?;
    let (json_bytes, bin) = if bytes.starts_with(b"glTF") {
        split_glb(&bytes).map_err(err)?
    } else {
        (&bytes[..], None)
    };
    let root: Root = json::deserialize::from_slice(json_bytes).map_err(|e| {
        // serde_json's line is the file's line for .gltf text.
        let line = (bin.is_none() && !bytes.starts_with(b"glTF")).then(|| e.line());
        ModelError::new(path, line, format!("not valid glTF JSON: {e}"))
    })?;
    if let Some(ext) = root
        .extensions_required
        .iter()
        .find(|e| !SUPPORTED.contains(&e.as_str()))
    {
        return Err(err(format!(
            "requires the extension `{ext}`, which Prism does not support: {}",
            required_extension_advice(ext)
        )));
    }
    let dir = path.parent().unwrap_or(Path::new("."));
    let buffers = load_buffers(&root, bin, dir, res).map_err(err)?;
    let mut reader = Reader {
        root: &root,
        buffers: &buffers,
        file: path,
        warnings: Vec::new(),
        ignored: Default::default(),
    };
    let mut materials = Vec::with_capacity(root.materials.len());
    for i in 0..root.materials.len() {
        materials.push(reader.material(i, res).map_err(err)?);
    }
    let default_slot = materials.len() as u32;
    let mut needs_default = false;
    let scene_index = match root.scene {
        Some(s) => Some(s.value()),
        None => (!root.scenes.is_empty()).then_some(0),
    };
    let Some(scene) = scene_index.map(|s| {
        root.scenes
            .get(s)
            .ok_or_else(|| format!("scene: scene {s} does not exist"))
    }) else {
        return Err(err("the file has no scene".into()));
    };
    let scene = scene.map_err(err)?;
    let roots: Vec<usize> = scene.nodes.iter().map(Index::value).collect();
    let graph = NodeGraph::new(&root).map_err(err)?;
    let instances = graph.instances(&roots).map_err(err)?;
    if instances > MAX_MODEL_PLACEMENTS {
        return Err(err(format!(
            "the node graph expands to {instances} node instances (nodes shared by several \
             parents multiply), more than the limit of {MAX_MODEL_PLACEMENTS}"
        )));
    }

    // The nodes the scene reaches, each once, in the order the walk
    // first meets them.
    let reachable = graph.reachable(&roots);
    let animations = reader.animations(&reachable.1).map_err(err)?;
    let mut meshes = Vec::new();
    // glTF mesh index → index into `meshes` (`None`: no triangles): a
    // mesh used by several nodes (or by a node placed many times) is read
    // and stored once. Every reachable node's mesh is read whatever its
    // pose, so a mesh first met while an animation hides it (a zero
    // scale) has its slot at the instants it shows.
    let mut mesh_slots: HashMap<usize, Option<usize>> = HashMap::new();
    for &n in &reachable.0 {
        let Some(mesh) = root.nodes[n].mesh else {
            continue;
        };
        let mesh = mesh.value();
        if mesh_slots.contains_key(&mesh) {
            continue;
        }
        let data = reader
            .mesh(mesh, n, default_slot, &mut needs_default)
            .map_err(err)?;
        // Only lines or points: skipped (already warned about).
        let slot = (!data.triangles.is_empty()).then(|| {
            meshes.push(data);
            meshes.len() - 1
        });
        mesh_slots.insert(mesh, slot);
    }
    let pose = match walk(
        &mut reader,
        &roots,
        &graph.children,
        &animations,
        0.0,
        &mesh_slots,
    ) {
        Ok(pose) => pose,
        // An animated file is posed again at each frame it is built for,
        // which reports what is wrong there; at 0 s it may not be shown.
        Err(_) if !animations.is_empty() => Pose::default(),
        Err(e) => return Err(err(e)),
    };
    let mut model = Model {
        meshes,
        placements: pose.placements,
        materials: Vec::new(),
        warnings: Vec::new(),
        lights: pose.lights,
        cameras: pose.cameras,
        motion: None,
    };
    let any_mesh = !mesh_slots.is_empty();
    if any_mesh && model.meshes.is_empty() {
        return Err(err(
            "has no triangles: every primitive of its meshes is lines or points, which Prism \
             does not render (in Blender, give the mesh faces)"
                .into(),
        ));
    }
    if needs_default {
        materials.push(Material::default());
    }
    model.materials = materials;
    for ext in &root.extensions_used {
        if !SUPPORTED.contains(&ext.as_str()) {
            reader.ignore(&format!("the extension {}", short(ext)), "extensionsUsed");
        }
    }
    if !root.skins.is_empty() {
        reader.ignore("skins", "");
    }
    if !reader.ignored.is_empty() {
        let list: Vec<String> = reader
            .ignored
            .iter()
            .map(|(feature, places)| {
                let places: Vec<&str> = places
                    .iter()
                    .map(String::as_str)
                    .filter(|p| !p.is_empty())
                    .collect();
                match places.as_slice() {
                    [] | ["extensionsUsed"] => feature.clone(),
                    [a] => format!("{feature} ({a})"),
                    [a, b] => format!("{feature} ({a}, {b})"),
                    [a, b, rest @ ..] => format!("{feature} ({a}, {b} and {} more)", rest.len()),
                }
            })
            .collect();
        reader.warn(format!(
            "Prism ignores what it cannot render of this file: {}",
            list.join("; ")
        ));
    }
    model.warnings = reader.warnings;
    if !animations.is_empty() {
        model.motion = Some(Arc::new(Motion {
            file: path.to_path_buf(),
            root,
            roots,
            children: graph.children,
            animations,
            mesh_slots,
        }));
    }
    Ok(model)
}

/// A glTF file whose nodes are animated: what it takes to place its
/// meshes, lights and cameras again at another time (the node graph and
/// the channels; the meshes are read once, at load).
pub struct Motion {
    file: std::path::PathBuf,
    root: Root,
    roots: Vec<usize>,
    children: Vec<Vec<usize>>,
    animations: HashMap<usize, NodeAnimation>,
    /// glTF mesh index → index into the model's meshes.
    mesh_slots: HashMap<usize, Option<usize>>,
}

impl std::fmt::Debug for Motion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Motion")
            .field("file", &self.file)
            .field("animated_nodes", &self.animations.len())
            .finish()
    }
}

impl Motion {
    /// The model's placements, lights and cameras at `seconds` of its
    /// animations (glTF time).
    pub fn pose(&self, seconds: f64) -> Result<Pose, ModelError> {
        let mut reader = Reader {
            root: &self.root,
            buffers: &[],
            file: &self.file,
            warnings: Vec::new(),
            ignored: Default::default(),
        };
        walk(
            &mut reader,
            &self.roots,
            &self.children,
            &self.animations,
            seconds,
            &self.mesh_slots,
        )
        .map_err(|e| ModelError::new(&self.file, None, e))
    }
}

/// The scene's node instances at `seconds`: each node's world transform
/// (its animated channels played at that time), its camera and light
/// placed, and its mesh (its slot in `mesh_slots`) placed. Depth first in
/// node order (children pushed in reverse), so "the first camera" is the
/// first one met reading the scene's nodes in order, as Blender lists
/// them. A meshed node that an animation moves (its own channels or an
/// ancestor's) and whose world transform is singular at `seconds` (a scale
/// animated to zero) is hidden at that instant; a still one is an error.
fn walk(
    reader: &mut Reader<'_>,
    roots: &[usize],
    children: &[Vec<usize>],
    animations: &HashMap<usize, NodeAnimation>,
    seconds: f64,
    mesh_slots: &HashMap<usize, Option<usize>>,
) -> Result<Pose, String> {
    let root = reader.root;
    let when = if animations.is_empty() {
        String::new()
    } else {
        format!(" at {seconds} s of its animation")
    };
    let mut pose = Pose::default();
    // (node, its parent's world transform, whether an ancestor is animated)
    let mut stack: Vec<(usize, DMat4, bool)> = roots
        .iter()
        .rev()
        .map(|&n| (n, DMat4::IDENTITY, false))
        .collect();
    while let Some((n, parent, moved)) = stack.pop() {
        let node = &root.nodes[n];
        let (local, moving) = match animations.get(&n) {
            Some(a) => (a.local_at(node, seconds), true),
            None => (local_transform(node), moved),
        };
        let world = parent * local;
        if !world.is_finite() {
            return Err(format!(
                "nodes[{n}]: its world transform{when} overflows (not finite)"
            ));
        }
        stack.extend(children[n].iter().rev().map(|&c| (c, world, moving)));
        if let Some(c) = node.camera
            && let Some(camera) = reader.camera(n, c.value(), &world)?
        {
            pose.cameras.push(camera);
        }
        if let Some(light) = node
            .extensions
            .as_ref()
            .and_then(|e| e.khr_lights_punctual.as_ref())
        {
            pose.lights
                .push(reader.light(n, light.light.value(), &world)?);
        }
        let Some(mesh) = node.mesh else { continue };
        if DMat3::from_mat4(world).determinant().abs() < 1e-12 {
            if moving {
                // Shrunk to nothing at this instant: not there.
                continue;
            }
            return Err(format!(
                "nodes[{n}]: its world transform is singular (a zero scale)"
            ));
        }
        if let Some(&Some(index)) = mesh_slots.get(&mesh.value()) {
            pose.placements.push((index, world));
        }
    }
    Ok(pose)
}

/// The channels that drive one node: each of its translation, rotation
/// and scale, if animated.
#[derive(Debug, Default)]
struct NodeAnimation {
    /// Translation, rotation, scale (a sampler several channels use is
    /// read and stored once).
    channels: [Option<Arc<Sampler>>; 3],
}

impl NodeAnimation {
    /// The node's local matrix at `seconds`: its animated properties
    /// played, the others as the node states them.
    fn local_at(&self, node: &json::Node, seconds: f64) -> DMat4 {
        let [t, r, s] = &self.channels;
        let t = t.as_ref().map_or_else(
            || DVec3::from_array(node.translation.unwrap_or([0.0; 3]).map(f64::from)),
            |t| t.at(seconds).truncate(),
        );
        let q = r.as_ref().map_or_else(
            || {
                DQuat::from_array(
                    node.rotation
                        .map_or([0.0, 0.0, 0.0, 1.0], |q| q.0)
                        .map(f64::from),
                )
            },
            |r| DQuat::from_vec4(r.at(seconds)),
        );
        let q = if q.length_squared() > 0.0 && q.is_finite() {
            q.normalize()
        } else {
            DQuat::from_array([f64::NAN; 4])
        };
        let s = s.as_ref().map_or_else(
            || DVec3::from_array(node.scale.unwrap_or([1.0; 3]).map(f64::from)),
            |s| s.at(seconds).truncate(),
        );
        DMat4::from_scale_rotation_translation(s, q, t)
    }
}

/// The JSON and BIN chunks of a GLB container, every length checked against
/// the bytes actually there.
fn split_glb(bytes: &[u8]) -> Result<(&[u8], Option<&[u8]>), String> {
    let word = |at: usize| -> Option<u32> {
        Some(u32::from_le_bytes(bytes.get(at..at + 4)?.try_into().ok()?))
    };
    let (Some(version), Some(length)) = (word(4), word(8)) else {
        return Err("GLB: the file ends inside its 12-byte header".into());
    };
    if version != 2 {
        return Err(format!("GLB: version {version}; expected 2"));
    }
    if length as usize != bytes.len() {
        return Err(format!(
            "GLB: the header says {length} bytes, but the file has {}",
            bytes.len()
        ));
    }
    let mut at = 12;
    let mut chunks = Vec::new();
    while at < bytes.len() {
        let (Some(len), Some(kind)) = (word(at), word(at + 4)) else {
            return Err(format!("GLB: chunk header at byte {at} is cut off"));
        };
        let start = at + 8;
        let end = start
            .checked_add(len as usize)
            .filter(|&e| e <= bytes.len())
            .ok_or_else(|| {
                format!(
                    "GLB: chunk at byte {at} claims {len} bytes, past the end of the file ({} bytes)",
                    bytes.len()
                )
            })?;
        chunks.push((kind, &bytes[start..end]));
        // Chunks are padded to 4-byte boundaries.
        at = end.next_multiple_of(4);
    }
    const JSON: u32 = u32::from_le_bytes(*b"JSON");
    const BIN: u32 = u32::from_le_bytes(*b"BIN\0");
    match chunks.as_slice() {
        [(JSON, json), rest @ ..] => Ok((*json, rest.first().filter(|c| c.0 == BIN).map(|c| c.1))),
        _ => Err("GLB: the first chunk is not JSON".into()),
    }
}

/// The bytes of every buffer: the GLB's BIN chunk, a base64 data URI, or a
/// file beside the model (read through the scene's read policy), each at
/// least as long as its declared `byteLength`.
fn load_buffers(
    root: &Root,
    bin: Option<&[u8]>,
    dir: &Path,
    res: &Resources,
) -> Result<Vec<Vec<u8>>, String> {
    let mut buffers = Vec::with_capacity(root.buffers.len());
    for (i, b) in root.buffers.iter().enumerate() {
        let at = format!("buffers[{i}]");
        let data = match b.uri.as_deref() {
            None if i == 0 => bin
                .ok_or(format!("{at}: has no uri and the file has no BIN chunk"))?
                .to_vec(),
            None => return Err(format!("{at}: has no uri")),
            // Only the declared bytes are read (and hashed): a buffer of
            // 376 bytes naming a 3 GB file costs 376 bytes.
            Some(uri) => read_uri(uri, dir, res, Some(b.byte_length.0))
                .map_err(|e| format!("{at}.uri: {e}"))?,
        };
        let declared = b.byte_length.0;
        if (data.len() as u64) < declared {
            return Err(format!(
                "{at}: byteLength is {declared}, but only {} bytes are there",
                data.len()
            ));
        }
        buffers.push(data);
    }
    Ok(buffers)
}

/// The bytes a glTF URI names: a `data:` URI (base64) or a relative path
/// (percent-encoded); `file://` paths too, which the read policy then
/// judges like any other path. Other schemes are refused.
/// With `declared`, a file's first `declared` bytes only.
fn read_uri(
    uri: &str,
    dir: &Path,
    res: &Resources,
    declared: Option<u64>,
) -> Result<Vec<u8>, String> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, payload) = rest
            .split_once(";base64,")
            .ok_or("a data URI must be base64 (data:...;base64,...)")?;
        return base64::decode(payload).map_err(|e| format!("bad base64 data: {e}"));
    }
    let path = match uri.strip_prefix("file://") {
        Some(p) => p,
        None if uri.contains("://") => {
            return Err(format!(
                "`{}`: only relative paths, file:// and data: URIs are read",
                short(uri)
            ));
        }
        None => uri,
    };
    let decoded = urlencoding::decode(path).map_err(|e| format!("bad URI: {e}"))?;
    let file = dir.join(decoded.as_ref());
    match declared {
        Some(len) => res.policy.read_prefix(&file, len),
        None => res.policy.read(&file),
    }
    .map_err(|e| format!("{}: {e}", file.display()))
}

/// `list[i]`, or an error at JSON path `at` naming what is missing.
fn lookup<'r, T>(list: &'r [T], i: usize, at: &str, what: &str) -> Result<&'r T, String> {
    list.get(i).ok_or_else(|| {
        format!(
            "{at}: {what} {i} does not exist ({} in the file)",
            list.len()
        )
    })
}

/// A value for messages, cut to a readable length.
fn short(s: &str) -> String {
    super::cut(s, 80)
}

/// Node children by index, checked: every child exists, no node is its own
/// ancestor.
struct NodeGraph {
    children: Vec<Vec<usize>>,
}

impl NodeGraph {
    fn new(root: &Root) -> Result<NodeGraph, String> {
        let n = root.nodes.len();
        let mut children = Vec::with_capacity(n);
        for (i, node) in root.nodes.iter().enumerate() {
            let mut list = Vec::new();
            for (k, c) in node.children.iter().flatten().enumerate() {
                let c = c.value();
                if c >= n {
                    return Err(format!(
                        "nodes[{i}].children[{k}]: node {c} does not exist ({n} nodes)"
                    ));
                }
                if c == i {
                    return Err(format!("nodes[{i}] lists itself as a child (a cycle)"));
                }
                list.push(c);
            }
            children.push(list);
        }
        let graph = NodeGraph { children };
        graph.check_acyclic()?;
        Ok(graph)
    }

    /// Depth-first search without recursion (a chain of nodes may be as
    /// long as the file allows); a child found on the current path closes a
    /// cycle, which is named.
    fn check_acyclic(&self) -> Result<(), String> {
        #[derive(Clone, Copy, PartialEq)]
        enum Mark {
            New,
            OnPath,
            Done,
        }
        let mut mark = vec![Mark::New; self.children.len()];
        for start in 0..self.children.len() {
            if mark[start] != Mark::New {
                continue;
            }
            // (node, next child to look at)
            let mut path = vec![(start, 0usize)];
            mark[start] = Mark::OnPath;
            while let Some(&mut (node, ref mut next)) = path.last_mut() {
                match self.children[node].get(*next) {
                    Some(&child) => {
                        *next += 1;
                        match mark[child] {
                            Mark::New => {
                                mark[child] = Mark::OnPath;
                                path.push((child, 0));
                            }
                            Mark::OnPath => {
                                let from = path.iter().position(|p| p.0 == child).unwrap_or(0);
                                let cycle: Vec<String> = path[from..]
                                    .iter()
                                    .map(|p| p.0.to_string())
                                    .chain(std::iter::once(child.to_string()))
                                    .collect();
                                return Err(format!(
                                    "the nodes form a cycle: {} (a node cannot be its own ancestor)",
                                    cycle.join(" → ")
                                ));
                            }
                            Mark::Done => {}
                        }
                    }
                    None => {
                        mark[node] = Mark::Done;
                        path.pop();
                    }
                }
            }
        }
        Ok(())
    }

    /// How many node instances the walk from `roots` visits, counted on the
    /// (acyclic) graph without expanding it: a node shared by k parents is
    /// visited once per path to it. Saturates instead of overflowing.
    fn instances(&self, roots: &[usize]) -> Result<u64, String> {
        let n = self.children.len();
        if let Some(&bad) = roots.iter().find(|&&r| r >= n) {
            return Err(format!("scene: root node {bad} does not exist ({n} nodes)"));
        }
        // Post-order without recursion.
        let mut count: Vec<Option<u64>> = vec![None; n];
        for &r in roots {
            let mut stack = vec![r];
            while let Some(&node) = stack.last() {
                if count[node].is_some() {
                    stack.pop();
                    continue;
                }
                let pending: Vec<usize> = self.children[node]
                    .iter()
                    .copied()
                    .filter(|&c| count[c].is_none())
                    .collect();
                if pending.is_empty() {
                    let below = self.children[node]
                        .iter()
                        .fold(1u64, |s, &c| s.saturating_add(count[c].unwrap_or(0)));
                    count[node] = Some(below);
                    stack.pop();
                } else {
                    stack.extend(pending);
                }
            }
        }
        Ok(roots
            .iter()
            .fold(0u64, |s, &r| s.saturating_add(count[r].unwrap_or(0))))
    }
}

impl NodeGraph {
    /// The nodes reachable from `roots` (which exist: see
    /// [`instances`](Self::instances)), each once, in the order a depth
    /// first walk in node order first meets them; and, by node, whether it
    /// is reachable.
    fn reachable(&self, roots: &[usize]) -> (Vec<usize>, Vec<bool>) {
        let mut seen = vec![false; self.children.len()];
        let mut order = Vec::new();
        let mut stack: Vec<usize> = roots.iter().rev().copied().collect();
        while let Some(n) = stack.pop() {
            if std::mem::replace(&mut seen[n], true) {
                continue;
            }
            order.push(n);
            stack.extend(self.children[n].iter().rev());
        }
        (order, seen)
    }
}

/// The node's local matrix: `matrix`, or translation × rotation × scale.
fn local_transform(node: &json::Node) -> DMat4 {
    if let Some(m) = node.matrix {
        return DMat4::from_cols_array(&m.map(f64::from));
    }
    let t = node.translation.unwrap_or([0.0; 3]).map(f64::from);
    let r = node
        .rotation
        .map_or([0.0, 0.0, 0.0, 1.0], |q| q.0)
        .map(f64::from);
    let s = node.scale.unwrap_or([1.0; 3]).map(f64::from);
    let q = DQuat::from_array(r);
    // A rotation must be a unit quaternion; normalise what rounding left.
    let q = if q.length_squared() > 0.0 && q.is_finite() {
        q.normalize()
    } else {
        DQuat::from_array([f64::NAN; 4])
    };
    DMat4::from_scale_rotation_translation(DVec3::from_array(s), q, DVec3::from_array(t))
}

/// Reads typed data out of the checked buffers, collecting warnings.
struct Reader<'a> {
    root: &'a Root,
    buffers: &'a [Vec<u8>],
    file: &'a Path,
    warnings: Vec<String>,
    /// Features used but not rendered → where (JSON paths): one warning.
    ignored: std::collections::BTreeMap<String, Vec<String>>,
}

/// An accessor's elements, every byte of them known to lie in its buffer.
struct Elements<'a> {
    data: &'a [u8],
    stride: usize,
    count: usize,
    component: ComponentType,
    normalized: bool,
}

impl Elements<'_> {
    /// Component `c` of element `i`, as a number (normalized integers
    /// mapped to [0, 1] as the glTF specification says).
    fn get(&self, i: usize, c: usize) -> f64 {
        let size = component_size(self.component);
        let at = i * self.stride + c * size;
        let b = &self.data[at..at + size];
        let raw = match self.component {
            ComponentType::F32 => return f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            ComponentType::U8 => f64::from(b[0]),
            ComponentType::I8 => f64::from(b[0] as i8),
            ComponentType::U16 => f64::from(u16::from_le_bytes([b[0], b[1]])),
            ComponentType::I16 => f64::from(i16::from_le_bytes([b[0], b[1]])),
            ComponentType::U32 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        };
        if self.normalized {
            let max = match self.component {
                ComponentType::U8 => 255.0,
                ComponentType::I8 => 127.0,
                ComponentType::U16 => 65535.0,
                ComponentType::I16 => 32767.0,
                _ => 1.0,
            };
            (raw / max).max(-1.0)
        } else {
            raw
        }
    }

    fn index(&self, i: usize) -> u32 {
        self.get(i, 0) as u32
    }
}

fn component_size(c: ComponentType) -> usize {
    match c {
        ComponentType::I8 | ComponentType::U8 => 1,
        ComponentType::I16 | ComponentType::U16 => 2,
        ComponentType::U32 | ComponentType::F32 => 4,
    }
}

fn type_name(t: Type) -> &'static str {
    match t {
        Type::Scalar => "SCALAR",
        Type::Vec2 => "VEC2",
        Type::Vec3 => "VEC3",
        Type::Vec4 => "VEC4",
        Type::Mat2 => "MAT2",
        Type::Mat3 => "MAT3",
        Type::Mat4 => "MAT4",
    }
}

fn component_name(c: ComponentType) -> &'static str {
    match c {
        ComponentType::I8 => "BYTE",
        ComponentType::U8 => "UNSIGNED_BYTE",
        ComponentType::I16 => "SHORT",
        ComponentType::U16 => "UNSIGNED_SHORT",
        ComponentType::U32 => "UNSIGNED_INT",
        ComponentType::F32 => "FLOAT",
    }
}

/// What an attribute may be: element type, and (component type, normalized).
struct Expect {
    kind: Type,
    components: &'static [(ComponentType, bool)],
}

const POSITION: Expect = Expect {
    kind: Type::Vec3,
    components: &[(ComponentType::F32, false)],
};
const NORMAL: Expect = POSITION;
const TEXCOORD: Expect = Expect {
    kind: Type::Vec2,
    components: &[
        (ComponentType::F32, false),
        (ComponentType::U8, true),
        (ComponentType::U16, true),
    ],
};
/// COLOR_0: float or normalized unsigned byte/short, RGB or RGBA.
const COLOR_COMPONENTS: &[(ComponentType, bool)] = &[
    (ComponentType::F32, false),
    (ComponentType::U8, true),
    (ComponentType::U16, true),
];
const COLOR3: Expect = Expect {
    kind: Type::Vec3,
    components: COLOR_COMPONENTS,
};
const COLOR4: Expect = Expect {
    kind: Type::Vec4,
    components: COLOR_COMPONENTS,
};
/// An animation sampler's key times.
const TIMES: Expect = Expect {
    kind: Type::Scalar,
    components: &[(ComponentType::F32, false)],
};
/// Keyed translations and scales.
const VECTORS: Expect = POSITION;
/// Keyed rotations: float or normalized integer quaternions.
const ROTATIONS: Expect = Expect {
    kind: Type::Vec4,
    components: &[
        (ComponentType::F32, false),
        (ComponentType::I8, true),
        (ComponentType::U8, true),
        (ComponentType::I16, true),
        (ComponentType::U16, true),
    ],
};
const INDICES: Expect = Expect {
    kind: Type::Scalar,
    components: &[
        (ComponentType::U8, false),
        (ComponentType::U16, false),
        (ComponentType::U32, false),
    ],
};

impl<'a> Reader<'a> {
    fn warn(&mut self, w: String) {
        let w = format!("{}: {w}", self.file.display());
        if !self.warnings.contains(&w) {
            self.warnings.push(w);
        }
    }

    /// The bytes of buffer view `v`, checked to lie inside its buffer.
    fn view_bytes(&self, v: usize) -> Result<&'a [u8], String> {
        let view = lookup(&self.root.buffer_views, v, "bufferViews", "buffer view")?;
        let b = view.buffer.value();
        let buffer = lookup(
            self.buffers,
            b,
            &format!("bufferViews[{v}].buffer"),
            "buffer",
        )?;
        let start = view.byte_offset.map_or(0, |o| o.0);
        let len = view.byte_length.0;
        start
            .checked_add(len)
            .and_then(|end| buffer.get(usize::try_from(start).ok()?..usize::try_from(end).ok()?))
            .ok_or_else(|| {
                format!(
                    "bufferViews[{v}]: bytes {start}..+{len} lie past the end of buffer {b} ({} bytes)",
                    buffer.len()
                )
            })
    }

    /// The accessor `index` read at JSON path `at`, checked against `expect`
    /// and against its buffer view and buffer.
    fn elements(
        &self,
        index: Index<json::Accessor>,
        at: &str,
        expect: &Expect,
    ) -> Result<Elements<'a>, String> {
        let root = self.root;
        let i = index.value();
        let a = lookup(&root.accessors, i, at, "accessor")?;
        let at = format!("{at} (accessors[{i}])");
        if a.sparse.is_some() {
            return Err(format!("{at}: sparse accessors are not supported"));
        }
        let kind = match a.type_ {
            Checked::Valid(t) => t,
            Checked::Invalid => return Err(format!("{at}: unknown element type")),
        };
        if kind != expect.kind {
            return Err(format!(
                "{at}: element type is {}; expected {}",
                type_name(kind),
                type_name(expect.kind)
            ));
        }
        let component = match a.component_type {
            Checked::Valid(GenericComponentType(c)) => c,
            Checked::Invalid => return Err(format!("{at}: unknown component type")),
        };
        if !expect.components.contains(&(component, a.normalized)) {
            let allowed: Vec<String> = expect
                .components
                .iter()
                .map(|(c, n)| {
                    format!(
                        "{}{}",
                        component_name(*c),
                        if *n { " (normalized)" } else { "" }
                    )
                })
                .collect();
            return Err(format!(
                "{at}: component type is {}{}; expected {}",
                component_name(component),
                if a.normalized { " (normalized)" } else { "" },
                allowed.join(" or ")
            ));
        }
        let Some(view_index) = a.buffer_view else {
            return Err(format!(
                "{at}: has no bufferView (an all-zero accessor), which is not supported"
            ));
        };
        let v = view_index.value();
        let view = lookup(
            &root.buffer_views,
            v,
            &format!("{at}.bufferView"),
            "buffer view",
        )?;
        let view_bytes = self.view_bytes(v)?;
        let view_len = view_bytes.len() as u64;
        let components = match kind {
            Type::Scalar => 1,
            Type::Vec2 => 2,
            Type::Vec3 => 3,
            _ => 4,
        };
        let element = (components * component_size(component)) as u64;
        let stride = view.byte_stride.map_or(element, |s| s.0 as u64);
        if stride < element {
            return Err(format!(
                "bufferViews[{v}]: byteStride {stride} is smaller than one element ({element} bytes)"
            ));
        }
        let offset = a.byte_offset.map_or(0, |o| o.0);
        let count = a.count.0;
        // Offset of the end of the last element, in u128: no overflow.
        let end = if count == 0 {
            offset as u128
        } else {
            offset as u128 + (count as u128 - 1) * stride as u128 + element as u128
        };
        if end > view_len as u128 {
            return Err(format!(
                "{at}: {count} elements of {element} bytes (stride {stride}) from offset {offset} \
                 need {end} bytes, but buffer view {v} has {view_len}"
            ));
        }
        let data = &view_bytes[offset as usize..];
        Ok(Elements {
            data,
            stride: stride as usize,
            count: count as usize,
            component,
            normalized: a.normalized,
        })
    }

    /// One glTF mesh (all its triangle primitives) in its own space.
    fn mesh(
        &mut self,
        m: usize,
        node: usize,
        default_slot: u32,
        needs_default: &mut bool,
    ) -> Result<MeshData, String> {
        let mesh = lookup(&self.root.meshes, m, &format!("nodes[{node}].mesh"), "mesh")?;
        let mut data = MeshData::default();
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let at = format!("meshes[{m}].primitives[{p}]");
            if primitive.mode != Checked::Valid(Mode::Triangles) {
                let name = mesh
                    .name
                    .as_deref()
                    .map_or(String::new(), |n| format!(" (mesh `{}`)", short(n)));
                let what = match primitive.mode {
                    Checked::Valid(Mode::Points) => "points",
                    Checked::Valid(Mode::Lines | Mode::LineLoop | Mode::LineStrip) => "lines",
                    Checked::Valid(_) => "triangle strips or fans",
                    Checked::Invalid => "of an unknown mode",
                };
                self.warn(format!(
                    "{at}{name}: {what}, not triangles; skipped (Prism renders triangles only)"
                ));
                continue;
            }
            let attribute = |s: Semantic| primitive.attributes.get(&Checked::Valid(s)).copied();
            if !primitive.targets.as_ref().is_none_or(Vec::is_empty) {
                self.ignore("morph targets", &at);
            }
            let Some(position) = attribute(Semantic::Positions) else {
                return Err(format!("{at}.attributes.POSITION: missing"));
            };
            let positions =
                self.elements(position, &format!("{at}.attributes.POSITION"), &POSITION)?;
            let count = positions.count;
            let base = data.positions.len();
            for i in 0..count {
                let v = DVec3::new(
                    positions.get(i, 0),
                    positions.get(i, 1),
                    positions.get(i, 2),
                );
                if !v.is_finite() {
                    return Err(format!(
                        "{at}.attributes.POSITION: vertex {i} is not finite"
                    ));
                }
                data.positions.push(v);
            }
            // Normals and uvs must cover every vertex of the mesh or none.
            match attribute(Semantic::Normals) {
                Some(n) if data.normals.len() == base => {
                    let normals = self.elements(n, &format!("{at}.attributes.NORMAL"), &NORMAL)?;
                    if normals.count != count {
                        return Err(format!(
                            "{at}.attributes.NORMAL: {} normals for {count} positions",
                            normals.count
                        ));
                    }
                    for i in 0..count {
                        let n = DVec3::new(normals.get(i, 0), normals.get(i, 1), normals.get(i, 2));
                        if !n.is_finite() {
                            return Err(format!(
                                "{at}.attributes.NORMAL: normal {i} is not finite"
                            ));
                        }
                        data.normals.push(n);
                    }
                }
                _ => data.normals.clear(),
            }
            match attribute(Semantic::TexCoords(0)) {
                Some(t) if data.uvs.len() == base => {
                    let uvs =
                        self.elements(t, &format!("{at}.attributes.TEXCOORD_0"), &TEXCOORD)?;
                    if uvs.count != count {
                        return Err(format!(
                            "{at}.attributes.TEXCOORD_0: {} coordinates for {count} positions",
                            uvs.count
                        ));
                    }
                    // glTF's v runs down the image; Prism's runs up.
                    for i in 0..count {
                        let uv = DVec2::new(uvs.get(i, 0), 1.0 - uvs.get(i, 1));
                        if !uv.is_finite() {
                            return Err(format!(
                                "{at}.attributes.TEXCOORD_0: coordinate {i} is not finite"
                            ));
                        }
                        data.uvs.push(uv);
                    }
                }
                _ => data.uvs.clear(),
            }
            match attribute(Semantic::Colors(0)) {
                Some(c) if data.colors.len() == base => {
                    let at = format!("{at}.attributes.COLOR_0");
                    let four = self.root.accessors.get(c.value()).map(|a| a.type_)
                        == Some(Checked::Valid(Type::Vec4));
                    let colors = self.elements(c, &at, if four { &COLOR4 } else { &COLOR3 })?;
                    if colors.count != count {
                        return Err(format!(
                            "{at}: {} colours for {count} positions",
                            colors.count
                        ));
                    }
                    // Linear RGB in [0, 1] (a reflectance, as baseColorFactor);
                    // alpha (VEC4) is not used. Non-finite is refused, as a
                    // position would be; above 1 is clamped, said once.
                    let mut clamped = false;
                    for i in 0..count {
                        let c = DVec3::new(colors.get(i, 0), colors.get(i, 1), colors.get(i, 2));
                        if !c.is_finite() {
                            return Err(format!("{at}: colour {i} is not finite"));
                        }
                        let kept = c.clamp(DVec3::ZERO, DVec3::ONE);
                        clamped |= kept != c;
                        data.colors.push(kept);
                    }
                    if clamped {
                        // One line per file (warn drops repeats).
                        self.warn(
                            "vertex colours (COLOR_0) outside [0, 1] are clamped to it".into(),
                        );
                    }
                }
                _ => data.colors.clear(),
            }
            let slot = match primitive.material {
                Some(i) if i.value() < self.root.materials.len() => i.value() as u32,
                Some(i) => {
                    return Err(format!(
                        "{at}.material: material {} does not exist ({} materials)",
                        i.value(),
                        self.root.materials.len()
                    ));
                }
                None => {
                    *needs_default = true;
                    default_slot
                }
            };
            let corner = |k: usize| -> Result<u32, String> {
                if (k as u64) >= u64::from(u32::MAX) {
                    return Err(format!("{at}: more vertices than Prism can index"));
                }
                Ok(k as u32)
            };
            let base32 = corner(base)?;
            let mut push = |a: u32, b: u32, c: u32| {
                data.triangles.push([base32 + a, base32 + b, base32 + c]);
                data.materials.push(slot);
            };
            match primitive.indices {
                Some(ix) => {
                    let indices = self.elements(ix, &format!("{at}.indices"), &INDICES)?;
                    if let Some(bad) =
                        (0..indices.count).find(|&i| indices.index(i) as usize >= count)
                    {
                        return Err(format!(
                            "{at}.indices: index {} (element {bad}) is past the {count} vertices",
                            indices.index(bad)
                        ));
                    }
                    for t in 0..indices.count / 3 {
                        push(
                            indices.index(3 * t),
                            indices.index(3 * t + 1),
                            indices.index(3 * t + 2),
                        );
                    }
                }
                None => {
                    corner(base + count)?;
                    for t in 0..count / 3 {
                        let t = 3 * t as u32;
                        push(t, t + 1, t + 2);
                    }
                }
            }
        }
        if data.normals.len() != data.positions.len() {
            data.normals.clear();
        }
        if data.colors.len() != data.positions.len() {
            data.colors.clear();
        }
        if data.uvs.len() != data.positions.len() {
            data.uvs.clear();
        }
        Ok(data)
    }

    /// A factor the specification bounds to [0, 1]: clamped, with a warning.
    fn unit_factor(&mut self, value: f32, at: &str) -> Result<f64, String> {
        let v = f64::from(value);
        if !v.is_finite() {
            return Err(format!("{at}: {value} is not a finite number"));
        }
        if !(0.0..=1.0).contains(&v) {
            self.warn(format!("{at}: {value} is outside [0, 1]; clamped"));
        }
        Ok(v.clamp(0.0, 1.0))
    }

    fn material(&mut self, i: usize, res: &mut Resources) -> Result<Material, String> {
        let m = &self.root.materials[i];
        let at = format!("materials[{i}]");
        let pbr = &m.pbr_metallic_roughness;
        let mut base = [0.0; 3];
        for (c, value) in base.iter_mut().enumerate() {
            *value = self.unit_factor(
                pbr.base_color_factor.0[c],
                &format!("{at}.pbrMetallicRoughness.baseColorFactor[{c}]"),
            )?;
        }
        let base = DVec3::from_array(base);
        let metallic = self.unit_factor(
            pbr.metallic_factor.0,
            &format!("{at}.pbrMetallicRoughness.metallicFactor"),
        )?;
        let roughness = self
            .unit_factor(
                pbr.roughness_factor.0,
                &format!("{at}.pbrMetallicRoughness.roughnessFactor"),
            )?
            .max(0.02);
        let texture = match &pbr.base_color_texture {
            None => Texture::Solid(base),
            Some(info) => self.texture(
                info,
                base,
                &format!("{at}.pbrMetallicRoughness.baseColorTexture"),
                res,
            )?,
        };
        for (present, feature) in [
            (m.normal_texture.is_some(), "normal maps"),
            (m.occlusion_texture.is_some(), "occlusion maps"),
            (
                pbr.metallic_roughness_texture.is_some(),
                "metallic-roughness maps",
            ),
            (
                m.alpha_mode != Checked::Valid(json::material::AlphaMode::Opaque),
                "alpha (alphaMode BLEND or MASK)",
            ),
        ] {
            if present {
                self.ignore(feature, &at);
            }
        }
        let ext = m.extensions.as_ref();
        let strength = match ext.and_then(|e| e.emissive_strength.as_ref()) {
            Some(s) => {
                let v = f64::from(s.emissive_strength.0);
                if !v.is_finite() || !(0.0..=MAX_VALUE).contains(&v) {
                    return Err(format!(
                        "{at}.extensions.KHR_materials_emissive_strength.emissiveStrength: {v} \
                         must be a finite number between 0 and {MAX_VALUE:e}"
                    ));
                }
                v
            }
            None => 1.0,
        };
        let mut emissive = [0.0; 3];
        for (c, value) in emissive.iter_mut().enumerate() {
            *value =
                self.unit_factor(m.emissive_factor.0[c], &format!("{at}.emissiveFactor[{c}]"))?;
        }
        let emissive = DVec3::from_array(emissive) * strength;
        let emission = match &m.emissive_texture {
            Some(info) if emissive != DVec3::ZERO => {
                self.texture(info, emissive, &format!("{at}.emissiveTexture"), res)?
            }
            _ => Texture::Solid(emissive),
        };
        let transmission = match ext.and_then(|e| e.transmission.as_ref()) {
            Some(t) => self.unit_factor(
                t.transmission_factor.0,
                &format!("{at}.extensions.KHR_materials_transmission.transmissionFactor"),
            )?,
            None => 0.0,
        };
        let ior = match ext.and_then(|e| e.ior.as_ref()) {
            Some(ior) => {
                let v = f64::from(ior.ior.0);
                if !v.is_finite() || !(1.0..=MAX_VALUE).contains(&v) {
                    return Err(format!(
                        "{at}.extensions.KHR_materials_ior.ior: {v} must be a finite number of at least 1"
                    ));
                }
                v
            }
            None => 1.5,
        };
        // A metal reflects its base colour (gold is gold), and transmitted
        // light is tinted by it too (KHR_materials_transmission).
        let (kr, kt) = Material::conserving(metallic * base, transmission * base);
        let alpha = roughness * roughness;
        let albedo = (1.0 - metallic) * (1.0 - transmission);
        Ok(Material {
            texture,
            // Under a uniform ambient of radiance Ia a Lambertian surface
            // returns albedo × Ia: its diffuse integrated over the sky.
            ka: albedo,
            kd: lambertian(albedo),
            // Scaled with the diffuse, so the highlight keeps its weight
            // beside it.
            ks: lambertian(1.0 - roughness),
            shininess: (2.0 / (alpha * alpha) - 2.0).clamp(1.0, 10_000.0),
            kr,
            kt,
            ior,
            fresnel: if transmission > 0.0 {
                Fresnel::Exact
            } else {
                Fresnel::Off
            },
            highlight: Highlight::Blinn,
            emission,
            // A metal's reflection and the transmitted light spread over
            // glTF's roughness (the same perceptual roughness, GGX α = r²).
            roughness: if kr == DVec3::ZERO && kt == DVec3::ZERO {
                0.0
            } else {
                roughness
            },
            glossy_samples: 16,
        })
    }

    /// Notes a feature the file uses that Prism does not render, and where.
    fn ignore(&mut self, feature: &str, at: &str) {
        let places = self.ignored.entry(feature.to_string()).or_default();
        if !places.iter().any(|p| p == at) {
            places.push(at.to_string());
        }
    }

    /// The channels of the file's first animation (the clip a viewer plays:
    /// the others are named as ignored) that drive the translation,
    /// rotation or scale of a node in `reachable`, by node. Each sampler is
    /// read and checked once however many channels use it (times finite
    /// and increasing, as many values as its interpolation needs, every
    /// value finite), and the keys read in all are bounded by
    /// [`MAX_ANIMATION_KEYS`]. Morph target weights, channels of unknown
    /// paths and channels whose keys lie in accessors Prism does not read
    /// (sparse, or without a bufferView) are noted as ignored, and so is a
    /// second channel on a property another already drives (the first in
    /// file order plays); channels on nodes the scene does not reach are
    /// not read.
    fn animations(&mut self, reachable: &[bool]) -> Result<HashMap<usize, NodeAnimation>, String> {
        use json::animation::{Interpolation as Json, Property};
        let root = self.root;
        let mut out: HashMap<usize, NodeAnimation> = HashMap::new();
        for a in 1..root.animations.len() {
            self.ignore(
                "animations after the first (Prism plays animations[0], the clip a viewer shows)",
                &format!("animations[{a}]"),
            );
        }
        let Some(animation) = root.animations.first() else {
            return Ok(out);
        };
        // (input accessor, output accessor, interpolation, rotation) → the
        // sampler those keys make.
        let mut read: HashMap<(usize, usize, Interpolation, bool), Arc<Sampler>> = HashMap::new();
        let mut keys: u64 = 0;
        for (c, channel) in animation.channels.iter().enumerate() {
            let at = format!("animations[0].channels[{c}]");
            let (slot, rotation) = match channel.target.path {
                Checked::Valid(Property::Translation) => (0, false),
                Checked::Valid(Property::Rotation) => (1, true),
                Checked::Valid(Property::Scale) => (2, false),
                Checked::Valid(Property::MorphTargetWeights) => {
                    self.ignore("morph target weight animations", &at);
                    continue;
                }
                Checked::Invalid => {
                    self.ignore("animation channels of unknown paths", &at);
                    continue;
                }
            };
            let n = channel.target.node.value();
            let node = lookup(&root.nodes, n, &format!("{at}.target.node"), "node")?;
            if !reachable.get(n).copied().unwrap_or(false) {
                // Outside the scene: it moves nothing Prism renders.
                continue;
            }
            if node.matrix.is_some() {
                return Err(format!(
                    "{at}.target.node: nodes[{n}] has a `matrix`, which animations cannot \
                     drive (the glTF specification animates translation, rotation and scale \
                     only)"
                ));
            }
            let s = channel.sampler.value();
            let sampler = lookup(&animation.samplers, s, &format!("{at}.sampler"), "sampler")?;
            let sat = format!("animations[0].samplers[{s}]");
            let interpolation = match sampler.interpolation {
                Checked::Valid(Json::Linear) => Interpolation::Linear,
                Checked::Valid(Json::Step) => Interpolation::Step,
                Checked::Valid(Json::CubicSpline) => Interpolation::CubicSpline,
                Checked::Invalid => {
                    return Err(format!(
                        "{sat}.interpolation: unknown; expected LINEAR, STEP or CUBICSPLINE"
                    ));
                }
            };
            let (i, o) = (sampler.input.value(), sampler.output.value());
            let mut unsupported = false;
            for (index, end) in [(i, "input"), (o, "output")] {
                let accessor = lookup(&root.accessors, index, &format!("{sat}.{end}"), "accessor")?;
                unsupported |= accessor.sparse.is_some() || accessor.buffer_view.is_none();
            }
            if unsupported {
                self.ignore(
                    "animation channels whose keys are in a sparse accessor or one without a \
                     bufferView",
                    &at,
                );
                continue;
            }
            let key = (i, o, interpolation, rotation);
            let sampler = match read.get(&key) {
                Some(sampler) => sampler.clone(),
                None => {
                    let input = self.elements(sampler.input, &format!("{sat}.input"), &TIMES)?;
                    let expect = if rotation { &ROTATIONS } else { &VECTORS };
                    let output = self.elements(sampler.output, &format!("{sat}.output"), expect)?;
                    // Counted before anything is read: accessors may
                    // all alias the same bytes.
                    keys = keys
                        .saturating_add(input.count as u64)
                        .saturating_add(output.count as u64);
                    if keys > MAX_ANIMATION_KEYS {
                        return Err(format!(
                            "{sat}: its {} key times and {} values bring the animation's keys \
                             to {keys}, more than the limit of {MAX_ANIMATION_KEYS} (key times \
                             and values of all its samplers together)",
                            input.count, output.count
                        ));
                    }
                    let times = (0..input.count).map(|i| input.get(i, 0)).collect();
                    let values = (0..output.count)
                        .map(|i| {
                            let w = if rotation { output.get(i, 3) } else { 0.0 };
                            DVec4::new(output.get(i, 0), output.get(i, 1), output.get(i, 2), w)
                        })
                        .collect();
                    let sampler = Arc::new(
                        Sampler::new(times, values, interpolation, rotation)
                            .map_err(|e| format!("{sat}.{e}"))?,
                    );
                    read.insert(key, sampler.clone());
                    sampler
                }
            };
            let channels = &mut out.entry(n).or_default().channels;
            if channels[slot].is_some() {
                self.ignore(
                    "animation channels on a property another channel already drives",
                    &at,
                );
            } else {
                channels[slot] = Some(sampler);
            }
        }
        Ok(out)
    }

    /// The texture `info` refers to, times `tint`, read through its
    /// sampler and KHR_texture_transform.
    fn texture(
        &mut self,
        info: &json::texture::Info,
        tint: DVec3,
        at: &str,
        res: &mut Resources,
    ) -> Result<Texture, String> {
        let image = self.image(info.index.value(), at, res)?;
        let mut sampling = Sampling::default();
        let mut tex_coord = info.tex_coord;
        if let Some(t) = info
            .extensions
            .as_ref()
            .and_then(|e| e.texture_transform.as_ref())
        {
            let finite = |v: &[f32]| v.iter().all(|x| x.is_finite() && x.abs() <= 1e15);
            if !finite(&t.offset.0) || !finite(&t.scale.0) || !finite(&[t.rotation.0]) {
                return Err(format!(
                    "{at}.extensions.KHR_texture_transform: offset, rotation and scale must be finite numbers"
                ));
            }
            sampling.transform = texture_transform(
                DVec2::from_array(t.offset.0.map(f64::from)),
                f64::from(t.rotation.0),
                DVec2::from_array(t.scale.0.map(f64::from)),
            );
            tex_coord = t.tex_coord.unwrap_or(tex_coord);
        }
        if tex_coord != 0 {
            self.ignore("texture coordinate sets other than TEXCOORD_0", at);
        }
        let texture = lookup(
            &self.root.textures,
            info.index.value(),
            &format!("{at}.index"),
            "texture",
        )?;
        if let Some(s) = texture.sampler {
            let t = info.index.value();
            let sampler = lookup(
                &self.root.samplers,
                s.value(),
                &format!("textures[{t}].sampler"),
                "sampler",
            )?;
            use json::texture::{MagFilter, WrappingMode};
            sampling.nearest = sampler.mag_filter == Some(Checked::Valid(MagFilter::Nearest));
            let wrap = |w: &Checked<WrappingMode>| match w {
                Checked::Valid(WrappingMode::ClampToEdge) => Wrap::Clamp,
                Checked::Valid(WrappingMode::MirroredRepeat) => Wrap::Mirror,
                _ => Wrap::Repeat,
            };
            sampling.wrap = [wrap(&sampler.wrap_s), wrap(&sampler.wrap_t)];
        }
        Ok(if sampling == Sampling::default() {
            Texture::Image { image, tint }
        } else {
            Texture::Sampled {
                image,
                tint,
                sampling,
            }
        })
    }

    /// Texture `t`'s image, decoded once per scene within the budget.
    fn image(
        &self,
        t: usize,
        at: &str,
        res: &mut Resources,
    ) -> Result<Arc<crate::shading::texture::ImageTexture>, String> {
        let root = self.root;
        let texture = lookup(&root.textures, t, &format!("{at}.index"), "texture")?;
        let i = texture.source.value();
        let image = lookup(&root.images, i, &format!("textures[{t}].source"), "image")?;
        let at = format!("images[{i}]");
        let failed = |e: String| format!("{at}: {e}");
        let model = res.policy.check(self.file).map_err(failed)?;
        match (&image.uri, image.buffer_view) {
            (Some(uri), _) if !uri.starts_with("data:") => {
                let decoded = urlencoding::decode(uri.strip_prefix("file://").unwrap_or(uri))
                    .map_err(|e| failed(format!("bad URI: {e}")))?;
                let file = self
                    .file
                    .parent()
                    .unwrap_or(Path::new("."))
                    .join(decoded.as_ref());
                res.texture_file(&file)
                    .map_err(|e| failed(format!("{}: {e}", file.display())))
            }
            (Some(uri), _) => {
                let dir = self.file.parent().unwrap_or(Path::new("."));
                let bytes = read_uri(uri, dir, res, None).map_err(failed)?;
                res.texture_bytes_of(TextureKey::Embedded(model, i), &bytes)
                    .map_err(failed)
            }
            (None, Some(view)) => {
                let bytes = self.view_bytes(view.value()).map_err(failed)?;
                res.texture_bytes_of(TextureKey::Embedded(model, i), bytes)
                    .map_err(failed)
            }
            (None, None) => Err(failed("has neither uri nor bufferView".into())),
        }
    }

    /// Camera `c` of node `node`, placed by `world`.
    fn camera(
        &mut self,
        node: usize,
        c: usize,
        world: &DMat4,
    ) -> Result<Option<ModelCamera>, String> {
        let camera = self.root.cameras.get(c).ok_or_else(|| {
            format!(
                "nodes[{node}].camera: camera {c} does not exist ({} cameras)",
                self.root.cameras.len()
            )
        })?;
        let positive = |v: f32, at: &str| -> Result<f64, String> {
            let v = f64::from(v);
            if v.is_finite() && v > 0.0 && v <= MAX_VALUE {
                Ok(v)
            } else {
                Err(format!(
                    "cameras[{c}].{at}: {v}; expected a positive number"
                ))
            }
        };
        let (projection, aspect_ratio) = match (&camera.perspective, &camera.orthographic) {
            (Some(p), _) => {
                let yfov = f64::from(p.yfov);
                if !(yfov > 0.0 && yfov < std::f64::consts::PI) {
                    return Err(format!(
                        "cameras[{c}].perspective.yfov: {yfov} rad; expected a field of view between 0 and π"
                    ));
                }
                let aspect = match p.aspect_ratio {
                    Some(a) => Some(positive(a, "perspective.aspectRatio")?),
                    None => None,
                };
                (ModelProjection::Perspective { yfov }, aspect)
            }
            (None, Some(o)) => {
                let ymag = positive(o.ymag, "orthographic.ymag")?;
                let xmag = positive(o.xmag, "orthographic.xmag")?;
                (ModelProjection::Orthographic { ymag }, Some(xmag / ymag))
            }
            (None, None) => {
                return Err(format!(
                    "cameras[{c}]: neither perspective nor orthographic"
                ));
            }
        };
        let forward = world.transform_vector3(-DVec3::Z).normalize_or_zero();
        let up = world.transform_vector3(DVec3::Y).normalize_or_zero();
        if forward == DVec3::ZERO || up == DVec3::ZERO {
            return Err(format!("nodes[{node}]: the camera's transform is singular"));
        }
        let node_name = self.root.nodes[node].name.clone();
        let own = camera.name.clone();
        Ok(Some(ModelCamera {
            name: node_name
                .clone()
                .or_else(|| own.clone())
                .unwrap_or_else(|| format!("cameras[{c}]")),
            alias: own.filter(|_| node_name.is_some()),
            aspect_ratio,
            projection,
            position: world.transform_point3(DVec3::ZERO),
            forward,
            up,
        }))
    }

    /// A KHR_lights_punctual light, placed by `world`.
    fn light(&mut self, node: usize, l: usize, world: &DMat4) -> Result<Light, String> {
        let lights = self
            .root
            .extensions
            .as_ref()
            .and_then(|e| e.khr_lights_punctual.as_ref())
            .map_or(&[][..], |k| &k.lights[..]);
        let light = lights.get(l).ok_or_else(|| {
            format!(
                "nodes[{node}].extensions.KHR_lights_punctual.light: light {l} does not exist ({} lights)",
                lights.len()
            )
        })?;
        let at = format!("extensions.KHR_lights_punctual.lights[{l}]");
        let mut color = [0.0; 3];
        for (c, value) in color.iter_mut().enumerate() {
            *value = self.unit_factor(light.color[c], &format!("{at}.color[{c}]"))?;
        }
        let intensity = f64::from(light.intensity);
        if !intensity.is_finite() || !(0.0..=MAX_VALUE).contains(&intensity) {
            return Err(format!(
                "{at}.intensity: {} must be a finite number between 0 and {MAX_VALUE:e}",
                light.intensity
            ));
        }
        let position = world.transform_point3(DVec3::ZERO);
        let shape = match light.type_ {
            Checked::Valid(json::extensions::scene::khr_lights_punctual::Type::Directional) => {
                LightShape::Directional {
                    direction: world.transform_vector3(-DVec3::Z).normalize_or_zero(),
                }
            }
            Checked::Valid(json::extensions::scene::khr_lights_punctual::Type::Point) => {
                LightShape::Point { position }
            }
            Checked::Valid(json::extensions::scene::khr_lights_punctual::Type::Spot) => {
                let Some(spot) = light.spot.as_ref() else {
                    return Err(format!("{at}: a spot light needs `spot`"));
                };
                let (inner, outer) = (
                    f64::from(spot.inner_cone_angle),
                    f64::from(spot.outer_cone_angle),
                );
                if !(0.0..=std::f64::consts::FRAC_PI_2).contains(&outer)
                    || !(0.0..=outer).contains(&inner)
                {
                    return Err(format!(
                        "{at}.spot: innerConeAngle {inner} and outerConeAngle {outer} rad; \
                         expected 0 ≤ inner ≤ outer ≤ π/2"
                    ));
                }
                if inner == outer {
                    // The specification asks for inner < outer; the edge
                    // is then a hard cut, which is what is drawn.
                    self.warn(format!(
                        "{at}.spot: innerConeAngle equals outerConeAngle ({inner} rad), which \
                         the glTF specification does not allow (inner < outer); the pool has a \
                         hard edge"
                    ));
                }
                LightShape::Spot {
                    position,
                    direction: world.transform_vector3(-DVec3::Z).normalize_or_zero(),
                    cos_inner: crate::math::transcendental::sin_cos(inner).1,
                    cos_outer: crate::math::transcendental::sin_cos(outer).1,
                    cone: SpotCone::Gltf,
                }
            }
            Checked::Invalid => return Err(format!("{at}.type: unknown light type")),
        };
        if matches!(shape, LightShape::Directional { direction } | LightShape::Spot { direction, .. } if direction == DVec3::ZERO)
        {
            return Err(format!("nodes[{node}]: the light's transform is singular"));
        }
        Ok(Light {
            inverse_square: !matches!(shape, LightShape::Directional { .. }),
            shape,
            radiance: DVec3::from_array(color) * photometric_to_radiometric(intensity),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blender_lights_convert_to_what_cycles_shows() {
        // Blender's exporter writes a 100 W point light as
        // 100 / (4π) × 683 cd. Over an albedo-0.8 plane 4 m below, Cycles
        // shows 0.1266: 0.8/π × (100/(4π)) / 4².
        let candela = 100.0 / (4.0 * std::f64::consts::PI) * 683.0;
        let il = photometric_to_radiometric(candela);
        assert!((il - 7.957_747).abs() < 1e-6, "{il}");
        let radiance = lambertian(0.8) * il / 16.0;
        assert!((radiance - 0.126_651).abs() < 1e-6, "{radiance}");
        // A 1 W/m² sun is 683 lux; straight down on the plane: 0.8/π.
        let sun = lambertian(0.8) * photometric_to_radiometric(683.0);
        assert!((sun - 0.254_648).abs() < 1e-6, "{sun}");
        // The old reading (candela as Il, no 1/π) was 683π times brighter.
        let old = 0.8 * candela / 16.0;
        assert!((old / radiance - 683.0 * std::f64::consts::PI).abs() < 1e-6);
    }

    fn graph(children: &[&[usize]]) -> NodeGraph {
        NodeGraph {
            children: children.iter().map(|c| c.to_vec()).collect(),
        }
    }

    #[test]
    fn cycles_are_named() {
        let e = graph(&[&[1], &[2], &[0]]).check_acyclic().unwrap_err();
        assert!(e.contains("0 → 1 → 2 → 0"), "{e}");
        assert!(graph(&[&[1, 2], &[2], &[]]).check_acyclic().is_ok());
    }

    #[test]
    fn shared_children_are_counted_without_expanding() {
        // 64 levels, each node pointing twice at the next: 2^64 − 1 paths,
        // counted (saturating) in linear time.
        let levels: Vec<Vec<usize>> = (0..64)
            .map(|i| if i < 63 { vec![i + 1, i + 1] } else { vec![] })
            .collect();
        let g = NodeGraph { children: levels };
        assert_eq!(g.instances(&[0]).unwrap(), u64::MAX);
        let small = graph(&[&[1, 1], &[2], &[]]);
        // 0, then 1 twice, each with 2: 1 + 2·2 = 5.
        assert_eq!(small.instances(&[0]).unwrap(), 5);
        assert!(small.instances(&[7]).is_err());
    }

    #[test]
    fn glb_lengths_are_checked_against_the_bytes() {
        let mut glb = Vec::new();
        glb.extend(b"glTF");
        glb.extend(2u32.to_le_bytes());
        glb.extend(0u32.to_le_bytes());
        assert!(split_glb(&glb).unwrap_err().contains("header says 0 bytes"));
        let json = b"{}  ";
        let mut good = Vec::new();
        good.extend(b"glTF");
        good.extend(2u32.to_le_bytes());
        good.extend((12 + 8 + json.len() as u32).to_le_bytes());
        good.extend((json.len() as u32).to_le_bytes());
        good.extend(b"JSON");
        good.extend(json);
        assert_eq!(split_glb(&good).unwrap(), (&json[..], None));
        // A chunk length of 0xFFFFFFFF is refused, not allocated.
        let mut huge = good.clone();
        huge[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(split_glb(&huge).unwrap_err().contains("past the end"));
    }
}
