//! Shared by the integration tests: the hard triangle pairs of
//! `tests/data/triangle-pairs.csv`, and the granular validations' materials.
#![allow(dead_code)]

mod exact;
pub use exact::exact_offset_from_triangle;

use dem::distance::Triangle;
use glam::DVec3;
use std::path::PathBuf;

pub struct Case {
    pub category: String,
    pub line: usize,
    pub a: Triangle,
    pub b: Triangle,
    pub reference: f64,
}

/// Where the hard cases live: `$TRIDEM_CASES` (another file of the same
/// format), or the copy the repository carries in `dem/tests/data/`.
pub fn cases_path() -> PathBuf {
    if let Ok(p) = std::env::var("TRIDEM_CASES") {
        return PathBuf::from(p);
    }
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/triangle-pairs.csv")
}

pub fn load_cases() -> Vec<Case> {
    let path = cases_path();
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    let mut category = String::from("uncategorised");
    let mut cases = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if let Some(c) = line.strip_prefix("# category:") {
            category = c.trim().to_string();
            continue;
        }
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let v: Vec<f64> = line
            .split(',')
            .map(|f| {
                f.trim()
                    .parse()
                    .unwrap_or_else(|_| panic!("line {}: {f}", i + 1))
            })
            .collect();
        assert_eq!(v.len(), 19, "line {}", i + 1);
        let p = |k: usize| DVec3::new(v[3 * k], v[3 * k + 1], v[3 * k + 2]);
        cases.push(Case {
            category: category.clone(),
            line: i + 1,
            a: [p(0), p(1), p(2)],
            b: [p(3), p(4), p(5)],
            reference: v[18],
        });
    }
    assert!(
        cases.len() > 1000,
        "only {} cases in {}",
        cases.len(),
        path.display()
    );
    cases
}

/// Distance from `p` to triangle `t`, computed relative to the triangle's first
/// vertex so that the check is as accurate as the thing it checks.
pub fn offset_from_triangle(p: DVec3, t: &Triangle) -> f64 {
    let o = t[0];
    let local = [DVec3::ZERO, t[1] - o, t[2] - o];
    let x = p - o;
    // Both are points of the triangle; on a sliver the projection is the less
    // accurate one, on its edges the boundary is exact.
    let face = (dem::distance::closest_point_triangle(x, &local) - x).length();
    let edges = (0..3)
        .map(|i| {
            let (_, _, c, _) =
                dem::distance::closest_points_segment_segment(local[i], local[(i + 1) % 3], x, x);
            (c - x).length()
        })
        .fold(f64::INFINITY, f64::min);
    face.min(edges)
}

/// Whether `p` lies within `tol` of triangle `t`: the fast check in doubles,
/// confirmed exactly when it fails (the projection on a sliver is only
/// accurate to rounding over the sine of its smallest angle).
pub fn within_triangle(p: DVec3, t: &Triangle, tol: f64) -> (bool, f64) {
    let off = offset_from_triangle(p, t);
    if off <= tol {
        return (true, off);
    }
    let exact = exact_offset_from_triangle(p, t);
    (exact <= tol, exact)
}

/// How far a returned closest point may sit from its triangle.
///
/// 1e-12 L, plus what is not the kernel's: a point is returned in absolute
/// coordinates, so it cannot be closer than a few ulps of the largest coordinate.
pub fn membership_tolerance(c: &Case) -> f64 {
    let l = dem::distance::pair_scale(&c.a, &c.b);
    let max_coord =
        c.a.iter()
            .chain(c.b.iter())
            .map(|v| v.abs().max_element())
            .fold(0.0, f64::max);
    let ulps = 8.0 * f64::EPSILON * max_coord;
    1e-12 * l + ulps
}

/// The kernels' instruction sets this CPU runs, best first (the baseline
/// always): each is tested, not only the one `Isa::detect` picks.
pub fn available_isas() -> Vec<dem::distance::Isa> {
    use dem::distance::Isa;
    [Isa::Avx512, Isa::Avx2, Isa::Baseline]
        .into_iter()
        .filter(|i| i.available() == *i)
        .collect()
}

/// Every body's position and angular momentum, as bits: two runs moved the
/// same when these are equal, step by step.
pub fn motion_bits(world: &dem::world::World) -> Vec<u64> {
    world
        .bodies
        .iter()
        .flat_map(|b| b.x.to_array().into_iter().chain(b.l.to_array()))
        .map(f64::to_bits)
        .collect()
}

/// The `[[materials]]` of the granular validations' reduced scenes (silo,
/// drum): glass-like grains and stiffer steel walls, restitution 0.4, with
/// the given halo and frictions.
pub fn grains_and_walls(halo: f64, grain_friction: f64, wall_friction: f64) -> String {
    format!(
        r#"
        [[materials]]
        name = "grain"
        density = 2500.0
        stiffness = 50000.0
        restitution = 0.4
        halo = {halo:e}
        friction = {grain_friction}
        [[materials]]
        name = "wall"
        density = 7800.0
        stiffness = 500000.0
        restitution = 0.4
        halo = {halo:e}
        friction = {wall_friction}
        "#
    )
}
