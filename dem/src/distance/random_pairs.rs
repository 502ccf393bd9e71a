//! The benchmark workload of the papers: pairs with vertices uniform in the unit cube.

use super::Triangle;
use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

/// `n` random triangle pairs, vertices uniform in [0, 1)^3, reproducible from `seed`.
pub fn random_unit_pairs(n: usize, seed: u64) -> Vec<(Triangle, Triangle)> {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut v = || DVec3::new(rng.random(), rng.random(), rng.random());
    (0..n).map(|_| ([v(), v(), v()], [v(), v(), v()])).collect()
}
