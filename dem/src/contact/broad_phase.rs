//! Broad phase: sort and sweep over the boxes of the body groups of a
//! triangle set, inflated by the halos, along the axis on which the boxes'
//! centres spread most (a pile on a floor is flat, a falling column tall: a
//! fixed axis would compare most boxes with most others in one of them).

use super::bounds::Bounds;
use super::triangle_set::TriangleSet;
use super::Phase;
use crate::body::Body;
use glam::DVec3;

/// Which part of a group a box covers.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Part {
    Owned,
    Ghost,
}

/// Pairs of group indices (g, h), g < h (so body(g) < body(h)), whose boxes
/// overlap and of which at least one body moves:
/// - local-local: the owned parts of both;
/// - local-ghost: the owned part of g and the ghost part of h. The pair of g's
///   ghosts with h's owned triangles is the business of the rank owning g's
///   triangles, so that each triangle pair is examined on exactly one rank.
///
/// Sorted, so that everything downstream is in a deterministic order.
pub(crate) fn body_pairs(set: &TriangleSet, bodies: &[Body], phase: Phase) -> Vec<(usize, usize)> {
    let groups = set.groups();
    let mut entries: Vec<(Bounds, usize, Part)> = Vec::with_capacity(2 * groups.len());
    for (k, g) in groups.iter().enumerate() {
        if !g.owned.is_empty() {
            entries.push((g.owned_box, k, Part::Owned));
        }
        if phase == Phase::LocalGhost && !g.ghost.is_empty() {
            entries.push((g.ghost_box, k, Part::Ghost));
        }
    }
    let axis = widest_axis(&entries);
    entries.sort_by(|x, y| x.0.lo[axis].total_cmp(&y.0.lo[axis]).then(x.1.cmp(&y.1)));
    let moving = |k: usize| !bodies[groups[k].body as usize].is_static();
    let mut pairs = Vec::new();
    for (n, &(bx, k, part)) in entries.iter().enumerate() {
        for &(by, l, other) in &entries[n + 1..] {
            if by.lo[axis] > bx.hi[axis] {
                break;
            }
            let pair = match (phase, part, other) {
                (Phase::LocalLocal, Part::Owned, Part::Owned) => (k.min(l), k.max(l)),
                (Phase::LocalGhost, Part::Owned, Part::Ghost) if k < l => (k, l),
                (Phase::LocalGhost, Part::Ghost, Part::Owned) if l < k => (l, k),
                _ => continue,
            };
            if pair.0 != pair.1 && (moving(k) || moving(l)) && bx.overlaps(&by) {
                pairs.push(pair);
            }
        }
    }
    pairs.sort_unstable();
    pairs
}

/// The axis of largest variance of the boxes' centres. Boxes that span most of
/// the scene (floors, walls) are left out: they overlap everything on any axis.
fn widest_axis(entries: &[(Bounds, usize, Part)]) -> usize {
    let scene = entries.iter().fold(Bounds::EMPTY, |acc, e| acc.union(&e.0));
    let span = scene.hi - scene.lo;
    let (mut n, mut sum, mut sum2) = (0.0, DVec3::ZERO, DVec3::ZERO);
    for (b, _, _) in entries {
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
