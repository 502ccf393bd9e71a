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
    /// Each body is moved once (a merge, not a sort of bodies hundreds of
    /// bytes long). Refused if a stream is out of order or an id comes twice.
    pub fn merge(&mut self, streams: Vec<Vec<Entry>>) -> Result<Vec<(DVec3, DVec3)>, String> {
        for s in &streams {
            if let Some(w) = s.windows(2).find(|w| w[0].id >= w[1].id) {
                return Err(format!(
                    "bodies {} and {} came to this rank out of order",
                    w[0].id, w[1].id
                ));
            }
        }
        let total: usize = streams.iter().map(Vec::len).sum();
        let w = &mut self.world;
        w.bodies.clear();
        w.ids.clear();
        self.roles.clear();
        self.owner.clear();
        self.halos.clear();
        self.owned.clear();
        self.work.clear();
        w.bodies.reserve_exact(total);
        let mut loads = Vec::with_capacity(total);
        let mut heads: Vec<_> = streams
            .into_iter()
            .map(|s| s.into_iter().peekable())
            .collect();
        loop {
            let next = heads
                .iter_mut()
                .enumerate()
                .filter_map(|(k, h)| h.peek().map(|e| (e.id, k)))
                .min();
            let Some((id, k)) = next else { break };
            let e = heads[k].next().expect("peeked");
            if w.ids.last() == Some(&id) {
                let role = self.roles.last().expect("a body before");
                return Err(format!(
                    "body {id} came to this rank twice (as {role:?} and {:?})",
                    e.role
                ));
            }
            let i = w.bodies.len();
            let halo = w.materials[e.body.material].halo.unwrap_or(0.0);
            w.ids.push(e.id);
            w.bodies.push(e.body);
            self.roles.push(e.role);
            self.owner.push(e.owner);
            self.halos.push(halo);
            self.work.push(e.work);
            if e.role == Role::Own {
                self.owned.push(i);
            }
            loads.push((e.force, e.torque));
        }
        Ok(loads)
    }

    /// Takes this rank's own bodies out, as entries in id order with their
    /// forces from `loads` (by index); the rest are dropped.
    pub fn take_owned(&mut self, loads: (&[DVec3], &[DVec3])) -> Vec<Entry> {
        let bodies = std::mem::take(&mut self.world.bodies);
        let mut out = Vec::with_capacity(self.owned.len());
        for (i, body) in bodies.into_iter().enumerate() {
            if self.roles[i] != Role::Own {
                continue;
            }
            out.push(Entry {
                id: self.world.ids[i],
                body,
                role: Role::Own,
                owner: self.owner[i],
                force: loads.0.get(i).copied().unwrap_or_default(),
                torque: loads.1.get(i).copied().unwrap_or_default(),
                work: self.work[i],
            });
        }
        out
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
        let back = l.take_owned((&f, &t));
        let ids: Vec<u32> = back.iter().map(|e| e.id).collect();
        assert_eq!(ids, vec![2, 5]);
        assert_eq!(back[1].force, DVec3::splat(5.0));
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
