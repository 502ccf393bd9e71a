//! The shape a triangulation describes: its flat faces, crease lines and
//! corners, whatever triangles happen to carry them.
//!
//! A box is 6 faces, 12 creases and 8 corners, whether it is meshed with 12
//! triangles or with 192. Contacts are built on these features (see
//! `contact::features`), so refining a mesh without changing its shape does
//! not change the contacts, and two coplanar triangles never make a contact
//! point along the diagonal between them.
//!
//! - A **face** is a maximal set of triangles connected across *flat* edges:
//!   edges whose two triangles' unit normals differ by less than
//!   [`FLAT_ANGLE`] radians (an angle, not a length: it holds at any size).
//! - A **crease** is a maximal chain of non-flat edges through vertices where
//!   the chain goes straight on: vertices on exactly two faces and exactly two
//!   non-flat edges of the same kind (both convex or both concave). Its ends are
//!   corners. Two faces meet along the whole chain.
//! - A **corner** is any other vertex touching a non-flat edge (three or more
//!   faces meet there, or creases branch or change kind).
//!
//! Vertices inside a face (one face around them) are none of these.

use super::TriMesh;
use glam::DVec3;
use std::collections::HashMap;

/// Two triangles are coplanar, and their shared edge flat, when their unit
/// normals differ by less than this angle (radians). A mesh read from a file
/// with single-precision coordinates has coplanar triangles whose normals
/// differ by about 1e-7; a real crease of less than a microradian is none.
pub const FLAT_ANGLE: f64 = 1e-6;

/// Marks "no crease" in [`Features::edge_crease`].
pub const NO_CREASE: u32 = u32::MAX;

/// A flat face: its plane in body coordinates.
#[derive(Debug, Clone, PartialEq)]
pub struct Face {
    /// Outward unit normal.
    pub normal: DVec3,
    /// A vertex of the face (index into the mesh's vertices).
    pub anchor: u32,
}

/// A crease line between two faces.
#[derive(Debug, Clone, PartialEq)]
pub struct Crease {
    /// The corner vertices at its ends, the lower index first.
    pub ends: [u32; 2],
    /// The faces on either side.
    pub faces: [u32; 2],
    /// Per side: the unit direction in the face's plane, perpendicular to the
    /// crease, pointing into the face (body coordinates).
    pub inward: [DVec3; 2],
    /// Whether the solid's interior angle along it is below 180 degrees.
    pub convex: bool,
}

/// Faces, creases and corners of a closed mesh, with what contact geometry
/// needs to find its way around them.
#[derive(Debug, Clone, PartialEq)]
pub struct Features {
    pub faces: Vec<Face>,
    /// Per triangle: its face.
    pub face_of: Vec<u32>,
    pub creases: Vec<Crease>,
    /// Per triangle and edge k (from vertex k to vertex k+1 mod 3): the crease
    /// that edge belongs to, or [`NO_CREASE`] for a flat edge.
    pub edge_crease: Vec<[u32; 3]>,
    /// Per vertex: whether it is a corner.
    pub corner: Vec<bool>,
    /// Per vertex: its neighbours along mesh edges (CSR by `neighbour_start`).
    neighbour_start: Vec<u32>,
    neighbours: Vec<u32>,
    /// Per vertex: the faces around it (CSR by `face_start`).
    face_start: Vec<u32>,
    vertex_faces: Vec<u32>,
}

impl Features {
    /// The features of a validated (closed, consistently oriented) mesh.
    pub fn of(mesh: &TriMesh) -> Features {
        let normals: Vec<DVec3> = (0..mesh.triangles.len())
            .map(|t| {
                let [a, b, c] = mesh.triangle(t);
                (b - a).cross(c - a).normalize_or_zero()
            })
            .collect();
        let edges = edge_map(mesh);
        let face_of = group_faces(mesh, &normals, &edges);
        let faces = face_planes(mesh, &face_of);
        let n_vertices = mesh.vertices.len();
        let (neighbour_start, neighbours) = csr(
            n_vertices,
            edges.keys().flat_map(|&(i, j)| [(i, j), (j, i)]),
        );
        let vertex_face_pairs = mesh
            .triangles
            .iter()
            .enumerate()
            .flat_map(|(t, tri)| tri.map(|v| (v, face_of[t])));
        let (face_start, vertex_faces) = csr_dedup(n_vertices, vertex_face_pairs);
        let mut f = Features {
            faces,
            face_of,
            creases: Vec::new(),
            edge_crease: vec![[NO_CREASE; 3]; mesh.triangles.len()],
            corner: vec![false; n_vertices],
            neighbour_start,
            neighbours,
            face_start,
            vertex_faces,
        };
        let sharp = sharp_edges(mesh, &f.face_of, &edges);
        f.mark_corners(&sharp);
        f.chain_creases(mesh, &sharp, &edges);
        f
    }

    /// The mesh neighbours of vertex `v`.
    pub fn neighbours(&self, v: u32) -> &[u32] {
        let v = v as usize;
        &self.neighbours[self.neighbour_start[v] as usize..self.neighbour_start[v + 1] as usize]
    }

    /// The faces around vertex `v`.
    pub fn faces_at(&self, v: u32) -> &[u32] {
        let v = v as usize;
        &self.vertex_faces[self.face_start[v] as usize..self.face_start[v + 1] as usize]
    }

    /// A vertex is a corner when it touches a non-flat edge and is not a
    /// pass-through vertex of a straight crease.
    fn mark_corners(&mut self, sharp: &HashMap<(u32, u32), bool>) {
        let mut kinds: Vec<Vec<bool>> = vec![Vec::new(); self.corner.len()];
        for (&(i, j), &convex) in sharp {
            kinds[i as usize].push(convex);
            kinds[j as usize].push(convex);
        }
        for (v, k) in kinds.iter().enumerate() {
            let pass_through = k.len() == 2 && k[0] == k[1] && self.faces_at(v as u32).len() == 2;
            self.corner[v] = !k.is_empty() && !pass_through;
        }
    }

    /// The vertices of the crease through non-flat edge (i, j), from one
    /// corner to the other (first = last for a loop without corners).
    fn walk_crease(&self, i: u32, j: u32, sharp: &HashMap<(u32, u32), bool>) -> Vec<u32> {
        let next_along = |v: u32, from: u32| -> Option<u32> {
            self.neighbours(v)
                .iter()
                .copied()
                .find(|&u| u != from && sharp.contains_key(&ordered(u, v)))
        };
        let mut chain = vec![i, j];
        for _ in 0..2 {
            loop {
                let (last, prev) = (chain[chain.len() - 1], chain[chain.len() - 2]);
                if self.corner[last as usize] || last == chain[0] {
                    break;
                }
                match next_along(last, prev) {
                    Some(u) => chain.push(u),
                    None => break,
                }
            }
            if chain.first() == chain.last() {
                break;
            }
            chain.reverse();
        }
        chain
    }

    /// Walks the non-flat edges into creases from corner to corner.
    fn chain_creases(
        &mut self,
        mesh: &TriMesh,
        sharp: &HashMap<(u32, u32), bool>,
        edges: &HashMap<(u32, u32), [u32; 2]>,
    ) {
        let mut crease_of: HashMap<(u32, u32), u32> = HashMap::new();
        let mut sharp_sorted: Vec<_> = sharp.keys().copied().collect();
        sharp_sorted.sort_unstable();
        for &(i, j) in &sharp_sorted {
            if crease_of.contains_key(&(i, j)) {
                continue;
            }
            let chain = self.walk_crease(i, j, sharp);
            if chain.first() == chain.last() {
                // A closed loop without corners: broken at its first vertex.
                self.corner[chain[0] as usize] = true;
            }
            let id = self.creases.len() as u32;
            for w in chain.windows(2) {
                crease_of.insert(ordered(w[0], w[1]), id);
            }
            let (a, b) = (chain[0], chain[chain.len() - 1]);
            let ends = if a <= b { [a, b] } else { [b, a] };
            let [t1, t2] = edges[&ordered(i, j)];
            let faces = [self.face_of[t1 as usize], self.face_of[t2 as usize]];
            let dir = (mesh.vertices[ends[1] as usize] - mesh.vertices[ends[0] as usize])
                .normalize_or_zero();
            let inward = [t1, t2].map(|t| inward_direction(mesh, t as usize, (i, j), dir));
            self.creases.push(Crease {
                ends,
                faces,
                inward,
                convex: sharp[&(i, j)],
            });
        }
        for (t, tri) in mesh.triangles.iter().enumerate() {
            for k in 0..3 {
                let e = ordered(tri[k], tri[(k + 1) % 3]);
                self.edge_crease[t][k] = crease_of.get(&e).copied().unwrap_or(NO_CREASE);
            }
        }
    }
}

fn ordered(i: u32, j: u32) -> (u32, u32) {
    (i.min(j), i.max(j))
}

/// Each edge (lower vertex first) with its two triangles.
fn edge_map(mesh: &TriMesh) -> HashMap<(u32, u32), [u32; 2]> {
    let mut edges: HashMap<(u32, u32), [u32; 2]> = HashMap::new();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for k in 0..3 {
            let e = ordered(tri[k], tri[(k + 1) % 3]);
            edges
                .entry(e)
                .and_modify(|p| p[1] = t as u32)
                .or_insert([t as u32, t as u32]);
        }
    }
    edges
}

/// Whether two unit normals are those of coplanar, same-facing triangles.
fn flat(n1: DVec3, n2: DVec3) -> bool {
    n1.dot(n2) > 0.0 && n1.cross(n2).length() < FLAT_ANGLE
}

/// Face index per triangle: components of triangles joined by flat edges,
/// numbered in order of their lowest triangle.
fn group_faces(
    mesh: &TriMesh,
    normals: &[DVec3],
    edges: &HashMap<(u32, u32), [u32; 2]>,
) -> Vec<u32> {
    let n = mesh.triangles.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    for &[t1, t2] in edges.values() {
        let (t1, t2) = (t1 as usize, t2 as usize);
        if flat(normals[t1], normals[t2]) {
            let (r1, r2) = (root(&mut parent, t1), root(&mut parent, t2));
            parent[r1.max(r2)] = r1.min(r2);
        }
    }
    let mut id = vec![u32::MAX; n];
    let mut face_of = vec![0u32; n];
    let mut next = 0;
    for (t, face) in face_of.iter_mut().enumerate() {
        let r = root(&mut parent, t);
        if id[r] == u32::MAX {
            id[r] = next;
            next += 1;
        }
        *face = id[r];
    }
    face_of
}

/// Each face's plane from its largest triangle (the best-conditioned normal).
fn face_planes(mesh: &TriMesh, face_of: &[u32]) -> Vec<Face> {
    let n_faces = face_of.iter().map(|&f| f as usize + 1).max().unwrap_or(0);
    let mut best: Vec<(f64, usize)> = vec![(-1.0, 0); n_faces];
    for (t, &f) in face_of.iter().enumerate() {
        let [a, b, c] = mesh.triangle(t);
        let area2 = (b - a).cross(c - a).length();
        if area2 > best[f as usize].0 {
            best[f as usize] = (area2, t);
        }
    }
    best.iter()
        .map(|&(_, t)| {
            let [a, b, c] = mesh.triangle(t);
            Face {
                normal: (b - a).cross(c - a).normalize(),
                anchor: mesh.triangles[t][0],
            }
        })
        .collect()
}

/// Non-flat edges (lower vertex first) and whether each is convex. Edges
/// inside one face are flat even when their own triangles differ by more
/// than [`FLAT_ANGLE`] through a chain of nearly flat ones.
fn sharp_edges(
    mesh: &TriMesh,
    face_of: &[u32],
    edges: &HashMap<(u32, u32), [u32; 2]>,
) -> HashMap<(u32, u32), bool> {
    edges
        .iter()
        .filter(|(_, &[t1, t2])| face_of[t1 as usize] != face_of[t2 as usize])
        .map(|(&(i, j), &[t1, t2])| {
            let [a, b, c] = mesh.triangle(t1 as usize);
            let n1 = (b - a).cross(c - a);
            let opposite = mesh.triangles[t2 as usize]
                .into_iter()
                .find(|&v| v != i && v != j)
                .expect("a triangle has a vertex off each of its edges");
            let convex = n1.dot(mesh.vertices[opposite as usize] - mesh.vertices[i as usize]) < 0.0;
            ((i, j), convex)
        })
        .collect()
}

/// The unit direction in triangle `t`'s plane, perpendicular to `dir` (the
/// crease through edge `e`), pointing into the triangle.
fn inward_direction(mesh: &TriMesh, t: usize, e: (u32, u32), dir: DVec3) -> DVec3 {
    let [a, b, c] = mesh.triangle(t);
    let n = (b - a).cross(c - a).normalize_or_zero();
    let m = n.cross(dir).normalize_or_zero();
    let opposite = mesh.triangles[t]
        .into_iter()
        .find(|&v| v != e.0 && v != e.1)
        .expect("a triangle has a vertex off each of its edges");
    let into = mesh.vertices[opposite as usize] - mesh.vertices[e.0 as usize];
    if into.dot(m) >= 0.0 {
        m
    } else {
        -m
    }
}

/// Compressed rows of `pairs` (row, value) over `n` rows, values sorted and
/// deduplicated within each row.
fn csr_dedup(n: usize, pairs: impl Iterator<Item = (u32, u32)>) -> (Vec<u32>, Vec<u32>) {
    let mut rows: Vec<Vec<u32>> = vec![Vec::new(); n];
    for (r, v) in pairs {
        rows[r as usize].push(v);
    }
    let mut start = Vec::with_capacity(n + 1);
    let mut values = Vec::new();
    start.push(0);
    for mut r in rows {
        r.sort_unstable();
        r.dedup();
        values.extend(r);
        start.push(values.len() as u32);
    }
    (start, values)
}

fn csr(n: usize, pairs: impl Iterator<Item = (u32, u32)>) -> (Vec<u32>, Vec<u32>) {
    csr_dedup(n, pairs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{box_mesh, sphere_hull, subdivided};

    #[test]
    fn a_box_has_six_faces_twelve_creases_eight_corners_however_meshed() {
        let b = box_mesh(DVec3::new(1.0, 2.0, 3.0)).unwrap();
        for times in 0..3 {
            let m = subdivided(&b, times).unwrap();
            let f = Features::of(&m);
            assert_eq!(f.faces.len(), 6, "refined {times} times");
            assert_eq!(f.creases.len(), 12);
            assert!(f.creases.iter().all(|c| c.convex));
            assert_eq!(f.corner.iter().filter(|&&c| c).count(), 8);
            // Corners are the box's corners, crease ends are corners.
            for (v, &c) in f.corner.iter().enumerate() {
                let p = m.vertices[v];
                let at_corner = p.x.abs() == 0.5 && p.y.abs() == 1.0 && p.z.abs() == 1.5;
                assert_eq!(c, at_corner, "vertex {v} at {p}");
            }
            for c in &f.creases {
                assert!(c.ends.iter().all(|&e| f.corner[e as usize]));
                let len =
                    (m.vertices[c.ends[1] as usize] - m.vertices[c.ends[0] as usize]).length();
                assert!([1.0, 2.0, 3.0].contains(&len), "crease of length {len}");
                // The inward directions lie in their faces, perpendicular to the crease.
                for s in 0..2 {
                    let n = f.faces[c.faces[s] as usize].normal;
                    assert!(c.inward[s].dot(n).abs() < 1e-15);
                }
            }
        }
    }

    #[test]
    fn every_edge_of_a_hull_is_a_convex_crease_and_every_vertex_a_corner() {
        let m = sphere_hull(20, 0.01, 7).unwrap();
        let f = Features::of(&m);
        assert_eq!(f.faces.len(), 20);
        assert_eq!(f.creases.len(), 30);
        assert!(f.creases.iter().all(|c| c.convex));
        assert!(f.corner.iter().all(|&c| c));
    }

    #[test]
    fn a_notch_has_concave_creases() {
        // An L-shaped prism: one concave crease along the inner corner.
        let p = [
            (0.0, 0.0),
            (2.0, 0.0),
            (2.0, 1.0),
            (1.0, 1.0),
            (1.0, 2.0),
            (0.0, 2.0),
        ];
        let mut v: Vec<DVec3> = p.iter().map(|&(x, y)| DVec3::new(x, y, 0.0)).collect();
        v.extend(p.iter().map(|&(x, y)| DVec3::new(x, y, 1.0)));
        // Bottom and top as fans from the notch's inner corner (vertex 3),
        // which sees the whole L.
        let mut t: Vec<[u32; 3]> = Vec::new();
        for k in [4u32, 5, 0, 1] {
            let next = (k + 1) % 6;
            t.push([3, next, k]);
            t.push([9, k + 6, next + 6]);
        }
        for k in 0..6u32 {
            let n = (k + 1) % 6;
            t.push([k, n, n + 6]);
            t.push([k, n + 6, k + 6]);
        }
        let m = TriMesh::new(v, t).unwrap();
        let f = Features::of(&m);
        assert_eq!(f.faces.len(), 8);
        assert_eq!(f.creases.iter().filter(|c| !c.convex).count(), 1);
        assert_eq!(f.creases.len(), 18);
    }
}
