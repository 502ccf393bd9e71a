//! `tridem distance`: triangle distances of pairs read from CSV.

use crate::cli::DistanceArgs;
use crate::error::{CliError, CliResult};
use crate::pairs_csv::parse_pairs;
use dem::distance::{distances, Options, PenaltyParams};
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
    let pairs = parse_pairs(&text, &source)?;
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
    for r in &out {
        writeln!(
            w,
            "{},{},{},{},{},{},{},{}",
            r.distance,
            r.p.x,
            r.p.y,
            r.p.z,
            r.q.x,
            r.q.y,
            r.q.z,
            r.solver.name()
        )
        .map_err(|e| CliError::runtime(format!("stdout: {e}")))?;
    }
    w.flush()
        .map_err(|e| CliError::runtime(format!("stdout: {e}")))
}
