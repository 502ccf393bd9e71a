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
//! Repartitioning reuses the previous cuts: each group's search starts from a
//! narrow bracket around its old cut, widened to the full extent only when the
//! target weight is not inside it.

use crate::cut_tree::{CutTree, Node};
use crate::{Aabb, Item, PartitionError, Partitioner};
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use rayon::prelude::*;

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
    /// Start from the previous cuts when repartitioning.
    pub reuse_cuts: bool,
    tree: Option<CutTree>,
    /// Histogram rounds the last partitioning needed (all levels).
    pub last_rounds: usize,
}

impl Default for Rcb {
    fn default() -> Self {
        Rcb {
            tolerance: 1e-4,
            max_rounds: 12,
            reuse_margin: 0.02,
            reuse_cuts: true,
            tree: None,
            last_rounds: 0,
        }
    }
}

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
        let size = comm.size();
        let previous = if self.reuse_cuts {
            self.tree.take()
        } else {
            None
        };
        let mut nodes = vec![Node::Leaf(0)];
        let mut group_of: Vec<u32> = vec![0; items.len()];
        let mut groups = vec![Group {
            node: 0,
            r0: 0,
            r1: size,
        }];
        let mut rounds = 0;
        loop {
            let active: Vec<usize> = (0..groups.len())
                .filter(|&g| groups[g].r1 - groups[g].r0 > 1)
                .collect();
            if active.is_empty() {
                break;
            }
            let ng = groups.len();
            // Bounding boxes and weights of every group's items.
            let (lo, hi, w) = group_boxes(items, &group_of, ng);
            let mut glo = vec![0.0; 3 * ng];
            let mut ghi = vec![0.0; 3 * ng];
            let mut gw = vec![0.0; ng];
            comm.all_reduce_into(&lo[..], &mut glo[..], SystemOperation::min());
            comm.all_reduce_into(&hi[..], &mut ghi[..], SystemOperation::max());
            comm.all_reduce_into(&w[..], &mut gw[..], SystemOperation::sum());

            // Per active group: axis, target, bracket.
            let mut dims = vec![0usize; ng];
            let mut target = vec![0.0; ng];
            let mut bracket = vec![(0.0f64, 0.0f64); ng];
            let mut full = vec![(0.0f64, 0.0f64); ng];
            let mut done = vec![true; ng];
            for &g in &active {
                let ext: [f64; 3] = [0, 1, 2].map(|k| ghi[3 * g + k] - glo[3 * g + k]);
                let d = (0..3)
                    .max_by(|&a, &b| ext[a].total_cmp(&ext[b]))
                    .unwrap_or(0);
                dims[g] = d;
                let n = (groups[g].r1 - groups[g].r0) as f64;
                let nl = ((groups[g].r1 - groups[g].r0) / 2) as f64;
                target[g] = gw[g] * nl / n;
                let (a, b) = (glo[3 * g + d], ghi[3 * g + d]);
                full[g] = if a <= b { (a, b) } else { (0.0, 0.0) };
                bracket[g] = full[g];
                if let Some(Node::Cut { dim, value, .. }) =
                    previous.as_ref().and_then(|t| t.nodes.get(groups[g].node))
                {
                    if *dim == d && a < b {
                        let m = self.reuse_margin * (b - a);
                        bracket[g] = ((value - m).max(a), (value + m).min(b));
                    }
                }
                done[g] = a >= b || a.is_nan() || gw[g] == 0.0;
            }
            let mut cut = vec![0.0; ng];
            for &g in &active {
                cut[g] = bracket[g].1;
            }
            // Histogram rounds until every active group's cut is close enough.
            for _round in 0..self.max_rounds {
                if active.iter().all(|&g| done[g]) {
                    break;
                }
                rounds += 1;

                // below[g][k]: weight of group g's items with x <= candidate(bracket[g], k), k = 0..=BINS.
                let local = items
                    .par_iter()
                    .zip(group_of.par_iter())
                    .fold(
                        || vec![0.0f64; ng * (BINS + 1)],
                        |mut acc, (it, &g)| {
                            let g = g as usize;
                            if !done[g] {
                                let x = it.point[dims[g]];
                                let (a, b) = bracket[g];
                                // First candidate at or above x.
                                let k = if x <= a {
                                    0
                                } else if x > b {
                                    BINS + 1
                                } else {
                                    let f = ((x - a) / (b - a) * BINS as f64).ceil() as usize;
                                    let k = f.min(BINS);
                                    // The estimate is off by at most one bin (rounding).
                                    if k > 0 && x <= candidate(bracket[g], k - 1) {
                                        k - 1
                                    } else if x > candidate(bracket[g], k) {
                                        k + 1
                                    } else {
                                        k
                                    }
                                };
                                if k <= BINS {
                                    acc[g * (BINS + 1) + k] += it.weight;
                                }
                            }
                            acc
                        },
                    )
                    .reduce(
                        || vec![0.0f64; ng * (BINS + 1)],
                        |mut a, b| {
                            a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
                            a
                        },
                    );
                let mut global = vec![0.0f64; ng * (BINS + 1)];
                comm.all_reduce_into(&local[..], &mut global[..], SystemOperation::sum());
                for &g in &active {
                    if done[g] {
                        continue;
                    }
                    let h = &mut global[g * (BINS + 1)..(g + 1) * (BINS + 1)];
                    for k in 1..=BINS {
                        h[k] += h[k - 1];
                    }
                    let t = target[g];
                    let tol = self.tolerance * gw[g];
                    if t < h[0] - tol || t > h[BINS] + tol {
                        // The reused bracket missed: search the whole extent.
                        bracket[g] = full[g];
                        continue;
                    }
                    let k = (0..=BINS).find(|&k| h[k] >= t).unwrap_or(BINS);
                    let best = if k > 0 && (t - h[k - 1]) < (h[k] - t) {
                        k - 1
                    } else {
                        k
                    };
                    cut[g] = candidate(bracket[g], best);
                    if (h[best] - t).abs() <= tol || k == 0 {
                        done[g] = true;
                    } else {
                        bracket[g] = (candidate(bracket[g], k - 1), candidate(bracket[g], k));
                        if bracket[g].1 - bracket[g].0 <= 1e-14 * (full[g].1 - full[g].0) {
                            done[g] = true;
                        }
                    }
                }
            }
            // Split the groups and reassign their items.
            let mut split = vec![None; ng];
            for &g in &active {
                let Group { node, r0, r1 } = groups[g];
                let mid = r0 + (r1 - r0) / 2;
                let left = nodes.len();
                nodes.push(Node::Leaf(r0));
                nodes.push(Node::Leaf(mid));
                nodes[node] = Node::Cut {
                    dim: dims[g],
                    value: cut[g],
                    left,
                    right: left + 1,
                };
                let gl = groups.len();
                groups.push(Group {
                    node: left,
                    r0,
                    r1: mid,
                });
                groups.push(Group {
                    node: left + 1,
                    r0: mid,
                    r1,
                });
                split[g] = Some((gl, dims[g], cut[g]));
            }
            group_of
                .par_iter_mut()
                .zip(items.par_iter())
                .for_each(|(g, it)| {
                    if let Some((gl, d, c)) = split[*g as usize] {
                        *g = if it.point[d] <= c {
                            gl as u32
                        } else {
                            gl as u32 + 1
                        };
                    }
                });
            // Retire the split groups by making them single-rank placeholders.
            for &g in &active {
                groups[g].r1 = groups[g].r0 + 1;
                groups[g].node = usize::MAX;
            }
        }
        // Leaves carry their ranks; items take the rank of their group.
        let owners = group_of
            .iter()
            .map(|&g| match nodes.get(groups[g as usize].node) {
                Some(Node::Leaf(r)) => *r,
                _ => groups[g as usize].r0,
            })
            .collect();
        self.tree = Some(CutTree { nodes });
        self.last_rounds = rounds;
        owners
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
