//! Energy books that do not depend on the order of their entries.
//!
//! An effect's books (the energy its springs store, the work its dashpots
//! and sliding took out) are sums over contacts or bodies. Split across
//! ranks, each rank holds some of the terms; summed in floating point, the
//! total would depend on how the terms were split. [`ExactSum`] keeps the
//! sum exactly, as a short list of non-overlapping partials (Shewchuk's
//! algorithm, as in Python's `math.fsum`), and rounds once at the end: the
//! result is the correctly rounded sum of the terms, whatever their order
//! and whichever rank added which, so a run's books are the same bits on
//! any rank count.

/// The exact sum of f64 terms, rounded once when read.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ExactSum {
    /// Non-overlapping, in increasing magnitude; their exact sum is the sum.
    partials: Vec<f64>,
    /// The sum of non-finite terms (they have no exact sum to keep).
    special: f64,
}

impl ExactSum {
    pub fn add(&mut self, mut x: f64) {
        if !x.is_finite() {
            self.special += x;
            return;
        }
        let mut kept = 0;
        for j in 0..self.partials.len() {
            let mut y = self.partials[j];
            if x.abs() < y.abs() {
                std::mem::swap(&mut x, &mut y);
            }
            // hi + lo == x + y exactly (|x| >= |y|).
            let hi = x + y;
            let lo = y - (hi - x);
            if lo != 0.0 {
                self.partials[kept] = lo;
                kept += 1;
            }
            x = hi;
        }
        self.partials.truncate(kept);
        self.partials.push(x);
    }

    /// Adds every term of `other`.
    pub fn merge(&mut self, other: &ExactSum) {
        other.partials.iter().for_each(|&p| self.add(p));
        self.special += other.special;
    }

    /// What travels between ranks: the partials, then the non-finite part.
    pub fn parts(&self) -> Vec<f64> {
        let mut v = self.partials.clone();
        v.push(self.special);
        v
    }

    /// The sum whose [`ExactSum::parts`] are `parts`.
    pub fn from_parts(parts: &[f64]) -> ExactSum {
        let mut s = ExactSum::default();
        if let [partials @ .., special] = parts {
            partials.iter().for_each(|&p| s.add(p));
            s.special = *special;
        }
        s
    }

    /// The sum, correctly rounded (round half to even).
    pub fn value(&self) -> f64 {
        if self.special != 0.0 || self.special.is_nan() {
            return self.special;
        }
        let p = &self.partials;
        let Some(&top) = p.last() else {
            return 0.0;
        };
        let (mut hi, mut lo, mut n) = (top, 0.0, p.len() - 1);
        while n > 0 {
            let x = hi;
            let y = p[n - 1];
            n -= 1;
            hi = x + y;
            lo = y - (hi - x);
            if lo != 0.0 {
                break;
            }
        }
        // A tie in the last rounding broken by the sign of what lies below.
        if n > 0 && ((lo < 0.0 && p[n - 1] < 0.0) || (lo > 0.0 && p[n - 1] > 0.0)) {
            let y = lo * 2.0;
            let x = hi + y;
            if y == x - hi {
                hi = x;
            }
        }
        hi
    }

    pub fn clear(&mut self) {
        self.partials.clear();
        self.special = 0.0;
    }
}

/// An effect's energy books: what it stores now, what it has taken out of
/// the bodies since the start, and this evaluation's terms of both.
#[derive(Debug, Clone, Default)]
pub struct Ledger {
    /// Energy stored at the last evaluation.
    pub stored: f64,
    /// Work taken out of the bodies since the start.
    pub taken: f64,
    /// This evaluation's terms: of the stored energy, and of the work.
    pub step_stored: ExactSum,
    pub step_taken: ExactSum,
}

impl Ledger {
    /// Books this evaluation's terms: the stored energy becomes their sum,
    /// the work grows by theirs.
    pub fn close(&mut self) {
        self.stored = self.step_stored.value();
        self.taken += self.step_taken.value();
        self.step_stored.clear();
        self.step_taken.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::ExactSum;
    use num_rational::BigRational;
    use num_traits::ToPrimitive;
    use rand::{Rng, SeedableRng};
    use rand_xoshiro::Xoshiro256StarStar;

    fn exact(terms: &[f64]) -> f64 {
        let sum = terms
            .iter()
            .map(|&t| BigRational::from_float(t).expect("finite"))
            .fold(BigRational::from_integer(0.into()), |a, b| a + b);
        sum.to_f64().expect("representable")
    }

    #[test]
    fn the_sum_is_the_correctly_rounded_exact_sum_in_any_order_and_split() {
        let mut rng = Xoshiro256StarStar::seed_from_u64(7);
        for case in 0..200 {
            let n = rng.random_range(1..60);
            let terms: Vec<f64> = (0..n)
                .map(|_| {
                    let m: f64 = rng.random_range(-1.0..1.0);
                    m * 2f64.powi(rng.random_range(-60..60))
                })
                .collect();
            let mut whole = ExactSum::default();
            terms.iter().for_each(|&t| whole.add(t));
            let reference = exact(&terms);
            assert_eq!(whole.value().to_bits(), reference.to_bits(), "case {case}");
            // Split in two halves summed apart, merged in the other order.
            let cut = rng.random_range(0..=n);
            let (mut a, mut b) = (ExactSum::default(), ExactSum::default());
            terms[..cut].iter().rev().for_each(|&t| a.add(t));
            terms[cut..].iter().for_each(|&t| b.add(t));
            b.merge(&ExactSum::from_parts(&a.parts()));
            assert_eq!(b.value().to_bits(), reference.to_bits(), "case {case}");
        }
    }

    #[test]
    fn cancellation_leaves_what_plain_addition_loses() {
        let mut s = ExactSum::default();
        for t in [1e100, 1.0, -1e100, 1e-20] {
            s.add(t);
        }
        assert_eq!(s.value(), 1.0 + 1e-20);
        assert_eq!(1e100 + 1.0 - 1e100 + 1e-20, 1e-20);
    }
}
