//! How a run is split across ranks: the command line over the scene's
//! `[parallel]`. The scene's names are parsed by the crates that own them
//! (`partition::Backend`, `distributed::Exchange`, `distributed::Weights`);
//! a name none knows is refused at its line, also on one process, where
//! `[parallel]` is not used.

use crate::cli::RunArgs;
use crate::error::{CliError, CliResult};
use dem::scene::Scene;
use distributed::{Exchange, Settings, Weights};

/// The scene's `[parallel]` under the command line's; the default
/// partitioner is zoltan-rcb, the exchange non-blocking, the weights pairs.
pub fn settings(args: &RunArgs, scene: &Scene) -> CliResult<Settings> {
    let p = &scene.parallel;
    let at = |key: &str, name: &str, e: String| {
        CliError::input(format!(
            "{}:{}: parallel.{key} `{name}`: {e}",
            args.scene.display(),
            p.line
        ))
    };
    fn read<T: std::str::FromStr<Err = String>>(
        given: Option<T>,
        named: &Option<String>,
        default: T,
        fail: impl Fn(&str, String) -> CliError,
    ) -> CliResult<T> {
        let from_scene = match named {
            Some(n) => Some(n.parse::<T>().map_err(|e| fail(n, e))?),
            None => None,
        };
        Ok(given.or(from_scene).unwrap_or(default))
    }
    let partitioner = read(
        args.partitioner,
        &p.partitioner,
        partition::Backend::ZoltanRcb,
        |n, e| at("partitioner", n, e),
    )?;
    let exchange = read(args.exchange, &p.exchange, Exchange::Nonblocking, |n, e| {
        at("exchange", n, e)
    })?;
    let weights = read(args.weights, &p.weights, Weights::Pairs, |n, e| {
        at("weights", n, e)
    })?;
    let every = args.repartition_every.or(p.repartition_every).unwrap_or(0);
    let when = args.repartition_when.or(p.repartition_when);
    if let Some(tau) = when.filter(|t| !(t.is_finite() && *t >= 1.0)) {
        return Err(CliError::input(format!(
            "repartition when the imbalance exceeds {tau}: an imbalance (max/mean) is 1 or more"
        )));
    }
    Ok(Settings {
        partitioner,
        repartition_every: (every > 0).then_some(every),
        repartition_when: when,
        exchange,
        skin: scene
            .effects
            .get::<dem::effects::ContactParams>()
            .map_or(0.0, |c| c.skin),
        weights,
        reuse: !args.fresh_partitions,
    })
}
