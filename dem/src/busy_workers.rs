//! Keeping the thread pool awake through a run of many short parallel sections.
//!
//! A DEM step has a few parallel sections (pair building, the kernel), each
//! some hundred microseconds, separated by short serial ones. Rayon puts an
//! idle worker to sleep after a few microseconds of polling, so every section
//! starts by waking it: a futex call and, on a virtual machine, an
//! inter-processor interrupt, which can cost more than a second thread saves
//! on sections this short. OpenMP runtimes avoid it by
//! spinning for a while before sleeping; [`with_busy_workers`] does the same
//! for the duration of a run: the other workers poll for work instead of
//! sleeping. They burn their cores while the run lasts, which is what a
//! dedicated simulation wants.

use rayon::Yield;
use std::sync::atomic::{AtomicBool, Ordering};

/// Runs `f` on a worker of the current pool while the other workers poll for
/// work; returns what `f` returns.
pub fn with_busy_workers<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    let others = rayon::current_num_threads().saturating_sub(1);
    let done = AtomicBool::new(false);
    let done = &done;
    rayon::scope(|s| {
        let runner = rayon::current_thread_index();
        for _ in 0..others {
            s.spawn(move |_| {
                // The thread running `f` may pick up a poller while it waits
                // for a stolen task: it must not poll, or `f` could never finish.
                if rayon::current_thread_index() == runner {
                    return;
                }
                while !done.load(Ordering::Acquire) {
                    if rayon::yield_now() != Some(Yield::Executed) {
                        std::hint::spin_loop();
                    }
                }
            });
        }
        let r = f();
        done.store(true, Ordering::Release);
        r
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rayon::prelude::*;

    #[test]
    fn runs_parallel_work_to_the_same_result_on_any_pool_size() {
        let expected: u64 = (0..100_000u64).map(|x| x * x % 7).sum();
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let got = pool.install(|| {
                with_busy_workers(|| {
                    // Many short sections, as in a simulation.
                    let short: u64 = (0..50)
                        .map(|_| (0..2_000u64).into_par_iter().map(|x| x % 3).sum::<u64>())
                        .sum();
                    assert_eq!(short, 50 * (0..2_000u64).map(|x| x % 3).sum::<u64>());
                    (0..100_000u64)
                        .into_par_iter()
                        .map(|x| x * x % 7)
                        .sum::<u64>()
                })
            });
            assert_eq!(got, expected, "{threads} threads");
        }
    }
}
