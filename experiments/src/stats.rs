//! Summaries of repeated measurements.

/// Which summary of repeated timings a benchmark reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Statistic {
    /// The typical run.
    #[default]
    Median,
    /// The fastest run: on a machine whose speed swings (a shared cloud machine), the
    /// least disturbed one, and the steadiest of the two between runs.
    Min,
}

impl Statistic {
    pub fn name(self) -> &'static str {
        match self {
            Statistic::Median => "median",
            Statistic::Min => "min",
        }
    }

    /// The summary of `v`. Panics on an empty input, like [`median`].
    pub fn of(self, v: Vec<f64>) -> f64 {
        match self {
            Statistic::Median => median(v),
            Statistic::Min => {
                assert!(!v.is_empty(), "no measurements");
                v.into_iter().fold(f64::INFINITY, f64::min)
            }
        }
    }
}

/// The median (the mean of the two middle values for an even count).
/// Panics on an empty input: every caller measures at least once.
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

#[cfg(test)]
mod tests {
    use super::{median, Statistic};

    #[test]
    fn median_of_odd_and_even_counts() {
        assert_eq!(median(vec![3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(vec![4.0, 1.0, 3.0, 2.0]), 2.5);
    }

    #[test]
    fn statistics_summarise_as_named() {
        let v = vec![4.0, 1.5, 3.0, 2.0];
        assert_eq!(Statistic::Median.of(v.clone()), 2.5);
        assert_eq!(Statistic::Min.of(v), 1.5);
    }
}
