//! Ghost bodies: copies of other ranks' particles within contact reach of
//! this rank's own, and the messages that keep them current.
//!
//! **Who gets what.** Each rank's *reach* is the union of its particles'
//! boxes (a sphere about the centre of mass of the shape's radius), each
//! inflated by the particle's halo and the ghost pad, kept as one box per
//! cell of a coarse grid ([`Reach`]); a particle goes to every other rank
//! whose reach its own inflated box overlaps. The test is
//! per body, against where the other rank's particles actually are, not the
//! region a partitioner drew: it holds for any partitioner, also one whose
//! regions are not boxes. The lists are symmetric: if rank r sends a body to
//! s, s sends one to r (the two boxes that overlap belong one to each), so
//! the per-step messages go both ways between the same neighbours.
//!
//! **When.** The lists hold while no particle's centre has moved farther
//! than the pad since they were drawn (every box was inflated by that much;
//! turning leaves a sphere about the centre where it is); they
//! are drawn anew then, and after a migration. Drawing them sends each new
//! ghost whole ([`BodyRecord`]); in between, only motions travel, 13 numbers
//! per ghost, in the order both sides agreed on (increasing id), no names.
//!
//! **Back to the owners.** A contact between an owned particle and a ghost
//! is computed once, on the rank owning the lower id. The force terms it puts
//! on the ghost travel back to the ghost's owner ([`return_terms`]), which
//! sums them in one process's order (see `forces`).

use crate::records::{bytes, bytes_mut, from_bytes, BodyRecord, Motion, TermRecord};
use dem::contact::Bounds;
use dem::world::World;
use glam::DVec3;
use mpi::point_to_point::MatchedReceiveVec;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use mpi::Count;
use partition::comm::{all_gather_v, all_to_all_v};
use std::time::Instant;

/// Tags of the per-step messages.
const MOTION_TAG: i32 = 0x6d6f;
const TERM_TAG: i32 = 0x7465;

/// The box of body `i`: a sphere of its shape's radius about its centre of
/// mass, inflated by `pad`.
pub fn body_box(world: &World, radius: &[f64], i: usize, pad: f64) -> Bounds {
    let b = &world.bodies[i];
    let r = DVec3::splat(radius[b.shape] + pad);
    Bounds {
        lo: b.x - r,
        hi: b.x + r,
    }
}

/// The ranks this rank exchanges with each step, and whom with what.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GhostLists {
    /// Per neighbour (increasing rank): the owned bodies sent there, by
    /// index, in increasing id.
    pub send: Vec<(i32, Vec<usize>)>,
    /// Per neighbour (increasing rank): the ghosts received from there, by
    /// index, in increasing id.
    pub recv: Vec<(i32, Vec<usize>)>,
}

impl GhostLists {
    /// Ghosts this rank holds.
    pub fn received(&self) -> usize {
        self.recv.iter().map(|r| r.1.len()).sum()
    }

    /// Ghosts this rank sends (one per body and receiving rank).
    pub fn sent(&self) -> usize {
        self.send.iter().map(|s| s.1.len()).sum()
    }
}

/// What drawing the lists brought: the reach of this rank, the ids it sends
/// to each neighbour, and the ghosts that arrived, whole.
pub struct Drawn {
    pub reach: Reach,
    /// Per neighbour (increasing rank): ids of owned bodies sent there.
    pub send: Vec<(i32, Vec<u32>)>,
    /// Per neighbour (increasing rank): the ghosts from there, in increasing id.
    pub arrived: Vec<(i32, Vec<BodyRecord>)>,
}

/// Cells per axis of a rank's reach: its particles' boxes are united per
/// cell of a grid over their union, not into one box. A rank's particles
/// fill its region unevenly (a silo's grains leave the corners, a moving
/// front drags outliers behind), and one box around them all takes in
/// another rank's particles far from any of this rank's; the grid's boxes
/// follow the particles. 3 x 3 x 3 cells are 1.3 KB per rank to gather.
pub const REACH_CELLS: usize = 3;

/// Where a rank's particles can touch others: the union of their inflated
/// boxes, as one box per non-empty cell of [`REACH_CELLS`]³ over their
/// union. Every particle's box lies within one of them.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Reach(Vec<Bounds>);

impl Reach {
    /// The reach of particles whose inflated boxes are `boxes`.
    pub fn of(boxes: &[Bounds]) -> Reach {
        let whole = boxes.iter().fold(Bounds::EMPTY, |u, b| u.union(b));
        if whole.is_empty() {
            return Reach::default();
        }
        let n = REACH_CELLS;
        let extent = whole.hi - whole.lo;
        let cell_of = |c: f64, lo: f64, e: f64| -> usize {
            let k = if e > 0.0 {
                ((c - lo) / e * n as f64) as usize
            } else {
                0
            };
            k.min(n - 1)
        };
        let mut cells = vec![Bounds::EMPTY; n * n * n];
        for b in boxes {
            let c = 0.5 * (b.lo + b.hi);
            let (i, j, k) = (
                cell_of(c.x, whole.lo.x, extent.x),
                cell_of(c.y, whole.lo.y, extent.y),
                cell_of(c.z, whole.lo.z, extent.z),
            );
            let cell = &mut cells[(i * n + j) * n + k];
            *cell = cell.union(b);
        }
        Reach(cells.into_iter().filter(|c| !c.is_empty()).collect())
    }

    /// Whether `b` overlaps the reach.
    pub fn overlaps(&self, b: &Bounds) -> bool {
        self.0.iter().any(|r| r.overlaps(b))
    }

    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Numbers of fixed length ([`REACH_CELLS`]³ boxes, empty ones padded),
    /// for an all-gather.
    fn numbers(&self) -> Vec<f64> {
        let mut out = Vec::with_capacity(6 * REACH_CELLS.pow(3));
        for k in 0..REACH_CELLS.pow(3) {
            let b = self.0.get(k).copied().unwrap_or(Bounds::EMPTY);
            out.extend_from_slice(&[b.lo.x, b.lo.y, b.lo.z, b.hi.x, b.hi.y, b.hi.z]);
        }
        out
    }

    fn from_numbers(c: &[f64]) -> Reach {
        let boxes = c.chunks_exact(6).map(|c| Bounds {
            lo: DVec3::new(c[0], c[1], c[2]),
            hi: DVec3::new(c[3], c[4], c[5]),
        });
        Reach(boxes.filter(|b| !b.is_empty()).collect())
    }
}

/// For each owned body (inflated box `boxes[k]`), the ranks other than `me`
/// whose reach it overlaps; per rank, the positions in `boxes` it sends.
pub fn sends(me: usize, boxes: &[Bounds], reaches: &[Reach]) -> Vec<Vec<usize>> {
    let mut send = vec![Vec::new(); reaches.len()];
    for (k, b) in boxes.iter().enumerate() {
        for (r, reach) in reaches.iter().enumerate() {
            if r != me && reach.overlaps(b) {
                send[r].push(k);
            }
        }
    }
    send
}

/// Draws the lists (collective): every rank's reach goes to every rank, each
/// rank sends its particles within others' reach, whole.
pub fn draw(
    comm: &SimpleCommunicator,
    world: &World,
    radius: &[f64],
    halos: &[f64],
    owned: &[usize],
    pad: f64,
) -> Drawn {
    let me = comm.rank() as usize;
    let boxes: Vec<Bounds> = owned
        .iter()
        .map(|&i| body_box(world, radius, i, halos[i] + pad))
        .collect();
    let mine = Reach::of(&boxes);
    let reaches: Vec<Reach> = all_gather_v(comm, &mine.numbers())
        .chunks_exact(6 * REACH_CELLS.pow(3))
        .map(Reach::from_numbers)
        .collect();
    let per_rank = sends(me, &boxes, &reaches);
    let counts: Vec<Count> = per_rank.iter().map(|s| s.len() as Count).collect();
    let zero = DVec3::ZERO;
    let records: Vec<BodyRecord> = per_rank
        .iter()
        .flatten()
        .map(|&k| {
            let i = owned[k];
            BodyRecord::of(world.id(i), &world.bodies[i], zero, zero)
        })
        .collect();
    let (got, got_counts) = all_to_all_v(comm, &records, &counts);
    let mut arrived = Vec::new();
    let mut rest = &got[..];
    for (r, &c) in got_counts.iter().enumerate() {
        let (head, tail) = rest.split_at(c as usize);
        rest = tail;
        if c > 0 {
            arrived.push((r as i32, head.to_vec()));
        }
    }
    let send = per_rank
        .iter()
        .enumerate()
        .filter(|(_, s)| !s.is_empty())
        .map(|(r, s)| (r as i32, s.iter().map(|&k| world.id(owned[k])).collect()))
        .collect();
    Drawn {
        reach: mine,
        send,
        arrived,
    }
}

/// How the ghosts' motions travel relative to the detection among owned bodies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Exchange {
    /// Posted before, completed after (the overlap of the paper's Algorithm 1).
    Nonblocking,
    /// Completed before it starts.
    Blocking,
}

dem::named_enum!(
    Exchange,
    "exchange",
    [(Blocking, "blocking"), (Nonblocking, "nonblocking")]
);

/// The motions' message buffers, kept from step to step: each exchange
/// packs and receives into the allocations of the one before (a step's
/// messages are the same sizes while the lists last), rather than
/// allocating and zeroing them anew.
#[derive(Debug, Default)]
pub struct Mailboxes {
    outbox: Vec<Vec<Motion>>,
    inbox: Vec<Vec<Motion>>,
}

impl Mailboxes {
    /// Per neighbour of `GhostLists::recv`, the motions of its ghosts, in
    /// order, as the last [`exchange_motions`] received them.
    pub fn received(&self) -> &[Vec<Motion>] {
        &self.inbox
    }

    /// The motions of the bodies `lists` sends, packed, and room for those
    /// it receives.
    fn pack(&mut self, lists: &GhostLists, world: &World) {
        self.outbox.resize_with(lists.send.len(), Vec::new);
        for (b, (_, ids)) in self.outbox.iter_mut().zip(&lists.send) {
            b.clear();
            b.extend(ids.iter().map(|&i| Motion::of(&world.bodies[i])));
        }
        self.inbox.resize_with(lists.recv.len(), Vec::new);
        for (b, (_, ids)) in self.inbox.iter_mut().zip(&lists.recv) {
            b.resize(ids.len(), Motion::default());
        }
    }
}

/// What [`exchange_motions`] did besides receiving, and how long it waited.
pub struct Received<R> {
    pub work: R,
    /// Seconds inside the call that completes the exchange: the same
    /// measure in both modes (after the work when nonblocking, before it
    /// when blocking).
    pub wait: f64,
    /// Seconds packing and posting the messages.
    pub post: f64,
}

/// Sends the motions of the listed bodies to their ranks and receives the
/// ghosts' into `mail`, running `work` meanwhile (nonblocking) or after (blocking).
/// `work` is handed a `progress` to call between pieces of its work: it
/// tests the posted requests, so that messages past the eager limit move
/// during the work and not only inside the final wait, and answers whether
/// any is still in flight.
///
/// The requests live in an rsmpi scope, which ends only once each has
/// completed, so no buffer is freed or read while MPI still writes it.
pub fn exchange_motions<R>(
    comm: &SimpleCommunicator,
    lists: &GhostLists,
    world: &World,
    mail: &mut Mailboxes,
    mode: Exchange,
    work: impl FnOnce(&mut dyn FnMut() -> bool) -> R,
) -> Received<R> {
    let start = Instant::now();
    mail.pack(lists, world);
    let Mailboxes { outbox, inbox } = mail;
    let mut wait = 0.0;
    let mut post = 0.0;
    let out = mpi::request::scope(|scope| {
        let mut requests: Vec<_> = inbox
            .iter_mut()
            .zip(&lists.recv)
            .map(|(b, &(r, _))| {
                Some(comm.process_at_rank(r).immediate_receive_into_with_tag(
                    scope,
                    bytes_mut(&mut b[..]),
                    MOTION_TAG,
                ))
            })
            .collect();
        for (b, &(r, _)) in outbox.iter().zip(&lists.send) {
            requests.push(Some(comm.process_at_rank(r).immediate_send_with_tag(
                scope,
                bytes(&b[..]),
                MOTION_TAG,
            )));
        }
        post = start.elapsed().as_secs_f64();
        let complete = |requests: &mut Vec<Option<_>>| {
            let start = Instant::now();
            for r in requests.iter_mut() {
                if let Some(r) = r.take() {
                    mpi::request::Request::wait(r);
                }
            }
            start.elapsed().as_secs_f64()
        };
        if mode == Exchange::Blocking {
            wait = complete(&mut requests);
        }
        let out = work(&mut || {
            for slot in requests.iter_mut() {
                if let Some(r) = slot.take() {
                    *slot = r.test().err();
                }
            }
            requests.iter().any(Option::is_some)
        });
        if mode == Exchange::Nonblocking {
            wait = complete(&mut requests);
        }
        out
    });
    Received {
        work: out,
        wait,
        post,
    }
}

/// Sends the force terms on other ranks' particles computed here
/// (`outgoing`: per rank, its terms), runs `meanwhile`, then receives the
/// terms on this rank's particles from the ranks in `incoming`. Returns what
/// arrived (an error for a message that is not whole term records: a bug)
/// and the seconds spent waiting for it. Both sides know from their
/// neighbour lists which ranks exchange terms (see `term_peers`), so a
/// message goes only where a pair across the cut may be in contact.
pub fn return_terms(
    comm: &SimpleCommunicator,
    outgoing: &[(i32, Vec<TermRecord>)],
    incoming: &[i32],
    meanwhile: impl FnOnce(),
) -> (Result<Vec<TermRecord>, String>, f64) {
    let mut arrived = Ok(Vec::new());
    let mut wait = 0.0;
    mpi::request::scope(|scope| {
        let sends: Vec<_> = outgoing
            .iter()
            .map(|(r, terms)| {
                comm.process_at_rank(*r)
                    .immediate_send_with_tag(scope, bytes(&terms[..]), TERM_TAG)
            })
            .collect();
        meanwhile();
        let start = Instant::now();
        for &r in incoming {
            let (message, _) = comm
                .process_at_rank(r)
                .matched_probe_with_tag(TERM_TAG)
                .matched_receive_vec::<u8>();
            match (from_bytes::<TermRecord>(&message), &mut arrived) {
                (Some(terms), Ok(all)) => all.extend(terms),
                (None, _) => {
                    arrived = Err(format!(
                        "a force-term message of {} bytes from rank {r}",
                        message.len()
                    ))
                }
                (Some(_), Err(_)) => {}
            }
        }
        for s in sends {
            s.wait();
        }
        wait = start.elapsed().as_secs_f64();
    });
    (arrived, wait)
}

/// The ranks this rank sends force terms to and receives them from, for the
/// life of a neighbour list: it sends to the owner of a ghost it pairs with
/// an owned particle of lower id (`ours`: such pairs, as (own, ghost)), and
/// receives from the owner of a ghost of lower id paired with an owned
/// particle (`theirs`: as (ghost, own)). The owner of each pair finds the
/// same pair in its own list, from the same bits, so the two sides agree.
pub fn term_peers(
    ours: &[(usize, usize)],
    theirs: &[(usize, usize)],
    owner: &[i32],
) -> (Vec<i32>, Vec<i32>) {
    let mut to: Vec<i32> = ours.iter().map(|&(_, ghost)| owner[ghost]).collect();
    let mut from: Vec<i32> = theirs.iter().map(|&(ghost, _)| owner[ghost]).collect();
    for v in [&mut to, &mut from] {
        v.sort_unstable();
        v.dedup();
    }
    (to, from)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube(lo: [f64; 3], size: f64) -> Bounds {
        let lo = DVec3::from_array(lo);
        Bounds {
            lo,
            hi: lo + DVec3::splat(size),
        }
    }

    /// A body goes to each other rank whose reach its box overlaps, never to
    /// its own, never to a rank with no particles (an empty reach).
    #[test]
    fn a_body_goes_where_its_box_meets_another_ranks_reach() {
        let boxes = [
            cube([0.0, 0.0, 0.0], 1.0), // inside rank 0's own reach only
            cube([1.9, 0.0, 0.0], 0.2), // touches rank 1's reach
            cube([1.9, 1.9, 1.9], 0.5), // touches ranks 1 and 3
            cube([9.0, 9.0, 9.0], 0.1), // far from all
        ];
        let reaches = [
            Reach::of(&[cube([0.0, 0.0, 0.0], 2.0)]),
            Reach::of(&[cube([2.0, 0.0, 0.0], 2.0)]),
            Reach::of(&[]),
            Reach::of(&[cube([2.2, 2.2, 2.2], 1.0)]),
        ];
        let s = sends(0, &boxes, &reaches);
        assert_eq!(s, vec![vec![], vec![1, 2], vec![], vec![2]]);
    }

    /// A reach holds every box it was made of, and leaves out the empty
    /// corners of their union: two particles at opposite corners of a cube
    /// do not reach its centre, nor the other corners. It survives its trip
    /// through numbers.
    #[test]
    fn a_reach_covers_its_boxes_and_not_the_space_between() {
        let boxes = [
            cube([0.0, 0.0, 0.0], 1.0),
            cube([9.0, 9.0, 9.0], 1.0),
            cube([0.5, 0.2, 0.9], 0.3),
        ];
        let r = Reach::of(&boxes);
        assert!(boxes.iter().all(|b| r.overlaps(b)));
        assert!(!r.overlaps(&cube([4.5, 4.5, 4.5], 1.0)));
        assert!(!r.overlaps(&cube([9.0, 0.0, 0.0], 1.0)));
        assert!(r.overlaps(&cube([1.0, 1.0, 1.0], 0.5)));
        assert_eq!(Reach::from_numbers(&r.numbers()), r);
        assert!(Reach::of(&[]).is_empty() && !Reach::of(&[]).overlaps(&boxes[0]));
    }

    /// Terms go to the owners of the ghosts this rank pairs with its own
    /// particles, and come from the owners of the ghosts of lower id paired
    /// with them; each rank once.
    #[test]
    fn terms_are_exchanged_with_the_owners_of_paired_ghosts() {
        // Bodies 0-2 owned here (rank 0), 3-4 ghosts of rank 1, 5 of rank 2.
        let owner = [0, 0, 0, 1, 1, 2];
        let ours = [(0, 3), (1, 3), (2, 4)];
        let theirs = [(5, 2)];
        let (to, from) = term_peers(&ours, &theirs, &owner);
        assert_eq!((to, from), (vec![1], vec![2]));
        assert_eq!(term_peers(&[], &[], &owner), (vec![], vec![]));
    }
}
