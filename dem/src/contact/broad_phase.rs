//! Broad phase: pairs of body groups whose boxes, inflated by the halos,
//! overlap, and of which at least one body moves.
//!
//! Moving boxes are sorted and swept along the axis on which their centres
//! spread most (a pile on a floor is flat, a falling column tall: a fixed axis
//! would compare most boxes with most others in one of them). Static boxes
//! (floors, walls, hoppers) are kept out of the sweep: they are usually
//! scene-sized, so in a sweep each would be compared with nearly every box
//! after it, and one sweep task would get all that work. Instead each static
//! box is tested against every moving box; static-static pairs never matter.
//!
//! With many moving boxes in a dense scene, a uniform grid finds their
//! pairs instead of the sweep (module `grid`): a sweep compares each box
//! with every box of its slab across the other two axes, hundreds in a silo
//! of ten thousand grains, where the grid's cells hold a box or two.
//!
//! The pairs are returned sorted, so everything downstream (task shares,
//! contact order, friction history) depends on the boxes alone, never on the
//! thread count nor on whether a grid or a sweep found them.

mod grid;

use super::bounds::Bounds;
use super::triangle_set::BodyGroup;
use super::Phase;
use crate::body::Body;
use glam::DVec3;
use rayon::prelude::*;

/// Which part of a group a box covers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Part {
    Owned,
    Ghost,
}

/// One box of the broad phase, with what the inner loops need at hand (not
/// behind an index into the groups and bodies).
#[derive(Debug, Clone, Copy)]
struct Entry {
    bounds: Bounds,
    group: usize,
    part: Part,
}

/// Moving boxes per parallel task of the broad phase, when it runs in parallel.
const SWEEP_GRAIN: usize = 32;

/// The sweep runs on one thread below this many moving boxes. Each box costs
/// its sweep step and a test per static box, about 100 ns: a hopper of 100
/// particles sweeps in some 10 us, less than splitting it across threads
/// costs. Measured with section timers on a 2-core cloud machine,
/// per 7,000-step run: 100 particles, one thread 132-144 ms serial against
/// 186-209 ms parallel, two threads 151 against 207-229 ms; 400 particles,
/// one thread 619-633 against 788-853 ms, two threads 763-820 against
/// 731-769 ms (a wash).
const PARALLEL_SWEEP_FROM: usize = 512;

/// The grid replaces the sweep from this many moving boxes (if the scene is
/// dense enough for one, see `grid`): below, a sweep's slabs are short.
const GRID_FROM: usize = 256;

/// A moving box as the sweep reads it: its extent along the sweep axis and
/// across it, packed so that testing a box is a few loads and no branches.
#[derive(Debug, Clone, Copy)]
struct SweepBox {
    lo: f64,
    hi: f64,
    /// lo and hi along the two other axes.
    across: [f64; 4],
}

impl SweepBox {
    fn new(b: &Bounds, axis: usize) -> SweepBox {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        SweepBox {
            lo: b.lo[axis],
            hi: b.hi[axis],
            across: [b.lo[u], b.hi[u], b.lo[v], b.hi[v]],
        }
    }

    /// Whether the boxes overlap across the sweep axis; `&`, not `&&`: about
    /// half the boxes met in a sweep overlap, so branches would mispredict.
    #[inline]
    fn overlaps_across(&self, o: &SweepBox) -> bool {
        let (a, b) = (&self.across, &o.across);
        (a[0] <= b[1]) & (b[0] <= a[1]) & (a[2] <= b[3]) & (b[2] <= a[3])
    }
}

/// The broad phase with what it keeps between steps: its buffers, and the
/// moving boxes in the last sweep order. Bodies move little in a step, so
/// the boxes are nearly sorted already and an insertion sort puts them back
/// in order in about one pass.
#[derive(Debug, Default)]
pub(crate) struct BroadPhase {
    /// Moving boxes in sweep order, each with its index in `fresh`.
    moving: Vec<(Entry, usize)>,
    /// This call's moving boxes in group order.
    fresh: Vec<Entry>,
    fixed: Vec<Entry>,
    /// Whether `moving` is in sweep order along `axis` from the last call.
    order_kept: bool,
    axis: usize,
    sweep: Vec<SweepBox>,
    grid: grid::Grid,
    pairs: Vec<(usize, usize)>,
    /// Scratch of `sort_pairs`.
    unsorted: Vec<(usize, usize)>,
    pair_counts: Vec<usize>,
}

impl BroadPhase {
    /// Pairs of group indices (g, h), g < h (so body(g) < body(h)), whose
    /// boxes overlap and of which at least one body moves:
    /// - local-local: the owned parts of both;
    /// - local-ghost: the owned part of g and the ghost part of h. The pair of
    ///   g's ghosts with h's owned triangles is the business of the rank
    ///   owning g's triangles, so that each triangle pair is examined on
    ///   exactly one rank;
    /// - across: the owned part of one and the ghost part of the other.
    ///
    /// Sorted, each pair once: a function of the boxes alone.
    ///
    /// Moving bodies' boxes are inflated by `pad` more (a neighbour list's
    /// half skin: the pairs then stay a superset of the overlapping ones
    /// while no body moves farther than `pad`).
    pub(crate) fn body_pairs(
        &mut self,
        groups: &[BodyGroup],
        bodies: &[Body],
        phase: Phase,
        pad: f64,
    ) -> &[(usize, usize)] {
        self.body_pairs_in_tasks_of(
            groups,
            bodies,
            phase,
            pad,
            SWEEP_GRAIN,
            PARALLEL_SWEEP_FROM,
            GRID_FROM,
        )
    }

    /// The pairs, with the sweep (or the grid, from `grid_from` moving
    /// boxes) in tasks of `grain` moving boxes once there are at least
    /// `parallel_from` of them.
    #[allow(clippy::too_many_arguments)]
    fn body_pairs_in_tasks_of(
        &mut self,
        groups: &[BodyGroup],
        bodies: &[Body],
        phase: Phase,
        pad: f64,
        grain: usize,
        parallel_from: usize,
        grid_from: usize,
    ) -> &[(usize, usize)] {
        self.collect(groups, bodies, phase, pad);
        self.pairs.clear();
        let on_grid =
            self.fresh.len() >= grid_from && self.grid.build(self.fresh.iter().map(|e| e.bounds));
        if !on_grid {
            self.sort();
        }
        let (fixed, n) = (&self.fixed, self.fresh.len());
        // A moving box's pairs with every static box.
        let with_fixed = |m: &Entry, pairs: &mut Vec<(usize, usize)>| {
            for f in fixed {
                if f.bounds.overlaps(&m.bounds) {
                    pairs.extend(pair_of(f, m, phase));
                }
            }
        };
        let tasks = if n < parallel_from.max(2 * grain) {
            n.max(1)
        } else {
            grain
        };
        if on_grid {
            let (fresh, grid) = (&self.fresh, &self.grid);
            let pairs_of = |i: usize, _: &mut Vec<u32>, pairs: &mut Vec<(usize, usize)>| {
                let m = &fresh[i];
                grid.candidates_of(i, |j| {
                    let o = &fresh[j];
                    if m.bounds.overlaps(&o.bounds) {
                        pairs.extend(pair_of(m, o, phase));
                    }
                });
                with_fixed(m, pairs);
            };
            in_tasks(n, tasks, pairs_of, &mut self.pairs);
        } else {
            let (moving, sweep) = (&self.moving, &self.sweep);
            // The pairs of moving box n: with the moving boxes after it in the
            // sweep, and with every static box.
            let pairs_of = |n: usize, hits: &mut Vec<u32>, pairs: &mut Vec<(usize, usize)>| {
                sweep_from(sweep, moving, n, phase, hits, pairs);
                with_fixed(&moving[n].0, pairs);
            };
            in_tasks(n, tasks, pairs_of, &mut self.pairs);
        }
        let pairs = &mut self.pairs;
        sort_pairs(pairs, &mut self.unsorted, &mut self.pair_counts);
        // Across, two groups may meet owned-ghost and ghost-owned.
        if phase == Phase::Across {
            pairs.dedup();
        }
        pairs
    }

    /// Gathers this call's boxes: static ones apart, moving ones into the
    /// last sweep order when they are the same boxes as last time.
    fn collect(&mut self, groups: &[BodyGroup], bodies: &[Body], phase: Phase, pad: f64) {
        let (fresh, fixed) = (&mut self.fresh, &mut self.fixed);
        fresh.clear();
        fixed.clear();
        for (k, g) in groups.iter().enumerate() {
            let body = &bodies[g.body as usize];
            // A driven obstacle moves like a particle, but need not be swept
            // with the particles: it meets only them.
            let (list, pad) = if body.is_fixed() {
                (&mut *fixed, 0.0)
            } else if body.is_static() {
                (&mut *fixed, pad)
            } else {
                (&mut *fresh, pad)
            };
            if !g.owned.is_empty() {
                list.push(Entry {
                    bounds: g.owned_box.inflated(pad),
                    group: k,
                    part: Part::Owned,
                });
            }
            if phase != Phase::LocalLocal && !g.ghost.is_empty() {
                list.push(Entry {
                    bounds: g.ghost_box.inflated(pad),
                    group: k,
                    part: Part::Ghost,
                });
            }
        }
        let same_boxes = self.moving.len() == fresh.len()
            && self.moving.iter().all(|(e, i)| {
                let f = &fresh[*i];
                (f.group, f.part) == (e.group, e.part)
            });
        if same_boxes {
            for (e, i) in &mut self.moving {
                e.bounds = fresh[*i].bounds;
            }
        } else {
            self.moving.clear();
            self.moving
                .extend(fresh.iter().enumerate().map(|(i, e)| (*e, i)));
            self.order_kept = false;
        }
    }

    /// Sorts the moving boxes along the axis of widest spread and packs them
    /// for the sweep.
    fn sort(&mut self) {
        let axis = widest_axis(self.moving.iter().map(|(e, _)| &e.bounds));
        let moving = &mut self.moving;
        if self.order_kept && axis == self.axis {
            insertion_sort_by_lo(moving, axis);
        } else {
            moving
                .sort_unstable_by(|(x, _), (y, _)| x.bounds.lo[axis].total_cmp(&y.bounds.lo[axis]));
            self.axis = axis;
            self.order_kept = true;
        }
        self.sweep.clear();
        self.sweep
            .extend(moving.iter().map(|(e, _)| SweepBox::new(&e.bounds, axis)));
    }
}

/// Appends the pairs `pairs_of` finds for each of boxes 0..n (with a
/// scratch of its own), on this thread when `grain` covers them all, else in
/// parallel tasks of at least `grain` boxes.
fn in_tasks(
    n: usize,
    grain: usize,
    pairs_of: impl Fn(usize, &mut Vec<u32>, &mut Vec<(usize, usize)>) + Sync,
    pairs: &mut Vec<(usize, usize)>,
) {
    if grain >= n {
        let mut hits = Vec::new();
        for i in 0..n {
            pairs_of(i, &mut hits, pairs);
        }
        return;
    }
    let found: Vec<(usize, usize)> = (0..n)
        .into_par_iter()
        .with_min_len(grain)
        .fold(
            || (Vec::new(), Vec::new()),
            |(mut hits, mut pairs), i| {
                pairs_of(i, &mut hits, &mut pairs);
                (hits, pairs)
            },
        )
        .map(|(_, pairs)| pairs)
        .reduce(Vec::new, |mut a, b| {
            a.extend_from_slice(&b);
            a
        });
    pairs.extend_from_slice(&found);
}

/// Sorts pairs of group indices by bucketing them by their first index
/// (counting sort), then the few in each bucket by the second: a few hundred
/// pairs per step are sorted several times faster than by comparisons.
fn sort_pairs(
    pairs: &mut [(usize, usize)],
    unsorted: &mut Vec<(usize, usize)>,
    counts: &mut Vec<usize>,
) {
    let Some(n) = pairs.iter().map(|p| p.0 + 1).max() else {
        return;
    };
    counts.clear();
    counts.resize(n + 1, 0);
    for p in pairs.iter() {
        counts[p.0 + 1] += 1;
    }
    for k in 1..=n {
        counts[k] += counts[k - 1];
    }
    // counts[k]: where bucket k starts.
    unsorted.clear();
    unsorted.extend_from_slice(pairs);
    for p in unsorted.iter() {
        pairs[counts[p.0]] = *p;
        counts[p.0] += 1;
    }
    // counts[k]: where bucket k ends, so bucket k is counts[k-1]..counts[k].
    let mut start = 0;
    for &end in &counts[..n] {
        pairs[start..end].sort_unstable_by_key(|p| p.1);
        start = end;
    }
}

/// Insertion sort by the boxes' lower ends along `axis`: one pass over boxes
/// that are already nearly in order.
fn insertion_sort_by_lo(moving: &mut [(Entry, usize)], axis: usize) {
    for i in 1..moving.len() {
        let key = moving[i].0.bounds.lo[axis];
        let mut j = i;
        while j > 0 && moving[j - 1].0.bounds.lo[axis] > key {
            j -= 1;
        }
        moving[j..=i].rotate_right(1);
    }
}

/// Appends the pairs of sorted box `n` with the boxes after it. The boxes
/// within reach along the sweep axis are tested across it without branching
/// (the only branch, the end of the reach, is taken once), the hits
/// collected in `hits`, then turned into pairs.
#[inline]
fn sweep_from(
    sweep: &[SweepBox],
    moving: &[(Entry, usize)],
    n: usize,
    phase: Phase,
    hits: &mut Vec<u32>,
    pairs: &mut Vec<(usize, usize)>,
) {
    let x = &sweep[n];
    hits.resize(sweep.len(), 0);
    let mut found = 0;
    for (j, y) in sweep.iter().enumerate().skip(n + 1) {
        if y.lo > x.hi {
            break;
        }
        hits[found] = j as u32;
        found += x.overlaps_across(y) as usize;
    }
    for &j in &hits[..found] {
        pairs.extend(pair_of(&moving[n].0, &moving[j as usize].0, phase));
    }
}

/// The pair two overlapping boxes stand for in `phase`, if any.
#[inline]
fn pair_of(x: &Entry, y: &Entry, phase: Phase) -> Option<(usize, usize)> {
    let (k, l) = (x.group, y.group);
    if k == l {
        return None;
    }
    match (phase, x.part, y.part) {
        (Phase::LocalLocal, Part::Owned, Part::Owned) => Some((k.min(l), k.max(l))),
        (Phase::LocalGhost, Part::Owned, Part::Ghost) if k < l => Some((k, l)),
        (Phase::LocalGhost, Part::Ghost, Part::Owned) if l < k => Some((l, k)),
        (Phase::Across, Part::Owned, Part::Ghost) | (Phase::Across, Part::Ghost, Part::Owned) => {
            Some((k.min(l), k.max(l)))
        }
        _ => None,
    }
}

/// The axis of largest variance of the boxes' centres. Boxes that span most of
/// the scene (floors, walls) are left out: they overlap everything on any axis.
fn widest_axis<'a>(boxes: impl Iterator<Item = &'a Bounds> + Clone) -> usize {
    let scene = boxes.clone().fold(Bounds::EMPTY, |acc, b| acc.union(b));
    let span = scene.hi - scene.lo;
    let (mut n, mut sum, mut sum2) = (0.0, DVec3::ZERO, DVec3::ZERO);
    for b in boxes {
        let size = b.hi - b.lo;
        if size.cmpgt(span * 0.5).any() {
            continue;
        }
        let c = (b.lo + b.hi) * 0.5;
        n += 1.0;
        sum += c;
        sum2 += c * c;
    }
    if n < 2.0 {
        return 0;
    }
    let var = sum2 / n - (sum / n) * (sum / n);
    if var.x >= var.y && var.x >= var.z {
        0
    } else if var.y >= var.z {
        1
    } else {
        2
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::{TriangleKey, TriangleSet};
    use glam::{DMat3, DQuat};
    use std::collections::BTreeSet;

    fn body(moving: bool) -> Body {
        Body {
            shape: 0,
            material: 0,
            x: DVec3::ZERO,
            q: DQuat::IDENTITY,
            v: DVec3::ZERO,
            l: DVec3::ZERO,
            inv_mass: if moving { 1.0 } else { 0.0 },
            mass: if moving { 1.0 } else { 0.0 },
            inv_inertia_body: DMat3::ZERO,
            inertia_body: DMat3::ZERO,
            drive: None,
            removed: false,
            pending: false,
        }
    }

    /// Bodies of random small triangles in a box, each triangle owned or a
    /// ghost at random, every fifth body static, one long static "wall".
    /// `shift` moves the bodies without changing which triangles are ghosts.
    fn scene(seed: u64, n: u32, shift: f64) -> (TriangleSet, Vec<Body>) {
        let mut s = seed;
        let mut rnd = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let (mut owned, mut ghosts) = (Vec::new(), Vec::new());
        for body in 0..n {
            let f = body as f64;
            let c = DVec3::new(rnd(), rnd(), 0.3 * rnd()) * 10.0
                + DVec3::new((7.1 * f).sin(), (3.3 * f).cos(), (1.7 * f).sin()) * shift;
            for index in 0..4 {
                let mut t = [c; 3];
                for v in &mut t {
                    *v += DVec3::new(rnd(), rnd(), rnd()) - 0.5;
                }
                if body == 0 {
                    // A wall along x: it overlaps many boxes on any axis.
                    t[1].x += 10.0;
                }
                let k = (TriangleKey { body, index }, t);
                if rnd() < 0.6 {
                    owned.push(k)
                } else {
                    ghosts.push(k)
                }
            }
        }
        let halos = vec![0.05; n as usize];
        let mut set = TriangleSet::with_owned(owned, &halos);
        set.set_ghosts(ghosts, &halos);
        let bodies = (0..n).map(|i| body(i % 5 != 3 && i != 0)).collect();
        (set, bodies)
    }

    /// The sweep against the definition, checked on every pair of groups.
    /// The pairs `broad` finds among `on`'s bodies in one phase, on `pool`,
    /// in tasks of `grain` moving boxes, on the grid from `grid_from` boxes.
    fn pairs_on(
        pool: &rayon::ThreadPool,
        broad: &mut BroadPhase,
        (set, bodies, phase): (&TriangleSet, &[Body], Phase),
        grain: usize,
        grid_from: usize,
    ) -> Vec<(usize, usize)> {
        pool.install(|| {
            broad
                .body_pairs_in_tasks_of(set.groups(), bodies, phase, 0.0, grain, 0, grid_from)
                .to_vec()
        })
    }

    fn all_pairs(set: &TriangleSet, bodies: &[Body], phase: Phase) -> BTreeSet<(usize, usize)> {
        let g = set.groups();
        let mut out = BTreeSet::new();
        for a in 0..g.len() {
            for b in a + 1..g.len() {
                let moving = |k: usize| !bodies[g[k].body as usize].is_static();
                let meet = |x: &Bounds, y: &Bounds| !x.is_empty() && !y.is_empty() && x.overlaps(y);
                let (ga, gb) = (&g[a], &g[b]);
                let found = match phase {
                    Phase::LocalLocal => meet(&ga.owned_box, &gb.owned_box),
                    Phase::LocalGhost => meet(&ga.owned_box, &gb.ghost_box),
                    Phase::Across => {
                        meet(&ga.owned_box, &gb.ghost_box) || meet(&ga.ghost_box, &gb.owned_box)
                    }
                };
                if (moving(a) || moving(b)) && found {
                    out.insert((a, b));
                }
            }
        }
        out
    }

    /// The grid finds what the definition finds, each pair once, on dense
    /// scenes at every scale and far from the origin, with large moving
    /// boxes among small ones, on any pool; and a sparse scene falls back
    /// to the sweep with the same answer.
    #[test]
    fn the_grid_finds_exactly_the_overlapping_pairs_once_at_any_scale() {
        let mut grids = 0;
        for seed in [4, 5, 6] {
            for (scale, far) in [(1.0, 0.0), (1e-6, 0.0), (1e6, 0.0), (1.0, 1e7), (1e-3, 1e9)] {
                for spread in [0.05, 30.0] {
                    let (set, bodies) = scene_scaled(seed, 1000, spread, scale, far);
                    for phase in [Phase::LocalLocal, Phase::LocalGhost, Phase::Across] {
                        let reference: Vec<_> =
                            all_pairs(&set, &bodies, phase).into_iter().collect();
                        for threads in [1, 2] {
                            let pool = rayon::ThreadPoolBuilder::new()
                                .num_threads(threads)
                                .build()
                                .unwrap();
                            let mut broad = BroadPhase::default();
                            let on = (&set, &bodies[..], phase);
                            let got = pairs_on(&pool, &mut broad, on, 16, 0);
                            assert_eq!(
                                got, reference,
                                "seed {seed}, scale {scale}, far {far}, spread {spread}, {phase:?}"
                            );
                        }
                    }
                    let mut broad = BroadPhase::default();
                    broad.collect(set.groups(), &bodies, Phase::LocalLocal, 0.0);
                    if broad.grid.build(broad.fresh.iter().map(|e| e.bounds)) {
                        grids += 1;
                        assert!(spread < 1.0, "a sparse scene gets no grid");
                    }
                }
            }
        }
        assert_eq!(grids, 15, "every dense scene on a grid");
    }

    /// Like `scene`, with the bodies in a box of side 10 · spread^(1/3)
    /// (a tenth of the boxes wider than the rest, moving), then scaled and
    /// moved `far` (times the scale) from the origin.
    fn scene_scaled(
        seed: u64,
        n: u32,
        spread: f64,
        scale: f64,
        far: f64,
    ) -> (TriangleSet, Vec<Body>) {
        let mut s = seed;
        let mut rnd = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let side = 10.0 * spread.cbrt();
        let (mut owned, mut ghosts) = (Vec::new(), Vec::new());
        for body in 0..n {
            let c = DVec3::new(rnd(), rnd(), rnd()) * side;
            let width = if body % 10 == 1 { 4.0 } else { 1.0 };
            for index in 0..4 {
                let mut t = [c; 3];
                for v in &mut t {
                    *v = (*v + (DVec3::new(rnd(), rnd(), rnd()) - 0.5) * width) * scale
                        + DVec3::splat(far * scale);
                }
                let k = (TriangleKey { body, index }, t);
                if rnd() < 0.6 {
                    owned.push(k)
                } else {
                    ghosts.push(k)
                }
            }
        }
        let halos = vec![0.05 * scale; n as usize];
        let mut set = TriangleSet::with_owned(owned, &halos);
        set.set_ghosts(ghosts, &halos);
        let bodies = (0..n).map(|i| body(i % 5 != 3)).collect();
        (set, bodies)
    }

    #[test]
    fn sweep_finds_exactly_the_overlapping_pairs_once_on_any_pool() {
        for seed in [1, 2, 3, 99] {
            for threads in [1, 2, 3] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                // Tasks of 8 and 32 boxes exercise the parallel sweep, a
                // grain above the box count the serial one.
                for grain in [8, SWEEP_GRAIN, 1000] {
                    // One broad phase through both phases and moving bodies:
                    // the kept order must never change the answer.
                    let mut broad = BroadPhase::default();
                    for phase in [Phase::LocalLocal, Phase::LocalGhost, Phase::Across] {
                        for shift in [0.0, 0.2, 0.2, 1.5, 0.0] {
                            let (set, bodies) = scene(seed, 150, shift);
                            let reference: Vec<_> =
                                all_pairs(&set, &bodies, phase).into_iter().collect();
                            assert!(reference.len() > 50, "a test with pairs to find");
                            let on = (&set, &bodies[..], phase);
                            let got = pairs_on(&pool, &mut broad, on, grain, usize::MAX);
                            // Sorted and each once, on every pool size:
                            // downstream task shares and contact order depend on it.
                            assert_eq!(
                                got, reference,
                                "seed {seed}, {phase:?}, shift {shift}, {threads} threads"
                            );
                        }
                    }
                }
            }
        }
    }
}
