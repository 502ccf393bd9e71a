//! Broad phase: sort and sweep over the boxes of the body groups of a
//! triangle set, inflated by the halos, along the axis on which the boxes'
//! centres spread most (a pile on a floor is flat, a falling column tall: a
//! fixed axis would compare most boxes with most others in one of them).
//!
//! The sweep runs in parallel over chunks of the sorted boxes (about 5% of a
//! one-thread hopper run is spent here, between the parallel sections). Each
//! chunk's pairs come out in sweep order and chunks are concatenated in order,
//! so the result depends on the boxes only, never on the thread count.
//! Measured on the hopper, two threads do not yet shorten it: the walls' boxes
//! sort first and each is checked against every other box, so the first chunk
//! holds nearly all the work. Static and scene-sized boxes want a loop of
//! their own (against the moving boxes only).

use super::bounds::Bounds;
use super::triangle_set::TriangleSet;
use super::Phase;
use crate::body::Body;
use glam::DVec3;
use rayon::prelude::*;

/// Which part of a group a box covers.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Part {
    Owned,
    Ghost,
}

/// One box of the sweep, with what the inner loop needs at hand (not behind
/// an index into the groups and bodies).
#[derive(Clone, Copy)]
struct Entry {
    bounds: Bounds,
    group: usize,
    part: Part,
    moving: bool,
}

/// Sorted boxes per parallel task of the sweep.
const SWEEP_GRAIN: usize = 16;

/// Pairs of group indices (g, h), g < h (so body(g) < body(h)), whose boxes
/// overlap and of which at least one body moves:
/// - local-local: the owned parts of both;
/// - local-ghost: the owned part of g and the ghost part of h. The pair of g's
///   ghosts with h's owned triangles is the business of the rank owning g's
///   triangles, so that each triangle pair is examined on exactly one rank.
///
/// In sweep order: a function of the boxes alone, so everything downstream is
/// in a deterministic order.
pub(crate) fn body_pairs(set: &TriangleSet, bodies: &[Body], phase: Phase) -> Vec<(usize, usize)> {
    let groups = set.groups();
    let mut entries: Vec<Entry> = Vec::with_capacity(2 * groups.len());
    for (k, g) in groups.iter().enumerate() {
        let moving = !bodies[g.body as usize].is_static();
        if !g.owned.is_empty() {
            entries.push(Entry {
                bounds: g.owned_box,
                group: k,
                part: Part::Owned,
                moving,
            });
        }
        if phase == Phase::LocalGhost && !g.ghost.is_empty() {
            entries.push(Entry {
                bounds: g.ghost_box,
                group: k,
                part: Part::Ghost,
                moving,
            });
        }
    }
    let axis = widest_axis(&entries);
    entries.sort_unstable_by(|x, y| {
        (x.bounds.lo[axis].total_cmp(&y.bounds.lo[axis]))
            .then(x.group.cmp(&y.group))
            .then((x.part as u8).cmp(&(y.part as u8)))
    });
    let entries = &entries;
    let chunks: Vec<Vec<(usize, usize)>> = (0..entries.len())
        .into_par_iter()
        .with_min_len(SWEEP_GRAIN)
        .fold(Vec::new, |mut pairs, n| {
            sweep_from(entries, n, axis, phase, &mut pairs);
            pairs
        })
        .collect();
    chunks.concat()
}

/// Appends the pairs of sorted entry `n` with the entries after it.
#[inline]
fn sweep_from(
    entries: &[Entry],
    n: usize,
    axis: usize,
    phase: Phase,
    pairs: &mut Vec<(usize, usize)>,
) {
    let x = &entries[n];
    let reach = x.bounds.hi[axis];
    for y in &entries[n + 1..] {
        if y.bounds.lo[axis] > reach {
            break;
        }
        if !(x.moving || y.moving) || x.group == y.group {
            continue;
        }
        let (k, l) = (x.group, y.group);
        let pair = match (phase, x.part, y.part) {
            (Phase::LocalLocal, Part::Owned, Part::Owned) => (k.min(l), k.max(l)),
            (Phase::LocalGhost, Part::Owned, Part::Ghost) if k < l => (k, l),
            (Phase::LocalGhost, Part::Ghost, Part::Owned) if l < k => (l, k),
            _ => continue,
        };
        if x.bounds.overlaps(&y.bounds) {
            pairs.push(pair);
        }
    }
}

/// The axis of largest variance of the boxes' centres. Boxes that span most of
/// the scene (floors, walls) are left out: they overlap everything on any axis.
fn widest_axis(entries: &[Entry]) -> usize {
    let scene = entries
        .iter()
        .fold(Bounds::EMPTY, |acc, e| acc.union(&e.bounds));
    let span = scene.hi - scene.lo;
    let (mut n, mut sum, mut sum2) = (0.0, DVec3::ZERO, DVec3::ZERO);
    for e in entries {
        let b = &e.bounds;
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
    use crate::contact::TriangleKey;
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
        }
    }

    /// Bodies of random small triangles in a box, each triangle owned or a
    /// ghost at random, every fifth body static, one long "wall" body.
    fn scene(seed: u64, n: u32) -> (TriangleSet, Vec<Body>) {
        let mut s = seed;
        let mut rnd = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let (mut owned, mut ghosts) = (Vec::new(), Vec::new());
        for body in 0..n {
            let c = DVec3::new(rnd(), rnd(), 0.3 * rnd()) * 10.0;
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
        let bodies = (0..n).map(|i| body(i % 5 != 3)).collect();
        (set, bodies)
    }

    /// The sweep against the definition, checked on every pair of groups.
    fn all_pairs(set: &TriangleSet, bodies: &[Body], phase: Phase) -> BTreeSet<(usize, usize)> {
        let g = set.groups();
        let mut out = BTreeSet::new();
        for a in 0..g.len() {
            for b in a + 1..g.len() {
                let moving = |k: usize| !bodies[g[k].body as usize].is_static();
                let other = match phase {
                    Phase::LocalLocal => g[b].owned_box,
                    Phase::LocalGhost => g[b].ghost_box,
                };
                if (moving(a) || moving(b))
                    && !g[a].owned_box.is_empty()
                    && !other.is_empty()
                    && g[a].owned_box.overlaps(&other)
                {
                    out.insert((a, b));
                }
            }
        }
        out
    }

    #[test]
    fn sweep_finds_exactly_the_overlapping_pairs_once_on_any_pool() {
        for seed in [1, 2, 3, 99] {
            let (set, bodies) = scene(seed, 150);
            for phase in [Phase::LocalLocal, Phase::LocalGhost] {
                let reference = all_pairs(&set, &bodies, phase);
                assert!(reference.len() > 50, "a test with pairs to find");
                let mut first = None;
                for threads in [1, 2, 3] {
                    let pool = rayon::ThreadPoolBuilder::new()
                        .num_threads(threads)
                        .build()
                        .unwrap();
                    let got = pool.install(|| body_pairs(&set, &bodies, phase));
                    let unique: BTreeSet<_> = got.iter().copied().collect();
                    assert_eq!(unique.len(), got.len(), "a pair found twice");
                    assert_eq!(unique, reference, "seed {seed}, {phase:?}");
                    // Same order on every pool size: downstream batches depend on it.
                    match &first {
                        None => first = Some(got),
                        Some(f) => assert_eq!(f, &got),
                    }
                }
            }
        }
    }
}
