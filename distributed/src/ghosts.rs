//! Ghost bodies: copies of other ranks' bodies within contact reach of this
//! rank's own, sent every step.
//!
//! **Who gets what.** Each rank's *reach* is the union of its bodies'
//! bounding boxes (a sphere about the centre of mass of the shape's radius),
//! each inflated by the body's halo and half the skin; a body goes to every
//! other rank whose reach its own inflated box overlaps. So the test is per
//! body, with the body's own size and halo (a large body reaches far, a small
//! one near), and against where the other rank's bodies actually are, not
//! the region the partitioner drew: it holds for any partitioner, also one
//! whose regions are not boxes. Obstacles are on every rank and never sent.
//!
//! **When.** The lists hold while no body has moved farther than half the
//! skin since they were drawn (both boxes were inflated by that much); the
//! caller redraws them then, and after every migration. In between, only the
//! bodies' motions travel, in the order both sides agreed on when the lists
//! were drawn: 13 numbers per ghost, no names.

use crate::records::Motion;
use dem::contact::Bounds;
use dem::world::World;
use glam::DVec3;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use mpi::Count;
use partition::comm::{all_gather_v, all_to_all_v};
use std::time::Instant;

/// Tag of the per-step ghost messages.
const MOTION_TAG: i32 = 0x6d6f;

/// The bodies this rank sends to and receives from each rank.
#[derive(Debug, Clone, Default)]
pub struct GhostLists {
    /// Per rank: owned bodies sent there, in increasing id.
    pub send: Vec<Vec<usize>>,
    /// Per rank: the bodies received from there, in the sender's order.
    pub receive: Vec<Vec<usize>>,
}

/// The box of body i: a sphere of its shape's radius about its centre of
/// mass, inflated by `pad`.
pub fn body_box(world: &World, radius: &[f64], i: usize, pad: f64) -> Bounds {
    let b = &world.bodies[i];
    let r = DVec3::splat(radius[b.shape] + pad);
    Bounds {
        lo: b.x - r,
        hi: b.x + r,
    }
}

impl GhostLists {
    /// Draws the lists (collective): `owned` bodies of this rank, boxes
    /// inflated by each body's halo plus `pad` (half the skin).
    pub fn draw(
        comm: &SimpleCommunicator,
        world: &World,
        radius: &[f64],
        halos: &[f64],
        owned: &[usize],
        pad: f64,
    ) -> GhostLists {
        let size = comm.size() as usize;
        let me = comm.rank() as usize;
        let boxes: Vec<Bounds> = owned
            .iter()
            .map(|&i| body_box(world, radius, i, halos[i] + pad))
            .collect();
        let reach = boxes.iter().fold(Bounds::EMPTY, |u, b| u.union(b));
        let mine = [
            reach.lo.x, reach.lo.y, reach.lo.z, reach.hi.x, reach.hi.y, reach.hi.z,
        ];
        let all: Vec<f64> = all_gather_v(comm, &mine);
        let reaches: Vec<Bounds> = all
            .chunks_exact(6)
            .map(|c| Bounds {
                lo: DVec3::new(c[0], c[1], c[2]),
                hi: DVec3::new(c[3], c[4], c[5]),
            })
            .collect();
        let mut send = vec![Vec::new(); size];
        for (&i, b) in owned.iter().zip(&boxes) {
            for (r, reach) in reaches.iter().enumerate() {
                if r != me && !reach.is_empty() && reach.overlaps(b) {
                    send[r].push(i);
                }
            }
        }
        let counts: Vec<Count> = send.iter().map(|s| s.len() as Count).collect();
        let ids: Vec<u64> = send.iter().flatten().map(|&i| i as u64).collect();
        let (got, got_counts) = all_to_all_v(comm, &ids, &counts);
        let mut receive = Vec::with_capacity(size);
        let mut rest = &got[..];
        for &c in &got_counts {
            let (head, tail) = rest.split_at(c as usize);
            receive.push(head.iter().map(|&i| i as usize).collect());
            rest = tail;
        }
        GhostLists { send, receive }
    }

    /// Ghosts this rank holds.
    pub fn received(&self) -> usize {
        self.receive.iter().map(Vec::len).sum()
    }

    /// Ghosts this rank sends (one per body and receiving rank).
    pub fn sent(&self) -> usize {
        self.send.iter().map(Vec::len).sum()
    }

    /// Every ghost body's id, in increasing order.
    pub fn ghost_ids(&self) -> Vec<usize> {
        let mut ids: Vec<usize> = self.receive.iter().flatten().copied().collect();
        ids.sort_unstable();
        ids
    }
}

/// How the ghosts' motions travel relative to the detection among owned bodies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Exchange {
    /// Posted before, completed after (the overlap of the paper's Algorithm 1).
    Nonblocking,
    /// Completed before it starts.
    Blocking,
}

impl std::str::FromStr for Exchange {
    type Err = String;
    fn from_str(s: &str) -> Result<Exchange, String> {
        match s {
            "nonblocking" => Ok(Exchange::Nonblocking),
            "blocking" => Ok(Exchange::Blocking),
            _ => Err(format!("unknown exchange `{s}` (nonblocking, blocking)")),
        }
    }
}

impl Exchange {
    pub fn name(self) -> &'static str {
        match self {
            Exchange::Nonblocking => "nonblocking",
            Exchange::Blocking => "blocking",
        }
    }
}

/// What [`exchange_motions_during`] received and how long it waited.
pub struct Received<R> {
    /// Per rank, the motions of `GhostLists::receive[r]`, in that order.
    pub motions: Vec<Vec<Motion>>,
    pub work: R,
    /// Seconds spent waiting for messages after `work` (nonblocking), or
    /// for the whole exchange (blocking).
    pub wait: f64,
}

/// Sends the motions of the listed bodies to their ranks and receives the
/// ghosts', running `work` meanwhile (nonblocking) or after (blocking).
///
/// The requests live in an rsmpi scope, which ends only once each has
/// completed, so no buffer is freed or read while MPI still writes it.
pub fn exchange_motions_during<R>(
    comm: &SimpleCommunicator,
    lists: &GhostLists,
    world: &World,
    mode: Exchange,
    work: impl FnOnce() -> R,
) -> Received<R> {
    let outbox: Vec<Vec<Motion>> = lists
        .send
        .iter()
        .map(|ids| ids.iter().map(|&i| Motion::of(&world.bodies[i])).collect())
        .collect();
    let mut inbox: Vec<Vec<Motion>> = lists
        .receive
        .iter()
        .map(|ids| vec![Motion::default(); ids.len()])
        .collect();
    let mut wait = 0.0;
    let out = mpi::request::scope(|scope| {
        let mut requests: Vec<_> = inbox
            .iter_mut()
            .enumerate()
            .filter(|(_, b)| !b.is_empty())
            .map(|(r, b)| {
                comm.process_at_rank(r as i32)
                    .immediate_receive_into_with_tag(scope, &mut b[..], MOTION_TAG)
            })
            .collect();
        for (r, b) in outbox.iter().enumerate().filter(|(_, b)| !b.is_empty()) {
            requests.push(comm.process_at_rank(r as i32).immediate_send_with_tag(
                scope,
                &b[..],
                MOTION_TAG,
            ));
        }
        if mode == Exchange::Blocking {
            let start = Instant::now();
            requests.drain(..).for_each(|r| {
                r.wait();
            });
            wait = start.elapsed().as_secs_f64();
        }
        let out = work();
        let start = Instant::now();
        requests.into_iter().for_each(|r| {
            r.wait();
        });
        wait += start.elapsed().as_secs_f64();
        out
    });
    Received {
        motions: inbox,
        work: out,
        wait,
    }
}
