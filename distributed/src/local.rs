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
    /// The kept bodies are not taken out and put back: the merge runs from
    /// the back of the world's own array, so that a rank never holds its
    /// bodies twice, which at a redraw or a migration would be its peak of
    /// memory. Refused if a stream is out of order or an id comes twice.
    pub fn admit(
        &mut self,
        keep: impl Fn(usize) -> bool,
        kept_loads: (&[DVec3], &[DVec3]),
        mut streams: Vec<Vec<Entry>>,
    ) -> Result<Vec<(DVec3, DVec3)>, String> {
        for s in &streams {
            if let Some(w) = s.windows(2).find(|w| w[0].id >= w[1].id) {
                return Err(format!(
                    "bodies {} and {} came to this rank out of order",
                    w[0].id, w[1].id
                ));
            }
        }
        let kept = self.keep_in_place(keep, kept_loads);
        let arriving: usize = streams.iter().map(Vec::len).sum();
        let n = kept.ids.len();
        let total = n + arriving;
        let w = &mut self.world;
        if let Some(e) = streams.iter().flatten().next() {
            let filler = e.body.clone();
            w.bodies.reserve_exact(arriving);
            w.bodies.resize(total, filler);
        }
        // From the back: the largest id not yet placed goes to slot k.
        let mut placed = Placed::with_capacity(total);
        let mut i = n;
        for k in (0..total).rev() {
            let from_stream = streams
                .iter()
                .enumerate()
                .filter_map(|(s, v)| v.last().map(|e| (e.id, s)))
                .max();
            let kept_id = i.checked_sub(1).map(|j| kept.ids[j]);
            let id = match (from_stream, kept_id) {
                (Some((a, s)), b) if b.is_none_or(|b| a > b) => {
                    let e = streams[s].pop().expect("a last entry");
                    let halo = w.materials[e.body.material].halo.unwrap_or(0.0);
                    w.bodies[k] = e.body;
                    placed.push(e.id, e.role, e.owner, halo, e.work, (e.force, e.torque));
                    e.id
                }
                (_, b) => {
                    let b = b.expect("total counts every body");
                    i -= 1;
                    w.bodies.swap(k, i);
                    placed.push(
                        b,
                        kept.roles[i],
                        kept.owner[i],
                        kept.halos[i],
                        kept.work[i],
                        kept.loads[i],
                    );
                    b
                }
            };
            if let Some(&after) = placed.ids.iter().rev().nth(1) {
                if after == id {
                    return Err(format!("body {id} came to this rank twice"));
                }
            }
        }
        Ok(self.install(placed))
    }

    /// Compacts the world to the bodies `keep` names, in place, and returns
    /// what they carry besides the bodies themselves.
    fn keep_in_place(
        &mut self,
        keep: impl Fn(usize) -> bool,
        loads: (&[DVec3], &[DVec3]),
    ) -> Placed {
        let w = &mut self.world;
        let n = w.bodies.len();
        let flags: Vec<bool> = (0..n).map(&keep).collect();
        let mut at = 0;
        w.bodies.retain(|_| {
            at += 1;
            flags[at - 1]
        });
        let mut kept = Placed::with_capacity(w.bodies.len());
        for i in (0..n).filter(|&i| flags[i]) {
            let load = (
                loads.0.get(i).copied().unwrap_or_default(),
                loads.1.get(i).copied().unwrap_or_default(),
            );
            let (id, role, owner) = (w.id(i), self.roles[i], self.owner[i]);
            kept.push(id, role, owner, self.halos[i], self.work[i], load);
        }
        kept
    }

    /// Takes `placed` (gathered from the last body to the first) as the
    /// bodies' ids, roles, owners, halos and work; returns their loads.
    fn install(&mut self, mut p: Placed) -> Vec<(DVec3, DVec3)> {
        p.reverse();
        self.world.ids = p.ids;
        self.roles = p.roles;
        self.owner = p.owner;
        self.halos = p.halos;
        self.work = p.work;
        self.owned = (0..self.roles.len())
            .filter(|&i| self.roles[i] == Role::Own)
            .collect();
        p.loads
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

/// What a rank keeps of each body besides the body itself, in a merge.
#[derive(Default)]
struct Placed {
    ids: Vec<u32>,
    roles: Vec<Role>,
    owner: Vec<i32>,
    halos: Vec<f64>,
    work: Vec<[f64; 2]>,
    loads: Vec<(DVec3, DVec3)>,
}

impl Placed {
    fn with_capacity(n: usize) -> Placed {
        Placed {
            ids: Vec::with_capacity(n),
            roles: Vec::with_capacity(n),
            owner: Vec::with_capacity(n),
            halos: Vec::with_capacity(n),
            work: Vec::with_capacity(n),
            loads: Vec::with_capacity(n),
        }
    }

    fn push(
        &mut self,
        id: u32,
        role: Role,
        owner: i32,
        halo: f64,
        work: [f64; 2],
        load: (DVec3, DVec3),
    ) {
        self.ids.push(id);
        self.roles.push(role);
        self.owner.push(owner);
        self.halos.push(halo);
        self.work.push(work);
        self.loads.push(load);
    }

    fn reverse(&mut self) {
        self.ids.reverse();
        self.roles.reverse();
        self.owner.reverse();
        self.halos.reverse();
        self.work.reverse();
        self.loads.reverse();
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
