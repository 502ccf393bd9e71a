//! `mpirun -np 2 tridem pingpong`: the time a message of n bytes takes
//! from rank 0 to rank 1 (half a round trip, the median of many), for n
//! from 8 bytes to 4 MiB: the latency α (the smallest message's time) and
//! the bandwidth β (from the slope over large messages) of t(n) = α + n/β,
//! the inputs of the communication model of docs/distributed.md
//! ("Projection").

use crate::cli::PingpongArgs;
use crate::error::{CliError, CliResult};
use mpi::traits::*;
use std::time::Instant;

/// Message sizes measured, in bytes.
const SIZES: [usize; 11] = [
    8,
    64,
    512,
    4 << 10,
    16 << 10,
    64 << 10,
    256 << 10,
    512 << 10,
    1 << 20,
    2 << 20,
    4 << 20,
];

pub fn run(args: &PingpongArgs) -> CliResult {
    let universe =
        mpi::initialize().ok_or_else(|| CliError::runtime("MPI was already initialised"))?;
    let comm = universe.world();
    if comm.size() < 2 {
        return Err(CliError::input(
            "pingpong needs two ranks: mpirun -np 2 tridem pingpong",
        ));
    }
    let me = comm.rank();
    let mut rows = Vec::new();
    for &n in &SIZES {
        let mut buf = vec![0u8; n];
        let mut times = Vec::with_capacity(args.repeat as usize);
        comm.barrier();
        for _ in 0..args.repeat {
            let start = Instant::now();
            match me {
                0 => {
                    comm.process_at_rank(1).send(&buf[..]);
                    comm.process_at_rank(1).receive_into(&mut buf[..]);
                }
                1 => {
                    comm.process_at_rank(0).receive_into(&mut buf[..]);
                    comm.process_at_rank(0).send(&buf[..]);
                }
                _ => {}
            }
            times.push(start.elapsed().as_secs_f64() / 2.0);
        }
        times.sort_by(f64::total_cmp);
        rows.push((n, times[times.len() / 2]));
    }
    if me != 0 {
        return Ok(());
    }
    let (alpha, beta) = fit(&rows);
    if args.json {
        let sizes: Vec<_> = rows
            .iter()
            .map(|&(n, t)| serde_json::json!({"bytes": n, "seconds": t}))
            .collect();
        let out = serde_json::json!({
            "latency_seconds": alpha,
            "bandwidth_bytes_per_second": beta,
            "one_way": sizes,
        });
        println!("{out}");
        return Ok(());
    }
    println!("{:>10} {:>14}", "bytes", "one way (us)");
    for (n, t) in &rows {
        println!("{n:>10} {:>14.3}", 1e6 * t);
    }
    println!(
        "latency a = {:.3} us (8 bytes), bandwidth b = {:.2} GB/s (slope from 64 KiB)",
        1e6 * alpha,
        beta / 1e9
    );
    Ok(())
}

/// The latency α, the time of the smallest message, and the bandwidth β,
/// from the least-squares slope of t against n over the messages of 64 KiB
/// and more (where the size, not the latency, sets the time).
fn fit(rows: &[(usize, f64)]) -> (f64, f64) {
    let alpha = rows[0].1;
    let large: Vec<(usize, f64)> = rows.iter().copied().filter(|r| r.0 >= 64 << 10).collect();
    let k = large.len() as f64;
    let (sx, sy) = large
        .iter()
        .fold((0.0, 0.0), |(a, b), &(n, t)| (a + n as f64, b + t));
    let (mx, my) = (sx / k, sy / k);
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for &(n, t) in &large {
        let dx = n as f64 - mx;
        sxy += dx * (t - my);
        sxx += dx * dx;
    }
    (alpha, sxx / sxy)
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_fit_recovers_a_line() {
        let rows: Vec<(usize, f64)> = super::SIZES
            .iter()
            .map(|&n| (n, 2e-6 + n as f64 / 5e9))
            .collect();
        let (a, b) = super::fit(&rows);
        assert!((a - (2e-6 + 8.0 / 5e9)).abs() < 1e-15, "{a}");
        assert!((b / 5e9 - 1.0).abs() < 1e-9, "{b}");
    }
}
