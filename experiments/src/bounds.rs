//! Every count read from the command line goes through one of these
//! parsers: the same rule in every command (a count that must be positive
//! refuses 0 rather than reading it as 1 or "all"), a bound that keeps a typo
//! from asking for hours or terabytes, and both in the message. Integers may
//! be written as `1e6`.

/// Threads of one process: far above any node's cores, far below what
/// would take minutes to spawn.
pub const MAX_THREADS: u64 = 1024;
/// Ranks of a study.
pub const MAX_RANKS: u64 = 65_536;
/// Repetitions of a measurement.
pub const MAX_REPEAT: u64 = 1000;
/// Batches per task of the dynamic and guided schedules.
pub const MAX_GRAIN: u64 = 1 << 24;

fn integer(s: &str) -> Result<u64, String> {
    if let Ok(n) = s.parse::<u64>() {
        return Ok(n);
    }
    match s.parse::<f64>() {
        Ok(x) if x >= 0.0 && x.fract() == 0.0 && x < u64::MAX as f64 => Ok(x as u64),
        _ => Err(format!("`{s}` is not a whole number")),
    }
}

fn within(s: &str, lo: u64, hi: u64) -> Result<u64, String> {
    let n = integer(s)?;
    if (lo..=hi).contains(&n) {
        Ok(n)
    } else {
        Err(format!("{n} is outside {lo}..={hi}"))
    }
}

pub fn threads(s: &str) -> Result<usize, String> {
    within(s, 1, MAX_THREADS).map(|n| n as usize)
}

pub fn ranks(s: &str) -> Result<usize, String> {
    within(s, 1, MAX_RANKS).map(|n| n as usize)
}

pub fn repeat(s: &str) -> Result<usize, String> {
    within(s, 1, MAX_REPEAT).map(|n| n as usize)
}

pub fn grain(s: &str) -> Result<usize, String> {
    within(s, 1, MAX_GRAIN).map(|n| n as usize)
}

/// Steps of a run, or an interval in steps (0 allowed where it means none).
pub fn steps(s: &str) -> Result<u64, String> {
    within(s, 0, dem::scene::MAX_STEPS)
}

/// An interval that must be at least one step.
pub fn every(s: &str) -> Result<u64, String> {
    within(s, 1, dem::scene::MAX_STEPS)
}

pub fn finish_rounds(s: &str) -> Result<usize, String> {
    within(s, 0, dem::scene::MAX_FINISH_ROUNDS as u64).map(|n| n as usize)
}

/// Items or pairs to generate: at least one; the memory they need is
/// checked against what the machine has before they are made
/// ([`fits_in_memory`]).
pub fn items(s: &str) -> Result<u64, String> {
    within(s, 1, u64::MAX / 1024)
}

/// Refuses work that needs more memory than the machine has available
/// (MemAvailable of /proc/meminfo; no check where it cannot be read).
pub fn fits_in_memory(what: &str, bytes: f64) -> Result<(), String> {
    let available = std::fs::read_to_string("/proc/meminfo").ok().and_then(|m| {
        m.lines()
            .find(|l| l.starts_with("MemAvailable:"))
            .and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok())
            .map(|kb| kb * 1024.0)
    });
    match available {
        Some(a) if bytes > a => Err(format!(
            "{what} would need about {:.1} GB of memory, and {:.1} GB are available",
            bytes / 1e9,
            a / 1e9
        )),
        _ => Ok(()),
    }
}

pub fn steps_usize(s: &str) -> Result<usize, String> {
    steps(s).map(|n| n as usize)
}

pub fn items_usize(s: &str) -> Result<usize, String> {
    items(s).map(|n| n as usize)
}

pub fn every_usize(s: &str) -> Result<usize, String> {
    every(s).map(|n| n as usize)
}
