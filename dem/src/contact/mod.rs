//! Contact detection between bodies made of triangles.
//!
//! The detector works on a [`TriangleSet`]: the triangles this process owns
//! and, split across ranks, ghost copies of triangles owned elsewhere. It
//! finds triangle contacts in two phases ([`Phase`]): local-local pairs first
//! (they need nothing from other ranks, so ghosts can be exchanged meanwhile),
//! then local-ghost pairs. On one node every triangle is owned and only the
//! first phase has work. Per phase:
//!
//! 0. On one node, the set follows the world: each body's box is computed from
//!    its pose, and the triangles of a moving body are filled in by the first
//!    detection task that needs them (`PassSet::fill`), on the
//!    core that then reads them. Each pool thread has a copy of the set of
//!    its own (`TriangleSet::mirror_lazily`), so that a triangle filled on
//!    one core is never read on the other: a body needed on both is filled
//!    twice, which costs less than moving its cache lines.
//! 1. Broad phase: sort and sweep over the bodies' boxes inflated by their halos
//!    (`broad_phase.rs`). With a skin ([`Detector::with_skin`]), on one node,
//!    the moving boxes are inflated by half the skin more and the pairs kept
//!    as a neighbour list, rebuilt only once two moving bodies may have
//!    moved a skin relative to one another, or a particle as far as its
//!    clearance from a fixed obstacle (`since_list.rs`); meanwhile each
//!    step's tasks fill the listed
//!    bodies and keep the pairs whose current boxes overlap, so the pairs
//!    examined are exactly those the broad phase would have returned.
//! 2. Triangle culling: a listed pair whose hulls were shown apart with a
//!    clearance that the bodies' displacements since have not used up is
//!    left out (see `PairMemo`); once they have, it is first tested again
//!    along the same direction on the whole bodies, from their vertices and
//!    poses, with no triangle read. A listed pair culled in full keeps its
//!    triangle pairs within reach plus a margin, examined alone (no culling)
//!    while the bodies' displacements since stay under it (`PairMemo::near`);
//!    otherwise only triangles whose inflated boxes overlap the other
//!    body's box, only pairs of those whose inflated boxes overlap, and only
//!    pairs that neither triangle's plane separates by more than the halo sum
//!    (the face normals are two separating axes: cheap, and decisive for large
//!    obstacle triangles whose boxes cover many particles).
//! 3. Narrow phase: the hybrid distance kernel on all surviving triangle pairs,
//!    in SIMD batches. Culling and kernel run in the same parallel task, over
//!    a share of the body pairs.
//! 4. A pair of triangles is in contact when their distance d is below the
//!    halo sum (the kernel's closest points are not kept: for parallel faces
//!    they are one choice among many).
//!
//! Then, per body pair, the contacts are built on the bodies' features from
//! its triangle contacts ([`features`]): corners of one body on the faces,
//! creases or corners of the other, and creases crossing creases, each a
//! named point with a normal and a depth. They do not depend on how the
//! triangles were split between tasks or ranks, nor on how the surfaces are
//! triangulated. On one node (one phase) each task builds the contacts of
//! the body pairs it owns, in parallel; split across ranks the caller builds
//! them once both phases are in ([`body_contacts`]).

mod bounds;
mod broad_phase;
pub mod features;
mod separation;
mod since_list;
mod sweep;
mod triangle_set;

pub use bounds::Bounds;
pub use features::{Contact, FeatureKey, FeatureKind, WeightGradient};
pub use since_list::ListMotion;
pub use triangle_set::{body_triangles, BodyGroup, SetTriangle, TriangleKey, TriangleSet};
use triangle_set::{Part, PassPairs, PassSet};

use crate::distance::{
    distance_many_serial, Closest, Counts, Options, PairSource, PenaltyStats, Triangle,
};
use crate::integrate::relative_travel_bound;
use crate::mesh::Features;
use crate::timing::{seconds_since, DetectionTimes};
use crate::world::World;
use features::{append_feature_contacts, FeatureScratch};
use glam::{DQuat, DVec3};
use rayon::prelude::*;
use since_list::ListPoses;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// A triangle pair within contact reach, before the body pair's contacts are built.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriangleContact {
    /// Triangle `a` of the lower-numbered body, `b` of the other.
    pub a: TriangleKey,
    pub b: TriangleKey,
    pub closest: Closest,
}

/// Which triangle pairs a detection pass examines.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Both triangles owned here.
    LocalLocal,
    /// An owned triangle of the lower-numbered body with a ghost of the other
    /// (the converse pairs belong to the rank owning the ghost).
    LocalGhost,
    /// Owned triangles of one body with the ghost triangles of the other, in
    /// either order: for sets in which each body is wholly owned or wholly a
    /// ghost, when both ranks of a pair across a cut compute it (each then
    /// acts on its own body, and no force travels back).
    Across,
}

/// The part a body plays in one rank's world, when a run is split across
/// ranks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// A particle this rank owns (moves, and computes the contacts of).
    Own,
    /// A copy of a particle owned elsewhere, within reach of this rank's.
    Ghost,
    /// A static obstacle.
    Obstacle,
}

/// Which of a rank's body pairs a share holds (see [`Detector::prepare`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Share {
    /// Pairs with no ghost: they need nothing from other ranks.
    Local = 0,
    /// Pairs of an owned particle and a ghost of higher id.
    Ghost = 1,
}

/// How the triangle pairs of a body pair are chosen for the kernel. Both
/// give the same contacts (no pair within reach is ever left out); they
/// differ in how many pairs they examine and what that costs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Culling {
    /// The bodies' hulls first (module `separation`): a body pair whose hulls are
    /// farther apart than its reach is done. Then the triangles near the
    /// other body's box, paired by a sweep over their boxes when there are
    /// many (module `sweep`): O(n + m) per body pair rather than O(n · m).
    #[default]
    Hulls,
    /// The triangles near the other body's box, each of one body's against
    /// each of the other's: O(n · m) per body pair, cheap for small meshes.
    Boxes,
}

crate::named_enum!(Culling, "culling", [(Hulls, "hulls"), (Boxes, "boxes")]);

/// What a listed body pair's last examination showed, for the next.
#[derive(Debug, Clone, Default)]
struct PairMemo {
    /// The direction that last separated (or nearly) its bodies' hulls,
    /// zero when not yet known (see [`separation::apart`]).
    hint: DVec3,
    /// While the two bodies' displacement relative to one another since
    /// `poses` (bounded by [`relative_travel_bound`]) stays under this,
    /// `near` still holds every
    /// triangle pair of theirs within reach (0: no such certificate). It is
    /// what the examination showed: the hulls' clearance beyond the reach
    /// (see [`separation::clearance`]), or the margin of `near`.
    budget: f64,
    /// The two bodies' poses (position, orientation) at the examination.
    poses: [(DVec3, DQuat); 2],
    /// The triangle pairs (indices into the set) that the examination found
    /// within reach plus [`Pass::margin`], nearest first; empty: none (the
    /// pair is left out, unexamined, while the budget lasts).
    near: Vec<(u32, u32)>,
    /// Per pair of `near`: by how much its distance then exceeded the reach,
    /// less the kernel's error allowance (see [`keep_near`]). A pair can be
    /// within reach now only if this is below the displacements since.
    gaps: Vec<f64>,
}

/// Pieces a share's pairs are examined in when messages are in flight
/// meanwhile (see [`Detector::detect_share`]): between pieces, the caller
/// lets them move.
const PROGRESS_PIECES: usize = 8;

/// Counts of one detection pass.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DetectionStats {
    pub body_pairs: u64,
    /// Body pairs among `body_pairs` whose convex hulls are farther apart
    /// than their reach: no triangle pair of theirs was examined.
    pub hulls_apart: u64,
    /// Listed body pairs not examined at all (not in `body_pairs`): their
    /// hulls were shown apart with a clearance, or none of their triangle
    /// pairs was within reach plus the kept pairs' margin, and the bodies'
    /// displacements since have not used that up (docs/dem.md, "Culling").
    pub known_apart: u64,
    /// Body pairs among `body_pairs` whose triangle pairs were taken from
    /// those kept at an earlier culling, with no culling of their own.
    pub near_kept: u64,
    pub triangle_pairs: u64,
    pub fallback_pairs: u64,
    pub contacts: u64,
    /// Contacts deeper than the halos (a corner behind a face, creases
    /// crossed): stiffness too low for the impact speed, or the step too long.
    pub deep_contacts: u64,
    /// Broad phases run (one per pass without a skin; with one, each
    /// rebuild of the neighbour list).
    pub broad_phases: u64,
    /// The fallback rate of the pass's least and most falling-back task
    /// (fallback pairs over the task's triangle pairs), summed over passes
    /// with tasks: how unevenly the kernel's fallbacks land on threads.
    pub task_fallback_min: f64,
    pub task_fallback_max: f64,
    /// Passes whose tasks examined triangle pairs (the count of the sums above).
    pub passes_with_pairs: u64,
}

impl std::ops::AddAssign for DetectionStats {
    fn add_assign(&mut self, o: DetectionStats) {
        self.body_pairs += o.body_pairs;
        self.hulls_apart += o.hulls_apart;
        self.known_apart += o.known_apart;
        self.near_kept += o.near_kept;
        self.triangle_pairs += o.triangle_pairs;
        self.fallback_pairs += o.fallback_pairs;
        self.contacts += o.contacts;
        self.deep_contacts += o.deep_contacts;
        self.broad_phases += o.broad_phases;
        self.task_fallback_min += o.task_fallback_min;
        self.task_fallback_max += o.task_fallback_max;
        self.passes_with_pairs += o.passes_with_pairs;
    }
}

/// Contact detector with its reusable buffers.
#[derive(Debug, Default)]
pub struct Detector {
    /// The one-node set, following the world, and one replica of it per
    /// further thread of the pool: see [`Detector::detect_moved`].
    sets: Vec<TriangleSet>,
    /// One per task of a pass, kept between passes for their capacity.
    tasks: Vec<Task>,
    broad: broad_phase::BroadPhase,
    /// Where the last pass spent its time.
    times: DetectionTimes,
    /// The neighbour list's skin (0: the broad phase runs in every pass).
    skin: f64,
    /// The body pairs of the last broad phase, with moving boxes inflated by
    /// half the skin, while `travel` stays within half the skin; split
    /// across ranks, in two shares (see [`Share`]), on one node all in the
    /// first.
    lists: [Vec<(usize, usize)>; 3],
    /// Per pair of the first two lists: what its last examination showed.
    memos: [Vec<PairMemo>; 2],
    /// Per pair of the first two lists: its bodies' ids, by which the next
    /// list finds the memos that still hold (see `carry_memos`); `None`:
    /// its memo is not carried.
    listed_ids: [Vec<Option<(u32, u32)>>; 2],
    /// Per body: body pairs and triangle pairs examined with it as the first
    /// body, since [`Detector::take_work`].
    work: Vec<[u64; 2]>,
    /// Whether [`Detector::count_work`] was asked for.
    count_work: bool,
    /// Whether `lists` hold a neighbour list that may be kept (the third
    /// list: pairs other ranks examine, see [`Detector::theirs`]).
    listed: bool,
    /// How far any point of any body may have moved since the list was
    /// built: the sum of each pass's largest travel.
    travel: f64,
    /// The bodies' poses when the list was built: once `travel` exceeds
    /// half the skin, whether the list still holds is measured from them.
    since: ListPoses,
    /// Per shape of the world: the largest distance of a vertex from the
    /// body's centre, which bounds how far a turn moves any point.
    radii: Vec<f64>,
    /// Bytes the copies of the set beyond the first may take (`None`:
    /// [`REPLICA_BUDGET`]); see [`Detector::with_replica_budget`].
    replica_budget: Option<usize>,
    culling: Culling,
}

/// Bytes the per-thread copies of the triangle set may take by default,
/// beyond the first: 256 MiB, a copy per thread (128 bytes per triangle)
/// for up to two million triangles on two threads, 65,000 on 32. Larger
/// sets get fewer copies, shared by the threads in turn (a copy is a
/// speed-up, never needed).
pub const REPLICA_BUDGET: usize = 256 << 20;

/// Candidate triangle pairs of a body pair above which they are found by a
/// sweep ([`sweep`]) rather than by testing every pair: below, the n · m
/// branch-free box tests cost less than sorting.
const SWEEP_ABOVE: usize = 256;

/// The margin of a listed body pair's kept triangle pairs, in skins. A
/// larger one keeps them for longer, and costs more kernel calls where they
/// are kept (the triangle pairs within reach and margin); no body moves more
/// than half a skin before the neighbour list is built anew, which forgets
/// them, so a margin of one skin would outlive every list.
const NEAR_MARGIN: f64 = 0.25;

/// How many body pairs ahead a detection task asks for the poses of the
/// bodies it will fill (see `PassSet::prefetch_pose`).
const PREFETCH_AHEAD: usize = 2;

/// What one parallel task of a detection pass owns: its share of the body
/// pairs is culled and sent through the kernel by the same thread, so the
/// triangle pairs stay in its cache and no pass joins between the two.
#[derive(Debug, Default)]
struct Task {
    /// Scratch of the culling: triangles of a near b's box, of b near a's
    /// box, and the pairs found for one triangle of b.
    candidates: Vec<u32>,
    others: Vec<u32>,
    /// Face planes of `candidates` and `others`.
    candidate_planes: Vec<(DVec3, f64)>,
    other_planes: Vec<(DVec3, f64)>,
    hits: Vec<(u32, u32)>,
    /// Boxes of `candidates` and `others`, and the sweep over them, for
    /// body pairs with many triangles near each other.
    candidate_boxes: Vec<Bounds>,
    other_boxes: Vec<Bounds>,
    sweep: sweep::Sweep,
    /// Scratch of `PassSet::fill`.
    vertices: Vec<DVec3>,
    /// Scratch of the hull test.
    hulls: HullScratch,
    /// Body pairs whose boxes overlapped but whose hulls are farther apart
    /// than their reach.
    hulls_apart: usize,
    /// Listed body pairs left out: an earlier certificate still holds.
    known_apart: usize,
    /// Body pairs examined on their kept triangle pairs.
    near_kept: usize,
    /// Body pairs culled in full in this pass whose triangle pairs are kept,
    /// and the scratch that sorts them (see [`keep_near`]).
    kept: Vec<Kept>,
    nearest: Vec<(f64, (u32, u32))>,
    /// Triangle pairs (indices into the set) that the kernel examines.
    owners: Vec<(u32, u32)>,
    out: Vec<Closest>,
    stats: Vec<PenaltyStats>,
    /// Body pairs whose boxes overlapped.
    body_pairs: usize,
    /// Per body pair examined: its first group, and the triangle pairs
    /// that went to the kernel (see [`Detector::work`]).
    work: Vec<(u32, u32)>,
    found: Vec<TriangleContact>,
    counts: Counts,
    scratch: FeatureScratch,
    contacts: Vec<Contact>,
    deep: u64,
    /// Seconds `run` took in the last pass.
    busy: f64,
}

impl Detector {
    /// A detector keeping a neighbour list with this skin (a length, >= 0;
    /// 0: no list, the broad phase runs in every pass). See [`Self::detect_moved`].
    pub fn with_skin(skin: f64) -> Detector {
        assert!(skin >= 0.0 && skin.is_finite(), "skin {skin}");
        Detector {
            skin,
            ..Detector::default()
        }
    }

    /// This detector choosing triangle pairs by `culling` (results do not
    /// depend on it).
    pub fn with_culling(self, culling: Culling) -> Detector {
        Detector { culling, ..self }
    }

    /// This detector with at most `bytes` for the copies of the triangle set
    /// beyond the first (0: one set, shared by all threads; results do not
    /// depend on it).
    pub fn with_replica_budget(self, bytes: usize) -> Detector {
        Detector {
            replica_budget: Some(bytes),
            ..self
        }
    }

    /// All contacts of the world on one node; `halos[i]` is body i's contact
    /// halo, `features[s]` the features of shape s. Runs the broad phase
    /// (nothing is known of how bodies moved).
    pub fn detect(
        &mut self,
        world: &World,
        features: &[Features],
        halos: &[f64],
        opts: &Options,
        contacts: &mut Vec<Contact>,
    ) -> DetectionStats {
        self.detect_moved(world, features, halos, opts, None, contacts)
    }

    /// Like [`Self::detect`], told `moved`: a bound on how far any point of any
    /// body has moved since the previous pass (`None`: unknown). With a skin,
    /// the broad phase is skipped while the list it last drew holds every
    /// pair that can touch: while these bounds add up to at most half the
    /// skin, and after that while the bodies' motion since, measured from
    /// their poses then, keeps the skin ([`ListMotion`]). Results are the
    /// same as without a skin.
    /// `halos` must not change between passes that keep the list (they are
    /// read when it is built).
    pub fn detect_moved(
        &mut self,
        world: &World,
        features: &[Features],
        halos: &[f64],
        opts: &Options,
        moved: Option<f64>,
        contacts: &mut Vec<Contact>,
    ) -> DetectionStats {
        self.travel += moved.unwrap_or(f64::INFINITY);
        // NaN travel (a body's state gone bad) rebuilds too.
        let keep = self.skin > 0.0
            && self.travel.is_finite()
            && (self.travel <= 0.5 * self.skin
                || self
                    .list_motion(world, 0..world.bodies.len())
                    .keeps(self.skin));
        let mut stats = self.prepare(world, halos, &[], keep);
        contacts.clear();
        stats += self.detect_share(world, features, halos, opts, Share::Local, None, contacts);
        stats
    }

    /// How the bodies `ids` of `world` (laid out as when the neighbour list
    /// was built) moved since, in the terms of the list's validity
    /// ([`ListMotion`]): merged over every body a rank moves, and kept while
    /// they [`ListMotion::keeps`] the skin. Unknown without a list.
    pub fn list_motion(&self, world: &World, ids: impl Iterator<Item = usize>) -> ListMotion {
        match self.listed {
            true => self.since.motion(&world.bodies, &self.radii, ids),
            false => ListMotion::UNKNOWN,
        }
    }

    /// Starts a detection whose pairs are then examined by
    /// [`Self::detect_share`]: moves the triangle sets with the bodies, and
    /// runs the broad phase unless `keep_list` and a neighbour list is held
    /// (the caller then knows that it still holds: no body moved farther
    /// than half the skin since it was built, or the bodies'
    /// [`Self::list_motion`] keeps the skin). Returns the counts of the
    /// broad phase.
    ///
    /// `roles` (empty on one node) splits the pairs of a rank's world, whose
    /// bodies are in the order of their ids: a pair is examined on the rank
    /// that owns its first particle (the lower id, or the particle of a pair
    /// with an obstacle), in [`Share::Local`] when neither body is a ghost,
    /// in [`Share::Ghost`] when one is. Pairs that are some other rank's
    /// business are dropped.
    pub fn prepare(
        &mut self,
        world: &World,
        halos: &[f64],
        roles: &[Role],
        keep_list: bool,
    ) -> DetectionStats {
        let mut sets = std::mem::take(&mut self.sets);
        if sets.is_empty() {
            sets.push(TriangleSet::default());
        }
        let start = Instant::now();
        let keep = keep_list && self.listed && sets[0].advance_lazily(world);
        if !keep {
            sets[0].follow_world_lazily(world, halos);
        }
        // Each thread fills and reads the moving bodies' triangles in a set of
        // its own: in one shared set, the triangles one core filled were
        // read by the other, and moving them between the cores cost more
        // than filling a body twice (docs/dem.md, "Threads").
        let copies = self.replica_budget.unwrap_or(REPLICA_BUDGET) / sets[0].bytes().max(1);
        let n_sets = rayon::current_num_threads().clamp(1, 1 + copies);
        sets.truncate(n_sets);
        sets.resize_with(n_sets, TriangleSet::default);
        let (primary, replicas) = sets.split_at_mut(1);
        for r in replicas {
            r.mirror_lazily(&primary[0]);
        }
        self.times = DetectionTimes {
            triangle_update: seconds_since(start),
            ..DetectionTimes::default()
        };
        let mut stats = DetectionStats::default();
        if !keep {
            let start = Instant::now();
            let views: Vec<PassSet> = sets.iter_mut().map(PassSet::new).collect();
            let pairs = broad_phase(&mut self.broad, world, &views, 0.5 * self.skin);
            split_pairs(pairs, views[0].groups(), roles, &mut self.lists);
            if self.skin > 0.0 {
                (self.since).record(world, views[0].groups(), 0.5 * self.skin);
            }
            // Without a skin the detection keeps no memory from step to
            // step: it is the reference the list is checked against.
            carry_memos(
                world,
                views[0].groups(),
                &self.lists,
                &mut self.memos,
                &mut self.listed_ids,
                self.skin > 0.0,
            );
            self.times.broad_phase = seconds_since(start);
            stats.broad_phases = 1;
            self.travel = 0.0;
            self.radii = world.shape_radii();
            self.listed = self.skin > 0.0;
        }
        self.sets = sets;
        stats
    }

    /// Counts, from now on, the work of each body pair examined for its
    /// first body (see [`Detector::take_work`]).
    pub fn count_work(&mut self) {
        self.count_work = true;
    }

    /// Per body of the world last examined: the body pairs and triangle
    /// pairs examined with it as the first body (split across ranks: the
    /// pairs whose cost its rank pays) since the last call, which starts
    /// the count anew. The cost of a body's contacts, for partitioning by
    /// work.
    pub fn take_work(&mut self) -> Vec<[u64; 2]> {
        std::mem::take(&mut self.work)
    }

    /// The body pairs of the last broad phase, split across ranks, of a
    /// ghost and an owned particle of higher id: the ghost's owner examines
    /// them (as bodies of this rank's world; on one node, none).
    pub fn theirs(&self) -> &[(usize, usize)] {
        &self.lists[2]
    }

    /// The body pairs of one share of the last broad phase (as bodies).
    pub fn share(&self, share: Share) -> &[(usize, usize)] {
        &self.lists[share as usize]
    }

    /// Examines one share of the pairs [`Self::prepare`] found (on one node,
    /// [`Share::Local`] holds them all), appending their contacts to
    /// `contacts` in pair order. With `progress`, the work is done in
    /// pieces, and `progress` called from this thread after each (to let
    /// messages in flight move) until it answers that none is in flight any
    /// more: the rest is then one piece, since each piece's tasks end their
    /// kernel batches part-filled. The
    /// bodies of the share must be where they are to be examined: a ghost's
    /// pose may arrive after `prepare`, before its share is examined.
    #[allow(clippy::too_many_arguments)]
    pub fn detect_share(
        &mut self,
        world: &World,
        features: &[Features],
        halos: &[f64],
        opts: &Options,
        share: Share,
        mut progress: Option<&mut dyn FnMut() -> bool>,
        contacts: &mut Vec<Contact>,
    ) -> DetectionStats {
        let list = std::mem::take(&mut self.lists[share as usize]);
        let mut memos = std::mem::take(&mut self.memos[share as usize]);
        memos.resize(list.len(), PairMemo::default());
        let mut sets = std::mem::take(&mut self.sets);
        let views: Vec<PassSet> = sets.iter_mut().map(PassSet::new).collect();
        let pass = Pass {
            world,
            sets: &views,
            halos,
            opts,
            phase: Phase::LocalLocal,
            build: Some(features),
            culling: self.culling,
            radii: &self.radii,
            margin: match self.culling {
                Culling::Hulls => NEAR_MARGIN * self.skin,
                Culling::Boxes => 0.0,
            },
        };
        let mut stats = DetectionStats::default();
        let pieces = if progress.is_some() {
            PROGRESS_PIECES
        } else {
            1
        };
        let per = list.len().div_ceil(pieces).max(1);
        let (mut rest, mut rest_memos) = (&list[..], &mut memos[..]);
        let mut in_flight = progress.is_some();
        // An empty list is one (empty) piece: the pass runs, and is timed.
        let mut first = true;
        while first || !rest.is_empty() {
            first = false;
            let len = if in_flight {
                per.min(rest.len())
            } else {
                rest.len()
            };
            let (piece, tail) = rest.split_at(len);
            let (memos, memos_tail) = std::mem::take(&mut rest_memos).split_at_mut(len);
            (rest, rest_memos) = (tail, memos_tail);
            let (s, n_tasks) = run_tasks(&mut self.tasks, &mut self.times, &pass, piece, memos);
            stats += s;
            // Each task built the contacts of its own body pairs (a body
            // pair's triangle contacts all come from one task), and the tasks
            // hold consecutive shares of the sorted body pairs, so joining
            // their contacts in task order gives what `body_contacts` would.
            for task in &self.tasks[..n_tasks] {
                contacts.extend_from_slice(&task.contacts);
                stats.deep_contacts += task.deep;
                stats.contacts += task.contacts.len() as u64;
                if self.count_work {
                    let groups = views[0].groups();
                    for &(g, n) in &task.work {
                        let body = groups[g as usize].body as usize;
                        if self.work.len() <= body {
                            self.work.resize(body + 1, [0; 2]);
                        }
                        self.work[body][0] += 1;
                        self.work[body][1] += u64::from(n);
                    }
                }
            }
            if let (true, Some(p)) = (in_flight, progress.as_mut()) {
                in_flight = p();
            }
        }
        drop(views);
        self.sets = sets;
        self.lists[share as usize] = list;
        self.memos[share as usize] = memos;
        stats
    }

    /// Where the last pass ([`Self::detect`] or [`Self::triangle_contacts`])
    /// spent its time (no triangle update in the latter: the caller's set).
    pub fn last_times(&self) -> DetectionTimes {
        self.times
    }

    /// Appends to `found` the triangle contacts of one phase on `set`, from
    /// which [`body_contacts`] builds the contacts once all phases are in.
    /// Returns the pass's counts (contacts counted by [`body_contacts`], so 0
    /// here).
    pub fn triangle_contacts(
        &mut self,
        world: &World,
        set: &TriangleSet,
        halos: &[f64],
        opts: &Options,
        phase: Phase,
        found: &mut Vec<TriangleContact>,
    ) -> DetectionStats {
        // The caller's set is shared: a pass may only read it.
        let view = PassSet::of_current(set).expect("a caller's set is never followed lazily");
        let pass = Pass {
            world,
            sets: std::slice::from_ref(&view),
            halos,
            opts,
            phase,
            build: None,
            culling: self.culling,
            radii: &[],
            margin: 0.0,
        };
        let (stats, n_tasks) = self.broad_and_narrow(&pass, 0.0);
        for task in &self.tasks[..n_tasks] {
            found.extend_from_slice(&task.found);
        }
        stats
    }

    /// The broad phase (moving boxes inflated by `pad` more), then the tasks
    /// of one phase on its pairs; returns the pass's counts and how many of
    /// `self.tasks` ran.
    fn broad_and_narrow(&mut self, pass: &Pass, pad: f64) -> (DetectionStats, usize) {
        let (world, set, phase) = (pass.world, &pass.sets[0], pass.phase);
        let start = Instant::now();
        // The broad phase is serial: meanwhile another thread fills triangles
        // that the tasks would otherwise fill (a no-op for sets that are not
        // filled lazily, and on one thread, where it starts after the broad
        // phase has already said stop).
        let stop = AtomicBool::new(false);
        let broad = &mut self.broad;
        let (body_pairs, ()) = rayon::join(
            || {
                let pairs = broad.body_pairs(set.groups(), &world.bodies, phase, pad);
                stop.store(true, Ordering::Relaxed);
                pairs
            },
            || pass.set_of_this_thread().prefill_until(world, &stop),
        );
        self.times = DetectionTimes {
            broad_phase: seconds_since(start),
            ..DetectionTimes::default()
        };
        // No list kept: nothing to remember either.
        let mut memos = vec![PairMemo::default(); body_pairs.len()];
        let (mut stats, n_tasks) = run_tasks(
            &mut self.tasks,
            &mut self.times,
            pass,
            body_pairs,
            &mut memos,
        );
        stats.broad_phases = 1;
        (stats, n_tasks)
    }
}

/// The broad phase over the lazily followed `sets` (moving boxes inflated
/// by `pad` more): pairs of group indices, sorted. Meanwhile another thread
/// fills triangles that the tasks would otherwise fill (on one thread, it
/// starts after the broad phase has already said stop).
fn broad_phase<'b>(
    broad: &'b mut broad_phase::BroadPhase,
    world: &World,
    sets: &[PassSet],
    pad: f64,
) -> &'b [(usize, usize)] {
    let stop = AtomicBool::new(false);
    let set = sets[0];
    let this_thread = sets[rayon::current_thread_index().unwrap_or(0) % sets.len()];
    let (pairs, ()) = rayon::join(
        || {
            let pairs = broad.body_pairs(set.groups(), &world.bodies, Phase::LocalLocal, pad);
            stop.store(true, Ordering::Relaxed);
            pairs
        },
        || this_thread.prefill_until(world, &stop),
    );
    pairs
}

/// Splits the broad phase's `pairs` (of `groups`, one per body) into the
/// shares of [`Detector::prepare`] (all in the first without `roles`), and
/// the pairs of a ghost and an owned particle of higher id, which the
/// ghost's owner examines (the third list).
fn split_pairs(
    pairs: &[(usize, usize)],
    groups: &[BodyGroup],
    roles: &[Role],
    lists: &mut [Vec<(usize, usize)>; 3],
) {
    lists.iter_mut().for_each(Vec::clear);
    if roles.is_empty() {
        lists[0].extend_from_slice(pairs);
        return;
    }
    for &(g, h) in pairs {
        let (a, b) = (groups[g].body as usize, groups[h].body as usize);
        if let Some(share) = share_of(roles[a], roles[b]) {
            lists[share as usize].push((g, h));
        } else if (roles[a], roles[b]) == (Role::Ghost, Role::Own) {
            lists[2].push((g, h));
        }
    }
}

/// New memos for new `lists` (of `groups`' indices): a pair listed before
/// (by its bodies' ids, `listed_ids`, set anew here) whose last examination
/// showed its bodies apart with a clearance keeps it, with the poses it
/// holds from and its separating direction: none depends on the list. Kept
/// triangle pairs are not carried, although on one node their set indices
/// would still hold: a rebuild is what sends a body pair whose kept pairs
/// have drifted beyond reach back to the hull test, whose certificate costs
/// no kernel call while it lasts. Carried, the kept pairs of grains that
/// have since parted go on to the kernel step after step (the same bits,
/// but many more triangle pairs, and slower on hopper-400 and silo-1000).
/// Nor are the hints of pairs that were not apart carried (GJK
/// started from a stale direction examines more triangle pairs than from
/// the centroids). Only pairs of bodies whose
/// triangles the set holds whole, in one part, carry: a rank's share of an
/// obstacle changes with its region, and a clearance from the old share
/// says nothing of the new one. Nothing is carried unless `carry`.
fn carry_memos(
    world: &World,
    groups: &[BodyGroup],
    lists: &[Vec<(usize, usize)>; 3],
    memos: &mut [Vec<PairMemo>; 2],
    listed_ids: &mut [Vec<Option<(u32, u32)>>; 2],
    carry: bool,
) {
    let id = |g: usize| world.id(groups[g].body as usize);
    let whole = |g: usize| {
        let group = &groups[g];
        let n = world.shapes[world.bodies[group.body as usize].shape]
            .triangles
            .len();
        let (owned, ghost) = (group.owned.len(), group.ghost.len());
        (owned, ghost) == (n, 0) || (owned, ghost) == (0, n)
    };
    for ((memos, ids), list) in memos.iter_mut().zip(listed_ids.iter_mut()).zip(lists) {
        let before: std::collections::HashMap<(u32, u32), usize> = ids
            .iter()
            .enumerate()
            .filter_map(|(k, p)| p.map(|p| (p, k)))
            .collect();
        let old = std::mem::take(memos);
        ids.clear();
        ids.extend(
            list.iter()
                .map(|&(g, h)| (carry && whole(g) && whole(h)).then(|| (id(g), id(h)))),
        );
        memos.extend(ids.iter().map(|p| {
            let found = p.and_then(|p| before.get(&p));
            let Some(m) = found.and_then(|&k| old.get(k)) else {
                return PairMemo::default();
            };
            if !(m.near.is_empty() && m.budget > 0.0) {
                return PairMemo::default();
            }
            PairMemo {
                hint: m.hint,
                budget: m.budget,
                poses: m.poses,
                ..PairMemo::default()
            }
        }));
    }
}

/// The share of a pair of bodies a < b (by id) on a rank, where `None`: the
/// pair is another rank's business (see [`Detector::prepare`]).
pub fn share_of(a: Role, b: Role) -> Option<Share> {
    match (a, b) {
        (Role::Own, Role::Own | Role::Obstacle) | (Role::Obstacle, Role::Own) => Some(Share::Local),
        (Role::Own, Role::Ghost) => Some(Share::Ghost),
        _ => None,
    }
}

/// What one detection pass works on. With `build` (the shapes' features),
/// each task also builds the contacts of its body pairs.
#[derive(Clone, Copy)]
struct Pass<'a> {
    world: &'a World,
    /// The same triangles: one set, or one per thread of the pool (the
    /// thread of index k uses set k, filling it on demand).
    sets: &'a [PassSet<'a>],
    halos: &'a [f64],
    opts: &'a Options,
    phase: Phase,
    build: Option<&'a [Features]>,
    culling: Culling,
    /// The shapes' radii, which bound how far a turn moves a point (see
    /// [`PairMemo::budget`]); empty: the memos are not kept, and no pair is
    /// left out.
    radii: &'a [f64],
    /// How much farther than their reach apart the triangle pairs a hull
    /// culling keeps for a listed body pair may be (see `PairMemo::near`;
    /// 0: none kept).
    margin: f64,
}

/// Runs the tasks of one phase on `body_pairs` (sorted), with their memos; returns the pass's counts and how many of
/// `tasks` ran, and sets the narrow phase's time.
///
/// Body pairs are shared among tasks as the kernel's schedule says
/// ([`Threading::share_lengths`](crate::distance::Threading::share_lengths)).
fn run_tasks(
    tasks: &mut Vec<Task>,
    times: &mut DetectionTimes,
    pass: &Pass,
    body_pairs: &[(usize, usize)],
    memos: &mut [PairMemo],
) -> (DetectionStats, usize) {
    let start = Instant::now();
    // One thread takes the pairs in one task: more would only end more
    // kernel batches part-filled.
    let threads = rayon::current_num_threads();
    let lengths = if threads == 1 && !body_pairs.is_empty() {
        vec![body_pairs.len()]
    } else {
        pass.opts.threading.share_lengths(body_pairs.len(), threads)
    };
    let n_tasks = lengths.len();
    if tasks.len() < n_tasks {
        tasks.resize_with(n_tasks, Task::default);
    }
    let (mut rest, mut rest_memos) = (body_pairs, memos);
    let shares = lengths.iter().map(|&len| {
        let (share, tail) = rest.split_at(len);
        let (share_memos, memos_tail) = std::mem::take(&mut rest_memos).split_at_mut(len);
        (rest, rest_memos) = (tail, memos_tail);
        (share, share_memos)
    });
    // Tasks taken in order by whichever thread is free (rayon's own
    // splitting would hand out halves of the list, whatever they cost).
    shares
        .zip(tasks[..n_tasks].iter_mut())
        .par_bridge()
        .for_each(|((share, memos), task)| {
            let start = Instant::now();
            task.run(pass, share, memos);
            task.busy = seconds_since(start);
        });
    times.narrow_phase += seconds_since(start);
    let mut stats = DetectionStats::default();
    let mut counts = Counts::default();
    let (mut least, mut most) = (f64::INFINITY, f64::NEG_INFINITY);
    for task in &tasks[..n_tasks] {
        times.narrow_phase_busy += task.busy;
        stats.body_pairs += task.body_pairs as u64;
        stats.hulls_apart += task.hulls_apart as u64;
        stats.known_apart += task.known_apart as u64;
        stats.near_kept += task.near_kept as u64;
        stats.triangle_pairs += task.owners.len() as u64;
        counts = counts + task.counts;
        if !task.owners.is_empty() {
            let rate = task.counts.fallback_pairs as f64 / task.owners.len() as f64;
            least = least.min(rate);
            most = most.max(rate);
        }
    }
    stats.fallback_pairs = counts.fallback_pairs as u64;
    if most >= least {
        stats.task_fallback_min = least;
        stats.task_fallback_max = most;
        stats.passes_with_pairs = 1;
    }
    (stats, n_tasks)
}

impl<'a> Pass<'a> {
    /// The set the calling thread reads and fills: thread k's is set k,
    /// or with fewer sets than threads (see [`REPLICA_BUDGET`]) set k modulo
    /// their number. Any set would give the same answers (they hold the same
    /// triangles); its own keeps them in its core's cache.
    fn set_of_this_thread(&self) -> PassSet<'a> {
        let k = rayon::current_thread_index().unwrap_or(0);
        self.sets[k % self.sets.len()]
    }
}

impl Task {
    /// Culls the triangle pairs of `body_pairs` (group indices of the pass's
    /// set) by inflated boxes and face planes, computes their distances and
    /// keeps those within reach, sorted by [`pair_order`]; with `build`,
    /// builds the body pairs' contacts from those too (in parallel with the
    /// other tasks rather than after them all).
    fn run(&mut self, pass: &Pass, body_pairs: &[(usize, usize)], memos: &mut [PairMemo]) {
        let set = pass.set_of_this_thread();
        let Pass {
            world,
            halos,
            opts,
            phase,
            build,
            culling,
            radii,
            margin,
            ..
        } = *pass;
        let remember = !radii.is_empty();
        let pose = |body: usize| (world.bodies[body].x, world.bodies[body].q);
        // How far any point of one of the memo's bodies may have moved
        // relative to any point of the other since.
        let moved_since = |memo: &PairMemo, bodies: [usize; 2]| -> f64 {
            let after = bodies.map(|i| &world.bodies[i]);
            relative_travel_bound(memo.poses, after, after.map(|b| radii[b.shape]))
        };
        let group_body = |g: usize| set.groups()[g].body as usize;
        self.body_pairs = 0;
        self.hulls_apart = 0;
        self.known_apart = 0;
        self.near_kept = 0;
        self.kept.clear();
        self.work.clear();
        let mut pairs = PassPairs::new(set, &mut self.owners);
        // On one thread the poses are in this core's cache already.
        let prefetch = rayon::current_num_threads() > 1;
        let prefetch_pair = |k: usize| {
            if let Some(&(g, h)) = body_pairs.get(k).filter(|_| prefetch) {
                set.prefetch_pose(g, world);
                set.prefetch_pose(h, world);
            }
        };
        (0..PREFETCH_AHEAD).for_each(prefetch_pair);
        for (k, (&(g, h), memo)) in body_pairs.iter().zip(memos.iter_mut()).enumerate() {
            prefetch_pair(k + PREFETCH_AHEAD);
            let bodies = [group_body(g), group_body(h)];
            let moved = if memo.budget > 0.0 {
                moved_since(memo, bodies)
            } else {
                f64::INFINITY
            };
            let holds = moved < memo.budget;
            if holds && memo.near.is_empty() {
                self.known_apart += 1;
                continue;
            }
            if !holds {
                let was_apart = memo.near.is_empty();
                memo.budget = 0.0;
                memo.near.clear();
                memo.gaps.clear();
                // Apart at the last look, along a direction that likely still
                // separates them: the whole bodies' slab along it, from their
                // vertices and poses, settles most such pairs with no
                // triangle read (nor filled).
                if remember && was_apart && memo.hint != DVec3::ZERO {
                    let reach = halos[bodies[0]] + halos[bodies[1]];
                    let clearance = whole_bodies_clearance(world, bodies, reach, memo.hint, radii);
                    if clearance > 0.0 {
                        memo.poses = bodies.map(pose);
                        memo.budget = clearance;
                        self.body_pairs += 1;
                        self.hulls_apart += 1;
                        self.work.push((g as u32, 0));
                        continue;
                    }
                }
            }
            let fa = set.fill(g, world, &mut self.vertices);
            let fb = set.fill(h, world, &mut self.vertices);
            let (a, b) = match phase {
                Phase::LocalLocal => (fa.owned(), fb.owned()),
                Phase::LocalGhost => (fa.owned(), fb.ghosts()),
                Phase::Across if fa.group().owned.is_empty() => (fa.ghosts(), fb.owned()),
                Phase::Across => (fa.owned(), fb.ghosts()),
            };
            // Pairs from a neighbour list (see `Detector::detect_moved`) may
            // have drifted apart; straight from the broad phase they overlap.
            let (a_box, b_box) = (a.bounds, b.bounds);
            if !a_box.overlaps(&b_box) {
                continue;
            }
            self.body_pairs += 1;
            let before = pairs.as_slice().len();
            if holds {
                // Every triangle pair within reach now was within reach and
                // margin when the list was kept, and nearer than the reach by
                // the displacements since: no culling to redo, and the kernel
                // only for those.
                let n = memo.gaps.partition_point(|&gap| gap < moved);
                pairs.between(&a, &b).extend(&memo.near[..n]);
                self.work.push((g as u32, n as u32));
                self.near_kept += 1;
                continue;
            }
            self.work.push((g as u32, 0));
            let [body_a, body_b] = bodies;
            let reach = halos[body_a] + halos[body_b];
            // What this examination shows holds while the bodies'
            // displacements since stay under the margin: it culls with it.
            memo.poses = [pose(body_a), pose(body_b)];
            memo.budget = if remember { margin } else { 0.0 };
            let wide = reach + margin;
            let (a_wide, b_wide) = (a_box.inflated(margin), b_box.inflated(margin));
            // The parts' triangles as locals, kept in registers across the
            // loops' stores; index i of the set is at i - start.
            let (at, a0) = (a.triangles(), a.range().start);
            let (bt, b0) = (b.triangles(), b.range().start);
            // Every test below passes for a sizeable fraction (30-60% in the
            // hopper), so branches on them would mispredict: each loop writes
            // every index and advances past those that pass.
            let n_a = select(&mut self.candidates, a.range(), |i| {
                at[i - a0].bounds.overlaps(&b_wide)
            });
            if n_a == 0 {
                continue;
            }
            let n_b = select(&mut self.others, b.range(), |j| {
                bt[j - b0].bounds.overlaps(&a_wide)
            });
            if n_b == 0 {
                continue;
            }
            let (candidates, others) = (&self.candidates[..n_a], &self.others[..n_b]);
            // Only the triangles near the other body can pair: the hull of
            // those is all the hull test needs, and is tighter than the body's.
            let hulls = culling == Culling::Hulls;
            let near = [(&a, candidates), (&b, others)];
            if hulls && self.hulls.apart(world, set, near, reach, &mut memo.hint) {
                self.hulls_apart += 1;
                // The whole parts' clearance along the certificate's
                // direction: the pair's rest until the bodies use it up.
                if remember {
                    let on = (world, set);
                    memo.budget = self.hulls.clearance(on, [&a, &b], reach, memo.hint, radii);
                }
                continue;
            }
            let planes_of = |ids: &[u32], t: &[SetTriangle], t0: usize, planes: &mut Vec<_>| {
                planes.clear();
                planes.extend(ids.iter().map(|&i| t[i as usize - t0].plane()));
            };
            planes_of(candidates, at, a0, &mut self.candidate_planes);
            planes_of(others, bt, b0, &mut self.other_planes);
            // a's boxes grown by the margin: the pairs within reach and margin.
            let boxes = |ids: &[u32], t: &[SetTriangle], t0: usize, pad: f64, out: &mut Vec<_>| {
                out.clear();
                out.extend(ids.iter().map(|&i| t[i as usize - t0].bounds.inflated(pad)));
            };
            boxes(candidates, at, a0, margin, &mut self.candidate_boxes);
            let mut between = pairs.between(&a, &b);
            let passes = |p: usize, q: usize| {
                let (ti, tj) = (
                    &at[candidates[p] as usize - a0],
                    &bt[others[q] as usize - b0],
                );
                self.candidate_boxes[p].overlaps(&tj.bounds)
                    & !plane_separates(self.other_planes[q], &ti.vertices, wide)
                    & !plane_separates(self.candidate_planes[p], &tj.vertices, wide)
            };
            if hulls && n_a * n_b > SWEEP_ABOVE {
                // Large meshes: only pairs whose boxes overlap are visited.
                boxes(others, bt, b0, 0.0, &mut self.other_boxes);
                let common = a_box.intersection(&b_box);
                let axis = (common.hi - common.lo).max_position();
                self.hits.clear();
                let hits = &mut self.hits;
                self.sweep.overlapping_pairs(
                    &self.candidate_boxes,
                    &self.other_boxes,
                    axis,
                    |p, q| {
                        if passes(p, q) {
                            hits.push((candidates[p], others[q]));
                        }
                    },
                );
                between.extend(&self.hits);
            } else {
                self.hits.resize(n_a, (0, 0));
                for (q, &j) in others.iter().enumerate() {
                    let mut found = 0;
                    for (p, &i) in candidates.iter().enumerate() {
                        self.hits[found] = (i, j);
                        found += passes(p, q) as usize;
                    }
                    between.extend(&self.hits[..found]);
                }
            }
            let added = pairs.as_slice().len() - before;
            if let Some(last) = self.work.last_mut() {
                last.1 = added as u32;
            }
            if margin > 0.0 && memo.budget > 0.0 {
                self.kept.push(Kept {
                    memo: k,
                    pairs: before..before + added,
                    reach,
                    allowance: kernel_allowance(&a_box.union(&b_box)),
                });
            }
        }
        let n = pairs.as_slice().len();
        self.out.resize(n, Closest::UNSET);
        self.stats.resize(n, PenaltyStats::default());
        self.counts = distance_many_serial(&pairs.source(), opts, &mut self.out, &mut self.stats)
            .expect("batch size validated by the scene");
        let found = (&self.kept[..], &self.out[..], pairs.as_slice());
        keep_near(found, memos, margin, &mut self.nearest);
        self.found.clear();
        let source = pairs.source();
        for (k, (&(i, j), r)) in pairs.as_slice().iter().zip(&self.out).enumerate() {
            let (ka, kb) = (set.key(i as usize), set.key(j as usize));
            let reach = halos[ka.body as usize] + halos[kb.body as usize];
            // A pair the kernel puts just beyond the reach may be within it
            // by the kernel's error: the feature contacts, built from the
            // features' exact data, decide (an extra pair adds no contact).
            // Only pairs within twice the reach are asked, which keeps the
            // allowance's box off the many pairs farther apart: beyond, the
            // kernel would have to err by more than the reach.
            if r.distance < reach
                || (r.distance < 2.0 * reach && r.distance < reach + pair_allowance(source.pair(k)))
            {
                self.found.push(TriangleContact {
                    a: ka,
                    b: kb,
                    closest: *r,
                });
            }
        }
        self.found.sort_unstable_by_key(pair_order);
        self.contacts.clear();
        self.deep = match build {
            Some(features) => append_body_contacts(
                &self.found,
                world,
                features,
                halos,
                &mut self.scratch,
                &mut self.contacts,
            ),
            None => 0,
        };
    }
}

/// A body pair culled in full by a task, whose triangle pairs (`pairs`,
/// positions in the task's pairs) are kept for the next steps.
#[derive(Debug, Clone)]
struct Kept {
    memo: usize,
    pairs: Range<usize>,
    reach: f64,
    allowance: f64,
}

/// What the kernel's distance of a triangle pair within `union` (the body
/// pair's box) may be off by: its answers are certified to 1e-13 of the
/// pair's scale or exact (module `distance`), and the world coordinates
/// carry the rounding of their distance from the origin; this allows far
/// more than either.
fn kernel_allowance(union: &Bounds) -> f64 {
    let extent = (union.hi - union.lo).length();
    let far = union.lo.abs().max(union.hi.abs()).max_element();
    1e-9 * extent + 64.0 * f64::EPSILON * far
}

/// [`kernel_allowance`] for one triangle pair, within the box of its six
/// vertices.
fn pair_allowance((a, b): (&Triangle, &Triangle)) -> f64 {
    kernel_allowance(&Bounds::of(a, 0.0).union(&Bounds::of(b, 0.0)))
}

/// Keeps, in the memo of each body pair of `kept`, its triangle pairs (of
/// `pairs`) nearer than reach plus `margin` by the kernel's distances
/// (`out`), nearest first, with their gaps beyond the reach less the
/// allowance. A pair with a distance that is not a number keeps nothing:
/// the body pair is culled in full next time. `near` is scratch.
fn keep_near(
    (kept, out, pairs): (&[Kept], &[Closest], &[(u32, u32)]),
    memos: &mut [PairMemo],
    margin: f64,
    near: &mut Vec<(f64, (u32, u32))>,
) {
    for kept in kept {
        let memo = &mut memos[kept.memo];
        let answers = &out[kept.pairs.clone()];
        if answers.iter().any(|r| r.distance.is_nan()) {
            memo.budget = 0.0;
            continue;
        }
        near.clear();
        near.extend(
            answers
                .iter()
                .zip(&pairs[kept.pairs.clone()])
                .map(|(r, &p)| (r.distance - kept.reach - kept.allowance, p))
                .filter(|&(gap, _)| gap < margin),
        );
        near.sort_unstable_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
        memo.gaps.extend(near.iter().map(|x| x.0));
        memo.near.extend(near.iter().map(|x| x.1));
    }
}

/// The two parts' corners, each once, for the hull test, and per mesh
/// vertex the call that last took it (`stamp`).
#[derive(Debug, Default)]
struct HullScratch {
    corners: [Vec<DVec3>; 2],
    seen: Vec<u64>,
    stamp: u64,
}

impl HullScratch {
    /// Whether the convex hulls of two sets of triangles, each some of a
    /// part's (by index into the set), are certainly farther apart than
    /// `reach` ([`separation::apart`]): then no triangle pair of theirs is
    /// within reach, and none need be examined.
    fn apart(
        &mut self,
        world: &World,
        set: PassSet,
        parts: [(&Part, &[u32]); 2],
        reach: f64,
        hint: &mut DVec3,
    ) -> bool {
        for ((part, ids), out) in parts.into_iter().zip(&mut self.corners) {
            self.stamp += 1;
            gather_corners(world, set, part, ids, self.stamp, &mut self.seen, out);
        }
        let union = parts[0].0.bounds.union(&parts[1].0.bounds);
        let extent = (union.hi - union.lo).length();
        separation::apart(&self.corners[0], &self.corners[1], reach, extent, hint)
    }

    /// After [`Self::apart`] found the parts apart along `d`: by how much
    /// more than `reach` all of their triangles are apart along it. A part
    /// that is a whole body is read from its mesh's vertices and pose (each
    /// vertex once; `radii` the shapes' radii), any other from its
    /// triangles.
    fn clearance(
        &self,
        on: (&World, PassSet),
        parts: [&Part; 2],
        reach: f64,
        d: DVec3,
        radii: &[f64],
    ) -> f64 {
        let Some(&origin) = self.corners[0].first() else {
            return 0.0;
        };
        let (world, set) = on;
        let union = parts[0].bounds.union(&parts[1].bounds);
        let extent = (union.hi - union.lo).length();
        let side = |part: &Part, upper: bool| {
            let extreme = separation::Extreme { d, origin, upper };
            match whole_body(world, set, part) {
                Some(body) => body_extreme(world, body, extreme, radii),
                None => extreme.of_triangles(part.triangles().iter().map(|t| &t.vertices)),
            }
        };
        let (hi_a, lo_b) = (side(parts[0], true), side(parts[1], false));
        separation::clearance(hi_a, lo_b, d, reach, extent)
    }
}

/// By how much more than `reach` two bodies (all of their meshes' points, at
/// their poses) are apart along `d`, as [`separation::clearance`] measures
/// it; zero or less: not shown apart along `d`. A part of a body in a
/// triangle set holds some of those points, so this holds for it too.
fn whole_bodies_clearance(
    world: &World,
    bodies: [usize; 2],
    reach: f64,
    d: DVec3,
    radii: &[f64],
) -> f64 {
    let [a, b] = bodies.map(|i| &world.bodies[i]);
    let origin = a.x;
    let side = |body: usize, upper: bool| {
        body_extreme(world, body, separation::Extreme { d, origin, upper }, radii)
    };
    // Bounds the distance between any two of their points.
    let extent = (b.x - a.x).length() + radii[a.shape] + radii[b.shape];
    separation::clearance(
        side(bodies[0], true),
        side(bodies[1], false),
        d,
        reach,
        extent,
    )
}

/// `extreme` over all of body `body`'s mesh points at its pose.
fn body_extreme(world: &World, body: usize, extreme: separation::Extreme, radii: &[f64]) -> f64 {
    let b = &world.bodies[body];
    let rotation = glam::DMat3::from_quat(b.q);
    extreme.of_posed(
        &world.shapes[b.shape].vertices,
        b.x,
        rotation,
        radii[b.shape],
    )
}

/// The body whose triangles `part` holds, if it holds all of them: the set's
/// parts are sorted by key, so n triangles from index 0 to n − 1 of a mesh of
/// n are the whole mesh, in mesh order.
fn whole_body(world: &World, set: PassSet, part: &Part) -> Option<usize> {
    let first = part.range().next()?;
    let key = set.key(first);
    let body = key.body as usize;
    let n = part.triangles().len();
    let whole = n == world.shapes[world.bodies[body].shape].triangles.len()
        && key.index == 0
        && set.key(first + n - 1).index as usize == n - 1;
    whole.then_some(body)
}

/// The corners of triangles `ids` of `part` into `out`, each mesh vertex
/// once (a closed mesh has about half as many vertices as triangles; the
/// hull test then reads each once rather than six times). `seen` marks the
/// mesh vertices taken, with `stamp`, new for each call.
fn gather_corners(
    world: &World,
    set: PassSet,
    part: &Part,
    ids: &[u32],
    stamp: u64,
    seen: &mut Vec<u64>,
    out: &mut Vec<DVec3>,
) {
    out.clear();
    let Some(first) = part.range().next() else {
        return;
    };
    let mesh = &world.shapes[world.bodies[set.key(first).body as usize].shape];
    if seen.len() < mesh.vertices.len() {
        seen.resize(mesh.vertices.len(), 0);
    }
    // A whole body's triangles are in mesh order: no key need be read.
    let whole = whole_body(world, set, part).is_some();
    let triangles = part.triangles();
    for &i in ids {
        let k = i as usize - first;
        let index = if whole {
            k
        } else {
            set.key(i as usize).index as usize
        };
        let corners = &mesh.triangles[index];
        for (&v, p) in corners.iter().zip(&triangles[k].vertices) {
            let mark = &mut seen[v as usize];
            if *mark != stamp {
                *mark = stamp;
                out.push(*p);
            }
        }
    }
}

/// The contacts of the body pairs of `found` (sorted in place by
/// [`pair_order`]), all of each body pair's triangle contacts present, on a
/// world whose shapes have `features`. Returns the number of contacts and of
/// deep ones (deeper than the halos).
pub fn body_contacts(
    found: &mut [TriangleContact],
    world: &World,
    features: &[Features],
    halos: &[f64],
    contacts: &mut Vec<Contact>,
) -> (u64, u64) {
    found.sort_unstable_by_key(pair_order);
    contacts.clear();
    let mut scratch = FeatureScratch::default();
    let deep = append_body_contacts(found, world, features, halos, &mut scratch, contacts);
    (contacts.len() as u64, deep)
}

/// The order of triangle contacts: by body pair, then by b's triangle, then
/// a's. A total order (no two triangle contacts share a key), so the
/// contacts never depend on how the triangle contacts were found.
pub fn pair_order(t: &TriangleContact) -> (u32, u32, u32, u32) {
    (t.a.body, t.b.body, t.b.index, t.a.index)
}

/// Appends the contacts of each body pair of `found` (sorted by
/// [`pair_order`]) to `contacts`; returns the number of deep ones.
fn append_body_contacts(
    found: &[TriangleContact],
    world: &World,
    features: &[Features],
    halos: &[f64],
    scratch: &mut FeatureScratch,
    contacts: &mut Vec<Contact>,
) -> u64 {
    found
        .chunk_by(|x, y| (x.a.body, x.b.body) == (y.a.body, y.b.body))
        .map(|group| append_feature_contacts(group, world, features, halos, scratch, contacts))
        .sum()
}

/// Whether the plane (n, d) of one triangle has all of `t` on one side, farther
/// than `reach`: then no point of `t` is within `reach` of that triangle.
/// Without branches (see `Task::run`); NaN never separates.
#[inline]
fn plane_separates((n, d): (DVec3, f64), t: &Triangle, reach: f64) -> bool {
    let h = [n.dot(t[0]) - d, n.dot(t[1]) - d, n.dot(t[2]) - d];
    let above = (h[0] > reach) & (h[1] > reach) & (h[2] > reach);
    let below = (h[0] < -reach) & (h[1] < -reach) & (h[2] < -reach);
    above | below
}

/// Writes into `out` the indices of `range` that `keep` accepts, in order,
/// without branching on `keep`; returns how many (the valid prefix of `out`).
#[inline]
fn select(out: &mut Vec<u32>, range: Range<usize>, keep: impl Fn(usize) -> bool) -> usize {
    out.resize(range.len(), 0);
    let mut found = 0;
    for i in range {
        out[found] = i as u32;
        found += keep(i) as usize;
    }
    found
}
