//! The repartition-frequency study's cost model: the time per step against
//! the repartitioning interval K, fitted to the two extremes (every step,
//! never) and asked about the settings between, which it was not fitted to:
//!
//!   t(K) = t0 + c/K + β r K/2
//!
//! - c: what one repartitioning costs, measured as the busy time per step
//!   (the mean over ranks, waits excluded) of the smallest K above the
//!   never-repartitioned run's, times K. The mean busy time is the ranks'
//!   total work, which the partition does not change, so the difference is
//!   everything a repartitioning adds: the partitioner, the migration, and
//!   the neighbour lists and triangle sets redrawn after it.
//! - r: how fast the busy imbalance grows after a repartitioning, per step,
//!   from the never-repartitioned run (its mean imbalance over S steps,
//!   1 + r S/2).
//! - t0, a step with the ranks balanced, and β, what a unit of imbalance
//!   costs per step: the two unknowns left in t(smallest K) and t(never).
//!
//! Every rate is fitted as non-negative. Its best K is √(2c/(β r)).

use super::common::{noise_floor, seconds_per_step, Group, Ran};
use super::ranks::{busy_imbalance, mean};
use std::fmt::Write as _;

/// What the study keeps of the model: its CSV and its verdict.
pub(super) struct Model {
    pub csv: String,
    pub verdict: String,
}

/// The fitted parameters (seconds; r per step; β seconds per unit).
#[derive(Debug, Clone, Copy)]
struct Fit {
    c: f64,
    t0: f64,
    r: f64,
    beta: f64,
    steps: f64,
}

impl Fit {
    /// The model fitted to the run every `k1` steps and the run that never
    /// repartitions, over `steps` steps each.
    fn new(k1: f64, first: &Group, never: &Group, steps: f64) -> Fit {
        let busy = |g: &Group| g.stat(busy_seconds).median;
        let c = (k1 * (busy(first) - busy(never))).max(0.0);
        let i_never = never.stat(busy_imbalance).median;
        let t_never = never.stat(seconds_per_step).median;
        let t1 = first.stat(seconds_per_step).median;
        let r = (2.0 * (i_never - 1.0) / steps).max(0.0);
        // t1 = t0 + c/k1 + β (i−1) k1/S and t_never = t0 + β (i−1), solved.
        let drift = (i_never - 1.0) * (1.0 - k1 / steps);
        let beta = if drift > 0.0 {
            ((t_never - t1 + c / k1) / drift).max(0.0)
        } else {
            0.0
        };
        let t0 = (t_never - beta * (i_never - 1.0).max(0.0)).max(0.0);
        Fit {
            c,
            t0,
            r,
            beta,
            steps,
        }
    }

    /// The time per step it predicts every `k` steps (0: never).
    fn predict(&self, k: f64) -> f64 {
        if k <= 0.0 || k >= self.steps {
            self.t0 + self.beta * self.r * self.steps / 2.0
        } else {
            self.t0 + self.c / k + self.beta * self.r * k / 2.0
        }
    }

    fn best_k(&self) -> Option<f64> {
        (self.beta * self.r > 0.0).then(|| (2.0 * self.c / (self.beta * self.r)).sqrt())
    }
}

/// A run's busy seconds per step, the mean over ranks.
fn busy_seconds(r: &Ran) -> f64 {
    mean(r, "busy_seconds")
}

/// The model fitted to `groups` (runs of `steps` steps), `k_of` giving each
/// every-K setting's K (never: 0), with its CSV and verdict.
pub(super) fn fit(groups: &[Group], steps: f64, k_of: impl Fn(&Group) -> Option<u64>) -> Model {
    let every: Vec<&Group> = groups
        .iter()
        .filter(|g| k_of(g).is_some() && g.spec.series != "noise floor")
        .collect();
    let kf = |g: &Group| k_of(g).unwrap_or(0) as f64;
    let first = every
        .iter()
        .filter(|g| kf(g) > 0.0)
        .min_by(|a, b| kf(a).total_cmp(&kf(b)));
    let never = every.iter().find(|g| kf(g) == 0.0);
    let (Some(&first), Some(&never)) = (first, never) else {
        return Model {
            csv: String::new(),
            verdict: "cost model: needs a K > 0 and never (0) among --every".into(),
        };
    };
    let model = Fit::new(kf(first), first, never, steps);
    let fitted = |g: &Group| std::ptr::eq(g, first) || std::ptr::eq(g, never);
    let csv = csv(&every, &model, &kf, &fitted, never);
    let floor = noise_floor(groups, seconds_per_step).unwrap_or(0.0);
    let verdict = verdict(&every, &model, &kf, &fitted, &first.spec.label, floor);
    Model { csv, verdict }
}

fn csv(
    every: &[&Group],
    model: &Fit,
    kf: &dyn Fn(&Group) -> f64,
    fitted: &dyn Fn(&Group) -> bool,
    never: &Group,
) -> String {
    let mut csv = String::from(
        "label,K,measured_median,measured_min,measured_max,predicted,\
         per_repartition_seconds,busy_imbalance_median,fitted_to\n",
    );
    let busy_never = never.stat(busy_seconds).median;
    for g in every {
        let k = kf(g);
        let t = g.stat(seconds_per_step);
        // What one repartitioning costs at this K, measured as c is.
        let per = if k > 0.0 {
            k * (g.stat(busy_seconds).median - busy_never)
        } else {
            0.0
        };
        writeln!(
            csv,
            "{},{k},{:e},{:e},{:e},{:e},{:e},{},{}",
            g.spec.label,
            t.median,
            t.lo,
            t.hi,
            model.predict(k),
            per,
            g.stat(busy_imbalance).median,
            fitted(g)
        )
        .expect("string");
    }
    csv
}

fn verdict(
    every: &[&Group],
    model: &Fit,
    kf: &dyn Fn(&Group) -> f64,
    fitted: &dyn Fn(&Group) -> bool,
    fitted_to: &str,
    floor: f64,
) -> String {
    let measured = |g: &Group| g.stat(seconds_per_step).median;
    let by = |f: &dyn Fn(&Group) -> f64| {
        every
            .iter()
            .min_by(|a, b| f(a).total_cmp(&f(b)))
            .copied()
            .expect("settings")
    };
    let model_best = by(&|g| model.predict(kf(g)));
    let measured_best = by(&measured);
    let gap = (measured(model_best) - measured(measured_best)) / measured(measured_best);
    // How far its times are from the measured ones where it was not fitted.
    let error = every
        .iter()
        .filter(|g| !fitted(g))
        .map(|g| (model.predict(kf(g)) - measured(g)) / measured(g))
        .max_by(|a, b| a.abs().total_cmp(&b.abs()));
    let k_star = match model.best_k() {
        Some(k) => format!("{k:.0}"),
        None => "none (imbalance costs nothing measurable)".into(),
    };
    let mut text = format!(
        "cost model (fitted to {fitted_to} and never, predicting the others): one repartitioning \
         {:.3} ms, a balanced step {:.3} ms, imbalance growing {:.2e} per step, costing \
         {:.3} ms per step per unit; its best K is {k_star}, among the settings {}; measured \
         best {}. ",
        1e3 * model.c,
        1e3 * model.t0,
        model.r,
        1e3 * model.beta,
        model_best.spec.label,
        measured_best.spec.label,
    );
    if gap <= floor {
        write!(
            text,
            "The model's choice is within the noise floor ({:.1}%) of the measured best: it \
             predicts the best setting.",
            100.0 * floor
        )
    } else {
        write!(
            text,
            "The model's choice is {:.1}% slower than the measured best, beyond the noise floor \
             ({:.1}%): it does not predict the best setting.",
            100.0 * gap,
            100.0 * floor
        )
    }
    .expect("string");
    if let Some(e) = error {
        write!(
            text,
            " Its time per step is off by up to {:+.1}% where it was not fitted{}.",
            100.0 * e,
            if e.abs() <= floor {
                ", within the noise floor"
            } else {
                ", beyond the noise floor"
            }
        )
        .expect("string");
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::common::Spec;

    /// A setting repartitioning every `k` steps (0: never) whose runs took
    /// `t` seconds per step, `busy` of them busy, at busy imbalance `i`.
    fn group(k: u64, t: f64, busy: f64, i: f64) -> Group {
        let label = if k == 0 {
            "never".into()
        } else {
            format!("every-{k}")
        };
        let spec = Spec {
            label,
            ranks: 2,
            threads: 1,
            args: vec!["--repartition-every".into(), k.to_string()],
            x: k as f64,
            series: "every K steps".into(),
        };
        let run = |d: f64| Ran {
            spec: spec.clone(),
            summary: serde_json::json!({
                "seconds_per_step": t * d,
                "per_step_over_ranks": { "busy_seconds": { "mean": busy * d } },
            }),
            lines: vec![serde_json::json!({ "busy_imbalance": i })],
        };
        let runs = vec![run(0.99), run(1.0), run(1.01)];
        Group { spec, runs }
    }

    fn k_of(g: &Group) -> Option<u64> {
        g.spec.args[1].parse().ok()
    }

    /// Runs that follow the model exactly: it recovers its parameters from
    /// the two extremes and predicts the settings between to rounding.
    #[test]
    fn the_model_recovers_a_law_it_was_not_fitted_to_in_between() {
        let (t0, c, beta, steps) = (1e-3, 4e-4, 2e-3, 3000.0);
        let (b0, r) = (0.9e-3, 1e-4);
        let t = |k: f64| t0 + c / k + beta * r * k / 2.0;
        let busy = |k: f64| b0 + c / k;
        // Each setting's imbalance: its own mean over a K-step drift.
        let groups: Vec<Group> = [1, 10, 100]
            .into_iter()
            .map(|k| group(k, t(k as f64), busy(k as f64), 1.0 + r * k as f64 / 2.0))
            .chain([group(
                0,
                t0 + beta * r * steps / 2.0,
                b0,
                1.0 + r * steps / 2.0,
            )])
            .collect();
        let model = fit(&groups, steps, k_of);
        let rows: Vec<Vec<&str>> = model
            .csv
            .lines()
            .skip(1)
            .map(|l| l.split(',').collect())
            .collect();
        assert_eq!(rows.len(), 4);
        for row in &rows {
            let (measured, predicted): (f64, f64) =
                (row[2].parse().unwrap(), row[5].parse().unwrap());
            assert!(
                (predicted - measured).abs() <= 1e-9 * measured,
                "{row:?}: {predicted} against {measured}"
            );
            let k: f64 = row[1].parse().unwrap();
            if k > 0.0 {
                let per: f64 = row[6].parse().unwrap();
                assert!((per - c).abs() <= 1e-9 * c, "{row:?}");
            }
        }
        // Its best K, √(2c/(βr)) = 63, lies between 10 and 100: the model
        // picks every-100 (t 1.0140 ms against every-10's 1.0410 ms).
        assert!(
            model.verdict.contains("its best K is 63"),
            "{}",
            model.verdict
        );
        assert!(
            model.verdict.contains("among the settings every-100"),
            "{}",
            model.verdict
        );
        assert!(
            model.verdict.contains("it predicts the best setting"),
            "{}",
            model.verdict
        );
    }

    /// A repartitioning that measures as cheaper than none, or an imbalance
    /// that costs less than balance: noise, fitted as zero, not negative.
    #[test]
    fn rates_are_never_negative() {
        let groups = vec![
            group(1, 1.0e-3, 0.8e-3, 1.0),
            group(10, 1.0e-3, 0.8e-3, 1.0),
            group(0, 0.9e-3, 0.85e-3, 1.3),
        ];
        let model = fit(&groups, 3000.0, k_of);
        for p in [
            "one repartitioning 0.000 ms",
            "costing 0.000 ms per step per unit",
        ] {
            assert!(model.verdict.contains(p), "{}", model.verdict);
        }
        assert!(model
            .verdict
            .contains("none (imbalance costs nothing measurable)"));
    }
}
