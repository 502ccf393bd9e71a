//! The triangles one contact detector works on, split into the ones this
//! process owns and ghosts: copies of triangles owned elsewhere that lie within
//! contact reach of owned ones.
//!
//! On one node every triangle is owned and there are no ghosts. Split across
//! ranks, each rank holds its owned triangles and, once the exchange is done,
//! its ghosts; the detector then finds local-local pairs (which need nothing
//! from other ranks, so they can run while ghosts are in flight) and
//! local-ghost pairs (see [`super::Phase`]).
//!
//! Triangles are stored owned first, then ghosts, each part sorted by
//! [`TriangleKey`], so a body's triangles are contiguous within each part and
//! every body present has one [`BodyGroup`].

use super::bounds::Bounds;
use crate::body::Body;
use crate::distance::Triangle;
use crate::mesh::TriMesh;
use crate::world::World;
use glam::{DMat3, DQuat, DVec3};
use rayon::prelude::*;
use std::cell::UnsafeCell;
use std::ops::Range;

mod pass;
pub(crate) use pass::{Part, PassPairs, PassSet};
use std::sync::atomic::{AtomicU8, Ordering};

/// A triangle's global name: its body and its index in the body's mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct TriangleKey {
    pub body: u32,
    pub index: u32,
}

/// One triangle in world space, with its box for culling.
///
/// The face plane is not stored: culling needs it only for the triangles
/// that pass the box tests, and computing it there, in the parallel detection
/// tasks, is cheaper than writing it for every triangle in the update, which
/// on several threads is limited by moving cache lines between cores.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SetTriangle {
    pub vertices: Triangle,
    /// Box inflated by the body's halo.
    pub bounds: Bounds,
}

impl SetTriangle {
    fn new(vertices: Triangle, halo: f64) -> SetTriangle {
        SetTriangle {
            vertices,
            bounds: Bounds::of(&vertices, halo),
        }
    }

    /// Unit normal (outward for a body's validated mesh) and offset n · v0;
    /// zero normal for a degenerate triangle.
    #[inline]
    pub fn plane(&self) -> (DVec3, f64) {
        let v = &self.vertices;
        let n = (v[1] - v[0]).cross(v[2] - v[0]).normalize_or_zero();
        (n, n.dot(v[0]))
    }
}

/// The triangles of one body present in the set.
#[derive(Debug, Clone, PartialEq)]
pub struct BodyGroup {
    pub body: u32,
    pub owned: Range<usize>,
    pub ghost: Range<usize>,
    /// Union of the inflated boxes of the owned / ghost triangles.
    pub owned_box: Bounds,
    pub ghost_box: Bounds,
}

/// Owned triangles, then ghost triangles, with one group per body.
#[derive(Debug, Clone, Default)]
pub struct TriangleSet {
    keys: Vec<TriangleKey>,
    triangles: Vec<Slot<SetTriangle>>,
    owned: usize,
    groups: Vec<BodyGroup>,
    /// Pose and halo each body's triangles were last computed for, when the
    /// set mirrors the whole world (`update_from_world`): static obstacles,
    /// often the largest meshes, are computed once.
    poses: Vec<Option<(DVec3, DQuat, f64)>>,
    /// Per group, when the set follows the world lazily: whether its
    /// triangles are current (empty: all are).
    fresh: Freshness,
    /// Per group, when the set follows the world lazily: the box of its
    /// triangles as last filled (see [`pass::Filled::owned`]).
    filled_boxes: Vec<Slot<Bounds>>,
    /// Per group: halo and whether the body moves, as of `follow_world`.
    halos: Vec<f64>,
    moving: Vec<bool>,
    /// Whether [`TriangleSet::advance_lazily`] ran since the last
    /// `follow_world`: recorded poses then no longer say what was filled.
    advanced: bool,
    /// Counts the runs of `follow_world`; a replica's, the primary's count
    /// it last mirrored (see [`TriangleSet::mirror_lazily`]).
    generation: u64,
}

/// Makes room for `n` elements in an emptied vector without amortised
/// doubling: a rank's set grows by a few ghosts at a time, and doubling would
/// hold up to twice the triangles it needs. An eighth of headroom keeps
/// small growth from reallocating every time. The old array is freed before
/// the new one is taken, so that the two are never held at once.
fn room_for<T>(v: &mut Vec<T>, n: usize) {
    debug_assert!(v.is_empty());
    if v.capacity() < n {
        *v = Vec::new();
        v.reserve_exact(n + n / 8);
    }
}

/// A triangle (or a group's box) of the set, which a detection pass
/// ([`PassSet::fill`]) may write through a shared reference.
///
/// Written only through `&mut TriangleSet`, or by `PassSet::fill` on a stale
/// group; a pass over a set with stale groups holds the set's `&mut` borrow
/// (`PassSet::new`), so outside the pass module every `&TriangleSet` reads
/// slots that no one writes.
#[repr(transparent)]
struct Slot<T>(UnsafeCell<T>);

// SAFETY: concurrent access is ordered by the groups' states (see `pass`):
// a slot is written by one thread while no other reads it, and then read
// by many through `&T`, which needs `T: Sync` as well as `T: Send`.
unsafe impl<T: Send + Sync> Sync for Slot<T> {}

impl<T: Copy> Slot<T> {
    fn new(t: T) -> Slot<T> {
        Slot(UnsafeCell::new(t))
    }

    /// # Safety
    /// No thread writes the slot meanwhile (see the type's doc).
    unsafe fn get(&self) -> T {
        unsafe { *self.0.get() }
    }
}

impl<T: Copy> Clone for Slot<T> {
    fn clone(&self) -> Slot<T> {
        // SAFETY: a `&TriangleSet` outside a pass reads slots no one writes.
        Slot::new(unsafe { self.get() })
    }
}

impl<T: Copy + std::fmt::Debug> std::fmt::Debug for Slot<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // SAFETY: as for `Clone`.
        unsafe { self.get() }.fmt(f)
    }
}

/// Group states of a set that follows the world lazily.
const CURRENT: u8 = 0;
const STALE: u8 = 1;
const FILLING: u8 = 2;

/// One state per group (empty: every group is current).
#[derive(Debug, Default)]
struct Freshness(Vec<AtomicU8>);

impl Freshness {
    fn all_current(n: usize) -> Freshness {
        Freshness((0..n).map(|_| AtomicU8::new(CURRENT)).collect())
    }
}

impl Clone for Freshness {
    fn clone(&self) -> Freshness {
        Freshness(
            self.0
                .iter()
                .map(|a| AtomicU8::new(a.load(Ordering::Acquire)))
                .collect(),
        )
    }
}

/// When [`TriangleSet::follow_world`] computes the triangles of moving bodies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Fill {
    Now,
    OnDemand,
}

/// `body`'s mesh vertices in world space, into `out`: each vertex once, by
/// the rotation matrix (a closed mesh has about half as many vertices as
/// triangles, each triangle three). The one place they are computed, so the
/// boxes and the triangles filled later agree to the bit.
fn world_vertices(body: &Body, mesh: &TriMesh, out: &mut Vec<DVec3>) {
    let r = DMat3::from_quat(body.q);
    out.clear();
    out.extend(mesh.vertices.iter().map(|&v| body.x + r * v));
}

/// Whether every vertex of `mesh` is a corner of one of its triangles: then
/// the union of its triangles' boxes is the box of its vertices.
fn uses_every_vertex(mesh: &TriMesh) -> bool {
    let mut used = vec![false; mesh.vertices.len()];
    for &v in mesh.triangles.iter().flatten() {
        used[v as usize] = true;
    }
    used.into_iter().all(|u| u)
}

/// The box of `vertices` inflated by `halo`: for the vertices of a mesh
/// whose every vertex is a corner, the union of its triangles' inflated
/// boxes ([`Bounds::of`]) to the bit, since subtracting (adding) the halo
/// rounds monotonically and so commutes with the minimum (maximum).
fn vertices_box(vertices: &[DVec3], halo: f64) -> Bounds {
    let (lo, hi) = vertices
        .iter()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    Bounds {
        lo: lo - DVec3::splat(halo),
        hi: hi + DVec3::splat(halo),
    }
}

/// Body `i`'s triangles in world space, appended to `out` with their keys:
/// the same bits as the set that follows the world computes, so that a rank
/// holding a copy of a body's pose finds what one node finds.
pub fn body_triangles(world: &World, i: usize, out: &mut Vec<(TriangleKey, Triangle)>) {
    let body = &world.bodies[i];
    let mesh = &world.shapes[body.shape];
    let mut vertices = Vec::with_capacity(mesh.vertices.len());
    world_vertices(body, mesh, &mut vertices);
    out.extend(mesh.triangles.iter().enumerate().map(|(k, t)| {
        let key = TriangleKey {
            body: i as u32,
            index: k as u32,
        };
        let v = |j: usize| vertices[t[j] as usize];
        (key, [v(0), v(1), v(2)])
    }));
}

/// Bodies per parallel task when the set follows the world: small, because
/// the work per body is uneven (static bodies cost nothing after the first
/// step and are often numbered last, so coarse shares leave a thread idle).
const UPDATE_GRAIN: usize = 4;

impl TriangleSet {
    /// Every triangle of every body, owned: the one-node set. Only bodies that
    /// moved (or whose halo changed) since the last call are recomputed.
    pub fn update_from_world(&mut self, world: &World, halos: &[f64]) {
        self.follow_world(world, halos, Fill::Now);
    }

    /// Like [`Self::update_from_world`], but the triangles of moving bodies
    /// are left to [`PassSet::fill`], called by whichever detection task
    /// needs them first; only the groups' boxes are computed here.
    ///
    /// Why: on several threads, rewriting every triangle in a pass of its own
    /// was limited by moving cache lines between the cores (the detection
    /// tasks had read them on the other core): hopper, 2 threads, 0.13-0.35 s
    /// per run against 0.07 s on one (`tridem scaling`, docs/dem.md). Filled by
    /// the task that reads them, they are written where they are used.
    pub(crate) fn follow_world_lazily(&mut self, world: &World, halos: &[f64]) {
        self.follow_world(world, halos, Fill::OnDemand);
    }

    /// Makes this set a replica of `primary`, a set that follows the world
    /// lazily, for the pass about to run: the same layout, groups and halos,
    /// the moving bodies' triangles left to [`PassSet::fill`] (on this
    /// replica, by the thread that uses it), the static bodies' copied when
    /// they changed. Call after `primary`'s own update and before any fill.
    pub(crate) fn mirror_lazily(&mut self, primary: &TriangleSet) {
        // Groups name their body and triangle ranges: equal groups, equal keys.
        let same_layout = self.keys.len() == primary.keys.len()
            && self.groups.len() == primary.groups.len()
            && self
                .groups
                .iter()
                .zip(&primary.groups)
                .all(|(a, b)| (a.body, &a.owned, &a.ghost) == (b.body, &b.owned, &b.ghost))
            && self.fresh.0.len() == primary.fresh.0.len()
            && self.poses.len() == primary.poses.len();
        if !same_layout || primary.fresh.0.is_empty() {
            self.clone_from(primary);
            return;
        }
        if self.generation == primary.generation {
            // Only the moving bodies moved since: the groups, poses and halos
            // are as mirrored, and rewriting them would take their cache
            // lines from the core that reads them.
            for (state, &moving) in self.fresh.0.iter_mut().zip(&self.moving) {
                if moving {
                    *state.get_mut() = STALE;
                }
            }
            return;
        }
        for g in 0..self.groups.len() {
            self.groups[g].owned_box = primary.groups[g].owned_box;
            let state = if primary.moving[g] {
                STALE
            } else {
                if self.poses[g] != primary.poses[g] || self.halos[g] != primary.halos[g] {
                    // A static body placed anew: copy its triangles, filled
                    // by `primary`'s update.
                    for i in primary.groups[g].owned.clone() {
                        *self.triangles[i].0.get_mut() = *primary.triangle(i);
                    }
                    // SAFETY: `primary` is borrowed outside a pass (see `Slot`).
                    *self.filled_boxes[g].0.get_mut() = unsafe { primary.filled_boxes[g].get() };
                }
                CURRENT
            };
            *self.fresh.0[g].get_mut() = state;
        }
        self.poses.clone_from(&primary.poses);
        self.halos.clone_from(&primary.halos);
        self.moving.clone_from(&primary.moving);
        self.generation = primary.generation;
    }

    /// The bodies have moved since the last [`Self::follow_world_lazily`]:
    /// every moving body's triangles and box are left to
    /// [`PassSet::fill`], without reading the bodies. For a detector
    /// whose body pairs come from a list built with a skin (`Detector`); the
    /// group boxes of [`Self::groups`] stay as they were: a pass's filled
    /// group has the current one ([`pass::Filled::owned`]). Returns
    /// false (and changes nothing) unless the set already follows `world`'s
    /// bodies lazily.
    pub(crate) fn advance_lazily(&mut self, world: &World) -> bool {
        let follows = self.ghosts().is_empty()
            && self.groups.len() == world.bodies.len()
            && self.fresh.0.len() == self.groups.len()
            && self.filled_boxes.len() == self.groups.len()
            && self.moving.len() == self.groups.len();
        if !follows {
            return false;
        }
        for (state, &moving) in self.fresh.0.iter_mut().zip(&self.moving) {
            if moving {
                *state.get_mut() = STALE;
            }
        }
        self.advanced = true;
        true
    }

    fn follow_world(&mut self, world: &World, halos: &[f64], fill: Fill) {
        self.generation += 1;
        let bodies = &world.bodies;
        let sizes = || bodies.iter().map(|b| world.shapes[b.shape].triangles.len());
        let layout_matches = self.ghosts().is_empty()
            && self.groups.len() == bodies.len()
            && self
                .groups
                .iter()
                .zip(sizes())
                .enumerate()
                .all(|(i, (g, n))| g.body as usize == i && g.owned.len() == n)
            && self.poses.len() == bodies.len()
            && self.fresh.0.len() == bodies.len()
            && self.filled_boxes.len() == bodies.len();
        if !layout_matches {
            self.keys.clear();
            self.groups.clear();
            room_for(&mut self.keys, sizes().sum());
            room_for(&mut self.groups, bodies.len());
            for (i, n) in sizes().enumerate() {
                let start = self.keys.len();
                self.keys.extend((0..n as u32).map(|index| TriangleKey {
                    body: i as u32,
                    index,
                }));
                self.groups.push(BodyGroup {
                    body: i as u32,
                    owned: start..self.keys.len(),
                    ghost: 0..0,
                    owned_box: Bounds::EMPTY,
                    ghost_box: Bounds::EMPTY,
                });
            }
            let end = self.keys.len();
            for g in &mut self.groups {
                g.ghost = end..end;
            }
            self.owned = end;
            let zero = SetTriangle::new([DVec3::ZERO; 3], 0.0);
            self.triangles.clear();
            room_for(&mut self.triangles, end);
            self.triangles.resize_with(end, || Slot::new(zero));
            self.poses.clear();
            room_for(&mut self.poses, bodies.len());
            self.poses.resize(bodies.len(), None);
            self.fresh = Freshness::all_current(bodies.len());
            self.filled_boxes = vec![Slot::new(Bounds::EMPTY); bodies.len()];
            self.advanced = false;
        }
        self.halos.clear();
        self.halos
            .extend(self.groups.iter().map(|g| halos[g.body as usize]));
        self.moving.clear();
        self.moving.extend(
            self.groups
                .iter()
                .map(|g| !bodies[g.body as usize].is_fixed()),
        );
        // After `advance_lazily`, a moving body's triangles may have been
        // filled at a later pose than the one recorded: its pose no longer
        // tells whether they are current.
        let poses_tell = !std::mem::take(&mut self.advanced);
        let every_vertex_used: Vec<bool> = world.shapes.iter().map(uses_every_vertex).collect();
        // One mutable slice of triangles per body, updated in parallel.
        let mut slices = Vec::with_capacity(bodies.len());
        let mut rest = &mut self.triangles[..];
        for g in &self.groups {
            let (head, tail) = rest.split_at_mut(g.owned.len());
            slices.push(head);
            rest = tail;
        }
        slices
            .into_par_iter()
            .zip(self.groups.par_iter_mut())
            .zip(self.poses.par_iter_mut())
            .zip(self.fresh.0.par_iter_mut())
            .zip(self.filled_boxes.par_iter_mut())
            .with_min_len(UPDATE_GRAIN)
            .for_each_init(
                Vec::new,
                |vertices, ((((tris, group), pose), fresh), filled_box)| {
                    let i = group.body as usize;
                    let (body, halo) = (&bodies[i], halos[i]);
                    let key = (body.x, body.q, halo);
                    if !body.is_present() {
                        // Gone: a box that overlaps nothing, so no pair has it.
                        group.owned_box = Bounds::EMPTY;
                        *filled_box.0.get_mut() = Bounds::EMPTY;
                        *fresh.get_mut() = CURRENT;
                        *pose = None;
                        return;
                    }
                    // Unmoved, and filled unless filling is left to the tasks (a
                    // set followed lazily and then updated at once must not keep
                    // the stale triangles of a body no task needed).
                    if (poses_tell || body.is_fixed())
                        && *pose == Some(key)
                        && (fill == Fill::OnDemand || *fresh.get_mut() == CURRENT)
                    {
                        return;
                    }
                    let mesh = &world.shapes[body.shape];
                    world_vertices(body, mesh, vertices);
                    // Fixed obstacles are filled now: once, since they never move.
                    let fill_now = fill == Fill::Now || body.is_fixed();
                    if !fill_now && every_vertex_used[body.shape] {
                        let bbox = vertices_box(vertices, halo);
                        *fresh.get_mut() = STALE;
                        group.owned_box = bbox;
                        *filled_box.0.get_mut() = bbox;
                        *pose = Some(key);
                        return;
                    }
                    let mut bbox = Bounds::EMPTY;
                    for (slot, t) in tris.iter_mut().zip(&mesh.triangles) {
                        let v = [
                            vertices[t[0] as usize],
                            vertices[t[1] as usize],
                            vertices[t[2] as usize],
                        ];
                        let triangle = SetTriangle::new(v, halo);
                        if fill_now {
                            *slot.0.get_mut() = triangle;
                        }
                        bbox = bbox.union(&triangle.bounds);
                    }
                    *fresh.get_mut() = if fill_now { CURRENT } else { STALE };
                    group.owned_box = bbox;
                    *filled_box.0.get_mut() = bbox;
                    *pose = Some(key);
                },
            );
    }

    /// A set of explicitly given owned triangles (one rank's share), without
    /// ghosts. `halos` is indexed by body.
    pub fn with_owned(mut owned: Vec<(TriangleKey, Triangle)>, halos: &[f64]) -> TriangleSet {
        let mut set = TriangleSet::default();
        set.set_owned(&mut owned, halos);
        set
    }

    /// Replaces every triangle by `owned` (sorted here by key), without
    /// ghosts; the set's storage is kept for the next call.
    pub fn set_owned(&mut self, owned: &mut [(TriangleKey, Triangle)], halos: &[f64]) {
        if !owned.is_sorted_by_key(|e| e.0) {
            owned.sort_by_key(|e| e.0);
        }
        self.poses.clear();
        self.fresh = Freshness::default();
        self.filled_boxes.clear();
        self.halos.clear();
        self.moving.clear();
        self.keys.clear();
        self.triangles.clear();
        self.groups.clear();
        self.owned = 0;
        self.push_part(owned, halos);
        self.owned = owned.len();
        let n = self.owned;
        let runs = self.runs(0..n);
        self.groups
            .extend(runs.into_iter().map(|(body, r, bbox)| BodyGroup {
                body,
                owned: r,
                ghost: n..n,
                owned_box: bbox,
                ghost_box: Bounds::EMPTY,
            }));
    }

    /// Replaces the ghosts (what arrived from other ranks), keeping the owned part.
    pub fn set_ghosts(&mut self, mut ghosts: Vec<(TriangleKey, Triangle)>, halos: &[f64]) {
        if !ghosts.is_sorted_by_key(|e| e.0) {
            ghosts.sort_by_key(|e| e.0);
        }
        self.keys.truncate(self.owned);
        self.triangles.truncate(self.owned);
        self.push_part(&ghosts, halos);
        let n = self.keys.len();
        let owned: Vec<BodyGroup> = self
            .groups
            .drain(..)
            .filter(|g| !g.owned.is_empty())
            .collect();
        let mut own = owned.into_iter().peekable();
        let mut gho = self.runs(self.owned..n).into_iter().peekable();
        let empty_owned = self.owned..self.owned;
        // Groups: merge the bodies of the two sorted parts.
        loop {
            let body = match (own.peek(), gho.peek()) {
                (None, None) => break,
                (Some(o), None) => o.body,
                (None, Some(g)) => g.0,
                (Some(o), Some(g)) => o.body.min(g.0),
            };
            let mut group = own.next_if(|o| o.body == body).unwrap_or(BodyGroup {
                body,
                owned: empty_owned.clone(),
                ghost: n..n,
                owned_box: Bounds::EMPTY,
                ghost_box: Bounds::EMPTY,
            });
            (group.ghost, group.ghost_box) = match gho.next_if(|g| g.0 == body) {
                Some((_, r, bbox)) => (r, bbox),
                None => (n..n, Bounds::EMPTY),
            };
            self.groups.push(group);
        }
    }

    /// Appends triangles with their halos' boxes.
    fn push_part(&mut self, part: &[(TriangleKey, Triangle)], halos: &[f64]) {
        for (k, t) in part {
            self.keys.push(*k);
            self.triangles
                .push(Slot::new(SetTriangle::new(*t, halos[k.body as usize])));
        }
    }

    /// The runs of one body's triangles in `range` (sorted by key), with
    /// the union of their boxes.
    fn runs(&self, range: Range<usize>) -> Vec<(u32, Range<usize>, Bounds)> {
        let mut runs: Vec<(u32, Range<usize>, Bounds)> = Vec::new();
        for i in range {
            let b = self.triangle(i).bounds;
            match runs.last_mut() {
                Some((body, r, bbox)) if *body == self.keys[i].body => {
                    r.end = i + 1;
                    *bbox = bbox.union(&b);
                }
                _ => runs.push((self.keys[i].body, i..i + 1, b)),
            }
        }
        runs
    }

    /// Indices of the owned triangles.
    pub fn owned(&self) -> Range<usize> {
        0..self.owned
    }

    /// Indices of the ghost triangles.
    pub fn ghosts(&self) -> Range<usize> {
        self.owned..self.keys.len()
    }

    /// Bytes the set's triangles and their keys take (most of its memory).
    pub fn bytes(&self) -> usize {
        self.triangles.len()
            * (std::mem::size_of::<Slot<SetTriangle>>() + std::mem::size_of::<TriangleKey>())
    }

    pub fn len(&self) -> usize {
        self.keys.len()
    }

    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }

    pub fn key(&self, i: usize) -> TriangleKey {
        self.keys[i]
    }

    /// Triangle `i`. Of a set that follows the world lazily, a moving body's
    /// triangles are as of the last detection pass that needed them.
    pub fn triangle(&self, i: usize) -> &SetTriangle {
        // SAFETY: no one writes the slots of a set borrowed outside a pass
        // (see `Slot`), for as long as this borrow lasts.
        unsafe { &*self.triangles[i].0.get() }
    }

    /// One group per body present, in body order.
    pub fn groups(&self) -> &[BodyGroup] {
        &self.groups
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The box a moving body gets when its triangles are left to the tasks
    /// (from its vertices) is the union of its triangles' boxes, to the bit,
    /// at every scale and far from the origin; a mesh with a vertex no
    /// triangle uses keeps the triangles' union.
    #[test]
    fn a_body_box_from_its_vertices_is_its_triangles_union_to_the_bit() {
        let mut s = 7u64;
        let mut rnd = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mesh = crate::mesh::sphere_hull(60, 1.0, 3).unwrap();
        assert!(uses_every_vertex(&mesh));
        for scale in [1e-6, 1e-3, 1.0, 1e3, 1e6] {
            for far in [0.0, 1e4, 1e7] {
                for _ in 0..20 {
                    let body = Body {
                        shape: 0,
                        material: 0,
                        x: DVec3::new(rnd(), rnd(), rnd()) * scale + DVec3::splat(far * scale),
                        q: DQuat::from_xyzw(rnd(), rnd(), rnd(), rnd()).normalize(),
                        v: DVec3::ZERO,
                        l: DVec3::ZERO,
                        inv_mass: 1.0,
                        mass: 1.0,
                        inv_inertia_body: DMat3::IDENTITY,
                        inertia_body: DMat3::IDENTITY,
                        drive: None,
                        removed: false,
                        pending: false,
                    };
                    let m = TriMesh {
                        vertices: mesh.vertices.iter().map(|&v| v * scale).collect(),
                        triangles: mesh.triangles.clone(),
                    };
                    let halo = 0.01 * scale * (1.0 + rnd());
                    let mut vertices = Vec::new();
                    world_vertices(&body, &m, &mut vertices);
                    let union = m.triangles.iter().fold(Bounds::EMPTY, |acc, t| {
                        acc.union(&Bounds::of(&t.map(|k| vertices[k as usize]), halo))
                    });
                    let bits = |b: &Bounds| [b.lo, b.hi].map(|v| v.to_array().map(f64::to_bits));
                    assert_eq!(
                        bits(&vertices_box(&vertices, halo)),
                        bits(&union),
                        "scale {scale}, far {far}"
                    );
                }
            }
        }
        let mut loose = mesh.clone();
        loose.vertices.push(DVec3::splat(9.0));
        assert!(!uses_every_vertex(&loose), "a vertex no triangle uses");
    }

    fn tri(x: f64) -> Triangle {
        [
            DVec3::new(x, 0.0, 0.0),
            DVec3::new(x + 1.0, 0.0, 0.0),
            DVec3::new(x, 1.0, 0.0),
        ]
    }

    #[test]
    fn groups_cover_owned_then_ghost_triangles_by_body() {
        let k = |body, index| TriangleKey { body, index };
        let owned = vec![
            (k(2, 0), tri(2.0)),
            (k(0, 1), tri(0.0)),
            (k(0, 0), tri(0.0)),
        ];
        let mut set = TriangleSet::with_owned(owned, &[0.1, 0.1, 0.1, 0.1]);
        set.set_ghosts(vec![(k(3, 5), tri(3.0)), (k(2, 1), tri(2.0))], &[0.1; 4]);
        assert_eq!(set.owned(), 0..3);
        assert_eq!(set.ghosts(), 3..5);
        let keys: Vec<_> = (0..set.len()).map(|i| set.key(i)).collect();
        assert_eq!(keys, vec![k(0, 0), k(0, 1), k(2, 0), k(2, 1), k(3, 5)]);
        let g: Vec<_> = set
            .groups()
            .iter()
            .map(|g| (g.body, g.owned.clone(), g.ghost.clone()))
            .collect();
        assert_eq!(g, vec![(0, 0..2, 5..5), (2, 2..3, 3..4), (3, 3..3, 4..5)]);
        let b = &set.groups()[1];
        assert_eq!(b.owned_box.lo, DVec3::new(1.9, -0.1, -0.1));
        assert!(set.groups()[0].ghost_box.is_empty());
    }

    /// Followed lazily, a moving body's triangles wait for a task; updated at
    /// once afterwards (same poses), the set must hold every triangle, as a
    /// set updated at once from the start does.
    #[test]
    fn an_update_after_a_lazy_follow_fills_what_no_task_filled() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/drop.toml");
        let world = crate::scene::Scene::load(&path).unwrap().world;
        let halos = world.per_body(|m| m.halo);
        let mut eager = TriangleSet::default();
        eager.update_from_world(&world, &halos);
        let mut lazy = TriangleSet::default();
        lazy.follow_world_lazily(&world, &halos);
        assert_eq!(lazy.groups(), eager.groups(), "boxes are computed up front");
        let differs = (0..eager.len()).any(|i| lazy.triangle(i) != eager.triangle(i));
        assert!(differs, "moving bodies are left to the tasks");
        lazy.update_from_world(&world, &halos);
        for i in 0..eager.len() {
            assert_eq!(lazy.triangle(i), eager.triangle(i), "triangle {i}");
        }
    }
}
