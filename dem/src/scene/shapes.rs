//! Shapes and placements of a scene's bodies.

use super::spec::{PlacementSpec, ShapeSpec};
use super::{positive, Ctx, SceneError, MAX_PARTICLES};
use crate::body::Body;
use crate::mesh::{
    box_mesh, load_mesh, sphere_hull, subdivided, tetrahedron, tube, MeshError, TriMesh,
};
use glam::{DQuat, DVec3};
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

/// A box subdivided 6 times has 49,152 triangles: enough for any test of
/// mesh independence, and a typo cannot ask for billions.
const MAX_SUBDIVIDE: usize = 6;
/// A convex hull of a million triangles is finer than any particle model
/// needs; its hull computation alone would take minutes.
const MAX_HULL_TRIANGLES: usize = 1_000_000;
/// A tube of 100,000 sides is round to a part in 10⁹ of its radius; more is
/// a typo.
const MAX_TUBE_SEGMENTS: usize = 100_000;

/// The smallest side of a shape's box in its own frame: how thick it is.
pub(super) fn smallest_extent(mesh: &TriMesh) -> f64 {
    let (lo, hi) = mesh.vertices.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), &v| (lo.min(v), hi.max(v)),
    );
    (hi - lo).min_element()
}

/// A particle's initial motion must be a number the integrator can carry:
/// its kinetic energy finite (a velocity of 1e200 m/s squares to infinity).
/// One whose surface crosses half its own thickness in a step, by its
/// speed or by its spin (|ω| times `reach`, its farthest point from its
/// centre), can pass through a wall between two detections: warned.
pub(super) fn check_motion(
    ctx: &Ctx,
    span: std::ops::Range<usize>,
    b: &Body,
    omega: DVec3,
    dt: f64,
    (thickness, reach): (f64, f64),
    warnings: &mut Vec<String>,
) -> Result<(), SceneError> {
    let energy = 0.5 * b.mass * b.v.length_squared() + 0.5 * omega.dot(b.l);
    if !(energy.is_finite() && b.l.is_finite() && b.q.is_finite() && b.x.is_finite()) {
        return ctx.err(
            span,
            format!(
                "particle: velocity [{:e}, {:e}, {:e}] m/s and angular velocity \
                 [{:e}, {:e}, {:e}] rad/s give a kinetic energy of {energy:e} J, \
                 which is not a finite number",
                b.v.x, b.v.y, b.v.z, omega.x, omega.y, omega.z
            ),
        );
    }
    let travel = (b.v.length() + omega.length() * reach) * dt;
    if travel > thickness / 2.0 {
        warnings.push(format!(
            "{}:{}: a particle's surface moves up to {travel:e} m in one step (its speed, and \
             its spin times its reach), more than half its thickness ({thickness:e} m): it can \
             pass through walls and other particles between two detections; lower dt, the \
             speed or the spin",
            ctx.file,
            ctx.line_of(span.start)
        ));
    }
    Ok(())
}

/// How many times the rounding of a body's coordinates its halo must be.
const HALO_IN_ROUNDINGS: f64 = 1024.0;

/// A body's points are rounded to the spacing of f64 at their distance
/// from the origin (a part in 2⁵² of it). Placed so far out that this
/// rounding is more than 1/[`HALO_IN_ROUNDINGS`] of its halo, within which
/// its contacts act and their depths are measured, the body's contacts
/// would be decided by rounding: refused, naming how far is too far. `far`:
/// the largest coordinate of any of its points; its halo (0: none) and its
/// thickness, which stands for the halo when it has none.
pub(super) fn check_resolution(
    ctx: &Ctx,
    span: std::ops::Range<usize>,
    far: f64,
    (halo, thickness): (f64, f64),
) -> Result<(), SceneError> {
    let halo = if halo > 0.0 { halo } else { thickness };
    let rounding = far.next_up() - far;
    if rounding * HALO_IN_ROUNDINGS <= halo {
        return Ok(());
    }
    ctx.err(
        span,
        format!(
            "a body reaches {far:e} m from the origin, where f64 rounds coordinates to \
             {rounding:e} m: more than 1/{HALO_IN_ROUNDINGS} of its halo ({halo:e} m), so \
             rounding would decide its contacts; move the scene nearer the origin \
             (geometry is exact relative to the scene's size, not its distance)"
        ),
    )
}

pub(super) fn make_shape(
    ctx: &Ctx,
    span: std::ops::Range<usize>,
    s: &ShapeSpec,
) -> Result<TriMesh, SceneError> {
    match s {
        ShapeSpec::Hull {
            triangles,
            radius,
            seed,
        } => {
            let r = positive(ctx, span.clone(), "shape.radius", *radius)?;
            if *triangles < 4 || triangles % 2 != 0 {
                return ctx.err(
                    span,
                    format!("a hull needs an even number of triangles >= 4, got {triangles}"),
                );
            }
            if *triangles > MAX_HULL_TRIANGLES {
                return ctx.err(
                    span,
                    format!(
                        "a hull of {triangles} triangles is more than the {MAX_HULL_TRIANGLES} \
                         a scene may ask for (about {:.0} GB per particle)",
                        *triangles as f64 * BYTES_PER_TRIANGLE / 1e9
                    ),
                );
            }
            built(ctx, span, sphere_hull(*triangles, r, *seed))
        }
        ShapeSpec::Box { size, subdivide } => {
            for (k, &x) in size.iter().enumerate() {
                positive(ctx, span.clone(), &format!("shape.size[{k}]"), x)?;
            }
            if *subdivide > MAX_SUBDIVIDE {
                return ctx.err(
                    span,
                    format!(
                        "shape.subdivide must be between 0 and {MAX_SUBDIVIDE}, got {subdivide}"
                    ),
                );
            }
            let mesh = box_mesh(DVec3::from_array(*size)).and_then(|b| subdivided(&b, *subdivide));
            built(ctx, span, mesh)
        }
        ShapeSpec::Tetrahedron { radius } => {
            let r = positive(ctx, span.clone(), "shape.radius", *radius)?;
            built(ctx, span, tetrahedron(r))
        }
        ShapeSpec::Tube {
            inner_radius,
            end_inner_radius,
            thickness,
            length,
            segments,
        } => {
            let r = positive(ctx, span.clone(), "shape.inner_radius", *inner_radius)?;
            let r1 = match end_inner_radius {
                Some(e) => positive(ctx, span.clone(), "shape.end_inner_radius", *e)?,
                None => r,
            };
            let t = positive(ctx, span.clone(), "shape.thickness", *thickness)?;
            let l = positive(ctx, span.clone(), "shape.length", *length)?;
            if !(3..=MAX_TUBE_SEGMENTS).contains(segments) {
                return ctx.err(
                    span,
                    format!(
                        "shape.segments must be between 3 and {MAX_TUBE_SEGMENTS}, got {segments}"
                    ),
                );
            }
            built(ctx, span, tube(r, r1, t, l, *segments))
        }
        ShapeSpec::Mesh { file, scale } => {
            let path = if file.is_absolute() {
                file.clone()
            } else {
                ctx.dir.join(file)
            };
            let s = positive(ctx, span.clone(), "shape.scale", *scale)?;
            let mesh = load_mesh(&path).or_else(|e| ctx.err(span.clone(), e.to_string()))?;
            // Scaled, the mesh is checked anew: a scale can underflow its
            // triangles' areas or overflow its coordinates.
            let scaled = mesh.scaled(s);
            built(ctx, span, TriMesh::new(scaled.vertices, scaled.triangles))
        }
    }
}

/// A shape's mesh, or the error naming why f64 cannot carry it at the size
/// the scene asks for.
fn built(
    ctx: &Ctx,
    span: std::ops::Range<usize>,
    mesh: Result<TriMesh, MeshError>,
) -> Result<TriMesh, SceneError> {
    mesh.or_else(|e| {
        ctx.err(
            span,
            format!(
                "the shape cannot be built in f64 at the size given (lengths too small or \
                 too large for f64 to carry its triangles): {e}"
            ),
        )
    })
}

/// Bytes a particle's triangle takes in a run, about: the world-space copy
/// and its box, per-thread copies, the broad phase's entries, the output.
const BYTES_PER_TRIANGLE: f64 = 400.0;

/// The axes' names, as messages give them.
const AXES: [&str; 3] = ["x", "y", "z"];

pub(super) fn placements(
    ctx: &Ctx,
    span: std::ops::Range<usize>,
    p: &PlacementSpec,
    radius: f64,
    triangles: usize,
) -> Result<Vec<[f64; 3]>, SceneError> {
    let count = match p {
        PlacementSpec::Single { .. } => 1.0,
        PlacementSpec::Lattice { count, .. } => count.iter().map(|&c| c as f64).product(),
        PlacementSpec::Random { count, .. } | PlacementSpec::Insert { count, .. } => *count as f64,
    };
    if count > MAX_PARTICLES as f64 {
        return ctx.err(
            span,
            format!(
                "{count:e} particles is more than the {MAX_PARTICLES} a scene may place \
                 (at {triangles} triangles each they would need about {:.0} GB)",
                count * triangles as f64 * BYTES_PER_TRIANGLE / 1e9
            ),
        );
    }
    match p {
        PlacementSpec::Single { position } => Ok(vec![*position]),
        PlacementSpec::Insert {
            count,
            region,
            rate,
            start,
            ..
        } => {
            let refuse = |why: String| ctx.err(span.clone(), format!("placement: {why}"));
            if *count == 0 {
                return refuse("count = 0 inserts no particle".into());
            }
            if let Err(why) = region.check() {
                return refuse(why);
            }
            if let Some(r) = rate.filter(|r| !(r.is_finite() && *r > 0.0)) {
                return refuse(format!("rate must be positive, got {r:e}"));
            }
            if !(start.is_finite() && *start >= 0.0) {
                return refuse(format!("start must be a time from 0 on, got {start:e}"));
            }
            // They wait at the region's centre until they enter.
            Ok(vec![region.centre().to_array(); *count])
        }
        PlacementSpec::Lattice {
            count,
            spacing,
            origin,
        } => {
            if let Some(axis) = (0..3).find(|&k| count[k] == 0) {
                let name = AXES[axis];
                return ctx.err(
                    span,
                    format!("placement.count {count:?} places no particle: give at least 1 along {name}"),
                );
            }
            let s = positive(ctx, span.clone(), "placement.spacing", *spacing)?;
            if s < 2.0 * radius {
                return ctx.err(
                    span,
                    format!(
                        "placement.spacing {s} is below the particle diameter {}",
                        2.0 * radius
                    ),
                );
            }
            let mut v = Vec::new();
            for k in 0..count[2] {
                for j in 0..count[1] {
                    for i in 0..count[0] {
                        v.push([
                            origin[0] + i as f64 * s,
                            origin[1] + j as f64 * s,
                            origin[2] + k as f64 * s,
                        ]);
                    }
                }
            }
            Ok(v)
        }
        PlacementSpec::Random {
            count,
            lo,
            hi,
            seed,
        } => {
            if *count == 0 {
                return ctx.err(span, "placement.count = 0 places no particle".to_string());
            }
            // A box that cannot hold one particle would put them outside it.
            if let Some(axis) = (0..3).find(|&k| hi[k] - lo[k] < 2.0 * radius) {
                let name = AXES[axis];
                return ctx.err(
                    span,
                    format!(
                        "placement: the box from lo {lo:?} to hi {hi:?} is {:e} m wide along {name}, \
                         less than a particle's diameter ({:e} m)",
                        hi[axis] - lo[axis],
                        2.0 * radius
                    ),
                );
            }
            // Random sequential packing: reject positions closer than a diameter.
            let mut rng = Xoshiro256PlusPlus::seed_from_u64(*seed);
            let mut v: Vec<[f64; 3]> = Vec::with_capacity(*count);
            let mut tries = 0usize;
            while v.len() < *count {
                tries += 1;
                if tries > 1000 * count.max(&1) {
                    return ctx.err(
                        span,
                        format!(
                            "could place only {} of {count} particles without overlap in the box",
                            v.len()
                        ),
                    );
                }
                let p = [0, 1, 2]
                    .map(|k| lo[k] + radius + (hi[k] - lo[k] - 2.0 * radius) * rng.random::<f64>());
                let ok = v.iter().all(|o| {
                    (0..3).map(|k| (o[k] - p[k]).powi(2)).sum::<f64>() >= (2.0 * radius).powi(2)
                });
                if ok {
                    v.push(p);
                }
            }
            Ok(v)
        }
    }
}

pub(super) fn random_rotation(rng: &mut Xoshiro256PlusPlus) -> DQuat {
    // Shoemake's uniform random unit quaternion.
    let (u1, u2, u3): (f64, f64, f64) = (rng.random(), rng.random(), rng.random());
    let tau = 2.0 * std::f64::consts::PI;
    DQuat::from_xyzw(
        (1.0 - u1).sqrt() * (tau * u2).sin(),
        (1.0 - u1).sqrt() * (tau * u2).cos(),
        u1.sqrt() * (tau * u3).sin(),
        u1.sqrt() * (tau * u3).cos(),
    )
    .normalize()
}
