//! Triangles of a large mesh near a box, found through clusters of nearby
//! triangles rather than by testing every triangle.
//!
//! The culling's first step keeps the triangles of body A whose boxes
//! overlap body B's box: n box tests per body pair, for a mesh of n
//! triangles. On large meshes (boulders of 2,000 triangles) most of them
//! fail, and the step costs most of the culling. So each mesh's triangles
//! are grouped, once, into clusters of [`CLUSTER`] triangles close to each
//! other in the body's frame: sorted by the Morton code of their centroids
//! (the bits of the three coordinates interleaved, each scaled to the mesh's
//! box, so that triangles close in the order are close in space) and cut
//! into consecutive runs. A cluster's box in a detection pass is the union
//! of its triangles' boxes, computed the first time a task needs the body in
//! the pass and kept for the body's other pairs. The selection then tests
//! the n / [`CLUSTER`] cluster boxes against B's box and only the triangles
//! of the clusters that overlap it.
//!
//! **The same triangles, in the same order.** A triangle whose box overlaps
//! B's box lies in a cluster whose box (a union containing it) overlaps it
//! too, so the triangles kept are exactly those of the plain test. They are
//! marked in a bitmap by their index in the mesh and read back in increasing
//! index, the order of the plain test: the triangle pairs, the kernel calls
//! and the contacts come out in the same order, and the run in the same bits.

use super::bounds::Bounds;
use super::triangle_set::SetTriangle;
use crate::mesh::TriMesh;
use std::collections::HashMap;

/// Triangles per cluster.
pub(crate) const CLUSTER: usize = 16;

/// Meshes with more triangles than this select through clusters; below, a
/// test per triangle costs about what the clusters' boxes would.
pub(crate) const CLUSTERED_ABOVE: usize = 8 * CLUSTER;

/// The order of `mesh`'s triangles along the Morton curve of their centroids
/// (ties by index), each coordinate scaled to the mesh's box with 21 bits.
pub(crate) fn morton_order(mesh: &TriMesh) -> Vec<u32> {
    let centroid = |t: &[u32; 3]| {
        (mesh.vertices[t[0] as usize] + mesh.vertices[t[1] as usize] + mesh.vertices[t[2] as usize])
            / 3.0
    };
    let centroids: Vec<_> = mesh.triangles.iter().map(centroid).collect();
    let lo = centroids.iter().copied().reduce(|a, b| a.min(b));
    let hi = centroids.iter().copied().reduce(|a, b| a.max(b));
    let (Some(lo), Some(hi)) = (lo, hi) else {
        return Vec::new();
    };
    let scale = (1u64 << 21) as f64 - 1.0;
    let cell = |x: f64, a: f64, b: f64| {
        let s = if b > a { (x - a) / (b - a) } else { 0.0 };
        (s.clamp(0.0, 1.0) * scale) as u64
    };
    let mut keyed: Vec<(u64, u32)> = centroids
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let code = spread(cell(c.x, lo.x, hi.x))
                | spread(cell(c.y, lo.y, hi.y)) << 1
                | spread(cell(c.z, lo.z, hi.z)) << 2;
            (code, i as u32)
        })
        .collect();
    keyed.sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}

/// The 21 low bits of `x` spread to every third bit.
fn spread(x: u64) -> u64 {
    let mut x = x & 0x1f_ffff;
    x = (x | x << 32) & 0x001f_0000_0000_ffff;
    x = (x | x << 16) & 0x001f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    x = (x | x << 2) & 0x1249_2492_4924_9249;
    x
}

/// A detection task's clusters: each shape's Morton order (kept, shapes do
/// not change), and the cluster boxes of the parts met in the current pass.
#[derive(Debug, Default)]
pub(crate) struct Clusters {
    orders: HashMap<usize, Vec<u32>>,
    /// Per part, by its first index in the pass's set.
    boxes: HashMap<usize, Vec<Bounds>>,
    bits: Vec<u64>,
}

impl Clusters {
    /// Forgets the cluster boxes: a new pass may see the bodies elsewhere.
    pub(crate) fn begin_pass(&mut self) {
        self.boxes.clear();
    }

    /// Writes to `out` the set indices (`start + i`) of the triangles `i` of
    /// `triangles`, the whole of mesh `shape` in its order, whose boxes
    /// overlap `other`, in increasing index; returns how many.
    pub(crate) fn select(
        &mut self,
        shape: usize,
        mesh: &TriMesh,
        triangles: &[SetTriangle],
        start: usize,
        other: &Bounds,
        out: &mut Vec<u32>,
    ) -> usize {
        let order = self
            .orders
            .entry(shape)
            .or_insert_with(|| morton_order(mesh));
        let boxes = self.boxes.entry(start).or_insert_with(|| {
            order
                .chunks(CLUSTER)
                .map(|c| {
                    c.iter().fold(Bounds::EMPTY, |b, &t| {
                        b.union(&triangles[t as usize].bounds)
                    })
                })
                .collect()
        });
        let n = triangles.len();
        self.bits.clear();
        self.bits.resize(n.div_ceil(64), 0);
        for (cluster, b) in order.chunks(CLUSTER).zip(boxes.iter()) {
            if !b.overlaps(other) {
                continue;
            }
            for &t in cluster {
                let keep = triangles[t as usize].bounds.overlaps(other);
                self.bits[t as usize / 64] |= u64::from(keep) << (t % 64);
            }
        }
        out.resize(n, 0);
        let mut found = 0;
        for (w, &word) in self.bits.iter().enumerate() {
            let mut rest = word;
            while rest != 0 {
                out[found] = (start + 64 * w + rest.trailing_zeros() as usize) as u32;
                found += 1;
                rest &= rest - 1;
            }
        }
        found
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::sphere_hull;
    use glam::DVec3;

    /// The clusters keep exactly the triangles a test of each keeps, in
    /// increasing index, at any size and distance from the origin, for
    /// boxes that cover none, a corner, a side or all of the mesh.
    #[test]
    fn clusters_select_what_a_test_per_triangle_selects() {
        let mesh = sphere_hull(2000, 1.0, 3);
        let mut clusters = Clusters::default();
        let mut out = Vec::new();
        for (k, (scale, offset)) in [(1.0, 0.0), (1e-6, 1e3), (1e6, -1e9), (0.01, 5e4)]
            .into_iter()
            .enumerate()
        {
            let at = |v: DVec3| v * scale + DVec3::splat(offset);
            let triangles: Vec<SetTriangle> = mesh
                .triangles
                .iter()
                .map(|t| SetTriangle::new(t.map(|v| at(mesh.vertices[v as usize])), 1e-3 * scale))
                .collect();
            let start = 17 * k;
            clusters.begin_pass();
            for (c, r) in [(2.0, 0.5), (1.0, 0.3), (0.0, 0.2), (0.0, 1.5), (0.7, 0.05)] {
                let centre = at(DVec3::new(c, 0.3 * c, -0.2 * c));
                let half = DVec3::splat(r * scale);
                let other = Bounds {
                    lo: centre - half,
                    hi: centre + half,
                };
                let n = clusters.select(k, &mesh, &triangles, start, &other, &mut out);
                let plain: Vec<u32> = (0..triangles.len())
                    .filter(|&i| triangles[i].bounds.overlaps(&other))
                    .map(|i| (start + i) as u32)
                    .collect();
                assert_eq!(&out[..n], &plain[..], "scale {scale}, box at {c} of {r}");
            }
        }
    }

    /// Morton order is a permutation, and its clusters are tighter than runs
    /// of the mesh's own order.
    #[test]
    fn the_order_is_a_permutation_whose_clusters_are_compact() {
        let mesh = sphere_hull(2000, 1.0, 7);
        let n = mesh.triangles.len();
        let order = morton_order(&mesh);
        let mut seen = order.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..n as u32).collect::<Vec<_>>());
        let extent = |ids: &[u32]| {
            let b = ids.iter().fold(Bounds::EMPTY, |b, &t| {
                let tri = mesh.triangles[t as usize].map(|v| mesh.vertices[v as usize]);
                b.union(&Bounds::of(&tri, 0.0))
            });
            let d = b.hi - b.lo;
            d.x + d.y + d.z
        };
        let mean = |ids: &[u32]| {
            let c: Vec<f64> = ids.chunks(CLUSTER).map(extent).collect();
            c.iter().sum::<f64>() / c.len() as f64
        };
        let plain: Vec<u32> = (0..n as u32).collect();
        assert!(
            mean(&order) < 0.7 * mean(&plain),
            "{} against {}",
            mean(&order),
            mean(&plain)
        );
    }
}
