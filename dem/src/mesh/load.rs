//! Meshes from OBJ and STL files.

use super::{MeshError, TriMesh};
use glam::DVec3;
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
            let opts = tobj::LoadOptions {
                triangulate: true,
                single_index: true,
                ..Default::default()
            };
            let (models, _) = tobj::load_obj(path, &opts).map_err(|e| err(e.to_string()))?;
            let mut v = Vec::new();
            let mut t = Vec::new();
            for m in models {
                let base = v.len() as u32;
                v.extend(
                    m.mesh
                        .positions
                        .chunks_exact(3)
                        .map(|p| DVec3::new(p[0], p[1], p[2])),
                );
                t.extend(
                    m.mesh
                        .indices
                        .chunks_exact(3)
                        .map(|c| [base + c[0], base + c[1], base + c[2]]),
                );
            }
            (v, t)
        }
        Some("stl") => {
            let mut f = std::fs::File::open(path).map_err(|e| err(e.to_string()))?;
            let s = stl_io::read_stl(&mut f).map_err(|e| err(e.to_string()))?;
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
