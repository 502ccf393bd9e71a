//! Brute force on every hard case of dem/tests/data/triangle-pairs.csv.
mod common;

use dem::distance::distance_triangle_triangle;

#[test]
fn brute_matches_references_on_every_case() {
    let mut failures = Vec::new();
    for c in common::load_cases() {
        let r = distance_triangle_triangle(&c.a, &c.b);
        let l = dem::distance::pair_scale(&c.a, &c.b);
        let err = (r.distance - c.reference).abs();
        // P on the first triangle, Q on the second, |P - Q| the distance.
        let on_tol = common::membership_tolerance(&c);
        let (p_in, p_off) = common::within_triangle(r.p, &c.a, on_tol);
        let (q_in, q_off) = common::within_triangle(r.q, &c.b, on_tol);
        let pq = ((r.p - r.q).length() - r.distance).abs();
        if !(err <= 1e-12 * l && p_in && q_in && pq <= on_tol) {
            failures.push(format!(
                "line {} [{}]: got {:e}, reference {:e}, err/L {:e}, P off {:e}, Q off {:e}, |PQ| - d {:e}",
                c.line, c.category, r.distance, c.reference, err / l, p_off / l, q_off / l, pq / l
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// The SIMD-batched brute force gives the scalar answers bit for bit, on
/// every hard case and on random pairs, whatever the batch composition, on
/// every instruction set this CPU has.
#[test]
fn batched_brute_force_equals_the_scalar_one() {
    let mut pairs: Vec<_> = common::load_cases().iter().map(|c| (c.a, c.b)).collect();
    pairs.extend(dem::distance::random_unit_pairs(5000, 9));
    for isa in common::available_isas() {
        for offset in [0, 3] {
            let slice = &pairs[offset..];
            let mut out = vec![distance_triangle_triangle(&slice[0].0, &slice[0].1); slice.len()];
            dem::distance::distance_triangle_triangle_many_on(slice, isa, &mut out);
            for ((a, b), r) in slice.iter().zip(&out) {
                let s = distance_triangle_triangle(a, b);
                assert_eq!(
                    r.distance.to_bits(),
                    s.distance.to_bits(),
                    "{isa:?}: {a:?} {b:?}"
                );
                assert_eq!(r.p, s.p, "{isa:?}");
                assert_eq!(r.q, s.q, "{isa:?}");
            }
        }
    }
}
