//! `tridem distance`: triangle distances of pairs read from CSV.

use crate::cli::DistanceArgs;
use crate::error::{CliError, CliResult};
use crate::pairs_csv::parse_pairs;
use dem::distance::{distances, Options, PenaltyParams, Triangle};
use glam::DVec3;
use std::io::{Read, Write};

pub fn run(args: &DistanceArgs) -> CliResult {
    let (text, source) = match &args.file {
        Some(path) => (
            std::fs::read_to_string(path)
                .map_err(|e| CliError::input(format!("{}: {e}", path.display())))?,
            path.display().to_string(),
        ),
        None => {
            let mut s = String::new();
            std::io::stdin()
                .read_to_string(&mut s)
                .map_err(|e| CliError::input(format!("stdin: {e}")))?;
            (s, "stdin".to_string())
        }
    };
    let read = parse_pairs(&text, &source)?;
    let scales: Vec<i32> = read.iter().map(|(a, b)| unit_exponent(a, b)).collect();
    let pairs: Vec<(Triangle, Triangle)> = read
        .iter()
        .zip(&scales)
        .map(|((a, b), &k)| (a.map(|v| scale(v, -k)), b.map(|v| scale(v, -k))))
        .collect();
    let opts = Options {
        method: args.method,
        batch: args.batch,
        penalty: PenaltyParams {
            finish_rounds: args.finish_rounds,
            ..PenaltyParams::default()
        },
        ..Options::default()
    };
    let (out, _, _) = distances(&pairs, &opts).map_err(|e| CliError::input(e.to_string()))?;
    let stdout = std::io::stdout();
    let mut w = std::io::BufWriter::new(stdout.lock());
    if args.header {
        writeln!(w, "distance,px,py,pz,qx,qy,qz,solver")
            .map_err(|e| CliError::runtime(format!("stdout: {e}")))?;
    }
    for (r, &k) in out.iter().zip(&scales) {
        let (p, q) = (scale(r.p, k), scale(r.q, k));
        writeln!(
            w,
            // Debug: the shortest digits that read back to the same f64,
            // with an exponent far from 1 (1e300, not 301 digits).
            "{:?},{:?},{:?},{:?},{:?},{:?},{:?},{}",
            scale(DVec3::new(r.distance, 0.0, 0.0), k).x,
            p.x,
            p.y,
            p.z,
            q.x,
            q.y,
            q.z,
            r.solver.name()
        )
        .map_err(|e| CliError::runtime(format!("stdout: {e}")))?;
    }
    w.flush()
        .map_err(|e| CliError::runtime(format!("stdout: {e}")))
}

/// The exponent k of the power of two 2^k nearest above the pair's largest
/// coordinate. The kernels square lengths: at 1e300 the squares overflow,
/// at 1e-300 they underflow to 0. A pair scaled by 2^-k has its largest
/// coordinate in [0.5, 1), and scaling by a power of two changes no bit of
/// a coordinate but its exponent, so the answer scaled back by 2^k is the
/// pair's own, over the whole range of f64.
fn unit_exponent(a: &Triangle, b: &Triangle) -> i32 {
    let largest = a
        .iter()
        .chain(b)
        .map(|v| v.abs().max_element())
        .fold(0.0, f64::max);
    if largest == 0.0 || !largest.is_finite() {
        return 0;
    }
    // The exponent of a normal or subnormal number, exactly.
    let bits = largest.to_bits();
    let biased = ((bits >> 52) & 0x7ff) as i32;
    if biased == 0 {
        -1022 - (bits & ((1 << 52) - 1)).leading_zeros() as i32 + 12
    } else {
        biased - 1022
    }
}

/// v × 2^k, exactly while the result is a normal number.
fn scale(v: DVec3, k: i32) -> DVec3 {
    let pow2 = |e: i32| f64::from_bits(((e + 1023) as u64) << 52);
    // Two factors, each within the normal range, reach any k in ±2100.
    let half = k / 2;
    v * pow2(half) * pow2(k - half)
}
