//! glTF 2.0 (.gltf and .glb) through the gltf crate: the meshes of the
//! default scene, each stored once and placed by every node that uses it
//! (with the node's world transform), the first camera,
//! KHR_lights_punctual lights, and materials mapped onto the Whitted model
//! (see docs/scene-format.md):
//! Od = baseColorFactor × baseColorTexture, kd = 1 − metallic,
//! kr = metallic, ks = 1 − roughness with a Blinn exponent 2/α² − 2
//! (α = roughness²), kt = KHR_materials_transmission, ior =
//! KHR_materials_ior (1.5 by default). What is not mapped is named in a
//! warning.

use std::path::Path;
use std::sync::Arc;

use glam::{DMat3, DMat4, DVec2, DVec3};

use super::{Model, ModelCamera, ModelError};
use crate::geometry::MeshData;
use crate::lights::{Light, LightShape};
use crate::shading::texture::ImageTexture;
use crate::shading::{Fresnel, Highlight, Material, Texture};

const SUPPORTED: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_materials_transmission",
    "KHR_materials_ior",
];

pub fn load(path: &Path) -> Result<Model, ModelError> {
    let err = |message: String| ModelError::new(path, None, message);
    let parsed = gltf::Gltf::open(path).map_err(|e| err(format!("cannot read glTF: {e}")))?;
    if let Some(ext) = parsed
        .extensions_required()
        .find(|e| !SUPPORTED.contains(e))
    {
        return Err(err(format!(
            "requires the extension `{ext}`, which Prism does not support"
        )));
    }
    let (doc, buffers, images) =
        gltf::import(path).map_err(|e| err(format!("cannot load glTF: {e}")))?;
    let mut warnings = Vec::new();
    let mut warn = |w: String| {
        let w = format!("{}: {w}", path.display());
        if !warnings.contains(&w) {
            warnings.push(w);
        }
    };
    let mut materials = Vec::new();
    for (i, m) in doc.materials().enumerate() {
        materials
            .push(material(&m, &images, &mut warn).map_err(|e| err(format!("material {i}: {e}")))?);
    }
    let default_slot = materials.len() as u32;
    let mut needs_default = false;
    // glTF mesh index → index into model.meshes: a mesh used by several
    // nodes is read and stored once.
    let mut mesh_slots = std::collections::HashMap::new();
    let mut model = Model {
        meshes: Vec::new(),
        placements: Vec::new(),
        materials: Vec::new(),
        warnings: Vec::new(),
        lights: Vec::new(),
        camera: None,
    };
    let Some(scene) = doc.default_scene().or_else(|| doc.scenes().next()) else {
        return Err(err("the file has no scene".into()));
    };
    let mut stack: Vec<(gltf::Node, DMat4)> = scene.nodes().map(|n| (n, DMat4::IDENTITY)).collect();
    while let Some((node, parent)) = stack.pop() {
        let local = DMat4::from_cols_array_2d(&node.transform().matrix().map(|c| c.map(f64::from)));
        let world = parent * local;
        stack.extend(node.children().map(|c| (c, world)));
        if let Some(camera) = node.camera() {
            match camera.projection() {
                gltf::camera::Projection::Perspective(p) if model.camera.is_none() => {
                    model.camera = Some(ModelCamera {
                        position: world.transform_point3(DVec3::ZERO),
                        forward: world.transform_vector3(-DVec3::Z).normalize(),
                        up: world.transform_vector3(DVec3::Y).normalize(),
                        yfov: f64::from(p.yfov()),
                    })
                }
                gltf::camera::Projection::Orthographic(_) => {
                    warn("orthographic cameras are ignored".into())
                }
                _ => {}
            }
        }
        if let Some(light) = node.light() {
            let color = DVec3::from_array(light.color().map(f64::from));
            let radiance = color * f64::from(light.intensity());
            let position = world.transform_point3(DVec3::ZERO);
            let shape = match light.kind() {
                gltf::khr_lights_punctual::Kind::Directional => LightShape::Directional {
                    direction: world.transform_vector3(-DVec3::Z).normalize(),
                },
                gltf::khr_lights_punctual::Kind::Point => LightShape::Point { position },
                gltf::khr_lights_punctual::Kind::Spot { .. } => {
                    warn("spot lights become point lights (the cone is ignored)".into());
                    LightShape::Point { position }
                }
            };
            model.lights.push(Light {
                inverse_square: !matches!(shape, LightShape::Directional { .. }),
                shape,
                radiance,
            });
        }
        let Some(mesh) = node.mesh() else { continue };
        if DMat3::from_mat4(world).determinant().abs() < 1e-12 {
            return Err(err(format!(
                "node {}: its transform is singular",
                node.index()
            )));
        }
        let index = match mesh_slots.get(&mesh.index()) {
            Some(&i) => i,
            None => {
                let data = read_mesh(&mesh, &buffers, default_slot, &mut needs_default, &mut warn)
                    .map_err(err)?;
                model.meshes.push(data);
                mesh_slots.insert(mesh.index(), model.meshes.len() - 1);
                model.meshes.len() - 1
            }
        };
        model.placements.push((index, world));
    }
    if needs_default {
        materials.push(Material::default());
    }
    model.materials = materials;
    model.warnings = warnings;
    Ok(model)
}

/// One glTF mesh (all its triangle primitives) in its own space.
fn read_mesh(
    mesh: &gltf::Mesh,
    buffers: &[gltf::buffer::Data],
    default_slot: u32,
    needs_default: &mut bool,
    warn: &mut impl FnMut(String),
) -> Result<MeshData, String> {
    let mut data = MeshData::default();
    for (p, primitive) in mesh.primitives().enumerate() {
        if primitive.mode() != gltf::mesh::Mode::Triangles {
            warn(format!(
                "mesh {}: primitive {p} is not triangles; skipped",
                mesh.index()
            ));
            continue;
        }
        let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
        let Some(positions) = reader.read_positions() else {
            return Err(format!(
                "mesh {} primitive {p} has no positions",
                mesh.index()
            ));
        };
        let base = data.positions.len() as u32;
        let before = data.positions.len();
        data.positions
            .extend(positions.map(|v| DVec3::from_array(v.map(f64::from))));
        let count = data.positions.len() - before;
        // Normals and uvs must cover every vertex of the mesh or none.
        match reader.read_normals() {
            Some(n) if data.normals.len() == before => data
                .normals
                .extend(n.map(|v| DVec3::from_array(v.map(f64::from)))),
            _ => data.normals.clear(),
        }
        match reader.read_tex_coords(0) {
            // glTF's v runs down the image; Prism's runs up.
            Some(t) if data.uvs.len() == before => data.uvs.extend(
                t.into_f32()
                    .map(|[u, v]| DVec2::new(f64::from(u), 1.0 - f64::from(v))),
            ),
            _ => data.uvs.clear(),
        }
        let indices: Vec<u32> = match reader.read_indices() {
            Some(i) => i.into_u32().collect(),
            None => (0..count as u32).collect(),
        };
        if let Some(&bad) = indices.iter().find(|&&i| i as usize >= count) {
            return Err(format!(
                "mesh {} primitive {p}: index {bad} past its {count} vertices",
                mesh.index()
            ));
        }
        let slot = match primitive.material().index() {
            Some(i) => i as u32,
            None => {
                *needs_default = true;
                default_slot
            }
        };
        for t in indices.chunks_exact(3) {
            data.triangles.push([base + t[0], base + t[1], base + t[2]]);
            data.materials.push(slot);
        }
    }
    if data.normals.len() != data.positions.len() {
        data.normals.clear();
    }
    if data.uvs.len() != data.positions.len() {
        data.uvs.clear();
    }
    Ok(data)
}

fn material(
    m: &gltf::Material,
    images: &[gltf::image::Data],
    warn: &mut impl FnMut(String),
) -> Result<Material, String> {
    let pbr = m.pbr_metallic_roughness();
    let [r, g, b, _] = pbr.base_color_factor().map(f64::from);
    let base = DVec3::new(r, g, b);
    let metallic = f64::from(pbr.metallic_factor());
    let roughness = f64::from(pbr.roughness_factor()).clamp(0.02, 1.0);
    let texture = match pbr.base_color_texture() {
        None => Texture::Solid(base),
        Some(info) => {
            let index = info.texture().source().index();
            let data = images
                .get(index)
                .ok_or(format!("image {index} is missing"))?;
            let channels = match data.format {
                gltf::image::Format::R8G8B8 => 3,
                gltf::image::Format::R8G8B8A8 => 4,
                other => return Err(format!("image {index}: unsupported pixel format {other:?}")),
            };
            let image = ImageTexture::from_srgb8(
                data.width as usize,
                data.height as usize,
                &data.pixels,
                channels,
            );
            Texture::Image {
                image: Arc::new(image),
                tint: base,
            }
        }
    };
    if m.normal_texture().is_some()
        || m.occlusion_texture().is_some()
        || m.emissive_texture().is_some()
        || pbr.metallic_roughness_texture().is_some()
    {
        warn("only base colour textures are used; normal, occlusion, emissive and metallic-roughness maps are ignored".into());
    }
    let mut kr = metallic;
    let mut kt = m
        .transmission()
        .map_or(0.0, |t| f64::from(t.transmission_factor()));
    if kr + kt > 1.0 {
        let s = 1.0 / (kr + kt);
        kr *= s;
        kt *= s;
    }
    let alpha = roughness * roughness;
    Ok(Material {
        texture,
        ka: 0.1,
        kd: (1.0 - metallic) * (1.0 - kt),
        ks: 1.0 - roughness,
        shininess: (2.0 / (alpha * alpha) - 2.0).clamp(1.0, 10_000.0),
        kr,
        kt,
        ior: m.ior().map_or(1.5, f64::from),
        fresnel: if kt > 0.0 {
            Fresnel::Exact
        } else {
            Fresnel::Off
        },
        highlight: Highlight::Blinn,
    })
}
