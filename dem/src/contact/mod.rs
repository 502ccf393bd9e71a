//! Contact detection between bodies made of triangles.
//!
//! 1. Broad phase: sort and sweep over the bodies' boxes inflated by their halos.
//! 2. Triangle culling: only triangles whose inflated boxes overlap the other
//!    body's box, only pairs of those whose inflated boxes overlap, and only
//!    pairs that neither triangle's plane separates by more than the halo sum
//!    (the face normals are two separating axes: cheap, and decisive for large
//!    obstacle triangles whose boxes cover many particles).
//! 3. Narrow phase: the hybrid distance kernel on all surviving triangle pairs,
//!    in SIMD batches, multi-threaded.
//! 4. A pair of triangles is in contact when d < halo_a + halo_b; depth is
//!    halo_a + halo_b - d, the contact point the midpoint of the closest points
//!    P, Q and the normal (P - Q)/|P - Q|. When P = Q (triangles crossing, a
//!    penetration deeper than the halos) the normal is the outward face normal
//!    of b's triangle.
//! 5. Contacts of one body pair whose points coincide to within half the halo
//!    sum (a vertex shared by several triangles, say) are merged, keeping the
//!    deepest; the survivors share the pair's stiffness (see effects::contact).

mod geometry;

use crate::body::Body;
use crate::distance::{distance_many, Closest, Options, PenaltyStats, Solver, Triangle};
use crate::world::World;
use geometry::{BodyGeometry, Bounds};
use glam::DVec3;
use rayon::prelude::*;

/// One contact between bodies `a` < `b`; the normal points from b to a.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    pub a: usize,
    pub b: usize,
    /// The triangle pair that produced it: the key of its friction history.
    pub tri_a: u32,
    pub tri_b: u32,
    pub point: DVec3,
    pub normal: DVec3,
    pub depth: f64,
    /// Contacts of this body pair after merging.
    pub share: u32,
}

/// Counts of one detection pass.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DetectionStats {
    pub body_pairs: u64,
    pub triangle_pairs: u64,
    pub fallback_pairs: u64,
    pub contacts: u64,
    /// Contacts whose triangles crossed: the bodies went deeper than their
    /// halos (stiffness too low for the impact speed, or the step too long).
    pub deep_contacts: u64,
}

/// Bodies per parallel task of the geometry update.
const GEOMETRY_GRAIN: usize = 16;

/// Contact detector with its reusable buffers.
#[derive(Debug, Default)]
pub struct Detector {
    geometry: Vec<BodyGeometry>,
    pairs: Vec<(Triangle, Triangle)>,
    owners: Vec<(u32, u32, u32)>,
    out: Vec<Closest>,
    stats: Vec<PenaltyStats>,
}

impl Detector {
    /// Finds all contacts; `halos[i]` is body i's contact halo.
    pub fn detect(
        &mut self,
        world: &World,
        halos: &[f64],
        opts: &Options,
        contacts: &mut Vec<Contact>,
    ) -> DetectionStats {
        let bodies = &world.bodies;
        // World-space triangles, planes and boxes of every body that moved.
        self.geometry.resize(bodies.len(), BodyGeometry::default());
        self.geometry
            .par_iter_mut()
            .zip(bodies.par_iter())
            .zip(halos.par_iter())
            .with_min_len(GEOMETRY_GRAIN)
            .for_each(|((g, b), &h)| g.update(b, &world.shapes[b.shape], h));
        let geometry = &self.geometry;
        let boxes: Vec<Bounds> = geometry.iter().map(|g| g.bbox).collect();
        let body_pairs = sweep(&boxes, bodies);

        // Triangle pairs of every body pair, culled by inflated boxes and face planes.
        let owners: Vec<(u32, u32, u32)> = body_pairs
            .par_iter()
            .enumerate()
            .map_init(Vec::new, |ha: &mut Vec<(u32, Bounds)>, (k, &(a, b))| {
                let (ga, gb) = (&geometry[a], &geometry[b]);
                let (ta, tb) = (&ga.triangles, &gb.triangles);
                let reach = halos[a] + halos[b];
                ha.clear();
                ha.extend(
                    ga.bounds
                        .iter()
                        .enumerate()
                        .filter(|(_, bx)| bx.overlaps(&boxes[b]))
                        .map(|(i, bx)| (i as u32, *bx)),
                );
                let mut found = Vec::new();
                if ha.is_empty() {
                    return found;
                }
                for (j, t) in tb.iter().enumerate() {
                    let bj = gb.bounds[j];
                    if !bj.overlaps(&boxes[a]) {
                        continue;
                    }
                    let pb = gb.planes[j];
                    for &(i, bi) in ha.iter() {
                        let ti = &ta[i as usize];
                        if bi.overlaps(&bj)
                            && !plane_separates(pb, ti, reach)
                            && !plane_separates(ga.planes[i as usize], t, reach)
                        {
                            found.push((k as u32, i, j as u32));
                        }
                    }
                }
                found
            })
            .flatten_iter()
            .collect();
        self.pairs.clear();
        self.pairs.par_extend(owners.par_iter().map(|&(k, i, j)| {
            let (a, b) = body_pairs[k as usize];
            (
                geometry[a].triangles[i as usize],
                geometry[b].triangles[j as usize],
            )
        }));
        self.owners = owners;
        let n = self.pairs.len();
        self.out.resize(n, placeholder());
        self.stats.resize(n, PenaltyStats::default());
        let counts = distance_many(&self.pairs, opts, &mut self.out, &mut self.stats)
            .expect("batch size validated by the scene");

        // Contacts, grouped by body pair (owners are in body-pair order).
        contacts.clear();
        let mut deep = 0u64;
        let mut start = 0;
        while start < n {
            let k = self.owners[start].0;
            let mut end = start;
            while end < n && self.owners[end].0 == k {
                end += 1;
            }
            let (a, b) = body_pairs[k as usize];
            let reach = halos[a] + halos[b];
            let first = contacts.len();
            for idx in start..end {
                let r = &self.out[idx];
                if r.distance >= reach {
                    continue;
                }
                let (_, i, j) = self.owners[idx];
                let d = r.p - r.q;
                let len = d.length();
                let normal = if len > 0.0 && len.is_finite() {
                    d / len
                } else {
                    deep += 1;
                    outward_normal(&self.geometry[b].triangles[j as usize], &bodies[b])
                };
                let c = Contact {
                    a,
                    b,
                    tri_a: i,
                    tri_b: j,
                    point: (r.p + r.q) * 0.5,
                    normal,
                    depth: reach - r.distance,
                    share: 1,
                };
                merge_into(&mut contacts[first..], c, 0.5 * reach)
                    .map_or_else(|| contacts.push(c), |_| ());
            }
            let share = (contacts.len() - first) as u32;
            for c in &mut contacts[first..] {
                c.share = share;
            }
            start = end;
        }
        DetectionStats {
            body_pairs: body_pairs.len() as u64,
            triangle_pairs: n as u64,
            fallback_pairs: counts.fallback_pairs as u64,
            contacts: contacts.len() as u64,
            deep_contacts: deep,
        }
    }
}

/// Whether the plane (n, d) of one triangle has all of `t` on one side, farther
/// than `reach`: then no point of `t` is within `reach` of that triangle.
#[inline]
fn plane_separates((n, d): (DVec3, f64), t: &Triangle, reach: f64) -> bool {
    let h = [n.dot(t[0]) - d, n.dot(t[1]) - d, n.dot(t[2]) - d];
    let (lo, hi) = (h[0].min(h[1]).min(h[2]), h[0].max(h[1]).max(h[2]));
    lo > reach || hi < -reach
}

/// Merges `c` into a contact of the same pair at (nearly) the same place,
/// keeping the deeper one; `None` when there is none.
fn merge_into(existing: &mut [Contact], c: Contact, tol: f64) -> Option<()> {
    let m = existing
        .iter_mut()
        .find(|e| (e.point - c.point).length() <= tol)?;
    if c.depth > m.depth {
        *m = c;
    }
    Some(())
}

/// Outward normal of a world-space triangle of body `b` (its mesh is outward-facing).
fn outward_normal(t: &Triangle, b: &Body) -> DVec3 {
    let n = (t[1] - t[0]).cross(t[2] - t[0]);
    let n = n.try_normalize().unwrap_or(DVec3::Z);
    // Static obstacles keep their own frame; the centroid test is only a guard.
    let c = (t[0] + t[1] + t[2]) / 3.0;
    if b.is_static() || n.dot(c - b.x) >= 0.0 {
        n
    } else {
        -n
    }
}

/// Sort and sweep along x: pairs of overlapping boxes with at least one dynamic body.
fn sweep(boxes: &[Bounds], bodies: &[Body]) -> Vec<(usize, usize)> {
    let mut order: Vec<usize> = (0..boxes.len()).collect();
    order.sort_by(|&i, &j| boxes[i].lo.x.total_cmp(&boxes[j].lo.x));
    let mut pairs = Vec::new();
    for (k, &i) in order.iter().enumerate() {
        for &j in &order[k + 1..] {
            if boxes[j].lo.x > boxes[i].hi.x {
                break;
            }
            if (bodies[i].is_static() && bodies[j].is_static()) || !boxes[i].overlaps(&boxes[j]) {
                continue;
            }
            pairs.push((i.min(j), i.max(j)));
        }
    }
    pairs.sort_unstable();
    pairs
}

fn placeholder() -> Closest {
    Closest {
        distance: f64::INFINITY,
        p: DVec3::ZERO,
        q: DVec3::ZERO,
        solver: Solver::Brute,
    }
}
