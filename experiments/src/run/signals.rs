//! The stop on a signal: a batch system's time limit, or Ctrl-C, ends a run
//! after the step under way, with its checkpoint.

use crate::error::{CliError, CliResult};
use signal_hook::consts::TERM_SIGNALS;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

/// A repeat of the stop signal within this many milliseconds is the same
/// request delivered twice (`scancel --full` signals the batch shell, which
/// forwards it, and tridem itself), not a second one.
const REPEAT_MS: u64 = 2000;

/// A flag that SIGTERM, SIGINT or SIGQUIT set: the run ends after the step
/// under way, with a checkpoint. A second signal, more than [`REPEAT_MS`]
/// after the first, ends the process at once.
pub(crate) fn stop_on_signals() -> CliResult<Arc<AtomicBool>> {
    use std::sync::atomic::AtomicU64;
    use std::sync::OnceLock;
    static ORIGIN: OnceLock<Instant> = OnceLock::new();
    // Milliseconds after ORIGIN of the first signal, plus one (0: none yet).
    static FIRST: AtomicU64 = AtomicU64::new(0);
    let origin = *ORIGIN.get_or_init(Instant::now);
    let stop = Arc::new(AtomicBool::new(false));
    for &signal in TERM_SIGNALS {
        let flag = Arc::clone(&stop);
        // SAFETY: the handler only reads the monotonic clock (clock_gettime
        // is async-signal-safe), touches atomics and calls _exit.
        unsafe {
            signal_hook::low_level::register(signal, move || {
                let now = origin.elapsed().as_millis() as u64 + 1;
                match FIRST.compare_exchange(0, now, Ordering::SeqCst, Ordering::SeqCst) {
                    Ok(_) => flag.store(true, Ordering::SeqCst),
                    Err(first) if now.saturating_sub(first) > REPEAT_MS => {
                        signal_hook::low_level::exit(128 + signal)
                    }
                    Err(_) => {}
                }
            })
        }
        .map_err(|e| CliError::runtime(format!("cannot handle signal {signal}: {e}")))?;
    }
    Ok(stop)
}
