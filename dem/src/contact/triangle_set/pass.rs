//! A detection pass's access to a [`TriangleSet`]: the one way to fill the
//! groups of a set that follows the world lazily, and to read triangles
//! while other threads may be filling other groups.
//!
//! A set followed lazily ([`TriangleSet::follow_world_lazily`]) leaves the
//! moving bodies' triangles to whichever detection task needs them first;
//! the tasks fill them through a shared reference, on several threads at
//! once. Reading a group's triangles while another thread writes them would
//! be a data race, so the types order the two:
//!
//! - a [`PassSet`] over a set that may have stale groups is made from
//!   `&mut TriangleSet` ([`PassSet::new`]): while the pass lasts, nothing
//!   else reads the set. Over a set whose groups are all current, nothing is
//!   ever written, and a shared borrow will do ([`PassSet::of_current`]).
//! - [`PassSet::fill`] returns a [`Filled`] group: the proof that its
//!   triangles are current, and stay so for the pass (a group goes stale
//!   only through `&mut TriangleSet`). Triangles are read through the
//!   [`Part`]s it hands out; ghosts are never filled, so they are readable
//!   through any group's proof.
//! - [`PassPairs`], the triangle pairs the kernel reads in place, takes a
//!   pair only from two parts of its own set, checked on entry
//!   ([`PassPairs::between`]).

use super::{BodyGroup, SetTriangle, Slot, TriangleKey, TriangleSet, CURRENT, FILLING, STALE};
use crate::contact::bounds::Bounds;
use crate::distance::{PairSource, Triangle};
use crate::prefetch::prefetch;
use crate::world::World;
use glam::DVec3;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, Ordering};

/// Spins of a thread waiting for another to fill a group before it yields
/// its core: a fill takes about a microsecond, a few hundred spins.
const SPINS_BEFORE_YIELD: u32 = 1000;

/// One detection pass's view of a set (see the module doc). Not `Debug`:
/// printing the set would read slots that other threads may be filling.
#[derive(Clone, Copy)]
pub(crate) struct PassSet<'p> {
    set: &'p TriangleSet,
}

/// A group whose owned triangles are current for the whole pass `'p`.
#[derive(Clone, Copy)]
pub(crate) struct Filled<'p> {
    set: &'p TriangleSet,
    g: usize,
}

/// Consecutive triangles of one group, readable for the whole pass `'p`,
/// with the union of their inflated boxes.
#[derive(Clone, Copy)]
pub(crate) struct Part<'p> {
    set: &'p TriangleSet,
    start: usize,
    triangles: &'p [SetTriangle],
    pub bounds: Bounds,
}

/// Triangle pairs of one pass, by index into its set, for the kernel to
/// read in place: each pair enters from two readable parts of that set.
pub(crate) struct PassPairs<'p, 'b> {
    set: &'p TriangleSet,
    pairs: &'b mut Vec<(u32, u32)>,
}

impl<'p> PassSet<'p> {
    /// A pass over `set`, whatever the state of its groups.
    pub(crate) fn new(set: &'p mut TriangleSet) -> PassSet<'p> {
        PassSet { set }
    }

    /// A pass over a set none of whose groups is stale (any set not followed
    /// lazily): nothing is filled, so the set may be shared meanwhile.
    /// `None` if some group is stale.
    pub(crate) fn of_current(set: &'p TriangleSet) -> Option<PassSet<'p>> {
        let current = set
            .fresh
            .0
            .iter()
            .all(|s| s.load(Ordering::Acquire) == CURRENT);
        current.then_some(PassSet { set })
    }

    /// One group per body present, in body order. A group's `owned_box` is
    /// as of the set's last full update: [`Filled::owned`] has the current one.
    pub(crate) fn groups(&self) -> &'p [BodyGroup] {
        &self.set.groups
    }

    pub(crate) fn key(&self, i: usize) -> TriangleKey {
        self.set.keys[i]
    }

    /// Makes group `g`'s triangles current (a no-op unless the set follows
    /// the world lazily and `g` moved): the first caller computes them, a
    /// concurrent caller waits for it. `vertices` is scratch.
    pub(crate) fn fill(&self, g: usize, world: &World, vertices: &mut Vec<DVec3>) -> Filled<'p> {
        let filled = Filled { set: self.set, g };
        let Some(state) = self.set.fresh.0.get(g) else {
            return filled;
        };
        let mut spins = 0u32;
        loop {
            // Load before trying to claim: most calls find the group current,
            // and a compare-exchange takes the cache line exclusively even when
            // it fails, so both threads asking about the same group would
            // bounce the line between their cores on every body pair.
            match state.load(Ordering::Acquire) {
                CURRENT => return filled,
                STALE => {
                    if state
                        .compare_exchange(STALE, FILLING, Ordering::Acquire, Ordering::Acquire)
                        .is_ok()
                    {
                        break;
                    }
                }
                // Another task is filling it: a microsecond or so, unless
                // its thread lost its core (threads or ranks beyond the
                // cores): then give the core up rather than spin out the
                // time slice.
                _ if spins < SPINS_BEFORE_YIELD => {
                    spins += 1;
                    std::hint::spin_loop();
                }
                _ => std::thread::yield_now(),
            }
        }
        self.write_group(g, world, vertices);
        state.store(CURRENT, Ordering::Release);
        filled
    }

    /// Computes group `g`'s triangles and box from its body's pose. Only
    /// for the thread that moved the group from STALE to FILLING.
    fn write_group(&self, g: usize, world: &World, vertices: &mut Vec<DVec3>) {
        let set = self.set;
        let group = &set.groups[g];
        let body = &world.bodies[group.body as usize];
        let halo = set.halos[g];
        let mesh = &world.shapes[body.shape];
        if !body.is_present() {
            // Gone: a box that overlaps nothing, so no pair reads its slots.
            // SAFETY: as for the box below: the group's own slot, while FILLING.
            unsafe { *set.filled_boxes[g].0.get() = Bounds::EMPTY };
            return;
        }
        super::world_vertices(body, mesh, vertices);
        let mut bbox = Bounds::EMPTY;
        for (slot, t) in set.triangles[group.owned.clone()]
            .iter()
            .zip(&mesh.triangles)
        {
            let v = [
                vertices[t[0] as usize],
                vertices[t[1] as usize],
                vertices[t[2] as usize],
            ];
            let triangle = SetTriangle::new(v, halo);
            // SAFETY: the caller moved the group from STALE to FILLING, so this
            // thread alone writes its slots, and no one reads them: a reader
            // holds a `Filled` for the group, made only once it is CURRENT
            // (stored by the caller with Release after this returns, loaded
            // with Acquire in `fill`). Groups' slots are disjoint.
            unsafe { *slot.0.get() = triangle };
            bbox = bbox.union(&triangle.bounds);
        }
        // SAFETY: as for the triangles: the group's own slot, while FILLING.
        unsafe { *set.filled_boxes[g].0.get() = bbox };
    }

    /// Starts loading the pose of group `g`'s body into this core's cache if
    /// the group is stale, for a [`Self::fill`] on it soon after.
    ///
    /// Why: on several threads the pose was last written by whichever core
    /// integrated the body, and waiting for its cache line took a quarter of
    /// the fills' time at two threads (hopper, docs/dem.md).
    #[inline]
    pub(crate) fn prefetch_pose(&self, g: usize, world: &World) {
        let set = self.set;
        let (Some(state), Some(group)) = (set.fresh.0.get(g), set.groups.get(g)) else {
            return;
        };
        if state.load(Ordering::Relaxed) != STALE {
            return;
        }
        let Some(body) = world.bodies.get(group.body as usize) else {
            return;
        };
        prefetch(&body.shape);
        prefetch(&body.x);
        prefetch(&body.q);
    }

    /// Fills stale groups, last to first, until `stop` is set. For a thread
    /// that would otherwise wait (see `Detector::broad_and_narrow`); the
    /// detection tasks fill whatever is left.
    pub(crate) fn prefill_until(&self, world: &World, stop: &AtomicBool) {
        let mut vertices = Vec::new();
        for g in (0..self.set.fresh.0.len()).rev() {
            if stop.load(Ordering::Relaxed) {
                return;
            }
            self.fill(g, world, &mut vertices);
        }
    }
}

impl<'p> Filled<'p> {
    pub(crate) fn group(&self) -> &'p BodyGroup {
        &self.set.groups[self.g]
    }

    /// The group's owned triangles, with their current box.
    pub(crate) fn owned(&self) -> Part<'p> {
        let set = self.set;
        let bounds = match set.filled_boxes.get(self.g) {
            // SAFETY: this group is current for 'p (see `Filled`): its box is
            // no longer written.
            Some(b) => unsafe { b.get() },
            None => self.group().owned_box,
        };
        // SAFETY: as for the box: the group's owned slots are current and
        // not written for 'p.
        unsafe { self.part(self.group().owned.clone(), bounds) }
    }

    /// The group's ghost triangles, with their box.
    pub(crate) fn ghosts(&self) -> Part<'p> {
        // SAFETY: ghost slots are written only through `&mut TriangleSet`,
        // which the pass's borrow excludes.
        unsafe { self.part(self.group().ghost.clone(), self.group().ghost_box) }
    }

    /// # Safety
    /// No slot of `range` is written during `'p`.
    unsafe fn part(&self, range: Range<usize>, bounds: Bounds) -> Part<'p> {
        let slots: &'p [Slot<SetTriangle>] = &self.set.triangles[range.clone()];
        // SAFETY: `Slot<T>` is a transparent `UnsafeCell<T>`, itself laid out
        // as `T`; the caller guarantees no writes during 'p.
        let triangles = unsafe {
            std::slice::from_raw_parts(slots.as_ptr().cast::<SetTriangle>(), slots.len())
        };
        Part {
            set: self.set,
            start: range.start,
            triangles,
            bounds,
        }
    }
}

impl<'p> Part<'p> {
    /// The part's indices in the set.
    pub(crate) fn range(&self) -> Range<usize> {
        self.start..self.start + self.triangles.len()
    }

    /// The part's triangles: the set's triangle i is at i - `range().start`.
    pub(crate) fn triangles(&self) -> &'p [SetTriangle] {
        self.triangles
    }
}

impl<'p, 'b> PassPairs<'p, 'b> {
    /// No pairs yet, kept in `buffer` (cleared).
    pub(crate) fn new(set: PassSet<'p>, buffer: &'b mut Vec<(u32, u32)>) -> PassPairs<'p, 'b> {
        buffer.clear();
        PassPairs {
            set: set.set,
            pairs: buffer,
        }
    }

    /// Where pairs of a triangle of `a` and one of `b` are appended.
    ///
    /// # Panics
    /// If a part is of another set.
    pub(crate) fn between(&mut self, a: &Part<'p>, b: &Part<'p>) -> PairsBetween<'_> {
        assert!(
            std::ptr::eq(a.set, self.set) && std::ptr::eq(b.set, self.set),
            "parts of another set"
        );
        PairsBetween {
            a: a.range(),
            b: b.range(),
            pairs: self.pairs,
        }
    }

    pub(crate) fn as_slice(&self) -> &[(u32, u32)] {
        self.pairs
    }

    /// The pairs for the kernel to read in place.
    pub(crate) fn source(&self) -> PairsInPlace<'_> {
        PairsInPlace {
            pairs: self.pairs,
            slots: &self.set.triangles,
        }
    }
}

/// Appends to a [`PassPairs`] the pairs between two of its set's parts.
pub(crate) struct PairsBetween<'s> {
    a: Range<usize>,
    b: Range<usize>,
    pairs: &'s mut Vec<(u32, u32)>,
}

impl PairsBetween<'_> {
    /// Appends `pairs` (i of part a, j of part b).
    ///
    /// # Panics
    /// If a pair's triangle is not in its part.
    pub(crate) fn extend(&mut self, pairs: &[(u32, u32)]) {
        let (a, b) = (&self.a, &self.b);
        // Without early exit: the pairs are almost always inside, and a
        // branch-free fold runs in SIMD lanes.
        let inside = pairs.iter().fold(true, |inside, &(i, j)| {
            inside & a.contains(&(i as usize)) & b.contains(&(j as usize))
        });
        assert!(inside, "a triangle pair outside its parts");
        self.pairs.extend_from_slice(pairs);
    }
}

/// The triangles of [`PassPairs`], read where they are: one indirection
/// less than through `PassPairs`, in the kernel's gather loop.
pub(crate) struct PairsInPlace<'a> {
    pairs: &'a [(u32, u32)],
    slots: &'a [Slot<SetTriangle>],
}

impl PairSource for PairsInPlace<'_> {
    fn len(&self) -> usize {
        self.pairs.len()
    }

    #[inline]
    fn pair(&self, k: usize) -> (&Triangle, &Triangle) {
        let (i, j) = self.pairs[k];
        // SAFETY: `PassPairs::extend` took the pair only from two parts of
        // this set, and a part's slots are not written for the pass (see
        // `Part`), which this borrow of the `PassPairs` lies within.
        unsafe {
            (
                &(*self.slots[i as usize].0.get()).vertices,
                &(*self.slots[j as usize].0.get()).vertices,
            )
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scene;

    /// The drop scene, and its triangles updated at once or followed lazily.
    fn drop_scene(lazily: bool) -> (World, TriangleSet) {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/drop.toml");
        let world = Scene::load(&path).unwrap().world;
        let halos = world.per_body(|m| m.halo);
        let mut set = TriangleSet::default();
        if lazily {
            set.follow_world_lazily(&world, &halos);
        } else {
            set.update_from_world(&world, &halos);
        }
        (world, set)
    }

    /// A lazily followed set, filled by a pass's concurrent tasks, reads the
    /// same bits as a set updated at once.
    #[test]
    fn filled_groups_read_what_an_eager_update_computes() {
        use rayon::prelude::*;
        let (_, eager) = drop_scene(false);
        let (world, mut lazy) = drop_scene(true);
        assert!(
            PassSet::of_current(&lazy).is_none(),
            "moving bodies are stale"
        );
        let pass = PassSet::new(&mut lazy);
        let n = pass.groups().len();
        // Every group asked for by several tasks at once, in both orders.
        let order: Vec<usize> = (0..n).chain((0..n).rev()).chain(0..n).collect();
        order.par_iter().for_each_init(Vec::new, |vertices, &g| {
            let filled = pass.fill(g, &world, vertices);
            let part = filled.owned();
            for (i, t) in part.range().zip(part.triangles()) {
                assert_eq!(t, eager.triangle(i), "triangle {i}");
            }
            assert_eq!(part.bounds, eager.groups()[g].owned_box, "group {g}");
        });
    }

    /// A pair is taken only from parts of the pass's own set.
    #[test]
    #[should_panic(expected = "outside its parts")]
    fn a_pair_outside_its_parts_is_refused() {
        let (world, set) = drop_scene(false);
        let pass = PassSet::of_current(&set).expect("updated at once: all current");
        let mut v = Vec::new();
        let a = pass.fill(0, &world, &mut v).owned();
        let b = pass.fill(1, &world, &mut v).owned();
        let mut buffer = Vec::new();
        let mut pairs = PassPairs::new(pass, &mut buffer);
        let (i, j) = (a.range().start as u32, b.range().start as u32);
        pairs.between(&a, &b).extend(&[(i, j)]);
        assert_eq!(pairs.as_slice().len(), 1);
        pairs.between(&a, &b).extend(&[(j, i)]);
    }

    #[test]
    #[should_panic(expected = "another set")]
    fn a_part_of_another_set_is_refused() {
        let (world, one) = drop_scene(false);
        let other = one.clone();
        let (p, q) = (
            PassSet::of_current(&one).unwrap(),
            PassSet::of_current(&other).unwrap(),
        );
        let mut v = Vec::new();
        let a = q.fill(0, &world, &mut v).owned();
        let mut buffer = Vec::new();
        let mut pairs = PassPairs::new(p, &mut buffer);
        pairs.between(&a, &a);
    }

    /// A set with stale groups is filled only by a pass that borrows it
    /// exclusively; once all are filled, a shared borrow will do.
    #[test]
    fn a_stale_set_is_not_shared_with_a_pass() {
        let (world, mut lazy) = drop_scene(true);
        assert!(PassSet::of_current(&lazy).is_none());
        let mut v = Vec::new();
        let pass = PassSet::new(&mut lazy);
        for g in 0..pass.groups().len() {
            pass.fill(g, &world, &mut v);
        }
        assert!(PassSet::of_current(&lazy).is_some(), "all filled");
    }
}
