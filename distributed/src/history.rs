//! Per-contact history at a migration: each contact's state lives on the
//! rank that computes the contact, the owner of its *home* particle (the
//! lower id, or the particle of a pair with an obstacle), and moves with it.
//! The effects' state is reached through `dem::effects::ContactHistory`
//! only: rows of numbers, each starting with the contact's two body ids.

use dem::effects::ContactHistory;

/// The home particle of a contact of bodies `a` < `b`.
pub fn home(a: u32, b: u32, is_obstacle: impl Fn(u32) -> bool) -> u32 {
    if is_obstacle(a) {
        b
    } else {
        a
    }
}

/// Takes out of `history` the rows whose home particle leaves this rank
/// (`me`), per destination rank: `new_owner` of this rank's particles.
/// Refused if a row's home particle is not one of them (the rows live with
/// their home particle: a bug otherwise).
pub fn leaving(
    history: &mut dyn ContactHistory,
    me: i32,
    size: usize,
    is_obstacle: impl Fn(u32) -> bool,
    new_owner: impl Fn(u32) -> Option<i32>,
) -> Result<Vec<Vec<f64>>, String> {
    let row = history.row_len();
    let mut lost = None;
    let taken = history.take_rows(&mut |a, b| {
        let h = home(a, b, &is_obstacle);
        match new_owner(h) {
            Some(r) => r != me,
            None => {
                lost = Some(h);
                false
            }
        }
    });
    if let Some(h) = lost {
        return Err(format!(
            "contact history of particle {h}, which this rank does not own"
        ));
    }
    let mut outbox = vec![Vec::new(); size];
    for r in taken.chunks_exact(row) {
        let h = home(r[0] as u32, r[1] as u32, &is_obstacle);
        let to = new_owner(h).expect("checked above") as usize;
        outbox[to].extend_from_slice(r);
    }
    Ok(outbox)
}

/// History rows in their order: lexicographic, as `ContactHistory::rows`
/// writes them (rows of `row` numbers; 0: none).
pub fn sorted_rows(rows: Vec<f64>, row: usize) -> Vec<f64> {
    if row == 0 {
        return rows;
    }
    let mut chunks: Vec<&[f64]> = rows.chunks_exact(row).collect();
    chunks.sort_by(|x, y| {
        x.iter()
            .zip(y.iter())
            .map(|(p, q)| p.total_cmp(q))
            .find(|o| o.is_ne())
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    chunks.into_iter().flatten().copied().collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use dem::effects::FrictionEffect;
    use dem::world::World;

    /// A friction history row of bodies a < b with spring `xi`.
    fn row(a: u32, b: u32, xi: f64) -> [f64; 8] {
        [a as f64, b as f64, 0.0, 1.0, 2.0, xi, 0.0, 0.0]
    }

    /// Rows follow their home particle to its new owner (an obstacle's pair
    /// follows the particle), stay when it stays, and arrive intact.
    #[test]
    fn rows_go_to_the_new_owner_of_their_home_particle() {
        let world = World::default();
        let mut history = FrictionEffect::new(&world);
        // Bodies 0-4 particles, 9 an obstacle; 2 has a lower id than 9,
        // and 9 pairs with 4 as (4, 9): home 4 either way.
        let rows = [
            row(0, 1, 0.5),
            row(1, 3, 0.25),
            row(2, 9, 0.125),
            row(4, 9, 1.0),
        ];
        let flat: Vec<f64> = rows.iter().flatten().copied().collect();
        history.add_rows(&flat, 10).unwrap();
        // This is rank 0; particles 0 and 4 move to rank 2, 1 to rank 1,
        // 2 stays.
        let owner = |id: u32| match id {
            0 | 4 => Some(2),
            1 => Some(1),
            2 => Some(0),
            _ => None,
        };
        let out = leaving(&mut history, 0, 3, |id| id == 9, owner).unwrap();
        let expect = |rs: &[[f64; 8]]| -> Vec<f64> { rs.iter().flatten().copied().collect() };
        assert_eq!(out[0], Vec::<f64>::new());
        assert_eq!(out[1], expect(&[row(1, 3, 0.25)]));
        assert_eq!(out[2], expect(&[row(0, 1, 0.5), row(4, 9, 1.0)]));
        assert_eq!(history.rows(), expect(&[row(2, 9, 0.125)]));
        // Arriving in any order, they take their place.
        let mut there = FrictionEffect::new(&world);
        let mut arrived = out[2].clone();
        arrived.rotate_left(8);
        there.add_rows(&arrived, 10).unwrap();
        assert_eq!(there.rows(), out[2]);
    }

    #[test]
    fn a_row_whose_home_particle_is_not_here_is_refused() {
        let world = World::default();
        let mut history = FrictionEffect::new(&world);
        history.add_rows(&row(5, 6, 0.0), 10).unwrap();
        let why = leaving(&mut history, 0, 2, |_| false, |_| None).unwrap_err();
        assert!(why.contains("particle 5"), "{why}");
    }

    #[test]
    fn rows_sort_as_the_effect_writes_them() {
        let rows: Vec<f64> = [row(3, 4, 0.0), row(0, 9, 1.0), row(0, 2, 2.0)]
            .iter()
            .flatten()
            .copied()
            .collect();
        let sorted = sorted_rows(rows, 8);
        let firsts: Vec<(f64, f64)> = sorted.chunks(8).map(|r| (r[0], r[1])).collect();
        assert_eq!(firsts, vec![(0.0, 2.0), (0.0, 9.0), (3.0, 4.0)]);
    }
}
