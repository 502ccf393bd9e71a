//! What every study keeps of its runs, and how it reads them: settings,
//! runs, their medians and spreads, the noise floor, the finding.

use crate::error::{CliError, CliResult};
use crate::plot::Bar;
use serde_json::Value;
use std::path::Path;

/// One setting of a study.
#[derive(Debug, Clone)]
pub(crate) struct Spec {
    pub label: String,
    /// 1: a run on one node, started directly (no launcher).
    pub ranks: usize,
    pub threads: usize,
    pub args: Vec<String>,
    /// The setting the study varies, as a number for plots (K, ranks, threads).
    pub x: f64,
    /// The series it belongs to in the figures.
    pub series: String,
}

pub(crate) struct Ran {
    pub spec: Spec,
    /// The run's JSON summary.
    pub summary: Value,
    /// Its metrics lines (distributed runs).
    pub lines: Vec<Value>,
}

/// A setting's runs.
pub(crate) struct Group {
    pub spec: Spec,
    pub runs: Vec<Ran>,
}

/// The median of a setting's runs, with the least and the most.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Stat {
    pub median: f64,
    pub lo: f64,
    pub hi: f64,
}

impl Stat {
    pub fn of(mut v: Vec<f64>) -> Stat {
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let median = match n {
            0 => 0.0,
            _ if n % 2 == 1 => v[n / 2],
            _ => 0.5 * (v[n / 2 - 1] + v[n / 2]),
        };
        Stat {
            median,
            lo: v.first().copied().unwrap_or(0.0),
            hi: v.last().copied().unwrap_or(0.0),
        }
    }

    pub fn bar(&self, x: f64, scale: f64) -> Bar {
        Bar {
            x,
            median: scale * self.median,
            lo: scale * self.lo,
            hi: scale * self.hi,
        }
    }
}

impl Group {
    pub fn stat(&self, value: impl Fn(&Ran) -> f64) -> Stat {
        Stat::of(self.runs.iter().map(value).collect())
    }
}

/// The label of the setting that repeats the first one, for the noise floor.
pub(crate) fn again(label: &str) -> String {
    format!("{label}-again")
}

/// The noise floor of a timing study: how far apart two groups of the same
/// setting measured (the relative difference of their medians), at least
/// half the relative spread of either.
pub(crate) fn noise_floor(groups: &[Group], value: impl Fn(&Ran) -> f64) -> Option<f64> {
    let first = groups.first()?;
    let twin = groups
        .iter()
        .find(|g| g.spec.label == again(&first.spec.label))?;
    Some(floor_between(first, twin, value))
}

/// The noise floor of two settings that do the same work: the gap between
/// their medians, or half the spread of either's runs, relative to the
/// first's median, whichever is largest.
pub(crate) fn floor_between(first: &Group, twin: &Group, value: impl Fn(&Ran) -> f64) -> f64 {
    let (a, b) = (first.stat(&value), twin.stat(&value));
    let rel = |s: &Stat| (s.hi - s.lo) / (2.0 * s.median);
    ((a.median - b.median).abs() / a.median)
        .max(rel(&a))
        .max(rel(&b))
}

/// What a timing study found, in a sentence: the fastest setting (by
/// median), the settings within the noise floor of it (no difference), and
/// how much slower the others are.
pub(crate) fn finding(groups: &[Group], time: impl Fn(&Ran) -> f64, floor: f64) -> String {
    let settings: Vec<(&Group, f64)> = groups
        .iter()
        .filter(|g| g.spec.series != "noise floor")
        .map(|g| (g, g.stat(&time).median))
        .collect();
    let Some(&(best, t)) = settings.iter().min_by(|a, b| a.1.total_cmp(&b.1)) else {
        return String::new();
    };
    let (mut same, mut slower) = (Vec::new(), Vec::new());
    for &(g, u) in &settings {
        if std::ptr::eq(g, best) {
            continue;
        }
        let gap = (u - t) / t;
        if gap <= floor {
            same.push(g.spec.label.clone());
        } else {
            slower.push(format!("{} +{:.0}%", g.spec.label, 100.0 * gap));
        }
    }
    let list = |v: &[String]| {
        if v.is_empty() {
            "none".into()
        } else {
            v.join(", ")
        }
    };
    format!(
        "found: fastest {} ({:.3} ms per step, median of {} runs); no difference beyond the \
         noise floor ({:.1}%): {}; slower: {}",
        best.spec.label,
        1e3 * t,
        best.runs.len(),
        100.0 * floor,
        list(&same),
        list(&slower)
    )
}

pub(crate) fn seconds_per_step(r: &Ran) -> f64 {
    r.summary["seconds_per_step"].as_f64().unwrap_or(0.0)
}

pub(crate) fn write(path: &Path, text: &str) -> CliResult {
    std::fs::write(path, text)
        .map_err(|e| CliError::runtime(format!("{}: cannot write: {e}", path.display())))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A setting whose runs took `times` milliseconds per step.
    fn group(label: &str, series: &str, times: &[f64]) -> Group {
        let spec = Spec {
            label: label.into(),
            ranks: 2,
            threads: 1,
            args: Vec::new(),
            x: 0.0,
            series: series.into(),
        };
        let runs = times
            .iter()
            .map(|&t| Ran {
                spec: spec.clone(),
                summary: serde_json::json!({ "seconds_per_step": 1e-3 * t }),
                lines: Vec::new(),
            })
            .collect();
        Group { spec, runs }
    }

    #[test]
    fn the_floor_is_the_gap_between_twins_or_their_spread() {
        // Medians 1.00 and 1.03 (3% apart); spreads 2% and 1% of the median.
        let groups = [
            group("a", "s", &[0.98, 1.0, 1.02]),
            group("b", "s", &[2.0, 2.0, 2.0]),
            group("a-again", "noise floor", &[1.02, 1.03, 1.04]),
        ];
        let floor = noise_floor(&groups, seconds_per_step).unwrap();
        assert!((floor - 0.03).abs() < 1e-12, "{floor}");
        // Wide spread dominates a small gap.
        let groups = [
            group("a", "s", &[0.5, 1.0, 1.5]),
            group("a-again", "noise floor", &[1.0, 1.0, 1.0]),
        ];
        assert!((noise_floor(&groups, seconds_per_step).unwrap() - 0.5).abs() < 1e-12);
    }

    #[test]
    fn a_finding_separates_settings_within_the_floor_from_slower_ones() {
        let groups = [
            group("a", "s", &[1.00, 1.00, 1.00]),
            group("b", "s", &[1.02, 1.02, 1.02]),
            group("c", "s", &[1.50, 1.50, 1.50]),
            group("a-again", "noise floor", &[0.90, 0.90, 0.90]),
        ];
        let text = finding(&groups, seconds_per_step, 0.03);
        assert!(text.starts_with("found: fastest a (1.000 ms"), "{text}");
        assert!(text.contains("noise floor (3.0%): b;"), "{text}");
        assert!(text.contains("slower: c +50%"), "{text}");
        // The twin measures the floor; it is not a setting.
        assert!(!text.contains("a-again"), "{text}");
    }
}
