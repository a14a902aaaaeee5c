//! Wavefront OBJ + MTL through tobj, with a line-by-line pre-check so that
//! the usual mistakes (faces pointing past the vertex list, coordinates
//! that are not numbers) are reported with their line.
//!
//! MTL to Whitted mapping (also in docs/scene-format.md):
//! Od = Kd (times map_Kd), kd = 1, ka = max(Ka), ks = max(Ks), shininess =
//! Ns; illum 0: ambient colour only; 1: no highlight; 2: highlight;
//! 3: + mirror reflection kr = max(Ks); 4, 6, 7: + transparency
//! kt = 1 − d (or max(Tf)), ior = Ni; 5, 7: Fresnel. kr + kt is scaled down
//! to 1 if it exceeds it.

use std::path::Path;

use glam::{DVec2, DVec3};

use super::{Model, ModelError};
use crate::geometry::MeshData;
use crate::shading::texture::ImageTexture;
use crate::shading::{Fresnel, Highlight, Material, Texture};

pub fn load(path: &Path) -> Result<Model, ModelError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| ModelError::new(path, None, format!("cannot read: {e}")))?;
    precheck(&text).map_err(|(line, message)| ModelError::new(path, Some(line), message))?;
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ..Default::default()
    };
    let (models, materials) = tobj::load_obj(path, &options)
        .map_err(|e| ModelError::new(path, None, format!("cannot load: {e}")))?;
    let mut warnings = Vec::new();
    let dir = path.parent().unwrap_or(Path::new("."));
    let mtl = match materials {
        Ok(m) => m,
        Err(e) => {
            warnings.push(format!(
                "{}: material library not loaded ({e}); using the default material",
                path.display()
            ));
            Vec::new()
        }
    };
    let mut materials = mtl
        .iter()
        .map(|m| material(m, dir, path, &mut warnings))
        .collect::<Result<Vec<_>, _>>()?;
    // Triangles without a material use a plain grey one after the file's.
    let default_slot = materials.len() as u32;
    let mut mesh = MeshData::default();
    let mut needs_default = false;
    for model in &models {
        let m = &model.mesh;
        let base = mesh.positions.len() as u32;
        let count = m.positions.len() / 3;
        mesh.positions.extend(
            m.positions
                .chunks_exact(3)
                .map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)),
        );
        let all_have = |len: usize, per: usize| len == count * per && count > 0;
        if all_have(m.normals.len(), 3) {
            mesh.normals.extend(
                m.normals
                    .chunks_exact(3)
                    .map(|n| DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64)),
            );
        }
        if all_have(m.texcoords.len(), 2) {
            mesh.uvs.extend(
                m.texcoords
                    .chunks_exact(2)
                    .map(|t| DVec2::new(t[0] as f64, t[1] as f64)),
            );
        }
        let slot = match m.material_id {
            Some(id) if id < materials.len() => id as u32,
            _ => {
                needs_default = true;
                default_slot
            }
        };
        for t in m.indices.chunks_exact(3) {
            mesh.triangles.push([base + t[0], base + t[1], base + t[2]]);
            mesh.materials.push(slot);
        }
    }
    // Normals or uvs only on some parts of the file: drop them everywhere.
    if mesh.normals.len() != mesh.positions.len() {
        if !mesh.normals.is_empty() {
            warnings.push(format!(
                "{}: normals given for part of the model only; shading it flat",
                path.display()
            ));
        }
        mesh.normals.clear();
    }
    if mesh.uvs.len() != mesh.positions.len() {
        mesh.uvs.clear();
    }
    if needs_default {
        materials.push(Material::default());
    }
    Ok(Model::single(mesh, materials, warnings))
}

/// Checks `v` and `f` lines: numbers that parse and are finite, face
/// indices (1-based, or negative = relative) within the vertices defined so
/// far. Returns the 1-based line and the problem.
fn precheck(text: &str) -> Result<(), (usize, String)> {
    let (mut v, mut vt, mut vn) = (0i64, 0i64, 0i64);
    for (i, line) in text.lines().enumerate() {
        let line_no = i + 1;
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let coords: Vec<&str> = words.collect();
                if coords.len() < 3 {
                    return Err((
                        line_no,
                        format!("a vertex needs 3 coordinates, got {}", coords.len()),
                    ));
                }
                for c in &coords[..3] {
                    match c.parse::<f64>() {
                        Ok(x) if x.is_finite() => {}
                        _ => {
                            return Err((
                                line_no,
                                format!("vertex coordinate `{c}` is not a finite number"),
                            ));
                        }
                    }
                }
                v += 1;
            }
            Some("vt") => vt += 1,
            Some("vn") => vn += 1,
            Some("f") => {
                let corners: Vec<&str> = words.collect();
                if corners.len() < 3 {
                    return Err((
                        line_no,
                        format!("a face needs at least 3 vertices, got {}", corners.len()),
                    ));
                }
                for corner in corners {
                    for (k, (part, count, what)) in corner
                        .split('/')
                        .zip([(v, "vertex"), (vt, "texture coordinate"), (vn, "normal")])
                        .map(|(p, (c, w))| (p, c, w))
                        .enumerate()
                    {
                        if part.is_empty() && k > 0 {
                            continue;
                        }
                        let Ok(index) = part.parse::<i64>() else {
                            return Err((
                                line_no,
                                format!("face index `{part}` is not an integer"),
                            ));
                        };
                        let resolved = if index < 0 { count + index + 1 } else { index };
                        if index == 0 || resolved < 1 || resolved > count {
                            return Err((
                                line_no,
                                format!(
                                    "face refers to {what} {index}, but only {count} are defined before this line"
                                ),
                            ));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// One MTL material as a Whitted material (see the module comment).
fn material(
    m: &tobj::Material,
    dir: &Path,
    obj: &Path,
    warnings: &mut Vec<String>,
) -> Result<Material, ModelError> {
    let rgb = |c: Option<[f32; 3]>| c.map(|c| DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64));
    let kd_color = rgb(m.diffuse).unwrap_or(DVec3::splat(0.8));
    let ka = rgb(m.ambient).map_or(0.1, |c| c.max_element());
    let ks = rgb(m.specular).map_or(0.0, |c| c.max_element());
    let illum = m.illumination_model.unwrap_or(2);
    let dissolve = m
        .dissolve
        .map(f64::from)
        .or_else(|| {
            m.unknown_param
                .get("Tr")
                .and_then(|t| t.trim().parse::<f64>().ok())
                .map(|tr| 1.0 - tr)
        })
        .unwrap_or(1.0);
    let tf = m.unknown_param.get("Tf").and_then(|t| {
        let v: Vec<f64> = t
            .split_whitespace()
            .filter_map(|x| x.parse().ok())
            .collect();
        v.iter().copied().reduce(f64::max)
    });
    let transparent = matches!(illum, 4 | 6 | 7);
    let mut kr = if matches!(illum, 3..=7) { ks } else { 0.0 };
    let mut kt = if transparent {
        tf.unwrap_or(1.0 - dissolve).clamp(0.0, 1.0)
    } else {
        0.0
    };
    if kr + kt > 1.0 {
        let s = 1.0 / (kr + kt);
        kr *= s;
        kt *= s;
    }
    let texture = match &m.diffuse_texture {
        None => Texture::Solid(kd_color),
        Some(file) => {
            let image_path = dir.join(file.trim());
            let image = ImageTexture::load(&image_path).map_err(|e| {
                ModelError::new(
                    obj,
                    None,
                    format!(
                        "material `{}`: texture {}: {e}",
                        m.name,
                        image_path.display()
                    ),
                )
            })?;
            Texture::Image {
                image: std::sync::Arc::new(image),
                tint: kd_color,
            }
        }
    };
    if m.normal_texture.is_some() || m.specular_texture.is_some() {
        warnings.push(format!(
            "{}: material `{}`: only map_Kd is used; other maps ignored",
            obj.display(),
            m.name
        ));
    }
    Ok(Material {
        texture,
        ka: if illum == 0 { 1.0 } else { ka },
        kd: if illum == 0 { 0.0 } else { 1.0 },
        ks: if illum >= 2 { ks } else { 0.0 },
        shininess: m.shininess.map_or(32.0, f64::from),
        kr,
        kt,
        ior: m.optical_density.map_or(1.0, f64::from).max(1e-3),
        fresnel: if matches!(illum, 5 | 7) {
            Fresnel::Exact
        } else {
            Fresnel::Off
        },
        highlight: Highlight::Phong,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn precheck_locates_bad_faces_and_numbers() {
        let ok = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf -3 -2 -1\n";
        assert_eq!(precheck(ok), Ok(()));
        let past = "v 0 0 0\nv 1 0 0\nv 0 1 0\n# comment\nf 1 2 4\n";
        let (line, msg) = precheck(past).unwrap_err();
        assert_eq!(line, 5);
        assert!(msg.contains("vertex 4, but only 3"), "{msg}");
        let nan = "v 0 0 0\nv 1 nan 0\n";
        assert_eq!(precheck(nan).unwrap_err().0, 2);
        let normal = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//2 3//1\n";
        assert!(precheck(normal).unwrap_err().1.contains("normal 2"));
    }
}
