//! Penalty and hybrid on every hard case of dem/tests/data/triangle-pairs.csv.
mod common;

use dem::distance::{distances, pair_scale, Fallback, Method, Options, Triangle};
use std::collections::BTreeMap;

fn pairs(cases: &[common::Case]) -> Vec<(Triangle, Triangle)> {
    cases.iter().map(|c| (c.a, c.b)).collect()
}

#[test]
fn hybrid_matches_references_on_every_case_for_every_batch_size_and_fallback() {
    let cases = common::load_cases();
    let pairs = pairs(&cases);
    for batch in [1, 8, 64] {
        for fallback in [Fallback::WholeBatch, Fallback::FailedPairs] {
            let opts = Options {
                method: Method::Hybrid,
                batch,
                fallback,
                ..Options::default()
            };
            let (out, _, _) = distances(&pairs, &opts).unwrap();
            let mut failures = Vec::new();
            for (c, r) in cases.iter().zip(&out) {
                let l = pair_scale(&c.a, &c.b);
                let tol = common::membership_tolerance(c);
                let err = (r.distance - c.reference).abs();
                let (p_in, p_off) = common::within_triangle(r.p, &c.a, tol);
                let (q_in, q_off) = common::within_triangle(r.q, &c.b, tol);
                let pq = ((r.p - r.q).length() - r.distance).abs();
                if !(err <= 1e-12 * l && p_in && q_in && pq <= tol) {
                    failures.push(format!(
                        "line {} [{}] by {}: got {:e}, reference {:e}, err/L {:e}, P off/L {:e}, Q off/L {:e}",
                        c.line, c.category, r.solver.name(), r.distance, c.reference, err / l, p_off / l, q_off / l
                    ));
                }
            }
            assert!(
                failures.is_empty(),
                "batch {batch}, {fallback:?}: {} failures:\n{}",
                failures.len(),
                failures.join("\n")
            );
        }
    }
}

/// Penalty answers are always finite, and a pair reported as converged is
/// within the certified tolerance of the reference: never a wrong answer
/// marked as converged, in any category (parallel faces included).
#[test]
fn penalty_is_finite_and_never_wrong_when_it_claims_convergence() {
    let cases = common::load_cases();
    let pairs = pairs(&cases);
    let opts = Options {
        method: Method::Penalty,
        ..Options::default()
    };
    let (out, stats, _) = distances(&pairs, &opts).unwrap();
    // Without the finish and with many iterations the regularisation gets
    // small: the answers must stay finite all the same.
    for iterations in [1, 4, 8, 16] {
        let raw = Options {
            method: Method::Penalty,
            penalty: dem::distance::PenaltyParams {
                max_iterations: iterations,
                finish_rounds: 0,
                ..Default::default()
            },
            ..Options::default()
        };
        let (raw_out, _, _) = distances(&pairs, &raw).unwrap();
        for (c, r) in cases.iter().zip(&raw_out) {
            assert!(
                r.distance.is_finite(),
                "line {}, {iterations} iterations: {r:?}",
                c.line
            );
        }
    }
    let mut per_category: BTreeMap<&str, (usize, usize, f64)> = BTreeMap::new();
    for ((c, r), s) in cases.iter().zip(&out).zip(&stats) {
        let l = pair_scale(&c.a, &c.b);
        assert!(
            r.distance.is_finite(),
            "line {}: penalty gave {:?}",
            c.line,
            r
        );
        let rel_err = (r.distance - c.reference).abs() / l;
        if s.converged {
            // Certified to tol = 1e-13 L, plus the rounding of the reference comparison.
            assert!(
                rel_err <= 2e-13,
                "line {} [{}]: converged but error {:e} L",
                c.line,
                c.category,
                rel_err
            );
        }
        let e = per_category.entry(c.category.as_str()).or_default();
        e.0 += 1;
        e.1 += s.converged as usize;
        e.2 = e.2.max(rel_err);
    }
    eprintln!("category            pairs  certified  max error / L (all pairs)");
    for (cat, (n, conv, max_err)) in &per_category {
        eprintln!("{cat:<18} {n:>6} {conv:>10}  {max_err:e}");
    }
    // The kernel must be useful, not only safe: most random pairs are certified.
    let (n, conv, _) = per_category["random_unit"];
    assert!(conv * 2 > n, "only {conv} of {n} random pairs certified");
}

#[test]
fn every_schedule_on_every_pool_gives_the_one_thread_answer() {
    use dem::distance::{Schedule, Threading};
    let cases = common::load_cases();
    let pairs = pairs(&cases);
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let reference = one.install(|| distances(&pairs, &Options::default()).unwrap());
    for schedule in [Schedule::Static, Schedule::Dynamic, Schedule::Guided] {
        for threads in [2, 3] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let opts = Options {
                threading: Threading { schedule, grain: 3 },
                ..Options::default()
            };
            let got = pool.install(|| distances(&pairs, &opts).unwrap());
            // Bitwise: the shares change who computes a pair, never how.
            assert_eq!(got.0, reference.0, "{schedule:?}, {threads} threads");
            assert_eq!(got.2, reference.2, "{schedule:?}, {threads} threads");
        }
    }
}

/// The penalty kernel gives the same answers and statistics, bit for bit, on
/// every instruction set this CPU has, for every batch size (the wide ones
/// load and store through in-register transposes, the baseline lane by lane),
/// on the hard cases and on random pairs.
#[test]
fn penalty_answers_do_not_depend_on_the_instruction_set() {
    use dem::distance::{penalty_many_on, Closest, Isa, PenaltyParams, PenaltyStats};
    let mut pairs = pairs(&common::load_cases());
    pairs.extend(dem::distance::random_unit_pairs(3001, 5));
    let prm = PenaltyParams::default();
    let run = |isa: Isa, batch: usize| {
        let mut out = vec![Closest::UNSET; pairs.len()];
        let mut stats = vec![PenaltyStats::default(); pairs.len()];
        penalty_many_on(&pairs, batch, &prm, isa, &mut out, &mut stats).unwrap();
        (out, stats)
    };
    let bits =
        |c: &Closest| [c.distance, c.p.x, c.p.y, c.p.z, c.q.x, c.q.y, c.q.z].map(f64::to_bits);
    let isas = common::available_isas();
    eprintln!("instruction sets: {isas:?}");
    for batch in [1, 2, 4, 8, 16, 32, 64] {
        let (reference, reference_stats) = run(Isa::Baseline, batch);
        for &isa in &isas {
            let (out, stats) = run(isa, batch);
            for k in 0..pairs.len() {
                assert!(
                    bits(&out[k]) == bits(&reference[k]) && stats[k] == reference_stats[k],
                    "{isa:?}, batch {batch}, pair {k}: {:?} {:?} against baseline {:?} {:?}",
                    out[k],
                    stats[k],
                    reference[k],
                    reference_stats[k]
                );
            }
        }
    }
}
