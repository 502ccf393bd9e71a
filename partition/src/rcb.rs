//! Native recursive coordinate bisection, parallel across ranks and threads.
//!
//! All bisections of one tree level run together, so every level costs a
//! fixed number of collective reductions whatever the number of groups. A
//! group is a range of ranks [r0, r1) and the items currently assigned to it;
//! it is cut along the longest axis of its items' bounding box so that the left
//! part holds the weight fraction floor(n/2)/n (any number of ranks, not only
//! powers of two). The weighted median is found by histograms: the weight at
//! or below K candidate cuts is reduced over all ranks and the bracket shrinks
//! to the bin holding the target, until the cut is within `tolerance` of the
//! target weight. Histograms are filled with rayon inside each rank.
//!
//! Items at one coordinate are split too. When the weighted median lies
//! inside a set of items at exactly one coordinate (a plane of a lattice,
//! which particles keep while they fall together), no cut between
//! coordinates comes near the target, and a whole plane would go to one
//! side. The cut is then put at that coordinate and its items, gathered on
//! every rank, go left in increasing id until the left half holds its
//! target. A point on a cut lies in both halves' closed regions:
//! [`Partitioner::owner`] names the left one, while the item itself may
//! have been dealt to the right.
//!
//! Repartitioning reuses the previous cuts: each group keeps its old cut's
//! axis while that axis is at least half its longest extent (so a domain
//! whose shape changes a little is not cut anew along another axis, which
//! would move about half the items), and its search starts from a
//! narrow bracket around its old cut, widened to the full extent only when the
//! target weight is not inside it. Parts keep their numbers: the left half of
//! a group goes to its lower ranks. So a repartitioning moves the items the
//! cuts pass over, in proportion to the drift.
//!
//! An old cut whose split is still close to its target stays where it is
//! (hysteresis, as Zoltan's `IMBALANCE_TOL` lets its RCB stop short of the
//! median): then the items that drifted across it do not move at all. Close
//! means within `reuse_slack` of each side's weight, scaled by the group's
//! share of the ranks: a leaf's load is the product of its ancestors' splits,
//! and these allowances, halving at each level, multiply to at most about
//! 1 + 2 `reuse_slack` over the whole tree, whatever the number of ranks.
//! A cut the work has shifted beyond its slack moves only back inside it,
//! to its edge on the side the work went (as Zoltan's RCB, searching from
//! its old cut, stops once within `IMBALANCE_TOL`), not to the median: it
//! passes over the items the shift beyond the slack asks for, no more.
//!
//! Keeping a cut still moves the items that drifted across it since the
//! last partitioning: they are held by the ranks of the half they left.
//! Where they drifted together (grains settling towards a floor, flowing
//! towards an outlet), moving the cut with them moves fewer. So of the
//! candidate cuts of the bracket around the old cut whose split is within
//! the slack, the one that moves the fewest items is taken, if it moves
//! fewer than the old cut does: one more reduction of the bracket's
//! histogram, with each bin's items counted by the half that holds them.

use crate::comm::all_gather_v;
use crate::cut_tree::{CutTree, Node};
use crate::{Aabb, Item, PartitionError, Partitioner};
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use rayon::prelude::*;

/// A repartitioning keeps a cut's axis while the group's extent along it is
/// at least this fraction of its longest extent. Small changes of shape then
/// move only the items the cuts pass over; once the shape has changed a lot
/// (a falling cloud become a flat pile), a cut across the old axis would make
/// slabs and cut no contacts, and the axis turns, at the cost of one large
/// migration.
pub const KEEP_AXIS: f64 = 0.5;

/// The axis of the longest extent, the first of equals (x before y before
/// z, as Zoltan's RCB picks): a cube of particles falling under gravity is
/// then cut upright, across the floor it lands on, not into a top half
/// that has no contacts yet and a bottom half that gets them all.
pub fn longest_axis(ext: &[f64; 3]) -> usize {
    (0..3).fold(0, |best, k| if ext[k] > ext[best] { k } else { best })
}

/// Whether a cut along `dim` is kept for a group of extents `ext`.
pub fn keeps_axis(ext: &[f64; 3], dim: usize) -> bool {
    let longest = ext.iter().copied().fold(0.0, f64::max);
    ext[dim] > 0.0 && ext[dim] >= KEEP_AXIS * longest
}

/// How the items exactly at a cut were dealt: `None` all went left (at or
/// below the cut), `Some(last)` those with ids up to `last` did (`Some(None)`:
/// none), see [`split_ties`].
type Tie = Option<Option<u64>>;

/// A previous cut a group may keep: its axis, its place, its tie.
type OldCut = (usize, f64, Tie);

/// Candidate cuts per histogram round.
const BINS: usize = 256;

/// Native RCB.
#[derive(Debug, Clone)]
pub struct Rcb {
    /// Allowed deviation of each cut's left weight from its target, relative to
    /// the group's weight.
    pub tolerance: f64,
    /// Histogram rounds at most per cut.
    pub max_rounds: usize,
    /// Half-width of the first bracket around a reused cut, relative to the extent.
    pub reuse_margin: f64,
    /// Keep the previous cuts' axes and start from their positions when
    /// repartitioning.
    pub reuse_cuts: bool,
    /// A reused cut is kept while both sides' weights are within this
    /// fraction of their targets, for the top cut; a group of n of the P
    /// ranks allows n / P of it (see the module doc).
    pub reuse_slack: f64,
    tree: Option<CutTree>,
    /// Per node of `tree`, how the items at its cut were dealt (see
    /// [`split_ties`]), so that a kept cut deals them the same way again.
    ties: Vec<Tie>,
}

impl Default for Rcb {
    fn default() -> Self {
        Rcb {
            tolerance: 1e-4,
            max_rounds: 12,
            reuse_margin: 0.02,
            reuse_cuts: true,
            reuse_slack: 0.02,
            tree: None,
            ties: Vec::new(),
        }
    }
}

#[derive(Debug, Clone, Copy)]
struct Group {
    node: usize,
    r0: i32,
    r1: i32,
}

impl Rcb {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn tree(&self) -> Option<&CutTree> {
        self.tree.as_ref()
    }

    fn bisect(&mut self, comm: &SimpleCommunicator, items: &[Item]) -> Vec<i32> {
        let previous = if self.reuse_cuts {
            self.tree
                .take()
                .map(|t| (t, std::mem::take(&mut self.ties)))
        } else {
            None
        };
        let previous = previous.as_ref().map(|(t, ties)| (t, &ties[..]));
        let mut level = Level {
            nodes: vec![Node::Leaf(0)],
            ties: vec![None],
            group_of: vec![0; items.len()],
            groups: vec![Group {
                node: 0,
                r0: 0,
                r1: comm.size(),
            }],
        };
        loop {
            let active: Vec<usize> = (0..level.groups.len())
                .filter(|&g| level.groups[g].r1 - level.groups[g].r0 > 1)
                .collect();
            if active.is_empty() {
                break;
            }
            let mut searches = self.start_searches(comm, items, &level, &active, previous);
            self.find_cuts(comm, items, &level.group_of, &active, &mut searches);
            split_ties(comm, items, &level.group_of, &active, &mut searches);
            level.split(items, &active, &searches);
        }
        // Leaves carry their ranks; items take the rank of their group.
        let Level {
            nodes,
            ties,
            group_of,
            groups,
        } = level;
        let owners = group_of
            .iter()
            .map(|&g| match nodes.get(groups[g as usize].node) {
                Some(Node::Leaf(r)) => *r,
                _ => groups[g as usize].r0,
            })
            .collect();
        self.tree = Some(CutTree { nodes });
        self.ties = ties;
        owners
    }

    /// Per group of the level: its axis (the previous cut's, else the
    /// longest of its items' box over all ranks), its target weight, and its
    /// first bracket (around the previous cut).
    fn start_searches(
        &self,
        comm: &SimpleCommunicator,
        items: &[Item],
        level: &Level,
        active: &[usize],
        previous: Option<(&CutTree, &[Tie])>,
    ) -> Vec<Search> {
        let ng = level.groups.len();
        let (lo, hi, w) = group_boxes(items, &level.group_of, ng);
        let mut glo = vec![0.0; 3 * ng];
        let mut ghi = vec![0.0; 3 * ng];
        let mut gw = vec![0.0; ng];
        comm.all_reduce_into(&lo[..], &mut glo[..], SystemOperation::min());
        comm.all_reduce_into(&hi[..], &mut ghi[..], SystemOperation::max());
        comm.all_reduce_into(&w[..], &mut gw[..], SystemOperation::sum());
        // Groups of one rank are not cut.
        let settled = Search {
            done: true,
            ..Search::default()
        };
        let mut searches = vec![settled; ng];
        let mut olds = vec![None; ng];
        for &g in active {
            let ext: [f64; 3] = [0, 1, 2].map(|k| ghi[3 * g + k] - glo[3 * g + k]);
            let longest = longest_axis(&ext);
            let Group { node, r0, r1 } = level.groups[g];
            // The old cut, while its axis is still not much shorter than the
            // longest (see [`KEEP_AXIS`]).
            let old = match previous.and_then(|(t, _)| t.nodes.get(node)) {
                Some(&Node::Cut { dim, value, .. }) if keeps_axis(&ext, dim) => Some((dim, value)),
                _ => None,
            };
            let tie = previous.and_then(|(_, ties)| ties.get(node).copied().flatten());
            olds[g] = old.map(|(dim, value)| (dim, value, tie));
            let d = old.map_or(longest, |(dim, _)| dim);
            let (a, b) = (glo[3 * g + d], ghi[3 * g + d]);
            let full = if a <= b { (a, b) } else { (0.0, 0.0) };
            let mut bracket = full;
            if let Some((_, value)) = old {
                let m = self.reuse_margin * (b - a);
                let near = ((value - m).max(a), (value + m).min(b));
                // An old cut the items have drifted away from is no guide.
                if near.0 < near.1 {
                    bracket = near;
                }
            }
            searches[g] = Search {
                dim: d,
                target: gw[g] * ((r1 - r0) / 2) as f64 / (r1 - r0) as f64,
                tol: self.tolerance * gw[g],
                bracket,
                full,
                cut: bracket.1,
                done: a >= b || a.is_nan() || gw[g] == 0.0,
                ..Search::default()
            };
        }
        // Every rank holds the same tree, so all take this branch or none.
        if olds.iter().any(Option::is_some) {
            let sides = self_sides(comm.rank(), &level.groups);
            let around = around_old_cuts(comm, items, &level.group_of, &olds, &searches, &sides);
            for &g in active {
                let Some((_, value, tie)) = olds[g] else {
                    continue;
                };
                let Group { r0, r1, .. } = level.groups[g];
                let share = f64::from(r1 - r0) / f64::from(comm.size());
                let f = f64::from((r1 - r0) / 2) / f64::from(r1 - r0);
                let slack = self.reuse_slack * share * f.min(1.0 - f) * gw[g];
                let s = &mut searches[g];
                if s.done {
                    continue;
                }
                let view = around.group(g);
                let off = view.left - s.target;
                let kept = (off.abs() <= slack).then_some((view.kept_moves, value, tie));
                let moved = view.least_moving(s.bracket, s.target, slack);
                // The cut that moves fewer items, the old one among equals.
                let choice = match (kept, moved) {
                    (Some(k), Some(m)) if m.0 < k.0 => Some(m),
                    (Some(k), _) => Some(k),
                    (None, m) => m,
                };
                if let Some((_, cut, tie)) = choice {
                    s.cut = cut;
                    s.tie = tie;
                    s.done = true;
                    s.converged = true;
                } else {
                    // Only back inside the slack, on the side the work
                    // shifted to: the cut passes over no more items than
                    // the shift beyond the slack asks.
                    s.target += off.signum() * (slack - s.tol).max(0.0);
                }
            }
        }
        searches
    }

    /// Histogram rounds until every active group's cut is close enough to
    /// its target (or `max_rounds` have run).
    fn find_cuts(
        &self,
        comm: &SimpleCommunicator,
        items: &[Item],
        group_of: &[u32],
        active: &[usize],
        searches: &mut [Search],
    ) {
        for _round in 0..self.max_rounds {
            if active.iter().all(|&g| searches[g].done) {
                break;
            }
            let local = histograms(items, group_of, searches);
            let mut global = vec![0.0f64; local.len()];
            comm.all_reduce_into(&local[..], &mut global[..], SystemOperation::sum());
            for &g in active {
                if !searches[g].done {
                    searches[g].narrow(&mut global[g * (BINS + 1)..(g + 1) * (BINS + 1)]);
                }
            }
        }
    }
}

/// The groups of one level of the tree, the nodes so far, and each item's group.
struct Level {
    nodes: Vec<Node>,
    /// Per node, how the items at its cut were dealt.
    ties: Vec<Tie>,
    group_of: Vec<u32>,
    groups: Vec<Group>,
}

impl Level {
    /// Cuts every active group in two at its search's cut, and moves its
    /// items into the halves.
    fn split(&mut self, items: &[Item], active: &[usize], searches: &[Search]) {
        let mut split = vec![None; self.groups.len()];
        for &g in active {
            let Group { node, r0, r1 } = self.groups[g];
            let mid = r0 + (r1 - r0) / 2;
            let left = self.nodes.len();
            self.nodes.push(Node::Leaf(r0));
            self.nodes.push(Node::Leaf(mid));
            self.ties.extend([None, None]);
            let s = &searches[g];
            self.ties[node] = s.tie;
            self.nodes[node] = Node::Cut {
                dim: s.dim,
                value: s.cut,
                left,
                right: left + 1,
            };
            split[g] = Some((self.groups.len() as u32, s.dim, s.cut, s.tie));
            self.groups.push(Group {
                node: left,
                r0,
                r1: mid,
            });
            self.groups.push(Group {
                node: left + 1,
                r0: mid,
                r1,
            });
            // Retired: a single-rank placeholder no item points to.
            self.groups[g] = Group {
                node: usize::MAX,
                r0,
                r1: r0 + 1,
            };
        }
        self.group_of
            .par_iter_mut()
            .zip(items.par_iter())
            .for_each(|(g, it)| {
                if let Some((gl, d, c, tie)) = split[*g as usize] {
                    *g = if goes_left(it, d, c, tie) { gl } else { gl + 1 };
                }
            });
    }
}

/// The search for one group's cut.
#[derive(Debug, Clone, Copy, Default)]
struct Search {
    dim: usize,
    /// Weight the left part should hold, and how far off it may be.
    target: f64,
    tol: f64,
    /// Where the cut is searched, and the group's whole extent.
    bracket: (f64, f64),
    full: (f64, f64),
    cut: f64,
    done: bool,
    /// Whether the cut came within tolerance of the target.
    converged: bool,
    /// Items at the cut split between the halves: the last id dealt left
    /// (`None`: none), see [`split_ties`].
    tie: Tie,
}

impl Search {
    /// One round: `h[k]` is the weight of the group's items at candidate k
    /// of the bracket; the cut moves to the candidate closest to the target
    /// and the bracket shrinks to the bin that holds it.
    fn narrow(&mut self, h: &mut [f64]) {
        for k in 1..=BINS {
            h[k] += h[k - 1];
        }
        let (t, tol) = (self.target, self.tol);
        if t < h[0] - tol || t > h[BINS] + tol {
            // The reused bracket missed: search the whole extent.
            self.bracket = self.full;
            return;
        }
        let k = (0..=BINS).find(|&k| h[k] >= t).unwrap_or(BINS);
        let best = if k > 0 && (t - h[k - 1]) < (h[k] - t) {
            k - 1
        } else {
            k
        };
        self.cut = candidate(self.bracket, best);
        if (h[best] - t).abs() <= tol || k == 0 {
            self.converged = (h[best] - t).abs() <= tol;
            self.done = true;
            return;
        }
        self.bracket = (candidate(self.bracket, k - 1), candidate(self.bracket, k));
        // The bracket cannot shrink below rounding of the extent.
        if self.bracket.1 - self.bracket.0 <= 1e-14 * (self.full.1 - self.full.0) {
            self.done = true;
        }
    }
}

/// For each group whose search ended short of its target with one
/// coordinate left in its bracket (an atom of weight: items at exactly one
/// coordinate), puts the cut at that coordinate and deals its items left in
/// increasing id until the left half comes closest to its target. The
/// decision is the same on every rank: searches are, and the atom's items
/// are gathered on all. Collective, whenever some group's search missed.
fn split_ties(
    comm: &SimpleCommunicator,
    items: &[Item],
    group_of: &[u32],
    active: &[usize],
    searches: &mut [Search],
) {
    let ng = searches.len();
    let open: Vec<bool> = (0..ng)
        .map(|g| {
            active.contains(&g)
                && !searches[g].converged
                && searches[g].bracket.0 < searches[g].bracket.1
        })
        .collect();
    if !open.contains(&true) {
        return;
    }
    let in_bracket = |it: &Item, g: usize| {
        let s = &searches[g];
        let x = it.point[s.dim];
        open[g] && x > s.bracket.0 && x <= s.bracket.1
    };
    // The coordinates left in each open bracket, and the weight below them.
    let (mut lo, mut hi) = (vec![f64::INFINITY; ng], vec![f64::NEG_INFINITY; ng]);
    for (it, &g) in items.iter().zip(group_of) {
        let g = g as usize;
        if in_bracket(it, g) {
            let x = it.point[searches[g].dim];
            lo[g] = lo[g].min(x);
            hi[g] = hi[g].max(x);
        }
    }
    let (mut glo, mut ghi) = (vec![0.0; ng], vec![0.0; ng]);
    comm.all_reduce_into(&lo[..], &mut glo[..], SystemOperation::min());
    comm.all_reduce_into(&hi[..], &mut ghi[..], SystemOperation::max());
    let atom: Vec<Option<f64>> = (0..ng)
        .map(|g| (open[g] && glo[g] == ghi[g]).then_some(glo[g]))
        .collect();
    let mut below = vec![0.0; ng];
    // (group, id, weight's bits) per item at an atom, flat.
    let mut ties: Vec<u64> = Vec::new();
    for (it, &g) in items.iter().zip(group_of) {
        let g = g as usize;
        if let Some(c) = atom[g] {
            let x = it.point[searches[g].dim];
            if x < c {
                below[g] += it.weight;
            } else if x == c {
                ties.extend([g as u64, it.id, it.weight.to_bits()]);
            }
        }
    }
    let mut gbelow = vec![0.0; ng];
    comm.all_reduce_into(&below[..], &mut gbelow[..], SystemOperation::sum());
    let gathered = all_gather_v(comm, &ties);
    let mut ties: Vec<&[u64]> = gathered.chunks_exact(3).collect();
    ties.sort_unstable_by_key(|t| (t[0], t[1]));
    for (g, c) in atom.iter().enumerate() {
        let Some(c) = *c else { continue };
        let s = &mut searches[g];
        let mut left = gbelow[g];
        let mut last = None;
        for t in ties.iter().filter(|t| t[0] == g as u64) {
            let w = f64::from_bits(t[2]);
            // Deal it left while that brings the left half closer.
            if (left + w - s.target).abs() >= (left - s.target).abs() {
                break;
            }
            left += w;
            last = Some(t[1]);
        }
        s.cut = c;
        s.tie = Some(last);
    }
}

/// Whether `it` goes to the left of the cut at `c` on axis `d`: at or below
/// it, but of the items exactly at a cut whose ties were dealt (`tie`), only
/// those with ids up to the last one dealt left.
fn goes_left(it: &Item, d: usize, c: f64, tie: Tie) -> bool {
    match tie {
        Some(last) if it.point[d] == c => last.is_some_and(|l| it.id <= l),
        _ => it.point[d] <= c,
    }
}

/// Which half of each group this rank's items are in now (before the
/// repartitioning): the half whose ranks hold this one, `None` for the
/// groups this rank is not in (its items in them move whatever the cut).
fn self_sides(me: i32, groups: &[Group]) -> Vec<Option<Side>> {
    groups
        .iter()
        .map(|&Group { r0, r1, .. }| {
            let mid = r0 + (r1 - r0) / 2;
            if (r0..mid).contains(&me) {
                Some(Side::Left)
            } else if (mid..r1).contains(&me) {
                Some(Side::Right)
            } else {
                None
            }
        })
        .collect()
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Side {
    Left,
    Right,
}

/// Per group with an old cut, summed over all ranks: the weight at or below
/// the cut, the items keeping it would move (those on the other side of it
/// from the half of the ranks that holds them), and per bin of the bracket
/// around it the weight and the items held by each half.
struct AroundOldCuts {
    flat: Vec<f64>,
}

/// Doubles per group: left weight, moves if kept, then (weight, held left,
/// held right) for bins 0..=BINS + 1 (the last: above the bracket).
const AROUND: usize = 2 + 3 * (BINS + 2);

struct AroundOldCut<'a> {
    left: f64,
    kept_moves: f64,
    bins: &'a [f64],
}

impl AroundOldCuts {
    fn group(&self, g: usize) -> AroundOldCut<'_> {
        let v = &self.flat[g * AROUND..(g + 1) * AROUND];
        AroundOldCut {
            left: v[0],
            kept_moves: v[1],
            bins: &v[2..],
        }
    }
}

impl AroundOldCut<'_> {
    /// Of the bracket's candidate cuts whose left weight is within `slack`
    /// of `target`, the one that moves the fewest items (then the closest
    /// to the target, then the lowest): the cut follows items that drifted
    /// across it together, as far as the slack lets it. Its moves, place
    /// and tie (none: the items at it go left).
    fn least_moving(
        &self,
        bracket: (f64, f64),
        target: f64,
        slack: f64,
    ) -> Option<(f64, f64, Tie)> {
        if bracket.0 >= bracket.1 {
            return None;
        }
        let held_left: f64 = self.bins.iter().skip(1).step_by(3).sum();
        let (mut w, mut l, mut r) = (0.0, 0.0, 0.0);
        let mut best: Option<(f64, f64, usize)> = None;
        for k in 0..=BINS {
            w += self.bins[3 * k];
            l += self.bins[3 * k + 1];
            r += self.bins[3 * k + 2];
            let miss = (w - target).abs();
            if miss > slack {
                continue;
            }
            let moves = r + (held_left - l);
            if best.is_none_or(|(m, d, _)| (moves, miss) < (m, d)) {
                best = Some((moves, miss, k));
            }
        }
        best.map(|(moves, _, k)| (moves, candidate(bracket, k), None))
    }
}

/// See [`AroundOldCuts`]; the bins are those of each group's search
/// bracket, which starts around its old cut (collective).
fn around_old_cuts(
    comm: &SimpleCommunicator,
    items: &[Item],
    group_of: &[u32],
    olds: &[Option<OldCut>],
    searches: &[Search],
    sides: &[Option<Side>],
) -> AroundOldCuts {
    let mut local = vec![0.0f64; olds.len() * AROUND];
    for (it, &g) in items.iter().zip(group_of) {
        let g = g as usize;
        let Some((d, value, tie)) = olds[g] else {
            continue;
        };
        let bracket = searches[g].bracket;
        let v = &mut local[g * AROUND..(g + 1) * AROUND];
        let left = goes_left(it, d, value, tie);
        if left {
            v[0] += it.weight;
        }
        if sides[g] == Some(if left { Side::Right } else { Side::Left }) {
            v[1] += 1.0;
        }
        let k = bin_of(it.point[d], bracket);
        v[2 + 3 * k] += it.weight;
        match sides[g] {
            Some(Side::Left) => v[3 + 3 * k] += 1.0,
            Some(Side::Right) => v[4 + 3 * k] += 1.0,
            None => {}
        }
    }
    let mut flat = vec![0.0f64; local.len()];
    comm.all_reduce_into(&local[..], &mut flat[..], SystemOperation::sum());
    AroundOldCuts { flat }
}

/// `h[g * (BINS + 1) + k]`: the weight of this rank's items of group g in
/// bin k of its bracket (at or below candidate k, above candidate k − 1),
/// for the groups still searching.
fn histograms(items: &[Item], group_of: &[u32], searches: &[Search]) -> Vec<f64> {
    let len = searches.len() * (BINS + 1);
    items
        .par_iter()
        .zip(group_of.par_iter())
        .fold(
            || vec![0.0f64; len],
            |mut acc, (it, &g)| {
                let s = &searches[g as usize];
                if !s.done {
                    let k = bin_of(it.point[s.dim], s.bracket);
                    if k <= BINS {
                        acc[g as usize * (BINS + 1) + k] += it.weight;
                    }
                }
                acc
            },
        )
        .reduce(
            || vec![0.0f64; len],
            |mut a, b| {
                a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
                a
            },
        )
}

/// The first candidate of `bracket` at or above x (BINS + 1: above them all).
fn bin_of(x: f64, bracket: (f64, f64)) -> usize {
    let (a, b) = bracket;
    if x <= a {
        return 0;
    }
    if x > b {
        return BINS + 1;
    }
    let k = (((x - a) / (b - a) * BINS as f64).ceil() as usize).min(BINS);
    // The estimate is off by at most one bin (rounding).
    if k > 0 && x <= candidate(bracket, k - 1) {
        k - 1
    } else if x > candidate(bracket, k) {
        k + 1
    } else {
        k
    }
}

/// Candidate cut k of BINS + 1 spread over the bracket [a, b] (k = BINS is b exactly).
fn candidate((a, b): (f64, f64), k: usize) -> f64 {
    if k == BINS {
        b
    } else {
        a + (b - a) * k as f64 / BINS as f64
    }
}

fn group_boxes(items: &[Item], group_of: &[u32], ng: usize) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    items
        .par_iter()
        .zip(group_of.par_iter())
        .fold(
            || {
                (
                    vec![f64::INFINITY; 3 * ng],
                    vec![f64::NEG_INFINITY; 3 * ng],
                    vec![0.0; ng],
                )
            },
            |(mut lo, mut hi, mut w), (it, &g)| {
                let g = g as usize;
                for k in 0..3 {
                    lo[3 * g + k] = lo[3 * g + k].min(it.point[k]);
                    hi[3 * g + k] = hi[3 * g + k].max(it.point[k]);
                }
                w[g] += it.weight;
                (lo, hi, w)
            },
        )
        .reduce(
            || {
                (
                    vec![f64::INFINITY; 3 * ng],
                    vec![f64::NEG_INFINITY; 3 * ng],
                    vec![0.0; ng],
                )
            },
            |(mut l1, mut h1, mut w1), (l2, h2, w2)| {
                for i in 0..l1.len() {
                    l1[i] = l1[i].min(l2[i]);
                    h1[i] = h1[i].max(h2[i]);
                }
                w1.iter_mut().zip(w2).for_each(|(a, b)| *a += b);
                (l1, h1, w1)
            },
        )
}

impl Partitioner for Rcb {
    fn name(&self) -> &'static str {
        "rcb"
    }

    fn partition(
        &mut self,
        comm: &SimpleCommunicator,
        items: &[Item],
    ) -> Result<Vec<i32>, PartitionError> {
        if items.iter().any(|i| {
            !i.point.iter().all(|x| x.is_finite()) || !i.weight.is_finite() || i.weight < 0.0
        }) {
            return Err(PartitionError::BadItem(
                "non-finite point or negative weight".into(),
            ));
        }
        Ok(self.bisect(comm, items))
    }

    fn owner(&self, p: [f64; 3]) -> Result<i32, PartitionError> {
        Ok(self.tree.as_ref().map_or(0, |t| t.owner(p)))
    }

    fn ranks_overlapping(&self, b: &Aabb, out: &mut Vec<i32>) -> Result<(), PartitionError> {
        match &self.tree {
            Some(t) => t.ranks_overlapping(b, out),
            None => out.push(0),
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The longest extent wins; among equals, the first axis, as in Zoltan.
    #[test]
    fn the_cut_axis_is_the_longest_and_the_first_of_equals() {
        assert_eq!(longest_axis(&[1.0, 1.0, 1.0]), 0);
        assert_eq!(longest_axis(&[1.0, 2.0, 2.0]), 1);
        assert_eq!(longest_axis(&[1.0, 2.0, 2.0 + 1e-12]), 2);
        assert_eq!(longest_axis(&[0.0, 0.0, 0.0]), 0);
    }
}
