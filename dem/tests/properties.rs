//! Property tests of the distance kernels: invariances, bounds, and agreement
//! between the three methods on random pairs at many scales.
use dem::distance::{
    distance_triangle_triangle, distances, pair_scale, random_unit_pairs, Method, Options,
    PenaltyParams, Triangle,
};
use glam::{DMat3, DQuat, DVec3};
use proptest::prelude::*;

fn vec3() -> impl Strategy<Value = DVec3> {
    (-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0).prop_map(|(x, y, z)| DVec3::new(x, y, z))
}

fn triangle() -> impl Strategy<Value = Triangle> {
    [vec3(), vec3(), vec3()]
}

/// Scale and place: size in 1e-6..1e6, offset up to 1e3 sizes from the origin.
fn placement() -> impl Strategy<Value = (f64, DVec3)> {
    (-6i32..=6, vec3()).prop_map(|(e, o)| {
        let s = 10f64.powi(e);
        (s, o * s * 1e3)
    })
}

fn tol(a: &Triangle, b: &Triangle) -> f64 {
    let max_coord = a
        .iter()
        .chain(b)
        .map(|v| v.abs().max_element())
        .fold(0.0, f64::max);
    1e-12 * pair_scale(a, b) + 16.0 * f64::EPSILON * max_coord
}

fn map(t: &Triangle, f: impl Fn(DVec3) -> DVec3) -> Triangle {
    [f(t[0]), f(t[1]), f(t[2])]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn symmetric(a in triangle(), b in triangle(), (s, o) in placement()) {
        let (a, b) = (map(&a, |v| v * s + o), map(&b, |v| v * s + o));
        let ab = distance_triangle_triangle(&a, &b).distance;
        let ba = distance_triangle_triangle(&b, &a).distance;
        prop_assert!((ab - ba).abs() <= tol(&a, &b), "{ab} vs {ba}");
    }

    #[test]
    fn invariant_under_rigid_motion_and_vertex_order(
        a in triangle(), b in triangle(), (s, o) in placement(),
        axis in vec3(), angle in 0.0f64..6.3, perm in 0usize..6,
    ) {
        let (a, b) = (map(&a, |v| v * s), map(&b, |v| v * s));
        let d = distance_triangle_triangle(&a, &b).distance;
        let rot = DQuat::from_axis_angle(axis.try_normalize().unwrap_or(DVec3::Z), angle);
        let m = |v: DVec3| rot * v + o;
        let p = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]][perm];
        let a2 = [m(a[p[0]]), m(a[p[1]]), m(a[p[2]])];
        let b2 = map(&b, m);
        let d2 = distance_triangle_triangle(&a2, &b2).distance;
        // The moved pair's coordinates are rounded to its own ulps: allow them.
        prop_assert!((d - d2).abs() <= tol(&a2, &b2) + 1e-14 * pair_scale(&a, &b), "{d} vs {d2}");
    }

    #[test]
    fn at_most_every_vertex_vertex_distance(a in triangle(), b in triangle(), (s, o) in placement()) {
        let (a, b) = (map(&a, |v| v * s + o), map(&b, |v| v * s + o));
        let d = distance_triangle_triangle(&a, &b);
        for u in &a {
            for v in &b {
                prop_assert!(d.distance <= (*u - *v).length() + tol(&a, &b));
            }
        }
        prop_assert!(d.distance.is_finite() && d.distance >= 0.0);
    }

    #[test]
    fn hybrid_and_certified_penalty_agree_with_brute(
        pairs in prop::collection::vec((triangle(), triangle()), 1..40),
        (s, o) in placement(), batch_pow in 0u32..7,
    ) {
        let pairs: Vec<(Triangle, Triangle)> = pairs
            .iter()
            .map(|(a, b)| (map(a, |v| v * s + o), map(b, |v| v * s + o)))
            .collect();
        let batch = 1usize << batch_pow;
        let brute = distances(&pairs, &Options { method: Method::Brute, batch, ..Options::default() }).unwrap().0;
        let hybrid = distances(&pairs, &Options { method: Method::Hybrid, batch, ..Options::default() }).unwrap().0;
        let (pen, stats, _) = distances(&pairs, &Options { method: Method::Penalty, batch, ..Options::default() }).unwrap();
        for i in 0..pairs.len() {
            let (a, b) = &pairs[i];
            prop_assert!((hybrid[i].distance - brute[i].distance).abs() <= tol(a, b));
            prop_assert!(pen[i].distance.is_finite());
            if stats[i].converged {
                prop_assert!((pen[i].distance - brute[i].distance).abs() <= 2e-13 * pair_scale(a, b) + tol(a, b));
            }
        }
    }
}

/// Well-separated, non-parallel pairs: Newton settles on them, and the penalty
/// answer agrees with brute force to its tolerance.
#[test]
fn penalty_converges_on_separated_pairs() {
    let pairs: Vec<(Triangle, Triangle)> = random_unit_pairs(2000, 7)
        .into_iter()
        .map(|(a, b)| (a, map(&b, |v| v + DVec3::new(0.0, 0.0, 2.5))))
        .collect();
    let prm = PenaltyParams {
        max_iterations: 8,
        ..PenaltyParams::default()
    };
    let opts = Options {
        method: Method::Penalty,
        penalty: prm,
        ..Options::default()
    };
    let (pen, stats, counts) = distances(&pairs, &opts).unwrap();
    for (i, (a, b)) in pairs.iter().enumerate() {
        let exact = distance_triangle_triangle(a, b).distance;
        assert!(exact > 0.5, "pair {i} is not separated");
        if stats[i].converged {
            assert!((pen[i].distance - exact).abs() <= 2e-13 * pair_scale(a, b));
        }
    }
    assert!(
        counts.certified * 100 >= 98 * pairs.len(),
        "only {} of {} separated pairs converged",
        counts.certified,
        pairs.len()
    );
}

/// Parallel faces: the minimiser is not unique and H is singular. The kernel may
/// give up, but never reports a wrong answer as converged.
#[test]
fn penalty_on_parallel_faces_never_claims_a_wrong_answer() {
    let mut claimed = 0;
    for (k, (a, b)) in random_unit_pairs(500, 11).into_iter().enumerate() {
        let flat = |t: &Triangle, z: f64| map(t, |v| DVec3::new(v.x, v.y, z));
        let h = 1e-3 * (1 + k % 100) as f64;
        let rot = DMat3::from_rotation_x(0.3 * k as f64);
        let (a, b) = (
            map(&flat(&a, 0.0), |v| rot * v),
            map(&flat(&b, h), |v| rot * v),
        );
        let exact = distance_triangle_triangle(&a, &b).distance;
        let opts = Options {
            method: Method::Penalty,
            batch: 1,
            ..Options::default()
        };
        let (pen, stats, _) = distances(&[(a, b)], &opts).unwrap();
        if stats[0].converged {
            claimed += 1;
            assert!(
                (pen[0].distance - exact).abs() <= 2e-13 * pair_scale(&a, &b),
                "pair {k}"
            );
        }
    }
    eprintln!("parallel faces: {claimed} of 500 certified");
}

/// A pair's penalty answer does not depend on which other pairs share its
/// batch: the same pairs in every batch size the kernel has (each reaches
/// the hybrid's share loop through its own kernel), on the same instruction
/// set, give the same verdicts and answers within the certified tolerance
/// (lanes differ only through Newton's early exit when a whole batch settles).
#[test]
fn penalty_answers_do_not_depend_on_the_batch() {
    let pairs = random_unit_pairs(3000, 11);
    let run = |batch| {
        let opts = Options {
            method: Method::Penalty,
            batch,
            ..Options::default()
        };
        distances(&pairs, &opts).unwrap()
    };
    let (one, s1, _) = run(1);
    for batch in [2, 4, 8, 16, 32, 64] {
        let (many, sn, _) = run(batch);
        let mut differ = 0;
        for (i, (a, b)) in pairs.iter().enumerate() {
            differ += (s1[i].converged != sn[i].converged) as usize;
            if s1[i].converged && sn[i].converged {
                let tol = 2e-13 * pair_scale(a, b);
                assert!(
                    (one[i].distance - many[i].distance).abs() <= tol,
                    "pair {i}, batch {batch}: {} vs {}",
                    one[i].distance,
                    many[i].distance
                );
            }
        }
        // Verdicts may differ only where the early exit changed Newton's path.
        assert!(
            differ * 100 <= pairs.len(),
            "{differ} verdicts differ at batch {batch}"
        );
    }
}
