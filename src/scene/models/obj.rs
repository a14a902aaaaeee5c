//! Wavefront OBJ + MTL through tobj, with a line-by-line pre-check so that
//! the usual mistakes (faces pointing past the vertex list, coordinates
//! that are not numbers) are reported with their line.
//!
//! MTL to Whitted mapping (also in docs/scene-format.md):
//! Od = Kd (times map_Kd), kd = 1, ka = max(Ka), ks = max(Ks), shininess =
//! Ns; illum 0: ambient colour only; 1: no highlight; 2: highlight;
//! 3: + mirror reflection kr = Ks (a colour: tinted metals); 4, 6, 7: and
//! transparency kt = Tf (a colour) or else 1 − d, ior = Ni; 5, 7: Fresnel.
//! kr + kt is scaled down so that no channel exceeds 1.

use std::cell::RefCell;
use std::path::Path;

use glam::{DVec2, DVec3};

use super::{Model, ModelError, cut};
use crate::geometry::MeshData;
use crate::limits::MAX_VALUE;
use crate::scene::resources::Resources;
use crate::shading::{Fresnel, Highlight, Material, Texture};

pub fn load(path: &Path, res: &mut Resources) -> Result<Model, ModelError> {
    let bytes = res
        .policy
        .read(path)
        .map_err(|e| ModelError::new(path, None, e))?;
    let text = String::from_utf8(bytes)
        .map_err(|_| ModelError::new(path, None, "not UTF-8 text; expected an OBJ file"))?;
    let uses =
        precheck(&text).map_err(|(line, message)| ModelError::new(path, Some(line), message))?;
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ..Default::default()
    };
    let dir = path.parent().unwrap_or(Path::new("."));
    let mut warnings = Vec::new();
    // tobj's loader callback cannot return our errors: they wait here.
    let mtl_problem: RefCell<Option<ModelError>> = RefCell::new(None);
    let mtl_missing: RefCell<Vec<String>> = RefCell::new(Vec::new());
    let policy = &res.policy;
    let load_mtl = |name: &Path| -> tobj::MTLLoadResult {
        let mtl_path = dir.join(name);
        if !mtl_path.exists() {
            mtl_missing.borrow_mut().push(format!(
                "{}: material library {} not found; using the default material",
                path.display(),
                mtl_path.display()
            ));
            return Err(tobj::LoadError::OpenFileFailed);
        }
        let checked = policy
            .read(&mtl_path)
            .map_err(|e| ModelError::new(&mtl_path, None, e))
            .and_then(|b| {
                String::from_utf8(b).map_err(|_| {
                    ModelError::new(&mtl_path, None, "not UTF-8 text; expected an MTL file")
                })
            })
            .and_then(|t| {
                precheck_mtl(&t).map_err(|(line, m)| ModelError::new(&mtl_path, Some(line), m))?;
                Ok(t)
            });
        match checked {
            Ok(t) => tobj::load_mtl_buf(&mut t.as_bytes()),
            Err(e) => {
                mtl_problem.borrow_mut().get_or_insert(e);
                Err(tobj::LoadError::ReadError)
            }
        }
    };
    let loaded = tobj::load_obj_buf(&mut text.as_bytes(), &options, load_mtl);
    if let Some(e) = mtl_problem.into_inner() {
        return Err(e);
    }
    warnings.extend(mtl_missing.into_inner());
    let (models, materials) =
        loaded.map_err(|e| ModelError::new(path, None, format!("cannot load: {e}")))?;
    let mtl = match materials {
        Ok(m) => m,
        Err(e) => {
            if warnings.is_empty() {
                warnings.push(format!(
                    "{}: material library not loaded ({e}); using the default material",
                    path.display()
                ));
            }
            Vec::new()
        }
    };
    for (line, name) in uses {
        if !mtl.iter().any(|m| m.name == name) {
            warnings.push(format!(
                "{}:{line}: usemtl `{}`: no material of that name in the material libraries; using the default material",
                path.display(),
                super::cut(&name, 80)
            ));
        }
    }
    let mut materials = mtl
        .iter()
        .map(|m| material(m, dir, path, res, &mut warnings))
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
/// far. Returns the `usemtl` names with their lines, or the 1-based line and
/// the problem.
fn precheck(text: &str) -> Result<Vec<(usize, String)>, (usize, String)> {
    let (mut v, mut vt, mut vn) = (0i64, 0i64, 0i64);
    let mut uses: Vec<(usize, String)> = Vec::new();
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
            Some("usemtl") => {
                let name = line.trim().split_once(' ').unwrap_or_default().1.trim();
                if !name.is_empty() && !uses.iter().any(|(_, n)| n == name) {
                    uses.push((line_no, name.to_string()));
                }
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
    Ok(uses)
}

/// Checks the values of an MTL file that become material coefficients:
/// colours (Ka, Kd, Ks, Ke, Tf) are three finite numbers in [0, MAX_VALUE],
/// Ns finite in [0, MAX_VALUE], Ni finite and positive, d and Tr in [0, 1],
/// illum an integer 0–10. Returns the 1-based line and the problem.
fn precheck_mtl(text: &str) -> Result<(), (usize, String)> {
    let number = |word: Option<&str>, key: &str| -> Result<f64, String> {
        let w = word.ok_or(format!("`{key}` needs a number"))?;
        match w.parse::<f64>() {
            Ok(x) if x.is_finite() => Ok(x),
            _ => Err(format!(
                "`{key}` value `{}` is not a finite number",
                cut(w, 40)
            )),
        }
    };
    for (i, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        let Some(key) = words.next() else { continue };
        let checked = match key {
            "Ka" | "Kd" | "Ks" | "Ke" | "Tf" => (0..3)
                .map(|_| number(words.next(), key))
                .collect::<Result<Vec<_>, _>>()
                .and_then(
                    |c| match c.iter().find(|x| !(0.0..=MAX_VALUE).contains(*x)) {
                        Some(x) => Err(format!(
                            "`{key}` component {x} is out of range; expected 0 to {MAX_VALUE:e}"
                        )),
                        None => Ok(()),
                    },
                ),
            "Ns" => number(words.next(), key).and_then(|x| {
                if (0.0..=MAX_VALUE).contains(&x) {
                    Ok(())
                } else {
                    Err(format!(
                        "`Ns` (shininess) {x} is out of range; expected 0 to {MAX_VALUE:e}"
                    ))
                }
            }),
            "Ni" => number(words.next(), key).and_then(|x| {
                if x > 0.0 && x <= MAX_VALUE {
                    Ok(())
                } else {
                    Err(format!(
                        "`Ni` (index of refraction) {x} must be greater than 0"
                    ))
                }
            }),
            "d" | "Tr" => number(words.next(), key).and_then(|x| {
                if (0.0..=1.0).contains(&x) {
                    Ok(())
                } else {
                    Err(format!("`{key}` {x} is out of range; expected 0 to 1"))
                }
            }),
            "illum" => match words.next().map(str::parse::<u32>) {
                Some(Ok(0..=10)) => Ok(()),
                _ => Err("`illum` must be an integer from 0 to 10".into()),
            },
            _ => Ok(()),
        };
        checked.map_err(|m| (i + 1, m))?;
    }
    Ok(())
}

/// One MTL material as a Whitted material (see the module comment).
fn material(
    m: &tobj::Material,
    dir: &Path,
    obj: &Path,
    res: &mut Resources,
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
    // Tf is the transmission filter: the colour that passes (one number
    // stands for three).
    let tf = m.unknown_param.get("Tf").and_then(|t| {
        let v: Vec<f64> = t
            .split_whitespace()
            .filter_map(|x| x.parse().ok())
            .collect();
        match v[..] {
            [g] => Some(DVec3::splat(g)),
            [r, g, b, ..] => Some(DVec3::new(r, g, b)),
            _ => None,
        }
    });
    let transparent = matches!(illum, 4 | 6 | 7);
    // The mirror reflects Ks's colour (a tinted metal), not its maximum.
    let kr = if matches!(illum, 3..=7) {
        rgb(m.specular).unwrap_or(DVec3::ZERO)
    } else {
        DVec3::ZERO
    };
    let kt = if transparent {
        tf.unwrap_or(DVec3::splat(1.0 - dissolve))
            .clamp(DVec3::ZERO, DVec3::ONE)
    } else {
        DVec3::ZERO
    };
    let (kr, kt) = Material::conserving(kr, kt);
    let texture = match &m.diffuse_texture {
        None => Texture::Solid(kd_color),
        Some(file) => {
            let image_path = dir.join(file.trim());
            let image = res.texture_file(&image_path).map_err(|e| {
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
                image,
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
        emission: Texture::Solid(DVec3::ZERO),
        roughness: 0.0,
        glossy_samples: 16,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn precheck_locates_bad_faces_and_numbers() {
        let ok = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf -3 -2 -1\n";
        assert_eq!(precheck(ok), Ok(Vec::new()));
        let past = "v 0 0 0\nv 1 0 0\nv 0 1 0\n# comment\nf 1 2 4\n";
        let (line, msg) = precheck(past).unwrap_err();
        assert_eq!(line, 5);
        assert!(msg.contains("vertex 4, but only 3"), "{msg}");
        let nan = "v 0 0 0\nv 1 nan 0\n";
        assert_eq!(precheck(nan).unwrap_err().0, 2);
        let normal = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//2 3//1\n";
        assert!(precheck(normal).unwrap_err().1.contains("normal 2"));
    }

    #[test]
    fn mtl_values_are_range_checked_with_their_line() {
        assert_eq!(
            precheck_mtl("newmtl a\nKd 0.5 0.5 0.5\nNs 10\nNi 1.5\nd 1\nillum 2\n"),
            Ok(())
        );
        for (bad, want) in [
            ("Ns nan", "not a finite number"),
            ("Kd nan 0 0", "not a finite number"),
            ("Kd -5 0 0", "out of range"),
            ("Ns -1e9", "out of range"),
            ("Ni 0", "greater than 0"),
            ("Ni -2", "greater than 0"),
            ("Kd 1 1", "needs a number"),
            ("d 2", "0 to 1"),
            ("illum 99", "0 to 10"),
        ] {
            let (line, m) = precheck_mtl(&format!("newmtl a\n{bad}\n")).unwrap_err();
            assert_eq!(line, 2, "{bad}");
            assert!(m.contains(want), "{bad}: {m}");
        }
    }
}
