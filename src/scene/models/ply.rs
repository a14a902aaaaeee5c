//! PLY (ASCII and binary) through ply-rs-bw: vertices with optional
//! normals and texture coordinates, faces of any size (fan-triangulated).

use std::path::Path;

use glam::{DVec2, DVec3};
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{Property, PropertyAccess};

use super::{Model, ModelError, fan};
use crate::geometry::MeshData;
use crate::scene::resources::Resources;

/// A vertex with only a position, as most large models have: 24 bytes, and
/// its array becomes the position array in place.
#[derive(Default)]
struct Position([f64; 3]);

#[derive(Default)]
struct Vertex {
    position: [f64; 3],
    normal: [f64; 3],
    uv: [f64; 2],
}

/// A face as read: triangles (nearly every face of a large model) inline,
/// 16 bytes, other polygons and indices out of range as their list.
enum Face {
    Triangle([u32; 3]),
    Polygon(Vec<i64>),
}

impl Default for Face {
    fn default() -> Self {
        Face::Polygon(Vec::new())
    }
}

impl Face {
    fn from_list(list: Vec<i64>) -> Face {
        match list[..] {
            [a, b, c] => match (u32::try_from(a), u32::try_from(b), u32::try_from(c)) {
                (Ok(a), Ok(b), Ok(c)) => Face::Triangle([a, b, c]),
                _ => Face::Polygon(list),
            },
            _ => Face::Polygon(list),
        }
    }
}

fn scalar(p: &Property) -> Option<f64> {
    Some(match *p {
        Property::Char(v) => v as f64,
        Property::UChar(v) => v as f64,
        Property::Short(v) => v as f64,
        Property::UShort(v) => v as f64,
        Property::Int(v) => v as f64,
        Property::UInt(v) => v as f64,
        Property::Float(v) => v as f64,
        Property::Double(v) => v,
        _ => return None,
    })
}

fn list(p: Property) -> Option<Vec<i64>> {
    Some(match p {
        Property::ListChar(v) => v.into_iter().map(i64::from).collect(),
        Property::ListUChar(v) => v.into_iter().map(i64::from).collect(),
        Property::ListShort(v) => v.into_iter().map(i64::from).collect(),
        Property::ListUShort(v) => v.into_iter().map(i64::from).collect(),
        Property::ListInt(v) => v.into_iter().map(i64::from).collect(),
        Property::ListUInt(v) => v.into_iter().map(i64::from).collect(),
        _ => return None,
    })
}

impl PropertyAccess for Vertex {
    fn new() -> Self {
        Vertex::default()
    }
    fn set_property(&mut self, key: &str, property: Property) {
        let Some(v) = scalar(&property) else { return };
        match key {
            "x" => self.position[0] = v,
            "y" => self.position[1] = v,
            "z" => self.position[2] = v,
            "nx" => self.normal[0] = v,
            "ny" => self.normal[1] = v,
            "nz" => self.normal[2] = v,
            "u" | "s" | "texture_u" | "texture_s" => self.uv[0] = v,
            "v" | "t" | "texture_v" | "texture_t" => self.uv[1] = v,
            _ => {}
        }
    }
}

impl PropertyAccess for Position {
    fn new() -> Self {
        Position::default()
    }
    fn set_property(&mut self, key: &str, property: Property) {
        let Some(v) = scalar(&property) else { return };
        match key {
            "x" => self.0[0] = v,
            "y" => self.0[1] = v,
            "z" => self.0[2] = v,
            _ => {}
        }
    }
}

impl PropertyAccess for Face {
    fn new() -> Self {
        Face::default()
    }
    fn set_property(&mut self, key: &str, property: Property) {
        if key == "vertex_indices" || key == "vertex_index" {
            if let Some(l) = list(property) {
                *self = Face::from_list(l);
            }
        }
    }
}

pub fn load(path: &Path, res: &mut Resources) -> Result<Model, ModelError> {
    let err = |message: String| ModelError::new(path, None, message);
    let bytes = res.policy.read(path).map_err(err)?;
    let mut reader = std::io::Cursor::new(&bytes[..]);
    let vertex_parser = Parser::<Vertex>::new();
    let face_parser = Parser::<Face>::new();
    let header = vertex_parser
        .read_header(&mut reader)
        .map_err(|e| err(format!("bad PLY header: {e}")))?;
    let (mut positions, mut normals, mut uvs) = (Vec::new(), Vec::new(), Vec::new());
    let mut faces = Vec::new();
    let mut warnings = Vec::new();
    for (name, element) in &header.elements {
        let truncated = |e: std::io::Error| {
            let what = if e.kind() == std::io::ErrorKind::UnexpectedEof {
                "the file ends early (truncated?)".to_string()
            } else {
                e.to_string()
            };
            err(format!(
                "element `{name}` ({} announced): {what}",
                element.count
            ))
        };
        match name.as_str() {
            "vertex" => {
                let has_normals = element.properties.contains_key("nx");
                let has_uvs = ["u", "s", "texture_u", "texture_s"]
                    .iter()
                    .any(|k| element.properties.contains_key(*k));
                if !has_normals && !has_uvs {
                    // Same layout: the collect reuses the parser's array.
                    positions = Parser::<Position>::new()
                        .read_payload_for_element(&mut reader, element, &header)
                        .map_err(truncated)?
                        .into_iter()
                        .map(|p| DVec3::from_array(p.0))
                        .collect();
                    continue;
                }
                let vertices = vertex_parser
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(truncated)?;
                positions = vertices
                    .iter()
                    .map(|v| DVec3::from_array(v.position))
                    .collect();
                if has_normals {
                    normals = vertices
                        .iter()
                        .map(|v| DVec3::from_array(v.normal))
                        .collect();
                }
                if has_uvs {
                    uvs = vertices.iter().map(|v| DVec2::from_array(v.uv)).collect();
                }
            }
            "face" => {
                faces = face_parser
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(truncated)?;
            }
            other => {
                // Elements after the ones we need may be skipped by reading
                // them as faces (their data must still be consumed).
                warnings.push(format!("{}: element `{other}` ignored", path.display()));
                face_parser
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(truncated)?;
            }
        }
    }
    let count = positions.len();
    let mut triangles = Vec::with_capacity(faces.len());
    for (i, face) in faces.iter().enumerate() {
        let out_of_range = |bad: i64| {
            err(format!(
                "face {i} refers to vertex {bad}, but there are {count} vertices"
            ))
        };
        match face {
            Face::Triangle(t) => {
                if let Some(&bad) = t.iter().find(|&&k| k as usize >= count) {
                    return Err(out_of_range(i64::from(bad)));
                }
                triangles.push(*t);
            }
            Face::Polygon(indices) => {
                if indices.len() < 3 {
                    return Err(err(format!(
                        "face {i} has {} vertices; at least 3 are needed",
                        indices.len()
                    )));
                }
                if let Some(&bad) = indices.iter().find(|&&k| k < 0 || k as usize >= count) {
                    return Err(out_of_range(bad));
                }
                let polygon: Vec<u32> = indices.iter().map(|&k| k as u32).collect();
                triangles.extend(fan(&polygon));
            }
        }
    }
    drop(faces);
    if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
        return Err(err(format!(
            "vertex {i} has a coordinate that is not a finite number"
        )));
    }
    let mesh = MeshData {
        positions,
        normals,
        uvs,
        triangles,
        materials: Vec::new(),
        colors: Vec::new(),
    };
    Ok(Model::single(mesh, Vec::new(), warnings))
}
