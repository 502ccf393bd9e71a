//! From the checked spec to the scene: settings, effects, materials,
//! bodies, the kernel's options, and the stable time step, each in its own
//! function, in the order a later one needs an earlier one's result.

use super::census::Run;
use super::shapes::{
    check_motion, check_resolution, make_shape, placements, random_rotation, smallest_extent,
};
use super::spec::PlacementSpec;
use super::spec::{
    KernelSpec, MaterialSpec, ObstacleSpec, ParticleSpec, SceneFile, SimulationSpec,
};
use super::{
    positive, Census, Ctx, Deal, OutputSection, Parallel, Scene, SceneError, MAX_PARTICLES,
    MAX_STEPS,
};
use crate::body::{Body, Drive, Profile};
use crate::distance::{Fallback, Method, Options, PenaltyParams, Schedule, Threading};
use crate::effects::{
    ContactParams, Declare, Effects, InsertionParams, Stream, WallMotionParams, KINDS,
};
use crate::material::{damping_ratio, in_series, Material};
use crate::mesh::{MassProperties, TriMesh};
use crate::world::World;
use glam::{DMat3, DQuat, DVec3};
use rand::SeedableRng;
use rand_xoshiro::Xoshiro256PlusPlus;
use std::ops::Range;
use toml::Spanned;

/// Bounds of the penalty kernel's settings in a scene: iteration counts are
/// reported per pair in a byte. The accuracy sweep (`tridem kernels
/// --accuracy`, rounds 0-4) found rounds after the second certifying almost
/// no more pairs; 8 leaves room above what was measured and keeps a typo
/// from turning every uncertified batch into a long loop.
const MAX_ITERATIONS: usize = 255;
pub const MAX_FINISH_ROUNDS: usize = 8;

/// The bodies a scene keeps, and the census of all it places.
struct Bodies {
    world: World,
    census: Census,
    deal: Deal,
    warnings: Vec<String>,
    /// The groups to insert during the run, with where the scene places each.
    streams: Vec<(Stream, Range<usize>)>,
}

impl Bodies {
    /// Keeps `body`, of id `id`, if it is the deal's.
    fn keep(&mut self, id: u32, body: Body) {
        if body.is_static() || self.deal.keeps(id) {
            self.world.bodies.push(body);
            if self.deal != Deal::WHOLE {
                self.world.ids.push(id);
            }
        }
    }
}

pub(super) fn build(ctx: &Ctx, spec: SceneFile, deal: Deal) -> Result<Scene, SceneError> {
    let sim_span = spec.simulation.span();
    let sim = spec.simulation.into_inner();
    let (dt, end_time) = time_stepping(ctx, sim_span.clone(), &sim)?;
    let mut effects = effects(ctx, &spec.effects)?;
    let materials = materials(ctx, &spec.materials, &effects)?;
    let mut bodies = Bodies {
        world: World {
            materials,
            ..World::default()
        },
        census: Census::default(),
        deal,
        warnings: Vec::new(),
        streams: Vec::new(),
    };
    for p in &spec.particles {
        add_particles(ctx, p, dt, &mut bodies)?;
    }
    let walls_move = effects.has::<WallMotionParams>();
    for o in &spec.obstacles {
        add_obstacle(ctx, o, walls_move, (dt, end_time), &mut bodies)?;
    }
    let moving = |b: &Body| b.drive.as_ref().is_some_and(|d| d.moves());
    if walls_move && !bodies.world.bodies.iter().any(moving) {
        let start = spec.effects.span().start;
        let key = key_offset(&ctx.text[start..], WallMotionParams::NAME);
        let at = key.map_or(start, |o| start + o);
        return ctx.err(
            at..at,
            "the wall_motion effect moves obstacles, and no obstacle sets a velocity \
             or angular_velocity",
        );
    }
    insertion(ctx, &spec.effects, &mut effects, &bodies)?;
    if bodies.census.particles() == 0 {
        return ctx.err(0..0, "the scene has no particles");
    }
    let kernel = match spec.kernel {
        None => Options::default(),
        Some(k) => kernel(ctx, k.span(), k.into_inner())?,
    };
    let stable_dt = effects
        .has::<ContactParams>()
        .then(|| stable_step(&bodies.world.materials, &bodies.census));
    let rocking_dt = (effects.has::<ContactParams>() && effects.rotate()).then(|| {
        rocking_step(
            &bodies.world.materials,
            &bodies.census,
            &bodies.world.shapes,
        )
    });
    if let Some(h) = stable_dt.filter(|&h| dt > h) {
        let msg = format!(
            "simulation.dt = {dt:e} s is above the stable step {h:e} s \
             (stiffest contact pair, lightest particle)"
        );
        if !sim.allow_unstable_dt {
            return ctx.err(
                sim_span,
                format!("{msg}; lower dt or set allow_unstable_dt = true"),
            );
        }
        bodies.warnings.push(msg);
    }
    let parallel = match spec.parallel {
        None => Parallel::default(),
        Some(p) => parallel(ctx, p.span(), p.into_inner()),
    };
    let output = match spec.output {
        None => OutputSection::default(),
        Some(o) => OutputSection {
            line: ctx.line_of(o.span().start),
            ..o.into_inner()
        },
    };
    Ok(Scene {
        world: bodies.world,
        effects,
        dt,
        end_time,
        output_every: sim.output_every,
        stable_dt,
        rocking_dt,
        kernel,
        warnings: bodies.warnings,
        parallel,
        output,
        census: bodies.census,
        deal,
        allow_deep_contacts: sim.allow_deep_contacts,
    })
}

/// dt and end_time, checked: positive, at least one step, at most MAX_STEPS.
fn time_stepping(
    ctx: &Ctx,
    span: Range<usize>,
    sim: &SimulationSpec,
) -> Result<(f64, f64), SceneError> {
    let dt = positive(ctx, span.clone(), "simulation.dt", sim.dt)?;
    let end_time = positive(ctx, span.clone(), "simulation.end_time", sim.end_time)?;
    if sim.output_every == 0 {
        return ctx.err(span, "simulation.output_every must be at least 1");
    }
    if end_time < dt {
        return ctx.err(
            span,
            format!(
                "simulation.end_time ({end_time:e} s) is shorter than one step (dt = {dt:e} s)"
            ),
        );
    }
    if end_time / dt > MAX_STEPS as f64 {
        return ctx.err(
            span,
            format!(
                "simulation.end_time / dt = {:.3e} steps, more than the {MAX_STEPS} a run may take",
                end_time / dt
            ),
        );
    }
    Ok((dt, end_time))
}

/// `[effects]`, each entry read by its registered kind; an error names the
/// line of the entry at fault.
fn effects(ctx: &Ctx, table: &Spanned<toml::Table>) -> Result<Effects, SceneError> {
    let entries = table.get_ref().iter().map(|(k, v)| (k.clone(), v.clone()));
    Effects::read(entries).or_else(|(key, cause)| {
        let start = table.span().start;
        let at = key_offset(&ctx.text[start..], &key).map_or(start, |o| start + o);
        ctx.err(at..at, cause)
    })
}

/// Where `key = ` first starts a line of `section` (from the `[effects]`
/// header on, the entry comes before any other use of the word as a key).
fn key_offset(section: &str, key: &str) -> Option<usize> {
    let mut offset = 0;
    for line in section.split_inclusive('\n') {
        let t = line.trim_start();
        if t.strip_prefix(key)
            .is_some_and(|rest| rest.trim_start().starts_with('='))
        {
            return Some(offset + line.len() - t.len());
        }
        offset += line.len();
    }
    None
}

/// The materials, each with exactly the parameters the declared effects
/// need, every one within its bounds.
fn materials(
    ctx: &Ctx,
    specs: &[Spanned<MaterialSpec>],
    effects: &Effects,
) -> Result<Vec<Material>, SceneError> {
    let mut materials: Vec<Material> = Vec::new();
    for m in specs {
        let span = m.span();
        let m = m.get_ref();
        let name = &m.name;
        if materials.iter().any(|x| &x.name == name) {
            return ctx.err(span, format!("material `{name}` is defined twice"));
        }
        positive(
            ctx,
            span.clone(),
            &format!("material `{name}`: density"),
            m.density,
        )?;
        let material = Material {
            name: name.clone(),
            density: m.density,
            stiffness: m.stiffness,
            restitution: m.restitution,
            halo: m.halo,
            friction: m.friction,
        };
        check_material_params(&material, effects).or_else(|cause| ctx.err(span.clone(), cause))?;
        materials.push(material);
        check_pair_laws(&materials).or_else(|cause| ctx.err(span, cause))?;
    }
    Ok(materials)
}

/// The last of `materials` meets every one (itself included) with a contact
/// stiffness f64 can carry: springs in series overflow to no number when
/// their stiffnesses' product or sum does.
fn check_pair_laws(materials: &[Material]) -> Result<(), String> {
    let Some((m, others)) = materials.split_last() else {
        return Ok(());
    };
    for o in others.iter().chain([m]) {
        if let (Some(ka), Some(kb)) = (m.stiffness, o.stiffness) {
            let k = in_series(ka, kb);
            if !(k.is_finite() && k > 0.0) {
                return Err(format!(
                    "material `{}`: its contact stiffness with `{}`, k_a k_b / (k_a + k_b) \
                     with k_a = {ka:e} and k_b = {kb:e}, is {k:e} in f64, not a positive \
                     finite number",
                    m.name, o.name
                ));
            }
        }
    }
    Ok(())
}

/// Every parameter a declared effect needs is set and within its bounds;
/// none is set for an effect the scene does not declare.
fn check_material_params(m: &Material, effects: &Effects) -> Result<(), String> {
    let name = &m.name;
    for (effect, p) in effects.material_params() {
        match (p.get)(m) {
            None => {
                return Err(format!(
                    "material `{name}` needs `{}` for the {effect} effect",
                    p.name
                ))
            }
            Some(x) if !(p.accepts)(x) => {
                return Err(format!(
                    "material `{name}`: {} must be {}, got {x}",
                    p.name, p.must_be
                ))
            }
            Some(_) => {}
        }
    }
    let declared = effects.names();
    for kind in KINDS.iter().filter(|k| !declared.contains(&k.name)) {
        if let Some(p) = kind.material_params.iter().find(|p| (p.get)(m).is_some()) {
            return Err(format!(
                "material `{name}` sets `{}`, but the scene does not declare the {} effect",
                p.name, kind.name
            ));
        }
    }
    Ok(())
}

fn material_index(
    ctx: &Ctx,
    span: Range<usize>,
    world: &World,
    name: &str,
) -> Result<usize, SceneError> {
    world
        .materials
        .iter()
        .position(|m| m.name == name)
        .map_or_else(|| ctx.err(span, format!("unknown material `{name}`")), Ok)
}

/// The particles of one `[[particles]]` entry: its shape, centred on its
/// centre of mass, at each of its placements.
fn add_particles(
    ctx: &Ctx,
    p: &Spanned<ParticleSpec>,
    dt: f64,
    bodies: &mut Bodies,
) -> Result<(), SceneError> {
    let span = p.span();
    let p = p.get_ref();
    let world = &mut bodies.world;
    let mat = material_index(ctx, span.clone(), world, &p.material)?;
    let mesh = make_shape(ctx, span.clone(), &p.shape)?;
    let props = MassProperties::of(&mesh, world.materials[mat].density);
    let local = mesh.translated(-props.centroid);
    let inv_inertia = props.inertia.inverse();
    let density = world.materials[mat].density;
    if !(props.mass.is_normal() && props.inertia.is_finite() && inv_inertia.is_finite()) {
        return ctx.err(
            span,
            format!(
                "the particle's mass ({:e} kg) and inertia are not finite, non-zero f64 \
                 numbers at this size and density ({density:e} kg/m^3)",
                props.mass
            ),
        );
    }
    let radius = local.reach();
    let thickness = smallest_extent(&local);
    let halo = world.materials[mat].halo.unwrap_or(0.0);
    if halo > thickness / 2.0 {
        return ctx.err(
            span,
            format!(
                "material `{}`: the halo ({halo:e} m) is more than half the particle's \
                 smallest extent ({thickness:e} m): contacts would act from further away \
                 than the particle is thick",
                p.material
            ),
        );
    }
    let positions = placements(
        ctx,
        span.clone(),
        &p.placement,
        radius,
        local.triangles.len(),
    )?;
    let far = positions
        .iter()
        .map(|p| DVec3::from_array(*p).abs().max_element())
        .fold(0.0, f64::max);
    check_resolution(ctx, span.clone(), far + radius, (halo, thickness))?;
    if bodies.census.bodies() + positions.len() > MAX_PARTICLES {
        return ctx.err(
            span,
            format!("the scene places more than the {MAX_PARTICLES} particles a scene may"),
        );
    }
    let shape = world.shapes.len();
    world.shapes.push(local);
    let first = bodies.census.bodies() as u32;
    let pending = match &p.placement {
        PlacementSpec::Insert {
            count,
            region,
            rate,
            start,
            seed,
        } => {
            let stream = Stream {
                first,
                count: *count as u32,
                shape,
                material: mat,
                region: region.clone(),
                rate: *rate,
                start: *start,
                seed: *seed,
            };
            bodies.streams.push((stream, span.clone()));
            true
        }
        _ => false,
    };
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(0x5eed);
    for (id, pos) in (first..).zip(&positions) {
        let q = orientation(ctx, span.clone(), p, &mut rng)?;
        let omega = DVec3::from_array(p.angular_velocity);
        let inertia_world = DMat3::from_quat(q) * props.inertia * DMat3::from_quat(q).transpose();
        let body = Body {
            shape,
            material: mat,
            x: DVec3::from_array(*pos),
            q,
            v: DVec3::from_array(p.velocity),
            l: inertia_world * omega,
            inv_mass: 1.0 / props.mass,
            mass: props.mass,
            inv_inertia_body: inv_inertia,
            inertia_body: props.inertia,
            drive: None,
            removed: false,
            pending,
        };
        check_motion(
            ctx,
            span.clone(),
            &body,
            omega,
            dt,
            (thickness, radius),
            &mut bodies.warnings,
        )?;
        bodies.keep(id, body);
    }
    let run = Run {
        ids: first..first + positions.len() as u32,
        shape,
        material: mat,
        mass: props.mass,
        inv_inertia,
        line: ctx.line_of(span.start),
        fixed: None,
        drive: None,
    };
    bodies.census.push(run);
    Ok(())
}

/// Hands the groups to insert to the insertion effect: refused when one
/// is placed without the effect declared, when the effect is declared with
/// none, or when a group's region (grown by its particles' reach) meets an
/// obstacle's triangle, as the obstacle stands at the start.
fn insertion(
    ctx: &Ctx,
    table: &Spanned<toml::Table>,
    effects: &mut Effects,
    bodies: &Bodies,
) -> Result<(), SceneError> {
    let declared = effects.has::<InsertionParams>();
    if !declared && bodies.streams.is_empty() {
        return Ok(());
    }
    if let Some((_, span)) = bodies.streams.first().filter(|_| !declared) {
        return ctx.err(
            span.clone(),
            "this group is inserted during the run: declare `insertion = {}` in [effects]",
        );
    }
    if declared && bodies.streams.is_empty() {
        let start = table.span().start;
        let key = key_offset(&ctx.text[start..], InsertionParams::NAME);
        let at = key.map_or(start, |o| start + o);
        return ctx.err(
            at..at,
            "the insertion effect inserts the groups placed with `kind = \"insert\"`, \
             and no group is",
        );
    }
    let world = &bodies.world;
    for (s, span) in &bodies.streams {
        let reach = world.shape_radii()[s.shape] + world.materials[s.material].halo.unwrap_or(0.0);
        let (lo, hi) = s.region.bounds();
        let (lo, hi) = (lo - reach, hi + reach);
        for (i, b) in (world.bodies.iter().enumerate()).filter(|(_, b)| b.is_static()) {
            let mesh = &world.shapes[b.shape];
            let r = b.rotation();
            let meets = mesh.triangles.iter().any(|t| {
                let v = t.map(|k| b.x + r * mesh.vertices[k as usize]);
                let (tlo, thi) = (v[0].min(v[1]).min(v[2]), v[0].max(v[1]).max(v[2]));
                tlo.cmple(hi).all() && thi.cmpge(lo).all()
            });
            if meets {
                return ctx.err(
                    span.clone(),
                    format!(
                        "placement.region, grown by the particles' radius and halo \
                         ({reach:e} m), reaches the obstacle of body id {}: insertion does \
                         not test against obstacles, so keep the region clear of them",
                        world.id(i)
                    ),
                );
            }
        }
    }
    let streams = bodies.streams.iter().map(|s| s.0.clone()).collect();
    effects.set(InsertionParams { streams });
    Ok(())
}

/// A particle's orientation: identity or random, then its rotation.
fn orientation(
    ctx: &Ctx,
    span: Range<usize>,
    p: &ParticleSpec,
    rng: &mut Xoshiro256PlusPlus,
) -> Result<DQuat, SceneError> {
    let q = match p.orientation.as_deref() {
        None | Some("identity") => DQuat::IDENTITY,
        Some("random") => random_rotation(rng),
        Some(o) => {
            return ctx.err(
                span,
                format!("orientation must be `identity` or `random`, got `{o}`"),
            )
        }
    };
    Ok(match p.rotation {
        Some(r) => turn(ctx, span, r)? * q,
        None => q,
    })
}

/// Largest angle a scene's `rotation` may give, in radians: beyond, f64
/// rounds the angle by more than 1e-10 rad, and a turn by it is a turn by
/// rounding (give such an angle modulo 2π).
const MAX_ANGLE: f64 = 1e6;

/// The turn by a scene's rotation vector (axis times angle, radians).
fn turn(ctx: &Ctx, span: Range<usize>, r: [f64; 3]) -> Result<DQuat, SceneError> {
    let r_vec = DVec3::from_array(r);
    let angle = r_vec.length();
    if !angle.is_finite() || angle > MAX_ANGLE {
        return ctx.err(
            span,
            format!(
                "rotation {r:?} turns by {angle:e} rad, more than {MAX_ANGLE:e}: give the \
                 angle modulo 2π"
            ),
        );
    }
    Ok(crate::exp_map::exp_map(r_vec))
}

/// An obstacle: its mesh in its own frame, where the scene puts it, and how
/// it moves (only where `walls_move`: the wall_motion effect is declared).
fn add_obstacle(
    ctx: &Ctx,
    o: &Spanned<ObstacleSpec>,
    walls_move: bool,
    (dt, end_time): (f64, f64),
    bodies: &mut Bodies,
) -> Result<(), SceneError> {
    let span = o.span();
    let o = o.get_ref();
    let world = &mut bodies.world;
    let mat = material_index(ctx, span.clone(), world, &o.material)?;
    let mesh = make_shape(ctx, span.clone(), &o.shape)?;
    let q = match o.rotation {
        Some(r) => turn(ctx, span.clone(), r)?,
        None => DQuat::IDENTITY,
    };
    let x = DVec3::from_array(o.position);
    let halo = world.materials[mat].halo.unwrap_or(0.0);
    let far = x.abs().max_element() + mesh.reach();
    check_resolution(ctx, span.clone(), far, (halo, smallest_extent(&mesh)))?;
    world.shapes.push(mesh);
    let drive = drive(ctx, span.clone(), o, (x, q), walls_move)?;
    if let Some(d) = &drive {
        let thinnest = bodies
            .census
            .runs()
            .iter()
            .filter(|r| r.fixed.is_none())
            .map(|r| smallest_extent(&world.shapes[r.shape]))
            .fold(f64::INFINITY, f64::min);
        let mesh = world
            .shapes
            .last()
            .expect("the obstacle's shape, just added");
        let thinnest = thinnest.min(smallest_extent(mesh));
        let warning = check_drive(ctx, span.clone(), d, mesh, (dt, end_time), thinnest)?;
        bodies.warnings.extend(warning);
    }
    // A moving wall is where its drive puts it at every time, 0 included.
    let (x, q) = drive.as_ref().map_or((x, q), |d| d.pose(0.0));
    let id = bodies.census.bodies() as u32;
    let body = Body {
        shape: world.shapes.len() - 1,
        material: mat,
        x,
        q,
        v: drive.as_ref().map_or(DVec3::ZERO, |d| d.velocity.at(0.0)),
        l: DVec3::ZERO,
        inv_mass: 0.0,
        mass: f64::INFINITY,
        inv_inertia_body: DMat3::ZERO,
        inertia_body: DMat3::ZERO,
        drive: drive.clone().map(Box::new),
        removed: false,
        pending: false,
    };
    bodies.census.push(Run {
        ids: id..id + 1,
        shape: body.shape,
        material: mat,
        mass: body.mass,
        inv_inertia: DMat3::ZERO,
        line: ctx.line_of(span.start),
        fixed: Some((x, q)),
        drive,
    });
    bodies.keep(id, body);
    Ok(())
}

/// An obstacle's prescribed motion, from its pose at time 0 (`None`: it
/// stands still). Refused unless finite, unless each velocity is given once
/// (constant or table), unless a table's times increase and its angular rows
/// keep one axis, and unless the scene declares the effect that books the
/// walls' work.
fn drive(
    ctx: &Ctx,
    span: Range<usize>,
    o: &ObstacleSpec,
    (x0, q0): (DVec3, DQuat),
    walls_move: bool,
) -> Result<Option<Drive>, SceneError> {
    let velocity = profile(ctx, span.clone(), "velocity", o.velocity, &o.velocity_table)?;
    let angular_velocity = profile(
        ctx,
        span.clone(),
        "angular_velocity",
        o.angular_velocity,
        &o.angular_velocity_table,
    )?;
    if !angular_velocity.keeps_one_axis() {
        return ctx.err(
            span,
            "angular_velocity_table: every row must turn about one axis (parallel \
             angular velocities): a turn about a changing axis has no closed form",
        );
    }
    if let Some(t) = o.remove_at {
        if !(t.is_finite() && t > 0.0) {
            return ctx.err(
                span,
                format!("remove_at must be a time after the start, got {t:e}"),
            );
        }
    }
    let drive = Drive::new(x0, q0, velocity, angular_velocity);
    let drive = match o.remove_at {
        Some(t) => drive.removed_at(t),
        None => drive,
    };
    if !drive.moves() {
        // Removed, or standing still: no work to book.
        return Ok(o.remove_at.map(|_| drive));
    }
    if !walls_move {
        return ctx.err(
            span,
            "this obstacle moves: declare `wall_motion = {}` in [effects], which books \
             the work moving walls do",
        );
    }
    Ok(Some(drive))
}

/// One of an obstacle's velocities: the constant `key`, or `key_table`, or
/// zero; refused when both are given, when a value is not finite, or when a
/// table is empty or its times do not increase.
fn profile(
    ctx: &Ctx,
    span: Range<usize>,
    key: &str,
    constant: Option<[f64; 3]>,
    table: &Option<Vec<[f64; 4]>>,
) -> Result<Profile, SceneError> {
    let finite = |v: &[f64]| v.iter().all(|c| c.is_finite());
    match (constant, table) {
        (Some(_), Some(_)) => ctx.err(span, format!("give {key} or {key}_table, not both")),
        (Some(v), None) if !finite(&v) => ctx.err(span, format!("{key} must be finite")),
        (Some(v), None) => Ok(Profile::Constant(DVec3::from_array(v))),
        (None, None) => Ok(Profile::Constant(DVec3::ZERO)),
        (None, Some(rows)) => {
            if rows.is_empty() {
                return ctx.err(span, format!("{key}_table has no rows"));
            }
            if let Some(k) = rows.iter().position(|r| !finite(r)) {
                return ctx.err(span, format!("{key}_table: row {} must be finite", k + 1));
            }
            if let Some(k) = rows.windows(2).position(|w| w[1][0] <= w[0][0]) {
                return ctx.err(
                    span,
                    format!(
                        "{key}_table: times must increase, but row {} has t = {:e} after t = {:e}",
                        k + 2,
                        rows[k + 1][0],
                        rows[k][0]
                    ),
                );
            }
            let knots = rows
                .iter()
                .map(|r| (r[0], DVec3::new(r[1], r[2], r[3])))
                .collect();
            Ok(Profile::Table(knots))
        }
    }
}

/// A moving wall must stay where numbers are finite over the whole run (a
/// velocity of 1e300 m/s is finite, its position after a second is not):
/// refused otherwise. One whose surface moves more than half the thickness
/// of itself or of the thinnest particle (`thinnest`) in one step can pass
/// through particles between two detections: warned.
fn check_drive(
    ctx: &Ctx,
    span: Range<usize>,
    d: &Drive,
    mesh: &TriMesh,
    (dt, end_time): (f64, f64),
    thinnest: f64,
) -> Result<Option<String>, SceneError> {
    let (end, _) = d.pose(end_time);
    if !end.is_finite() {
        return ctx.err(
            span,
            format!(
                "this obstacle's velocity takes it beyond finite numbers by end_time = \
                 {end_time:e} s"
            ),
        );
    }
    let reach = mesh.reach();
    let speed = d.velocity.largest() + d.angular_velocity.largest() * reach;
    let travel = speed * dt;
    Ok((travel > thinnest / 2.0).then(|| {
        format!(
            "{}:{}: a moving obstacle's surface moves up to {travel:e} m in one step, more \
             than half the thickness of the thinnest body ({thinnest:e} m): it can pass \
             through particles between two detections; lower dt or the speed",
            ctx.file,
            ctx.line_of(span.start)
        )
    }))
}

/// `[kernel]`: the detection's method, batch, fallback, schedule and the
/// penalty kernel's settings, each within its bounds.
fn kernel(ctx: &Ctx, span: Range<usize>, k: KernelSpec) -> Result<Options, SceneError> {
    let method: Method = k
        .method
        .parse()
        .map_or_else(|e| ctx.err(span.clone(), e), Ok)?;
    let schedule: Schedule = k
        .schedule
        .parse()
        .map_or_else(|e| ctx.err(span.clone(), e), Ok)?;
    if !crate::distance::penalty::BATCH_SIZES.contains(&k.batch) {
        return ctx.err(
            span,
            format!(
                "kernel.batch must be one of 1, 2, 4, 8, 16, 32, 64, got {}",
                k.batch
            ),
        );
    }
    if k.grain == 0 {
        return ctx.err(span, "kernel.grain must be at least 1");
    }
    if method == Method::Brute
        && (k.iterations.is_some() || k.finish_rounds.is_some() || k.tolerance.is_some())
    {
        return ctx.err(
            span,
            "kernel.iterations, kernel.finish_rounds and kernel.tolerance set the \
             penalty kernel, which method = \"brute\" does not run",
        );
    }
    let penalty = penalty_params(&k).or_else(|cause| ctx.err(span, cause))?;
    Ok(Options {
        method,
        batch: k.batch,
        penalty,
        fallback: if k.fallback_failed_pairs {
            Fallback::FailedPairs
        } else {
            Fallback::WholeBatch
        },
        threading: Threading {
            schedule,
            grain: k.grain,
        },
    })
}

/// The penalty kernel's settings `[kernel]` sets, each within its bounds.
fn penalty_params(k: &KernelSpec) -> Result<PenaltyParams, String> {
    let mut penalty = PenaltyParams::default();
    if let Some(tol) = k.tolerance {
        // Below a few ulps nothing is ever certified; at 1e-2 an answer may
        // be 1% of the pair's size off.
        if !(1e-15..=1e-2).contains(&tol) {
            return Err(format!(
                "kernel.tolerance must be between 1e-15 and 1e-2, got {tol}"
            ));
        }
        penalty.tol = tol;
    }
    if let Some(n) = k.iterations {
        // Per-pair iteration counts are reported in a byte.
        if !(1..=MAX_ITERATIONS).contains(&n) {
            return Err(format!(
                "kernel.iterations must be between 1 and {MAX_ITERATIONS}, got {n}"
            ));
        }
        penalty.max_iterations = n;
    }
    if let Some(n) = k.finish_rounds {
        if n > MAX_FINISH_ROUNDS {
            return Err(format!(
                "kernel.finish_rounds must be between 0 and {MAX_FINISH_ROUNDS}, got {n}"
            ));
        }
        penalty.finish_rounds = n;
    }
    Ok(penalty)
}

/// The stable step of the contact springs: ω = √(k/m*) for the stiffest
/// pair of materials that can meet (springs in series) and the lightest
/// reduced mass (half the lightest particle), h = (2/ω)(√(1 + ζ²) − ζ)
/// with the largest damping ratio.
fn stable_step(materials: &[Material], census: &Census) -> f64 {
    let (k_max, zeta) = stiffest_law(materials, census);
    step_of(k_max, 2.0 / census.lightest(), zeta)
}

/// The stable step of a particle rocking on a corner: [`stable_step`] with
/// each particle's mass replaced by its smallest effective mass at a point
/// of its surface, 1/m_eff = 1/m + r² λ_max(I⁻¹), r the farthest vertex from
/// its centre of mass (a push at that corner, square to the arm, about the
/// axis of least inertia: the worst case). A body resting on corners rocks
/// about them at up to this rate; a step above it does not resolve the
/// rocking, which then keeps a resting body rattling.
fn rocking_step(materials: &[Material], census: &Census, shapes: &[TriMesh]) -> f64 {
    let (k_max, zeta) = stiffest_law(materials, census);
    let inv_mass = census
        .particle_runs()
        .map(|r| {
            let reach = shapes[r.shape]
                .vertices
                .iter()
                .map(|v| v.length_squared())
                .fold(0.0, f64::max);
            1.0 / r.mass + reach * largest_eigenvalue(r.inv_inertia)
        })
        .fold(0.0, f64::max);
    step_of(k_max, 2.0 * inv_mass, zeta)
}

/// h = (2/ω)(√(1 + ζ²) − ζ), ω = √(k / m*), for a pair of inverse reduced
/// mass `inv_mass`.
fn step_of(k: f64, inv_mass: f64, zeta: f64) -> f64 {
    let omega = (k * inv_mass).sqrt();
    2.0 / omega * ((1.0 + zeta * zeta).sqrt() - zeta)
}

/// The largest eigenvalue of a symmetric positive semi-definite 3×3 matrix
/// (the trigonometric solution of its characteristic cubic).
fn largest_eigenvalue(a: DMat3) -> f64 {
    let [c0, c1, c2] = [a.x_axis, a.y_axis, a.z_axis];
    let p1 = c1.x * c1.x + c2.x * c2.x + c2.y * c2.y;
    let q = (c0.x + c1.y + c2.z) / 3.0;
    if p1 <= f64::EPSILON * q * q {
        return c0.x.max(c1.y).max(c2.z);
    }
    let p2 = (c0.x - q).powi(2) + (c1.y - q).powi(2) + (c2.z - q).powi(2) + 2.0 * p1;
    let p = (p2 / 6.0).sqrt();
    let b = (a - DMat3::from_diagonal(DVec3::splat(q))) * (1.0 / p);
    let r = (b.determinant() / 2.0).clamp(-1.0, 1.0);
    q + 2.0 * p * (r.acos() / 3.0).cos()
}

/// The stiffest pair of materials that can meet (springs in series) and
/// the largest damping ratio.
fn stiffest_law(materials: &[Material], census: &Census) -> (f64, f64) {
    let (used, used_by_particles) = census.materials_used(materials.len());
    let stiffness = |i: usize| materials[i].stiffness.unwrap_or(0.0);
    let mut k_max = 0.0f64;
    for i in (0..materials.len()).filter(|&i| used_by_particles[i]) {
        for j in (0..materials.len()).filter(|&j| used[j]) {
            let (ki, kj) = (stiffness(i), stiffness(j));
            k_max = k_max.max(in_series(ki, kj));
        }
    }
    let zeta = materials
        .iter()
        .filter_map(|m| m.restitution)
        .map(damping_ratio)
        .fold(0.0, f64::max);
    (k_max, zeta)
}

/// `[parallel]`, with its line (its names are checked where they are used).
fn parallel(ctx: &Ctx, span: Range<usize>, p: Parallel) -> Parallel {
    Parallel {
        line: ctx.line_of(span.start),
        ..p
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// R diag(λ) Rᵀ has the eigenvalues λ, whatever the rotation R, at any
    /// scale; repeated eigenvalues included.
    #[test]
    fn the_largest_eigenvalue_of_a_rotated_diagonal_is_its_largest_entry() {
        let r = DMat3::from_quat(DQuat::from_axis_angle(
            DVec3::new(0.3, -1.0, 0.6).normalize(),
            0.9,
        ));
        for (d, scale) in [
            ([1.0, 2.0, 5.0], 1.0),
            ([3.0, 3.0, 0.5], 1e-9),
            ([4.0, 4.0, 4.0], 1e12),
            ([0.0, 7.0, 1.0], 1.0),
        ] {
            let lambda = DVec3::from_array(d) * scale;
            let a = r * DMat3::from_diagonal(lambda) * r.transpose();
            let got = largest_eigenvalue(a);
            let want = lambda.max_element();
            assert!(
                (got - want).abs() <= 1e-12 * want,
                "{d:?} x {scale}: {got} against {want}"
            );
        }
    }
}
