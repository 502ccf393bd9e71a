//! Meshes from OBJ and STL files.

use super::{MeshError, TriMesh};
use glam::DVec3;
use std::collections::HashMap;
use std::path::Path;

/// Loads an OBJ or STL file (by extension) and validates it.
pub fn load_mesh(path: &Path) -> Result<TriMesh, MeshError> {
    let err = |cause: String| MeshError::Load {
        path: path.display().to_string(),
        cause,
    };
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let (vertices, triangles) = match ext.as_deref() {
        Some("obj") => {
            // Position indices only: with its texture and normal indices a
            // corner would be a vertex per face it has a normal in, and a
            // closed mesh exported with normals would read as open.
            let opts = tobj::LoadOptions {
                triangulate: true,
                single_index: false,
                ..Default::default()
            };
            let (models, _) = tobj::load_obj(path, &opts).map_err(|e| err(e.to_string()))?;
            merged_models(
                models
                    .iter()
                    .map(|m| (&m.mesh.positions[..], &m.mesh.indices[..])),
            )
        }
        Some("stl") => {
            let bytes = std::fs::read(path).map_err(|e| err(e.to_string()))?;
            let mut text = std::io::Cursor::new(stl_keywords_lowercased(bytes));
            let s = stl_io::read_stl(&mut text)
                .map_err(|e| err(format!("not a readable STL file, ASCII or binary ({e})")))?;
            let v = s
                .vertices
                .iter()
                .map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64))
                .collect();
            let t = s
                .faces
                .iter()
                .map(|f| {
                    [
                        f.vertices[0] as u32,
                        f.vertices[1] as u32,
                        f.vertices[2] as u32,
                    ]
                })
                .collect();
            (v, t)
        }
        _ => return Err(err("unknown mesh format (use .obj or .stl)".into())),
    };
    TriMesh::new(vertices, triangles).map_err(|e| err(e.to_string()))
}

/// One mesh of an OBJ's models (its groups, objects and material runs),
/// each given as its positions and its triangles' indices into them. Each
/// model holds its own copy of the positions its faces use: copies of one
/// `v` line have the same bits, and are one vertex again (in the order of
/// their first use), so that a closed surface split into groups stays closed.
fn merged_models<'a>(
    models: impl Iterator<Item = (&'a [f64], &'a [u32])>,
) -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    let mut index: HashMap<[u64; 3], u32> = HashMap::new();
    for (positions, indices) in models {
        let ids: Vec<u32> = positions
            .chunks_exact(3)
            .map(|p| {
                let key = [p[0].to_bits(), p[1].to_bits(), p[2].to_bits()];
                *index.entry(key).or_insert_with(|| {
                    vertices.push(DVec3::new(p[0], p[1], p[2]));
                    (vertices.len() - 1) as u32
                })
            })
            .collect();
        let id = |i: u32| ids[i as usize];
        triangles.extend(
            indices
                .chunks_exact(3)
                .map(|c| [id(c[0]), id(c[1]), id(c[2])]),
        );
    }
    (vertices, triangles)
}

/// ASCII STL's keywords are lowercase by the format, but some exporters
/// write them in capitals (`SOLID`, `FACET NORMAL`): such a file is read
/// lowercased, its numbers unchanged. A binary file (its size that of the
/// facet count in its header) is left as it is, whatever its header says.
fn stl_keywords_lowercased(mut bytes: Vec<u8>) -> Vec<u8> {
    let starts_in_capitals =
        bytes.len() >= 5 && bytes[..5].eq_ignore_ascii_case(b"solid") && &bytes[..5] != b"solid";
    let binary = bytes.len() >= 84 && {
        let facets = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]);
        bytes.len() as u64 == 84 + 50 * u64::from(facets)
    };
    if starts_in_capitals && !binary && bytes.is_ascii() {
        bytes.make_ascii_lowercase();
    }
    bytes
}
