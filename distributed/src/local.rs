//! One rank's world: the particles it owns, copies (ghosts) of other ranks'
//! particles within contact reach of its own, and the obstacles within
//! reach, in increasing order of their ids in the scene.
//!
//! Kept in id order, the rank's bodies are numbered as one process numbers
//! them, up to gaps: body pairs, contacts and each body's force terms then
//! come in one process's order, which is what makes the results the same
//! bits on any rank count. What outlives a renumbering names bodies by id
//! (`World::id`): contacts, friction history, output.

use dem::body::Body;
use dem::contact::Role;
use dem::material::Material;
use dem::mesh::TriMesh;
use dem::world::World;
use glam::DVec3;

/// A body as it enters a rank's world.
#[derive(Debug, Clone)]
pub struct Entry {
    pub id: u32,
    pub body: Body,
    pub role: Role,
    /// The rank that owns it (this rank's for its own; -1 for an obstacle).
    pub owner: i32,
    /// The force and torque of the last evaluation (the next half kick
    /// needs them; zero for ghosts and obstacles).
    pub force: DVec3,
    pub torque: DVec3,
    /// Its contacts' work since the last partitioning: body pairs and
    /// triangle pairs examined with it as the home particle.
    pub work: [f64; 2],
}

/// One rank's bodies (see the module doc).
#[derive(Debug, Clone, Default)]
pub struct Local {
    /// Shapes and materials: all the scene's (one per kind of particle and
    /// per obstacle, not per body); bodies: this rank's, in id order.
    pub world: World,
    pub roles: Vec<Role>,
    /// Per body, the rank owning it (-1: an obstacle).
    pub owner: Vec<i32>,
    /// Per body, its contact halo.
    pub halos: Vec<f64>,
    /// The owned bodies, in increasing index (and id).
    pub owned: Vec<usize>,
    /// Per body, its [`Entry::work`].
    pub work: Vec<[f64; 2]>,
}

impl Local {
    /// A world of the scene's shapes and materials, with no bodies yet.
    pub fn new(shapes: Vec<TriMesh>, materials: Vec<Material>) -> Local {
        Local {
            world: World {
                shapes,
                materials,
                ..World::default()
            },
            ..Local::default()
        }
    }

    /// Makes the bodies of `streams`, each in increasing id, this rank's, in
    /// id order; returns each body's force and torque, by its new index.
    /// Refused if a stream is out of order or an id comes twice.
    pub fn merge(&mut self, streams: Vec<Vec<Entry>>) -> Result<Vec<(DVec3, DVec3)>, String> {
        self.admit(|_| false, (&[], &[]), streams)
    }

    /// Keeps the bodies `keep` names (by index), in place, and merges in
    /// the bodies of `streams`, each in increasing id: the rank's bodies are
    /// then the kept and the new, in id order. Returns each body's force and
    /// torque by its new index: a kept body's from `kept_loads` (by its old
    /// index; zero where it is short), a new body's from its entry.
    ///
    /// The merge is planned first (every body's new index, which also finds
    /// an id given twice before anything changes), then each kept body moves
    /// once, straight to its new slot, within the world's own array: a rank
    /// never holds its bodies twice, which at a redraw or a migration would
    /// be its peak of memory. Refused if a stream is out of order or an id
    /// comes twice.
    pub fn admit(
        &mut self,
        keep: impl Fn(usize) -> bool,
        kept_loads: (&[DVec3], &[DVec3]),
        streams: Vec<Vec<Entry>>,
    ) -> Result<Vec<(DVec3, DVec3)>, String> {
        for s in &streams {
            if let Some(w) = s.windows(2).find(|w| w[0].id >= w[1].id) {
                return Err(format!(
                    "bodies {} and {} came to this rank out of order",
                    w[0].id, w[1].id
                ));
            }
        }
        let kept: Vec<usize> = (0..self.world.bodies.len()).filter(|&i| keep(i)).collect();
        let w = &self.world;
        let plan = Plan::of(|i| w.id(i), &kept, &streams)?;
        self.move_kept(&kept, &plan.kept_to, &streams);
        let loads = self.describe(&kept, &plan, kept_loads, &streams);
        let w = &mut self.world;
        for (s, stream) in streams.into_iter().enumerate() {
            for (e, &k) in stream.into_iter().zip(&plan.new_to[s]) {
                w.bodies[k] = e.body;
            }
        }
        w.bodies.truncate(plan.total);
        self.owned = (0..self.roles.len())
            .filter(|&i| self.roles[i] == Role::Own)
            .collect();
        Ok(loads)
    }

    /// Moves each kept body (old index `kept[j]`) to its new index
    /// `to[j]`, in place. The order keeps every move's target free: a body
    /// moving down goes after every kept body below it has (those go lower
    /// still), a body moving up after every kept body above it, so a target
    /// holds a body that is not kept or one already moved away. The slots
    /// past the old end are filled first with a copy of an arriving body,
    /// which the arrivals then overwrite.
    fn move_kept(&mut self, kept: &[usize], to: &[usize], streams: &[Vec<Entry>]) {
        let w = &mut self.world;
        let total = to.len() + streams.iter().map(Vec::len).sum::<usize>();
        if total > w.bodies.len() {
            let filler = streams
                .iter()
                .flatten()
                .next()
                .expect("an arrival")
                .body
                .clone();
            w.bodies.reserve_exact(total - w.bodies.len());
            w.bodies.resize(total, filler);
        }
        let moves = kept.iter().zip(to);
        for (&from, &k) in moves.clone().filter(|&(&from, &k)| k < from) {
            w.bodies.swap(from, k);
        }
        for (&from, &k) in moves.rev().filter(|&(&from, &k)| k > from) {
            w.bodies.swap(from, k);
        }
    }

    /// Sets the bodies' ids, roles, owners, halos and work by their new
    /// index from the kept bodies' old ones and the arrivals; returns their
    /// loads.
    fn describe(
        &mut self,
        kept: &[usize],
        plan: &Plan,
        kept_loads: (&[DVec3], &[DVec3]),
        streams: &[Vec<Entry>],
    ) -> Vec<(DVec3, DVec3)> {
        let n = plan.total;
        let mut ids = vec![0; n];
        let mut roles = vec![Role::Own; n];
        let mut owner = vec![0; n];
        let mut halos = vec![0.0; n];
        let mut work = vec![[0.0; 2]; n];
        let mut loads = vec![(DVec3::ZERO, DVec3::ZERO); n];
        for (&i, &k) in kept.iter().zip(&plan.kept_to) {
            (ids[k], roles[k], owner[k]) = (self.world.id(i), self.roles[i], self.owner[i]);
            (halos[k], work[k]) = (self.halos[i], self.work[i]);
            loads[k] = (
                kept_loads.0.get(i).copied().unwrap_or_default(),
                kept_loads.1.get(i).copied().unwrap_or_default(),
            );
        }
        let materials = &self.world.materials;
        for (stream, to) in streams.iter().zip(&plan.new_to) {
            for (e, &k) in stream.iter().zip(to) {
                (ids[k], roles[k], owner[k]) = (e.id, e.role, e.owner);
                halos[k] = materials[e.body.material].halo.unwrap_or(0.0);
                (work[k], loads[k]) = (e.work, (e.force, e.torque));
            }
        }
        self.world.ids = ids;
        (self.roles, self.owner, self.halos, self.work) = (roles, owner, halos, work);
        loads
    }

    /// The index of the body of id `id`, if this rank holds it.
    pub fn index_of(&self, id: u32) -> Option<usize> {
        self.world.ids.binary_search(&id).ok()
    }

    /// Triangles of the owned bodies.
    pub fn owned_triangles(&self) -> u64 {
        let w = &self.world;
        self.owned
            .iter()
            .map(|&i| w.shapes[w.bodies[i].shape].triangles.len() as u64)
            .sum()
    }

    /// Triangles of all the bodies this rank holds.
    pub fn triangles(&self) -> u64 {
        let w = &self.world;
        w.bodies
            .iter()
            .map(|b| w.shapes[b.shape].triangles.len() as u64)
            .sum()
    }
}

/// Where a merge puts each body: the kept ones' new indices (in the order
/// of their old ones) and each stream's.
struct Plan {
    kept_to: Vec<usize>,
    new_to: Vec<Vec<usize>>,
    total: usize,
}

impl Plan {
    /// The merge in id order of the kept bodies (`kept`: old indices, in
    /// increasing order, whose ids `id` gives) and the streams (each in
    /// increasing id). Refused if an id comes twice.
    fn of(
        id: impl Fn(usize) -> u32,
        kept: &[usize],
        streams: &[Vec<Entry>],
    ) -> Result<Plan, String> {
        let mut plan = Plan {
            kept_to: Vec::with_capacity(kept.len()),
            new_to: streams
                .iter()
                .map(|s| Vec::with_capacity(s.len()))
                .collect(),
            total: 0,
        };
        let mut at = vec![0; streams.len()];
        let mut j = 0;
        let mut last: Option<u32> = None;
        loop {
            let head = (streams.iter().enumerate())
                .filter_map(|(s, v)| v.get(at[s]).map(|e| (e.id, s)))
                .min();
            let next_kept = kept.get(j).map(|&i| id(i));
            let from_stream = head.filter(|&(a, _)| next_kept.is_none_or(|b| a < b));
            let id = match (from_stream, next_kept) {
                (Some((a, s)), _) => {
                    at[s] += 1;
                    plan.new_to[s].push(plan.total);
                    a
                }
                (None, Some(b)) => {
                    j += 1;
                    plan.kept_to.push(plan.total);
                    b
                }
                (None, None) => return Ok(plan),
            };
            if last == Some(id) {
                return Err(format!("body {id} came to this rank twice"));
            }
            last = Some(id);
            plan.total += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dem::material::Material;
    use glam::{DMat3, DQuat};

    fn body(x: f64) -> Body {
        Body {
            shape: 0,
            material: 0,
            x: DVec3::new(x, 0.0, 0.0),
            q: DQuat::IDENTITY,
            v: DVec3::ZERO,
            l: DVec3::ZERO,
            inv_mass: 1.0,
            mass: 1.0,
            inv_inertia_body: DMat3::IDENTITY,
            inertia_body: DMat3::IDENTITY,
            drive: None,
            removed: false,
            pending: false,
        }
    }

    fn entry(id: u32, role: Role) -> Entry {
        Entry {
            id,
            body: body(id as f64),
            role,
            owner: if role == Role::Own { 0 } else { 1 },
            force: DVec3::splat(id as f64),
            torque: DVec3::ZERO,
            work: [0.0; 2],
        }
    }

    fn local() -> Local {
        let m = Material {
            name: "m".into(),
            density: 1.0,
            stiffness: None,
            restitution: None,
            halo: Some(0.5),
            friction: None,
        };
        let mesh = TriMesh {
            vertices: Vec::new(),
            triangles: Vec::new(),
        };
        Local::new(vec![mesh], vec![m])
    }

    /// Bodies come in any order and are kept in id order, with their roles,
    /// owners and forces; the owned are listed; an id is found by search.
    #[test]
    fn bodies_are_held_in_id_order() {
        let mut l = local();
        let streams = vec![
            vec![entry(2, Role::Own), entry(5, Role::Own)],
            vec![entry(9, Role::Ghost)],
            vec![],
            vec![entry(40, Role::Obstacle)],
        ];
        let loads = l.merge(streams).unwrap();
        assert_eq!(l.world.ids, vec![2, 5, 9, 40]);
        assert_eq!(
            l.roles,
            vec![Role::Own, Role::Own, Role::Ghost, Role::Obstacle]
        );
        assert_eq!(l.owned, vec![0, 1]);
        assert_eq!(l.world.bodies[2].x.x, 9.0);
        assert_eq!(loads[3].0, DVec3::splat(40.0));
        assert_eq!(l.halos, vec![0.5; 4]);
        assert_eq!((l.index_of(9), l.index_of(3)), (Some(2), None));
        let (f, t): (Vec<DVec3>, Vec<DVec3>) = loads.into_iter().unzip();
        // The owned stay, with their loads; new ghosts and obstacles come.
        let own = |i: usize| l.roles[i] == Role::Own;
        let own: Vec<bool> = (0..4).map(own).collect();
        let loads = l
            .admit(
                |i| own[i],
                (&f, &t),
                vec![
                    vec![entry(1, Role::Ghost), entry(7, Role::Ghost)],
                    vec![entry(3, Role::Obstacle), entry(40, Role::Obstacle)],
                ],
            )
            .unwrap();
        assert_eq!(l.world.ids, vec![1, 2, 3, 5, 7, 40]);
        let xs: Vec<f64> = l.world.bodies.iter().map(|b| b.x.x).collect();
        assert_eq!(xs, vec![1.0, 2.0, 3.0, 5.0, 7.0, 40.0]);
        assert_eq!(l.owned, vec![1, 3]);
        assert_eq!(l.roles[2], Role::Obstacle);
        assert_eq!(l.owner, vec![1, 0, 1, 0, 1, 1]);
        assert_eq!(loads[1].0, DVec3::splat(2.0));
        assert_eq!(loads[3].0, DVec3::splat(5.0));
        assert_eq!(loads[4].0, DVec3::splat(7.0));
    }

    /// Admitting is a merge by id: on many random worlds, kept sets and
    /// arrivals, the rank's bodies, roles, owners and loads are those of
    /// the kept and the arrived sorted by id, as a plain sort finds them.
    #[test]
    fn admitting_is_a_sort_of_the_kept_and_the_arrived_by_id() {
        let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
        let mut next = move |n: u64| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed % n
        };
        for _ in 0..300 {
            let mut l = local();
            let old: Vec<u32> = (0..200).filter(|_| next(3) == 0).collect();
            let role = |id: u32| [Role::Own, Role::Ghost, Role::Obstacle][id as usize % 3];
            l.merge(vec![old.iter().map(|&id| entry(id, role(id))).collect()])
                .unwrap();
            let keep: Vec<bool> = old.iter().map(|_| next(4) != 0).collect();
            let loads: Vec<DVec3> = old.iter().map(|&id| DVec3::splat(-f64::from(id))).collect();
            let kept: Vec<u32> = (old.iter().zip(&keep))
                .filter_map(|(&id, &k)| k.then_some(id))
                .collect();
            let mut streams = vec![Vec::new(); 1 + next(3) as usize];
            let arriving: Vec<u32> = (0..200).filter(|id| !kept.contains(id)).collect();
            for id in arriving {
                if next(4) != 0 {
                    continue;
                }
                let s = next(streams.len() as u64) as usize;
                streams[s].push(entry(id, Role::Ghost));
            }
            let mut want: Vec<(u32, Role, f64)> = (kept.iter())
                .map(|&id| (id, role(id), -f64::from(id)))
                .chain(streams.iter().flatten().map(|e| (e.id, e.role, e.force.x)))
                .collect();
            want.sort_by_key(|w| w.0);
            let got = l.admit(|i| keep[i], (&loads, &loads), streams).unwrap();
            let ids: Vec<u32> = want.iter().map(|w| w.0).collect();
            assert_eq!(l.world.ids, ids);
            let xs: Vec<f64> = l.world.bodies.iter().map(|b| b.x.x).collect();
            let want_x: Vec<f64> = ids.iter().map(|&id| f64::from(id)).collect();
            assert_eq!(xs, want_x);
            let roles: Vec<Role> = want.iter().map(|w| w.1).collect();
            assert_eq!(l.roles, roles);
            let owners: Vec<i32> = roles.iter().map(|&r| i32::from(r != Role::Own)).collect();
            assert_eq!(l.owner, owners);
            let f: Vec<f64> = got.iter().map(|g| g.0.x).collect();
            assert_eq!(f, want.iter().map(|w| w.2).collect::<Vec<_>>());
            let owned: Vec<usize> = (0..ids.len()).filter(|&i| roles[i] == Role::Own).collect();
            assert_eq!(l.owned, owned);
            assert_eq!(l.halos, vec![0.5; ids.len()]);
        }
    }

    /// Kept in place, a kept body whose id arrives again is refused.
    #[test]
    fn a_kept_body_arriving_again_is_refused() {
        let mut l = local();
        l.merge(vec![vec![entry(2, Role::Own), entry(5, Role::Own)]])
            .unwrap();
        let why = l
            .admit(|_| true, (&[], &[]), vec![vec![entry(5, Role::Ghost)]])
            .unwrap_err();
        assert!(why.contains("body 5") && why.contains("twice"), "{why}");
    }

    #[test]
    fn a_body_given_twice_or_out_of_order_is_refused() {
        let mut l = local();
        let why = l
            .merge(vec![vec![entry(3, Role::Own)], vec![entry(3, Role::Ghost)]])
            .unwrap_err();
        assert!(why.contains("body 3"), "{why}");
        let why = l
            .merge(vec![vec![entry(4, Role::Own), entry(3, Role::Own)]])
            .unwrap_err();
        assert!(why.contains("out of order"), "{why}");
    }
}
