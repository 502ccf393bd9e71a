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

    /// The sum of the negated terms (exact: the partials stay non-overlapping).
    pub fn negated(&self) -> ExactSum {
        ExactSum {
            partials: self.partials.iter().map(|p| -p).collect(),
            special: -self.special,
        }
    }

    /// What travels between ranks: the partials, then the non-finite part.
    pub fn parts(&self) -> Vec<f64> {
        let mut v = self.partials.clone();
        v.push(self.special);
        v
    }

    /// The sum as canonical parts: the correctly rounded sum, then the
    /// correctly rounded remainder, and so on until nothing remains (in
    /// increasing magnitude), then the non-finite part. The same sum gives
    /// the same parts however its terms were added or split, which
    /// [`ExactSum::parts`] does not promise; checkpoints store these.
    pub fn canonical_parts(&self) -> Vec<f64> {
        let mut rest = self.clone();
        rest.special = 0.0;
        let mut parts = Vec::new();
        loop {
            let v = rest.value();
            if v == 0.0 {
                break;
            }
            parts.push(v);
            rest.add(-v);
        }
        parts.reverse();
        parts.push(self.special);
        parts
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

/// An effect's energy books, as exact sums over the terms this process
/// entered: the energy it stores at the last evaluation, and the work it has
/// taken out of the bodies since the start of the run. Both are kept exact
/// and rounded only when read, so the books of a run split across ranks
/// merge (at output steps only) into the same bits as one process's.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Ledger {
    stored: ExactSum,
    taken: ExactSum,
}

impl Ledger {
    /// A new evaluation: the stored energy is entered afresh.
    pub fn begin(&mut self) {
        self.stored.clear();
    }

    /// A term of the energy stored now.
    pub fn store(&mut self, energy: f64) {
        self.stored.add(energy);
    }

    /// A term of the work taken out of the bodies.
    pub fn take(&mut self, work: f64) {
        self.taken.add(work);
    }

    pub fn stored(&self) -> &ExactSum {
        &self.stored
    }

    pub fn taken(&self) -> &ExactSum {
        &self.taken
    }

    /// The books as plain numbers ([`ExactSum::canonical_parts`] of both
    /// sums), for a checkpoint.
    pub fn state(&self) -> (Vec<f64>, Vec<f64>) {
        (self.stored.canonical_parts(), self.taken.canonical_parts())
    }

    /// Takes back what [`Ledger::state`] gave; refused unless every part is
    /// finite but the last of each (the sum of non-finite terms).
    pub fn restore(&mut self, stored: &[f64], taken: &[f64]) -> Result<(), String> {
        for (what, parts) in [("stored energy", stored), ("work taken", taken)] {
            let [partials @ .., _] = parts else {
                return Err(format!("the books' {what} has no parts"));
            };
            if !partials.iter().all(|p| p.is_finite()) {
                return Err(format!("the books' {what} holds a non-finite part"));
            }
        }
        self.stored = ExactSum::from_parts(stored);
        self.taken = ExactSum::from_parts(taken);
        Ok(())
    }

    /// Adds another process's books to these.
    pub fn merge(&mut self, other: &Ledger) {
        self.stored.merge(&other.stored);
        self.taken.merge(&other.taken);
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

    /// Canonical parts depend on the sum alone: split and merged in any
    /// order, the same numbers; and they sum back to it.
    #[test]
    fn canonical_parts_are_a_function_of_the_sum() {
        let mut rng = Xoshiro256StarStar::seed_from_u64(11);
        for case in 0..200 {
            let n = rng.random_range(1..40);
            let terms: Vec<f64> = (0..n)
                .map(|_| rng.random_range(-1.0..1.0) * 2f64.powi(rng.random_range(-80..80)))
                .collect();
            let mut whole = ExactSum::default();
            terms.iter().for_each(|&t| whole.add(t));
            let cut = rng.random_range(0..=n);
            let (mut a, mut b) = (ExactSum::default(), ExactSum::default());
            terms[..cut].iter().rev().for_each(|&t| a.add(t));
            terms[cut..].iter().for_each(|&t| b.add(t));
            b.merge(&a);
            let (p, q) = (whole.canonical_parts(), b.canonical_parts());
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&p), bits(&q), "case {case}");
            let back = ExactSum::from_parts(&p);
            assert_eq!(
                back.value().to_bits(),
                exact(&terms).to_bits(),
                "case {case}"
            );
            let mut rest = back.clone();
            rest.merge(&whole.negated());
            assert_eq!(
                rest.value(),
                0.0,
                "case {case}: the parts are the whole sum"
            );
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
