//! Contacts between the features of two bodies: where their surfaces,
//! rounded by the halos, actually overlap.
//!
//! Each body is its mesh rounded by its halo (a sphere of that radius swept
//! over the surface). Two bodies touch where the rounded surfaces overlap:
//! where a point of one comes within the halo sum `reach` of the other. The
//! triangle kernel finds which triangle pairs are within reach; the contacts
//! are then built on the bodies' features (faces, creases and corners, see
//! [`Features`]), never on the triangles:
//!
//! - **corner–body**: a corner c of one body and its closest feature on the
//!   other, found in that body's Voronoi regions: a face F when c projects
//!   into F (closed region; gap h = signed distance to F's plane), a convex
//!   crease when c lies in the open wedge between its two faces' regions
//!   (gap |c − q|, q the closest point of the crease), a corner w when c
//!   lies in w's region ((c − w)·(u − w) ≤ 0 for every neighbour u of w).
//!   Every corner within reach gets its contact: these are the corners of the
//!   region where the bodies overlap.
//! - **crease–crease**: two convex creases whose lines' closest points lie
//!   inside both (open) creases, facing each other: gap g = (p − q)·n̂ with
//!   n̂ ∥ u_a × u_b, signed so that it leaves b's crease outward. These are
//!   the corners of the overlap where an edge of one body crosses an edge of
//!   the other.
//!
//! A contact's depth is δ = reach − gap > 0, its normal the unit gradient of
//! the gap (from b to a), its point the midpoint of the closest points. Its
//! spring energy k δ²/2 is then a potential of the two poses whose gradient is
//! the force k δ along the normal through that point, and a contact appears
//! and leaves with δ = 0: the contact law conserves energy (see
//! `effects::contact`). A flat face lying on another carries its load at the
//! corners of their overlap, so the torque it exerts depends on where the
//! faces overlap, never on which closest points the triangle kernel returned;
//! a box meshed with 12 triangles or with 192 has the same corners and
//! creases, and the same contacts.
//!
//! Boundaries between regions are assigned to exactly one contact (faces
//! closed, creases open, corners closed except along a face normal), and
//! every quantity is computed from the feature's own canonical data (the
//! face's plane, a crease's end corners, an edge oriented from its lower
//! vertex), so two triangles that find the same contact find it bit for bit
//! alike, and it is kept once.

use super::TriangleContact;
use crate::body::Body;
use crate::mesh::{Features, TriMesh, FLAT_ANGLE, NO_CREASE};
use crate::world::World;
use glam::{DMat3, DVec3};
use std::cell::RefCell;

/// Which features of bodies a and b touch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[repr(u8)]
pub enum FeatureKind {
    /// A corner of a on a face of b.
    CornerFace = 0,
    /// A face of a under a corner of b.
    FaceCorner = 1,
    /// A corner of a on a crease of b.
    CornerCrease = 2,
    /// A crease of a under a corner of b.
    CreaseCorner = 3,
    CornerCorner = 4,
    CreaseCrease = 5,
}

impl FeatureKind {
    pub const ALL: [FeatureKind; 6] = [
        FeatureKind::CornerFace,
        FeatureKind::FaceCorner,
        FeatureKind::CornerCrease,
        FeatureKind::CreaseCorner,
        FeatureKind::CornerCorner,
        FeatureKind::CreaseCrease,
    ];

    pub fn from_index(i: u8) -> Option<FeatureKind> {
        FeatureKind::ALL.get(i as usize).copied()
    }
}

/// The name of a contact within its body pair: which feature of a (vertex,
/// face or crease index of a's shape) touches which feature of b.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct FeatureKey {
    pub kind: FeatureKind,
    pub on_a: u32,
    pub on_b: u32,
}

/// One contact between bodies `a` < `b`; the normal points from b to a.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    pub a: usize,
    pub b: usize,
    /// Which features touch: the contact's name from step to step (friction
    /// keeps its history under it).
    pub key: FeatureKey,
    pub point: DVec3,
    pub normal: DVec3,
    /// Overlap of the rounded surfaces, reach − gap (> 0).
    pub depth: f64,
    /// The share of its spring the contact carries (1 but for creases
    /// crossing near a corner or at a shallow angle, see `ramp` and
    /// `CROSSING_FADE_SINE`), and its gradient.
    pub weight: f64,
    pub gradient: WeightGradient,
}

/// Sines of angles below this make two creases parallel: their overlap is
/// carried by the corners at its ends.
const PARALLEL_SINE: f64 = 1e-12;

/// Below this sine of the angle between two creases (10°), their crossing's
/// contact fades out ([`ramp`] of the sine over it), leaving their overlap to
/// the corners at its ends, as for parallel creases. Where two creases
/// cross at an angle θ, a sideways move of one moves the crossing along the
/// creases 1/sin θ times as far, and so does the weight that ramps it near
/// their ends: unfaded, the weight's gradient, and the torque the spring's
/// energy exerts through it, would grow as 1/sin θ without bound, enough
/// at near-parallel creases to fling a resting grain off at hundreds of
/// metres per second in one step. Faded, they stay within a few times the
/// contact's own force, and the contact still appears and leaves with no
/// weight, so the energy stays continuous.
const CROSSING_FADE_SINE: f64 = 0.173_648_177_666_930_33;

/// Scratch reused between body pairs.
#[derive(Debug, Default)]
pub(crate) struct FeatureScratch {
    corners: Vec<(Side, u32, u32)>,
    creases: Vec<(u32, u32)>,
    found: Vec<Contact>,
    /// The two bodies' triangles as the queries read them.
    facets: [Memo<Facet>; 2],
    /// World positions of the two bodies' vertices, each computed once per
    /// body pair (and so the same bits wherever it is used).
    vertices: [Placed; 2],
}

/// Which body a corner belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Side {
    A,
    B,
}

/// One body as contact geometry sees it.
struct Solid<'a> {
    body: &'a Body,
    /// The body's rotation matrix: vertices are placed as the triangle set
    /// places them (`x + R v`), to the same bits.
    rotation: DMat3,
    mesh: &'a TriMesh,
    features: &'a Features,
    vertices: &'a Placed,
}

/// Meshes of at most this many vertices (grains) are placed whole when a
/// body pair starts: a grain's contacts read most of its vertices, and an
/// array read costs less than the memo's bookkeeping. Larger meshes (an
/// obstacle met by a small grain) are placed vertex by vertex, as read.
const PLACED_WHOLE: usize = 64;

/// World positions of one body's vertices for one body pair: all of them,
/// or those read so far.
#[derive(Debug, Default)]
struct Placed {
    whole: bool,
    all: Vec<DVec3>,
    some: RefCell<Memo<DVec3>>,
}

impl Placed {
    /// Ready for `body` (with `mesh` and `rotation`, its rotation matrix).
    fn reset(&mut self, body: &Body, mesh: &TriMesh, rotation: DMat3) {
        self.whole = mesh.vertices.len() <= PLACED_WHOLE;
        self.all.clear();
        if self.whole {
            let place = |&v: &DVec3| body.x + rotation * v;
            self.all.extend(mesh.vertices.iter().map(place));
        } else {
            self.some.get_mut().reset(mesh.vertices.len());
        }
    }
}

impl Solid<'_> {
    /// Vertex `v` in the world, `x + R v` either way, so the same bits.
    #[inline]
    fn vertex(&self, v: u32) -> DVec3 {
        let placed = self.vertices;
        if placed.whole {
            return placed.all[v as usize];
        }
        *placed.some.borrow_mut().get(v, || {
            self.body.x + self.rotation * self.mesh.vertices[v as usize]
        })
    }

    fn direction(&self, local: DVec3) -> DVec3 {
        self.rotation * local
    }
}

/// Appends the feature contacts of one body pair, given all its triangle
/// contacts (`group`, nonempty, all of bodies a < b), sorted by key; returns
/// how many are deeper than the halos (gap < 0).
pub(crate) fn append_feature_contacts(
    group: &[TriangleContact],
    world: &World,
    features: &[Features],
    halos: &[f64],
    scratch: &mut FeatureScratch,
    contacts: &mut Vec<Contact>,
) -> u64 {
    let (a, b) = (group[0].a.body as usize, group[0].b.body as usize);
    let mut caches = std::mem::take(&mut scratch.vertices);
    let rotations = [a, b].map(|i| DMat3::from_quat(world.bodies[i].q));
    for ((cache, i), rotation) in caches.iter_mut().zip([a, b]).zip(rotations) {
        let body = &world.bodies[i];
        cache.reset(body, &world.shapes[body.shape], rotation);
    }
    let solid = |i: usize, cache, rotation| Solid {
        body: &world.bodies[i],
        rotation,
        mesh: &world.shapes[world.bodies[i].shape],
        features: &features[world.bodies[i].shape],
        vertices: cache,
    };
    let (sa, sb) = (
        solid(a, &caches[0], rotations[0]),
        solid(b, &caches[1], rotations[1]),
    );
    let reach = halos[a] + halos[b];
    queries(group, &sa, &sb, reach, scratch);
    scratch.found.clear();
    let mut deep = 0;
    for &(side, v, t) in &scratch.corners {
        let (p, q) = match side {
            Side::A => (&sa, &sb),
            Side::B => (&sb, &sa),
        };
        if let Some(mut c) = corner_contact(p, v, q, t, reach) {
            deep += u64::from(c.depth > reach);
            if side == Side::B {
                c.flip();
            }
            scratch.found.push(Contact {
                a,
                b,
                ..c.contact()
            });
        }
    }
    for &(la, lb) in &scratch.creases {
        if let Some(c) = crease_contact(&sa, la, &sb, lb, reach) {
            deep += u64::from(c.depth > reach);
            scratch.found.push(Contact {
                a,
                b,
                ..c.contact()
            });
        }
    }
    scratch.vertices = caches;
    scratch.found.sort_unstable_by_key(|c| c.key);
    scratch.found.dedup_by_key(|c| c.key);
    contacts.extend_from_slice(&scratch.found);
    deep
}

/// The corner queries (side, corner, triangle of the other body) and convex
/// crease pairs the triangle contacts of one body pair call for, each once.
fn queries(group: &[TriangleContact], sa: &Solid, sb: &Solid, reach: f64, s: &mut FeatureScratch) {
    s.corners.clear();
    s.creases.clear();
    let [facets_a, facets_b] = &mut s.facets;
    facets_a.reset(sa.mesh.triangles.len());
    facets_b.reset(sb.mesh.triangles.len());
    for t in group {
        let fa = facets_a.get(t.a.index, || Facet::new(sa, t.a.index, reach));
        let fb = facets_b.get(t.b.index, || Facet::new(sb, t.b.index, reach));
        let (tri_a, tri_b) = (fa.triangle, fb.triangle);
        let (pa, pb) = (&fa.corners, &fb.corners);
        // A corner (an edge) can touch the other triangle only if it is (a
        // point of it is) within reach of that triangle's plane.
        let (near_a, near_b) = (fb.within_reach(pa), fa.within_reach(pb));
        for k in 0..3 {
            if near_a[k].0 && sa.features.corner[tri_a[k] as usize] && inside_box(pa[k], fb.grown) {
                s.corners.push((Side::A, tri_a[k], t.b.index));
            }
            if near_b[k].0 && sb.features.corner[tri_b[k] as usize] && inside_box(pb[k], fa.grown) {
                s.corners.push((Side::B, tri_b[k], t.a.index));
            }
        }
        for k in fa.crease_edges(near_a) {
            for l in fb.crease_edges(near_b) {
                if boxes_meet(fa.edges[k], fb.edges[l], fa.pad) {
                    s.creases.push((fa.creases[k], fb.creases[l]));
                }
            }
        }
    }
    s.corners.sort_unstable();
    s.corners.dedup();
    s.creases.sort_unstable();
    s.creases.dedup();
}

/// What the corner and crease queries read of one triangle of a body pair,
/// computed once per body pair however many triangle contacts it has.
#[derive(Debug, Clone, Copy)]
struct Facet {
    triangle: [u32; 3],
    corners: [DVec3; 3],
    /// The plane's unnormalised normal, and the reach (with a margin for
    /// rounding) in units of it.
    normal: DVec3,
    reach_n: f64,
    /// The triangle's box grown by the reach (and the margin).
    grown: (DVec3, DVec3),
    /// Per edge k (from corner k to k+1): its box, and its convex crease
    /// (`NO_CREASE` if none).
    edges: [(DVec3, DVec3); 3],
    creases: [u32; 3],
    /// The reach with the margin for rounding.
    pad: f64,
}

impl Facet {
    fn new(solid: &Solid, t: u32, reach: f64) -> Facet {
        let triangle = solid.mesh.triangles[t as usize];
        let corners = triangle.map(|v| solid.vertex(v));
        let normal = (corners[1] - corners[0]).cross(corners[2] - corners[0]);
        let pad = reach * (1.0 + 1e-9);
        let f = solid.features;
        let convex = |l: u32| l != NO_CREASE && f.creases[l as usize].convex;
        Facet {
            triangle,
            corners,
            normal,
            reach_n: pad * normal.length(),
            grown: grown_box(&corners, reach),
            edges: std::array::from_fn(|k| {
                let (p, q) = (corners[k], corners[(k + 1) % 3]);
                (p.min(q), p.max(q))
            }),
            creases: f.edge_crease[t as usize].map(|l| if convex(l) { l } else { NO_CREASE }),
            pad,
        }
    }

    /// The edges with a convex crease that `near` (of [`Facet::within_reach`])
    /// finds may be within reach.
    fn crease_edges(&self, near: [(bool, bool); 3]) -> impl Iterator<Item = usize> + '_ {
        (0..3).filter(move |&k| near[k].1 && self.creases[k] != NO_CREASE)
    }

    /// Per corner k of `t`: whether it is within reach of this triangle's
    /// plane, and whether edge k (from corner k to k+1) may be (its ends not
    /// both beyond reach on one side). The margin covers rounding.
    #[inline]
    fn within_reach(&self, t: &[DVec3; 3]) -> [(bool, bool); 3] {
        // Heights h |n| along the unnormalised normal n, against m |n|.
        let (n, m) = (self.normal, self.reach_n);
        let h = t.map(|x| (x - self.corners[0]).dot(n));
        std::array::from_fn(|k| {
            let (h0, h1) = (h[k], h[(k + 1) % 3]);
            let edge = !((h0 >= m && h1 >= m) || (h0 <= -m && h1 <= -m));
            (h0.abs() < m, edge)
        })
    }
}

/// Values per element of a mesh (a vertex, a triangle), each computed at
/// most once per body pair. A reset costs what the body pair used, not the
/// size of the mesh: a large obstacle meets many small grains.
#[derive(Debug)]
struct Memo<T> {
    /// Per element, its slot in `values` (`u32::MAX`: none yet).
    slot: Vec<u32>,
    values: Vec<T>,
    touched: Vec<u32>,
}

impl<T> Default for Memo<T> {
    fn default() -> Self {
        Memo {
            slot: Vec::new(),
            values: Vec::new(),
            touched: Vec::new(),
        }
    }
}

impl<T> Memo<T> {
    /// Ready for a mesh of `n` elements, none known.
    fn reset(&mut self, n: usize) {
        for &i in &self.touched {
            self.slot[i as usize] = u32::MAX;
        }
        self.touched.clear();
        self.values.clear();
        if self.slot.len() < n {
            self.slot.resize(n, u32::MAX);
        }
    }

    /// Element `i`'s value, made by `make` the first time it is asked for.
    #[inline]
    fn get(&mut self, i: u32, make: impl FnOnce() -> T) -> &T {
        let mut at = self.slot[i as usize];
        if at == u32::MAX {
            at = self.values.len() as u32;
            self.values.push(make());
            self.slot[i as usize] = at;
            self.touched.push(i);
        }
        &self.values[at as usize]
    }
}

/// The box of a triangle grown by `reach` (and a margin for rounding).
fn grown_box(t: &[DVec3; 3], reach: f64) -> (DVec3, DVec3) {
    let m = DVec3::splat(reach * (1.0 + 1e-9));
    (t[0].min(t[1]).min(t[2]) - m, t[0].max(t[1]).max(t[2]) + m)
}

fn inside_box(p: DVec3, (lo, hi): (DVec3, DVec3)) -> bool {
    p.cmpgt(lo).all() && p.cmplt(hi).all()
}

/// Whether two segments' boxes (`lo`, `hi`), grown by `pad`, overlap: else
/// no point of one is within reach of the other.
fn boxes_meet((lo_a, hi_a): (DVec3, DVec3), (lo_b, hi_b): (DVec3, DVec3), pad: f64) -> bool {
    (lo_a - hi_b).max_element() < pad && (lo_b - hi_a).max_element() < pad
}

/// A contact seen from the body whose corner it is: normal from the other
/// body to the corner's.
struct Found {
    kind: FeatureKind,
    /// The feature of the body the contact is seen from, and of the other.
    own: u32,
    other: u32,
    point: DVec3,
    normal: DVec3,
    depth: f64,
    weight: f64,
    gradient: WeightGradient,
}

impl Found {
    /// The same contact with the bodies' roles swapped (a corner of b; its
    /// weight is 1, with no gradient to swap).
    fn flip(&mut self) {
        self.kind = match self.kind {
            FeatureKind::CornerFace => FeatureKind::FaceCorner,
            FeatureKind::CornerCrease => FeatureKind::CreaseCorner,
            k => k,
        };
        std::mem::swap(&mut self.own, &mut self.other);
        self.normal = -self.normal;
    }

    fn contact(&self) -> Contact {
        Contact {
            a: 0,
            b: 0,
            key: FeatureKey {
                kind: self.kind,
                on_a: self.own,
                on_b: self.other,
            },
            point: self.point,
            normal: self.normal,
            depth: self.depth,
            weight: self.weight,
            gradient: self.gradient,
        }
    }
}

/// Corner `v` of `p` against triangle `t` of `q`: a contact with the face,
/// a convex crease or a corner of `q`, whichever Voronoi region holds the
/// corner (see the module doc).
fn corner_contact(p: &Solid, v: u32, q: &Solid, t: u32, reach: f64) -> Option<Found> {
    let c = p.vertex(v);
    let fq = q.features;
    let face = fq.face_of[t as usize];
    let plane = &fq.faces[face as usize];
    let n = q.direction(plane.normal);
    let from_anchor = c - q.vertex(plane.anchor);
    let h = from_anchor.dot(n);
    // No point of the triangle is within reach when its plane is not (with
    // room for a triangle tilted within FLAT_ANGLE of its face's plane).
    if h.abs() >= reach + FLAT_ANGLE * from_anchor.length() {
        return None;
    }
    let tri = q.mesh.triangles[t as usize];
    let corners = tri.map(|i| q.vertex(i));
    if inside(c, tri, &corners, n) {
        return (h > -reach && h < reach).then(|| Found {
            kind: FeatureKind::CornerFace,
            own: v,
            other: face,
            point: c - n * (0.5 * h),
            normal: n,
            depth: reach - h,
            weight: 1.0,
            gradient: WeightGradient::default(),
        });
    }
    let creases = fq.edge_crease[t as usize]
        .into_iter()
        .filter(|&l| l != NO_CREASE && fq.creases[l as usize].convex);
    let by_crease = creases.filter_map(|l| corner_crease(c, v, q, l, reach));
    let by_corner = tri
        .into_iter()
        .filter(|&w| fq.corner[w as usize])
        .filter_map(|w| corner_corner(c, v, q, w, reach));
    // At most one region holds the corner; taking the deepest only makes the
    // choice certain should rounding put it in two.
    by_crease
        .chain(by_corner)
        .max_by(|x, y| x.depth.total_cmp(&y.depth))
}

/// Whether `c` projects (along `n`) into the triangle with vertex indices
/// `tri` and world positions `corners`, boundary included. Each edge is
/// tested from its lower vertex, so the two triangles of an edge decide a
/// point on it with the same number, of opposite signs, and never both miss it.
fn inside(c: DVec3, tri: [u32; 3], corners: &[DVec3; 3], n: DVec3) -> bool {
    (0..3).all(|k| {
        let (i, j) = (k, (k + 1) % 3);
        let (lo, hi, sign) = if tri[i] < tri[j] {
            (i, j, 1.0)
        } else {
            (j, i, -1.0)
        };
        let w = (corners[hi] - corners[lo]).cross(c - corners[lo]).dot(n);
        sign * w >= 0.0
    })
}

/// Corner `c` (vertex `v` of its body) against convex crease `l` of `q`:
/// a contact when `c` lies in the crease's open region.
fn corner_crease(c: DVec3, v: u32, q: &Solid, l: u32, reach: f64) -> Option<Found> {
    let crease = &q.features.creases[l as usize];
    let (e0, e1) = (q.vertex(crease.ends[0]), q.vertex(crease.ends[1]));
    let u = e1 - e0;
    let uu = u.dot(u);
    let s = (c - e0).dot(u) / uu;
    if !(s > 0.0 && s < 1.0) {
        return None;
    }
    let on = e0 + u * s;
    let d = c - on;
    let [m0, m1] = crease.inward.map(|m| q.direction(m));
    if !(d.dot(m0) < 0.0 && d.dot(m1) < 0.0) {
        return None;
    }
    let g = d.length();
    (g > 0.0 && g < reach).then(|| Found {
        kind: FeatureKind::CornerCrease,
        own: v,
        other: l,
        point: (c + on) * 0.5,
        normal: d / g,
        depth: reach - g,
        weight: 1.0,
        gradient: WeightGradient::default(),
    })
}

/// Corner `c` (vertex `v` of its body) against corner `w` of `q`: a contact
/// when `c` lies in `w`'s region and not on one of its faces' normals (the
/// face contact has those).
fn corner_corner(c: DVec3, v: u32, q: &Solid, w: u32, reach: f64) -> Option<Found> {
    let at = q.vertex(w);
    let d = c - at;
    let fq = q.features;
    if fq
        .neighbours(w)
        .iter()
        .any(|&u| d.dot(q.vertex(u) - at) > 0.0)
    {
        return None;
    }
    let on_normal = |f: &u32| {
        let n = q.direction(fq.faces[*f as usize].normal);
        d.cross(n) == DVec3::ZERO && d.dot(n) > 0.0
    };
    if fq.faces_at(w).iter().any(on_normal) {
        return None;
    }
    let g = d.length();
    (g > 0.0 && g < reach).then(|| Found {
        kind: FeatureKind::CornerCorner,
        own: v,
        other: w,
        point: (c + at) * 0.5,
        normal: d / g,
        depth: reach - g,
        weight: 1.0,
        gradient: WeightGradient::default(),
    })
}

/// Convex crease `la` of `a` against convex crease `lb` of `b`: a contact
/// where they cross within reach (see the module doc), weighted by
/// [`ramp`] of the crossing's distance to the creases' ends.
fn crease_contact(a: &Solid, la: u32, b: &Solid, lb: u32, reach: f64) -> Option<Found> {
    let (ca, cb) = (
        &a.features.creases[la as usize],
        &b.features.creases[lb as usize],
    );
    let a0 = a.vertex(ca.ends[0]);
    let b0 = b.vertex(cb.ends[0]);
    let (ua, ub) = (a.vertex(ca.ends[1]) - a0, b.vertex(cb.ends[1]) - b0);
    let (len_a, len_b) = (ua.length(), ub.length());
    let lines = Lines::new(a0, ua / len_a, b0, ub / len_b)?;
    let (sigma, tau) = (lines.sigma, lines.tau);
    if !(sigma > 0.0 && sigma < len_a && tau > 0.0 && tau < len_b) {
        return None;
    }
    let outward = |x: &Solid, faces: [u32; 2]| {
        faces
            .iter()
            .map(|&f| x.direction(x.features.faces[f as usize].normal))
            .sum::<DVec3>()
    };
    let mut n = lines.ua.cross(lines.ub) / lines.d.sqrt();
    let facing_b = n.dot(outward(b, cb.faces));
    if facing_b == 0.0 {
        return None;
    }
    if facing_b < 0.0 {
        n = -n;
    }
    // NaN fails too.
    if n.dot(outward(a, ca.faces)).partial_cmp(&0.0) != Some(std::cmp::Ordering::Less) {
        return None;
    }
    let (p, q) = (a0 + lines.ua * sigma, b0 + lines.ub * tau);
    let g = (p - q).dot(n);
    if !(g > -reach && g < reach) {
        return None;
    }
    let (weight, gradient) = crossing_weight(&lines, len_a, len_b, reach, a.body.x, b.body.x);
    Some(Found {
        kind: FeatureKind::CreaseCrease,
        own: la,
        other: lb,
        point: (p + q) * 0.5,
        normal: n,
        depth: reach - g,
        weight,
        gradient,
    })
}

/// The weight of a crossing of creases of lengths `len_a` and `len_b` along
/// `lines` (bodies centred at `xa` and `xb`), and its gradient: 1 away from
/// the creases' ends, falling to 0 at them ([`ramp`]), and faded at shallow
/// angles ([`CROSSING_FADE_SINE`]).
fn crossing_weight(
    lines: &Lines,
    len_a: f64,
    len_b: f64,
    reach: f64,
    xa: DVec3,
    xb: DVec3,
) -> (f64, WeightGradient) {
    let end_ramp = |x: f64, len: f64| {
        let (near, sign) = if x <= len - x {
            (x, 1.0)
        } else {
            (len - x, -1.0)
        };
        (ramp(near / reach), sign * ramp_slope(near / reach) / reach)
    };
    let ((wa, dwa), (wb, dwb)) = (end_ramp(lines.sigma, len_a), end_ramp(lines.tau, len_b));
    let x = lines.d.sqrt() / CROSSING_FADE_SINE;
    let (wf, dwf) = (ramp(x), ramp_slope(x) / CROSSING_FADE_SINE);
    let (ds, dt) = lines.gradients(xa, xb);
    let gradient = ds
        .scaled(wb * dwa * wf)
        .plus(&dt.scaled(wa * dwb * wf))
        .plus(&lines.sine_gradient().scaled(wa * wb * dwf));
    (wa * wb * wf, gradient)
}

/// How much of its spring a crossing of creases keeps at a distance `x`
/// (in halo sums) from the nearer end of either crease: 0 at the end, 1 from
/// one halo sum on, smooth between (x²(3 − 2x)). At a crease's end the
/// crossing meets the corner there, which has its own contact: the crossing
/// leaves or joins with no weight, so the energy stays continuous.
fn ramp(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

fn ramp_slope(x: f64) -> f64 {
    if (0.0..=1.0).contains(&x) {
        6.0 * x * (1.0 - x)
    } else {
        0.0
    }
}

/// The closest points of two lines a0 + σ ua and b0 + τ ub (unit directions):
/// σ = (c Q − P)/D, τ = (Q − c P)/D with w = a0 − b0, P = w·ua, Q = w·ub,
/// c = ua·ub and D = 1 − c².
struct Lines {
    a0: DVec3,
    b0: DVec3,
    ua: DVec3,
    ub: DVec3,
    w: DVec3,
    c: f64,
    d: f64,
    p: f64,
    q: f64,
    sigma: f64,
    tau: f64,
}

impl Lines {
    /// `None` for lines parallel to within [`PARALLEL_SINE`].
    fn new(a0: DVec3, ua: DVec3, b0: DVec3, ub: DVec3) -> Option<Lines> {
        let c = ua.dot(ub);
        let d = ua.cross(ub).length_squared();
        if d.partial_cmp(&(PARALLEL_SINE * PARALLEL_SINE)) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        let w = a0 - b0;
        let (p, q) = (w.dot(ua), w.dot(ub));
        Some(Lines {
            a0,
            b0,
            ua,
            ub,
            w,
            c,
            d,
            p,
            q,
            sigma: (c * q - p) / d,
            tau: (q - c * p) / d,
        })
    }

    /// The gradients of σ and τ with respect to the two bodies' motions,
    /// for lines fixed in bodies centred at `xa` and `xb`.
    fn gradients(&self, xa: DVec3, xb: DVec3) -> (WeightGradient, WeightGradient) {
        let Lines {
            a0,
            b0,
            ua,
            ub,
            w,
            c,
            d,
            p,
            q,
            sigma,
            tau,
        } = *self;
        // Partial derivatives by w, ua and ub (D depends on c = ua·ub).
        let sigma_w = (ub * c - ua) / d;
        let sigma_a = (ub * q - w) / d + ub * (2.0 * c * sigma / d);
        let sigma_b = (ua * q + w * c) / d + ua * (2.0 * c * sigma / d);
        let tau_w = (ub - ua * c) / d;
        let tau_a = (-ub * p - w * c) / d + ub * (2.0 * c * tau / d);
        let tau_b = (w - ua * p) / d + ua * (2.0 * c * tau / d);
        let (ra, rb) = (a0 - xa, b0 - xb);
        let rigid = |dw: DVec3, da: DVec3, db: DVec3| WeightGradient {
            force_a: dw,
            torque_a: ra.cross(dw) + ua.cross(da),
            torque_b: -rb.cross(dw) + ub.cross(db),
        };
        (rigid(sigma_w, sigma_a, sigma_b), rigid(tau_w, tau_a, tau_b))
    }
}

impl Lines {
    /// The gradient of sin θ = |ua × ub| with respect to the two bodies'
    /// motions: a rotation δθ of a turns ua by δθ × ua, which changes the
    /// sine by δθ · (ua × (ub × n̂)), n̂ = ua × ub / sin θ; likewise for b.
    fn sine_gradient(&self) -> WeightGradient {
        let n = self.ua.cross(self.ub) / self.d.sqrt();
        WeightGradient {
            force_a: DVec3::ZERO,
            torque_a: self.ua.cross(self.ub.cross(n)),
            torque_b: self.ub.cross(n.cross(self.ua)),
        }
    }
}

/// The gradient of a contact's weight with respect to the motions of its
/// bodies: d/dx_a (the translation of a; that of b is its opposite), d/dθ_a
/// and d/dθ_b (rotations about the centres of mass).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct WeightGradient {
    pub force_a: DVec3,
    pub torque_a: DVec3,
    pub torque_b: DVec3,
}

impl WeightGradient {
    fn scaled(&self, s: f64) -> WeightGradient {
        WeightGradient {
            force_a: self.force_a * s,
            torque_a: self.torque_a * s,
            torque_b: self.torque_b * s,
        }
    }

    fn plus(&self, o: &WeightGradient) -> WeightGradient {
        WeightGradient {
            force_a: self.force_a + o.force_a,
            torque_a: self.torque_a + o.torque_a,
            torque_b: self.torque_b + o.torque_b,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;

    const REACH: f64 = 1e-3;

    /// A crease of body a (centred at `xa`) from `a0` along `ua`, and one of
    /// body b; each 10 halo sums long.
    #[derive(Clone, Copy)]
    struct Creases {
        xa: DVec3,
        a0: DVec3,
        ua: DVec3,
        xb: DVec3,
        b0: DVec3,
        ub: DVec3,
    }

    const LEN: f64 = 10.0 * REACH;

    /// Crease a along x from the origin; crease b at `angle` to it in the
    /// plane half a reach above, crossing a at `sigma` and itself at `tau`.
    fn crossing(angle: f64, sigma: f64, tau: f64) -> Creases {
        let ub = DVec3::new(angle.cos(), angle.sin(), 0.0);
        let at = DVec3::new(sigma, 0.0, 0.5 * REACH);
        Creases {
            xa: DVec3::new(0.3, 0.2, -0.4) * LEN,
            a0: DVec3::ZERO,
            ua: DVec3::X,
            xb: DVec3::new(0.2, -0.1, 0.5) * LEN,
            b0: at - ub * tau,
            ub,
        }
    }

    fn weight(c: &Creases) -> (f64, WeightGradient) {
        let lines = Lines::new(c.a0, c.ua, c.b0, c.ub).expect("not parallel");
        crossing_weight(&lines, LEN, LEN, REACH, c.xa, c.xb)
    }

    fn turn(x: DVec3, p: DVec3, u: DVec3, r: DVec3) -> (DVec3, DVec3) {
        let q = DQuat::from_scaled_axis(r);
        (x + q * (p - x), q * u)
    }

    /// The weight's gradient is its derivative: central differences of the
    /// weight under small translations of a and rotations of a and b about
    /// their centres, near the creases' ends and at angles inside and
    /// outside the fade.
    #[test]
    fn a_crossings_weight_gradient_is_its_derivative() {
        let h = 1e-9;
        for angle in [1.2, 0.5, 0.15, 0.06] {
            for (sigma, tau) in [(0.4, 5.0), (0.7, 0.3), (9.5, 0.8)] {
                let c = crossing(angle, sigma * REACH, tau * REACH);
                let (w, g) = weight(&c);
                assert!(w > 0.0 && w < 1.0, "{angle} {sigma} {tau}: {w}");
                for k in 0..3 {
                    let e = DVec3::AXES[k] * h;
                    let moved = |s: f64| {
                        let mut m = c;
                        m.a0 += e * s;
                        weight(&m).0
                    };
                    let turned_a = |s: f64| {
                        let mut m = c;
                        (m.a0, m.ua) = turn(c.xa, c.a0, c.ua, e * s);
                        weight(&m).0
                    };
                    let turned_b = |s: f64| {
                        let mut m = c;
                        (m.b0, m.ub) = turn(c.xb, c.b0, c.ub, e * s);
                        weight(&m).0
                    };
                    let fd = |f: &dyn Fn(f64) -> f64| (f(1.0) - f(-1.0)) / (2.0 * h);
                    let scale = 1.0 / REACH;
                    for (name, numeric, exact) in [
                        ("translation of a", fd(&moved), g.force_a[k]),
                        ("rotation of a", fd(&turned_a), g.torque_a[k]),
                        ("rotation of b", fd(&turned_b), g.torque_b[k]),
                    ] {
                        assert!(
                            (numeric - exact).abs() <= 1e-5 * scale,
                            "angle {angle}, at ({sigma}, {tau}) reach, {name} about axis {k}: \
                             difference quotient {numeric}, gradient {exact}"
                        );
                    }
                }
            }
        }
    }

    /// Near-parallel creases: their crossing runs along them 1/sin θ times
    /// as fast as they move, but the weight's gradient stays within a few
    /// times 1/reach (translation) and lever/reach (rotation), at every
    /// angle down to the parallel and everywhere along the ramps.
    #[test]
    fn a_crossings_weight_gradient_stays_bounded_at_shallow_angles() {
        for sine in [0.5, 0.1, 1e-2, 1e-3, 1e-6, 1e-10] {
            for k in 1..40 {
                let sigma = 0.05 * k as f64 * REACH;
                let c = crossing(f64::asin(sine), sigma, 0.5 * REACH);
                let (_, g) = weight(&c);
                let lever = 2.0 * LEN;
                let worst = (g.force_a.length() * REACH)
                    .max(g.torque_a.length() * REACH / lever)
                    .max(g.torque_b.length() * REACH / lever);
                assert!(
                    worst <= 20.0,
                    "sin θ = {sine}, σ = {sigma}: gradient {worst} times 1/reach"
                );
            }
        }
    }
}
