//! Closedness, orientation and degeneracy checks.

use super::{MeshError, TriMesh};
use std::collections::HashMap;

pub(super) fn validate(m: &TriMesh) -> Result<(), MeshError> {
    if m.triangles.len() < 4 {
        return Err(MeshError::TooFewTriangles(m.triangles.len()));
    }
    for (i, v) in m.vertices.iter().enumerate() {
        if !v.is_finite() {
            return Err(MeshError::NonFinite(i));
        }
    }
    for (i, t) in m.triangles.iter().enumerate() {
        for &v in t {
            if v as usize >= m.vertices.len() {
                return Err(MeshError::BadIndex {
                    triangle: i,
                    vertex: v,
                    count: m.vertices.len(),
                });
            }
        }
        let [a, b, c] = t.map(|k| m.vertices[k as usize]);
        let (e0, e1, e2) = (b - a, c - b, a - c);
        let longest = e0
            .length_squared()
            .max(e1.length_squared())
            .max(e2.length_squared());
        // Relative test: |e0 x e1| against the longest edge squared, no absolute epsilon.
        if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] || e0.cross(e1).length() <= 1e-12 * longest
        {
            return Err(MeshError::Degenerate(i));
        }
    }
    // Each directed edge once; its reverse once.
    let mut directed: HashMap<(u32, u32), usize> = HashMap::with_capacity(3 * m.triangles.len());
    for t in &m.triangles {
        for k in 0..3 {
            let e = (t[k], t[(k + 1) % 3]);
            *directed.entry(e).or_default() += 1;
        }
    }
    for (&(a, b), &n) in &directed {
        if n > 1 {
            return Err(MeshError::Inconsistent(a, b));
        }
        let back = directed.get(&(b, a)).copied().unwrap_or(0);
        if back != 1 {
            let (lo, hi) = (a.min(b), a.max(b));
            return Err(MeshError::Open(lo, hi, n + back));
        }
    }
    if m.signed_volume() == 0.0 {
        return Err(MeshError::NoVolume);
    }
    Ok(())
}
