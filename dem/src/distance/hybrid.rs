//! The hybrid method and the multi-core driver for all three methods.
//!
//! Hybrid: the penalty kernel runs on a batch; if any pair of the batch was not
//! certified, the batch is recomputed by brute force ([`Fallback::WholeBatch`],
//! the published rule), or only its uncertified pairs are
//! ([`Fallback::FailedPairs`], gathered into full SIMD batches of the brute
//! force). Either way every hybrid answer is within the
//! certificate's tolerance of the exact one, or is the brute-force answer.
//!
//! Threads: rayon over batches, with OpenMP-like static scheduling (equal
//! contiguous chunks, one per thread) or dynamic scheduling (chunks of `grain`
//! batches taken on demand).

use super::distance_triangle_triangle_batch::{
    distance_triangle_triangle_batch, LANES as BRUTE_LANES,
};
use super::isa::{Isa, Supported};
use super::pair_source::{chunk_ranges, PairSource, Window};
use super::penalty::{
    penalty_batch_on, penalty_many_on, PenaltyParams, PenaltyStats, UnsupportedBatch,
};
use super::{Closest, Triangle};
use rayon::prelude::*;

/// Which computation answers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Exact: the nine edge-edge and six vertex-face closest points.
    Brute,
    /// The penalty Newton solver alone, on SIMD batches.
    Penalty,
    /// Penalty, with brute force for the pairs it does not certify.
    Hybrid,
}

crate::named_enum!(
    Method,
    "method",
    [(Brute, "brute"), (Penalty, "penalty"), (Hybrid, "hybrid")]
);

/// What the hybrid recomputes by brute force when a batch has uncertified pairs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Fallback {
    /// The whole batch (the published kernel). A pair's answer then depends
    /// on its batch mates, and so on how pairs are cut into tasks.
    WholeBatch,
    /// Only the uncertified pairs: each pair's answer is its own, whatever
    /// the batches and threads. The default.
    #[default]
    FailedPairs,
}

/// How work (batches of pairs, or body pairs in contact detection) is cut
/// into consecutive shares and spread over threads. Shares of the dynamic and
/// guided schedules are taken in order, each by whichever thread is free.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Schedule {
    /// Equal shares, one per thread (OpenMP `schedule(static)`).
    Static,
    /// Shares of `grain` items taken on demand (OpenMP `schedule(dynamic, grain)`).
    Dynamic,
    /// Shares that shrink as the work runs out: 1/(2 threads) of what is left,
    /// at least `grain` items, taken on demand (OpenMP `schedule(guided,
    /// grain)` with half its share). Large shares first keep the kernel's
    /// batches full; small ones last even out the finish. The default: on
    /// contact detection, where body pairs differ in cost, it leaves the
    /// least idle time.
    #[default]
    Guided,
}

crate::named_enum!(
    Schedule,
    "schedule",
    [(Static, "static"), (Dynamic, "dynamic"), (Guided, "guided")]
);

/// Threading of a call to [`distance_many`]. It runs in the current rayon pool:
/// install a pool of the wanted size around the call to choose the thread count.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Threading {
    pub schedule: Schedule,
    /// Batches (body pairs, in contact detection) per share of the dynamic
    /// schedule, and the smallest share of the guided one.
    pub grain: usize,
}

impl Threading {
    /// Lengths of the consecutive shares `n` items are cut into for `threads`
    /// threads: they add up to `n`, none is empty.
    pub fn share_lengths(&self, n: usize, threads: usize) -> Vec<usize> {
        let (grain, threads) = (self.grain.max(1), threads.max(1));
        let mut lengths = Vec::new();
        let mut rest = n;
        while rest > 0 {
            let len = match self.schedule {
                Schedule::Static => n.div_ceil(threads),
                Schedule::Dynamic => grain,
                Schedule::Guided => (rest / (2 * threads)).max(grain),
            }
            .min(rest);
            lengths.push(len);
            rest -= len;
        }
        lengths
    }
}

impl Default for Threading {
    fn default() -> Self {
        Threading {
            schedule: Schedule::default(),
            grain: 16,
        }
    }
}

/// Options of [`distance_many`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    pub method: Method,
    /// Pairs per batch: one of 1, 2, 4, 8, 16, 32, 64.
    pub batch: usize,
    pub penalty: PenaltyParams,
    pub fallback: Fallback,
    pub threading: Threading,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            method: Method::Hybrid,
            batch: 8,
            penalty: PenaltyParams::default(),
            fallback: Fallback::default(),
            threading: Threading::default(),
        }
    }
}

/// Counts of one call.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Counts {
    pub pairs: usize,
    /// Pairs the penalty kernel certified.
    pub certified: usize,
    /// Pairs whose answer was recomputed by brute force (hybrid).
    pub fallback_pairs: usize,
    /// Batches that fell back (hybrid).
    pub fallback_batches: usize,
}

impl std::ops::Add for Counts {
    type Output = Counts;
    fn add(self, o: Counts) -> Counts {
        Counts {
            pairs: self.pairs + o.pairs,
            certified: self.certified + o.certified,
            fallback_pairs: self.fallback_pairs + o.fallback_pairs,
            fallback_batches: self.fallback_batches + o.fallback_batches,
        }
    }
}

/// Distance of every pair by the chosen method, on the current rayon pool.
/// `out` and `stats` must have the length of `pairs`; `stats` is filled for the
/// penalty and hybrid methods.
pub fn distance_many(
    pairs: &[(Triangle, Triangle)],
    opts: &Options,
    out: &mut [Closest],
    stats: &mut [PenaltyStats],
) -> Result<Counts, UnsupportedBatch> {
    check_arguments(pairs.len(), opts, out.len(), stats.len())?;
    let n_batches = pairs.len().div_ceil(opts.batch);
    let shares = opts
        .threading
        .share_lengths(n_batches, rayon::current_num_threads());
    let (mut p, mut o, mut s) = (pairs, out, stats);
    let mut work = Vec::with_capacity(shares.len());
    for batches in shares {
        let len = (batches * opts.batch).min(p.len());
        let ((p0, p1), (o0, o1), (s0, s1)) =
            (p.split_at(len), o.split_at_mut(len), s.split_at_mut(len));
        work.push((p0, o0, s0));
        (p, o, s) = (p1, o1, s1);
    }
    // Shares taken in order by whichever thread is free (rayon's own
    // splitting would hand out halves of the list, whatever they cost).
    let counts = work
        .into_iter()
        .par_bridge()
        .map(|(p, o, s)| serial_chunk(p, opts, o, s))
        .reduce(Counts::default, |a, b| a + b);
    Ok(counts)
}

/// Like [`distance_many`] on the calling thread only: for callers that are
/// already inside a parallel task of their own (contact detection runs
/// culling and kernel together per task).
pub fn distance_many_serial<P: PairSource + ?Sized>(
    pairs: &P,
    opts: &Options,
    out: &mut [Closest],
    stats: &mut [PenaltyStats],
) -> Result<Counts, UnsupportedBatch> {
    check_arguments(pairs.len(), opts, out.len(), stats.len())?;
    if pairs.is_empty() {
        return Ok(Counts::default());
    }
    Ok(serial_chunk(pairs, opts, out, stats))
}

/// Buffers of the pairs' length (a caller's bug otherwise) and a batch size
/// the kernel has (a user's choice).
fn check_arguments(
    pairs: usize,
    opts: &Options,
    out: usize,
    stats: usize,
) -> Result<(), UnsupportedBatch> {
    assert_eq!(pairs, out);
    assert_eq!(pairs, stats);
    if !super::penalty::BATCH_SIZES.contains(&opts.batch) {
        return Err(UnsupportedBatch(opts.batch));
    }
    Ok(())
}

/// One thread's share, batch by batch.
fn serial_chunk<P: PairSource + ?Sized>(
    pairs: &P,
    opts: &Options,
    out: &mut [Closest],
    stats: &mut [PenaltyStats],
) -> Counts {
    let mut counts = Counts {
        pairs: pairs.len(),
        ..Counts::default()
    };
    let isa = Isa::detect().supported();
    match opts.method {
        Method::Brute => {
            for r in chunk_ranges(pairs.len(), BRUTE_LANES) {
                distance_triangle_triangle_batch(&Window::new(pairs, r.clone()), isa, &mut out[r]);
            }
        }
        Method::Penalty | Method::Hybrid => {
            let run = match opts.batch {
                1 => penalty_share::<1, P>,
                2 => penalty_share::<2, P>,
                4 => penalty_share::<4, P>,
                8 => penalty_share::<8, P>,
                _ => penalty_share::<16, P>,
            };
            run(pairs, opts, isa, out, stats, &mut counts);
        }
    }
    counts
}

/// The penalty (and the hybrid's fallback) on one share, batch by batch,
/// with the batch kernel of `N` lanes called directly (`N` the batch size, or
/// 16 for batches of 32 and 64, which run as 16-lane blocks).
fn penalty_share<const N: usize, P: PairSource + ?Sized>(
    pairs: &P,
    opts: &Options,
    isa: Supported,
    out: &mut [Closest],
    stats: &mut [PenaltyStats],
    counts: &mut Counts,
) {
    let mut failed = FailedPairs::new(isa);
    for r in chunk_ranges(pairs.len(), opts.batch) {
        let p = Window::new(pairs, r.clone());
        let (o, s) = (&mut out[r.clone()], &mut stats[r.clone()]);
        if opts.batch == N {
            penalty_batch_on::<N, _>(&p, &opts.penalty, isa, o, s);
        } else {
            penalty_many_on(&p, opts.batch, &opts.penalty, isa.isa(), o, s)
                .expect("batch size checked");
        }
        let certified = s.iter().filter(|x| x.converged).count();
        counts.certified += certified;
        if opts.method == Method::Hybrid && certified < p.len() {
            counts.fallback_batches += 1;
            match opts.fallback {
                Fallback::WholeBatch => {
                    for rr in chunk_ranges(p.len(), BRUTE_LANES) {
                        let pp = Window::new(&p, rr.clone());
                        distance_triangle_triangle_batch(&pp, isa, &mut o[rr]);
                    }
                    counts.fallback_pairs += p.len();
                }
                Fallback::FailedPairs => {
                    for k in r.filter(|&k| !stats[k].converged) {
                        counts.fallback_pairs += 1;
                        failed.push(pairs, k, out);
                    }
                }
            }
        }
    }
    failed.flush(out);
}

/// Uncertified pairs gathered into full SIMD batches of the brute force.
///
/// The brute force runs as soon as a few batches are full, while their pairs
/// and answers are still in cache: gathering a whole share first and
/// recomputing at the end read every failed pair back from memory (with
/// 200,000 random pairs, each of the 6% failed pairs then cost two to three
/// times a brute-force pair; see docs/distance.md).
///
/// The queue takes its room when a pair first fails: a share with none (a
/// piece of a rank's detection is often a few body pairs) sets up nothing.
struct FailedPairs {
    isa: Supported,
    /// Indices into the pairs of the waiting pairs, and copies of them.
    index: Vec<usize>,
    buf: Vec<(Triangle, Triangle)>,
}

impl FailedPairs {
    fn new(isa: Supported) -> Self {
        FailedPairs {
            isa,
            index: Vec::new(),
            buf: Vec::new(),
        }
    }

    /// Queues pair `k`; runs the brute force when the queue is full.
    fn push<P: PairSource + ?Sized>(&mut self, pairs: &P, k: usize, out: &mut [Closest]) {
        let (a, b) = pairs.pair(k);
        if self.buf.capacity() == 0 {
            self.index.reserve_exact(FAILED_QUEUE);
            self.buf.reserve_exact(FAILED_QUEUE);
        }
        self.index.push(k);
        self.buf.push((*a, *b));
        if self.buf.len() == FAILED_QUEUE {
            self.flush(out);
        }
    }

    /// Runs the brute force on the waiting pairs and writes their answers.
    fn flush(&mut self, out: &mut [Closest]) {
        let n = self.buf.len();
        if n == 0 {
            return;
        }
        let mut res = [out[self.index[0]]; BRUTE_LANES];
        for r in chunk_ranges(n, BRUTE_LANES) {
            let m = r.len();
            distance_triangle_triangle_batch(&self.buf[r.clone()], self.isa, &mut res[..m]);
            for (&k, x) in self.index[r].iter().zip(&res[..m]) {
                out[k] = *x;
            }
        }
        self.index.clear();
        self.buf.clear();
    }
}

/// Failed pairs queued before the brute force runs on them: four of its
/// batches at a time, so the two kernels' code takes turns in the instruction
/// cache less often, while the queued pairs (some 500 pairs back at a 6%
/// failure rate) are still in the data cache. Measured against one batch at a
/// time: hybrid over penalty 1.10-1.11 against 1.12-1.13 (docs/distance.md).
const FAILED_QUEUE: usize = QUEUE_BATCHES * BRUTE_LANES;
const QUEUE_BATCHES: usize = 4;

/// Distances of all pairs with the given options, into fresh buffers.
pub fn distances(
    pairs: &[(Triangle, Triangle)],
    opts: &Options,
) -> Result<(Vec<Closest>, Vec<PenaltyStats>, Counts), UnsupportedBatch> {
    let mut out = vec![Closest::UNSET; pairs.len()];
    let mut stats = vec![PenaltyStats::default(); pairs.len()];
    let counts = distance_many(pairs, opts, &mut out, &mut stats)?;
    Ok((out, stats, counts))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shares_cover_the_work_in_order_as_each_schedule_says() {
        for schedule in [Schedule::Static, Schedule::Dynamic, Schedule::Guided] {
            for n in [0, 1, 7, 100, 1001] {
                for threads in [1, 2, 8] {
                    let t = Threading { schedule, grain: 4 };
                    let lengths = t.share_lengths(n, threads);
                    assert_eq!(lengths.iter().sum::<usize>(), n);
                    assert!(lengths.iter().all(|&l| l > 0));
                    let last = lengths.len().saturating_sub(1);
                    match schedule {
                        Schedule::Static => assert!(lengths.len() <= threads),
                        Schedule::Dynamic => assert!(lengths[..last].iter().all(|&l| l == 4)),
                        Schedule::Guided => {
                            // Shrinking, never below the grain but for the rest.
                            assert!(lengths.windows(2).all(|w| w[0] >= w[1]));
                            assert!(lengths[..last].iter().all(|&l| l >= 4));
                        }
                    }
                }
            }
        }
        let guided = Threading {
            schedule: Schedule::Guided,
            grain: 4,
        };
        assert_eq!(
            guided.share_lengths(100, 2),
            [25, 18, 14, 10, 8, 6, 4, 4, 4, 4, 3]
        );
    }
}
