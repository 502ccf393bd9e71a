//! Brute force on every hard case of ../shared/cases/triangle-pairs.csv.
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
        let p_off = common::offset_from_triangle(r.p, &c.a);
        let q_off = common::offset_from_triangle(r.q, &c.b);
        let pq = ((r.p - r.q).length() - r.distance).abs();
        let on_tol = common::membership_tolerance(&c);
        if !(err <= 1e-12 * l && p_off <= on_tol && q_off <= on_tol && pq <= on_tol) {
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
