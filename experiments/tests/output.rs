//! What `run.h5` and `run.xmf` hold, checked against the states they are
//! made from and against values computed here from the scene: the
//! particles' derived fields, the contact network, the surface's materials,
//! the XDMF index's references, and `tridem plot`'s energy books.
mod common;

use common::{scene, tridem};
use dem::mesh::{MassProperties, TriMesh};
use dem::scene::Scene;
use glam::{DQuat, DVec3};
use ndarray::{Array1, Array2};

fn temp(name: &str) -> std::path::PathBuf {
    std::env::temp_dir().join(format!("tridem-output-{name}-{}", std::process::id()))
}

/// The hopper, 4,000 steps: grains on the funnel, in contact.
fn hopper_run(name: &str) -> std::path::PathBuf {
    common::hopper_run_into(temp(name))
}

fn vec3(a: &Array2<f64>, i: usize) -> DVec3 {
    DVec3::new(a[[i, 0]], a[[i, 1]], a[[i, 2]])
}

fn read2(g: &hdf5::Group, name: &str) -> Array2<f64> {
    g.dataset(name).unwrap().read_2d().unwrap()
}

fn read1<T: hdf5::H5Type>(g: &hdf5::Group, name: &str) -> Array1<T> {
    g.dataset(name).unwrap().read_1d().unwrap()
}

fn close(a: f64, b: f64, scale: f64) -> bool {
    (a - b).abs() <= 1e-12 * scale.max(f64::MIN_POSITIVE)
}

/// The particles' fields: speed = |v|, kinetic energies from the scene's
/// masses and from inertia tensors computed here from the written meshes,
/// angular velocity from the angular momentum, coordination = the
/// contacts each body appears in, and the materials of bodies and surface
/// cells as the scene assigns them.
#[test]
fn particle_fields_follow_from_the_states_and_the_scene() {
    let dir = hopper_run("particles");
    let s = Scene::load(std::path::Path::new(&scene("hopper.toml"))).unwrap();
    let f = hdf5::File::open(dir.join("run.h5")).unwrap();
    let root = f.group("/").unwrap();
    let material: Array1<u32> = read1(&root, "bodies/material");
    let mass: Array1<f64> = read1(&root, "bodies/mass");
    let obstacle: Array1<u8> = read1(&root, "bodies/obstacle");
    let steps = f.group("steps").unwrap();
    let last = steps.len() - 1;
    let mut in_contact = 0;
    for k in [0, last] {
        let g = steps.group(&k.to_string()).unwrap();
        let (v, l) = (read2(&g, "velocities"), read2(&g, "angular_momenta"));
        let q = read2(&g, "orientations");
        let w = read2(&g, "angular_velocities");
        let speed: Array1<f64> = read1(&g, "speeds");
        let kt: Array1<f64> = read1(&g, "kinetic_translation");
        let kr: Array1<f64> = read1(&g, "kinetic_rotation");
        let coordination: Array1<u32> = read1(&g, "contacts");
        let pairs: Array2<u32> = g
            .dataset("contact_forces/bodies")
            .unwrap()
            .read_2d()
            .unwrap();
        let mut counted = vec![0u32; v.nrows()];
        for p in pairs.rows() {
            counted[p[0] as usize] += 1;
            counted[p[1] as usize] += 1;
        }
        assert_eq!(coordination.to_vec(), counted, "step {k}");
        in_contact += counted.iter().filter(|&&c| c > 0).count();
        for (i, b) in s.world.bodies.iter().enumerate() {
            assert_eq!(material[i] as usize, b.material);
            assert_eq!(obstacle[i] == 1, b.is_static());
            if b.is_static() {
                assert_eq!((mass[i], speed[i], kt[i], kr[i]), (0.0, 0.0, 0.0, 0.0));
                continue;
            }
            assert_eq!(mass[i], b.mass);
            let vi = vec3(&v, i);
            assert!(
                close(speed[i], vi.length(), vi.length()),
                "speed of body {i}"
            );
            let e = 0.5 * b.mass * vi.length_squared();
            assert!(
                close(kt[i], e, e),
                "kinetic energy of body {i}: {} vs {e}",
                kt[i]
            );
            // The inertia tensor from the mesh as written (body frame,
            // centred on the centre of mass) and the material's density.
            let shape = f.group(&format!("shapes/{}", b.shape)).unwrap();
            let vertices = read2(&shape, "vertices");
            let triangles: Array2<u32> = shape.dataset("triangles").unwrap().read_2d().unwrap();
            let mesh = TriMesh {
                vertices: (0..vertices.nrows()).map(|r| vec3(&vertices, r)).collect(),
                triangles: triangles
                    .rows()
                    .into_iter()
                    .map(|t| [t[0], t[1], t[2]])
                    .collect(),
            };
            let inertia = MassProperties::of(&mesh, s.world.materials[b.material].density).inertia;
            let qi = DQuat::from_xyzw(q[[i, 0]], q[[i, 1]], q[[i, 2]], q[[i, 3]]);
            let li = vec3(&l, i);
            let omega = qi * (inertia.inverse() * (qi.inverse() * li));
            let scale = omega.length() + 1e-300;
            assert!(
                (vec3(&w, i) - omega).length() <= 1e-9 * scale,
                "angular velocity of body {i}: {:?} vs {omega:?}",
                vec3(&w, i)
            );
            let e = 0.5 * li.dot(omega);
            assert!(
                (kr[i] - e).abs() <= 1e-9 * e.abs().max(1e-300),
                "rotation energy of body {i}"
            );
        }
    }
    assert!(
        in_contact > 0,
        "no body in contact: the coordination check proved nothing"
    );
    // Each surface cell's material is its body's.
    let body: Array1<u32> = read1(&root, "surface/body");
    let cell: Array1<u32> = read1(&root, "surface/material");
    for (t, &b) in body.iter().enumerate() {
        assert_eq!(cell[t], material[b as usize], "triangle {t}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// The contact network: a line per contact from body centre to body centre
/// (the contact point for an obstacle's end), and forces that add up.
#[test]
fn contact_lines_join_the_bodies_in_contact() {
    let dir = hopper_run("contacts");
    let f = hdf5::File::open(dir.join("run.h5")).unwrap();
    let obstacle: Array1<u8> = f.dataset("bodies/obstacle").unwrap().read_1d().unwrap();
    let steps = f.group("steps").unwrap();
    let g = steps.group(&(steps.len() - 1).to_string()).unwrap();
    let x = read2(&g, "positions");
    let c = g.group("contact_forces").unwrap();
    let pairs: Array2<u32> = c.dataset("bodies").unwrap().read_2d().unwrap();
    let lines: Array2<u32> = c.dataset("lines").unwrap().read_2d().unwrap();
    let ends = read2(&c, "line_points");
    let (point, force) = (read2(&c, "points"), read2(&c, "forces"));
    let (normal, tangential) = (read2(&c, "normal_forces"), read2(&c, "tangential_forces"));
    let magnitude: Array1<f64> = read1(&c, "normal_force_magnitudes");
    let overlap: Array1<f64> = read1(&c, "overlaps");
    let slides: Array1<u8> = c.dataset("slides").unwrap().read_1d().unwrap();
    assert!(pairs.nrows() > 0, "no contacts at the last step");
    for r in 0..pairs.nrows() {
        for (side, &id) in pairs.row(r).iter().enumerate() {
            let end = vec3(&ends, lines[[r, side]] as usize);
            let expected = if obstacle[id as usize] == 1 {
                vec3(&point, r)
            } else {
                vec3(&x, id as usize)
            };
            assert_eq!(end, expected, "contact {r}, end {side}");
        }
        let n = vec3(&normal, r);
        assert!(close(magnitude[r], n.length(), n.length()));
        assert_eq!(vec3(&force, r), n + vec3(&tangential, r));
        assert!(overlap[r] > 0.0);
        // The hopper's materials all have μ = 0.3: a sliding contact's
        // friction is held at μ |F_n|, a sticking one's is below it. F_n as
        // written holds, besides the spring and dashpot friction is capped
        // by, the part of a crease crossing's weight gradient, ½ k δ² ∇w:
        // about δ/Λ of the spring's force, and δ is a few µm against a
        // halo sum Λ of 0.5 mm here, so 1e-2.
        let (t, cap) = (vec3(&tangential, r).length(), 0.3 * n.length());
        match slides[r] {
            1 => assert!(
                (t - cap).abs() <= 1e-2 * cap,
                "contact {r} slides: {t} of {cap}"
            ),
            _ => assert!(t <= cap * (1.0 + 1e-2), "contact {r} sticks: {t} of {cap}"),
        }
    }
    assert!(slides.iter().any(|&s| s == 1), "none slides");
    assert!(slides.iter().any(|&s| s == 0), "none sticks");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Every dataset `run.xmf` names exists in `run.h5` with the dimensions the
/// index states; and the four collections each have a grid per step.
#[test]
fn the_xdmf_index_names_only_what_the_file_holds() {
    let dir = hopper_run("xdmf");
    let items = xdmf_items_in_file(&dir);
    let f = hdf5::File::open(dir.join("run.h5")).unwrap();
    let xmf = std::fs::read_to_string(dir.join("run.xmf")).unwrap();
    let steps = f.group("steps").unwrap().len() as usize;
    for grid in ["surface", "particles", "contacts", "contact_points"] {
        let name = format!("<Grid Name=\"{grid}\" GridType=\"Collection\"");
        assert!(xmf.contains(&name), "no {grid} collection");
        let per_step = (0..steps)
            .filter(|k| xmf.contains(&format!("<Grid Name=\"{grid}{k}\"")))
            .count();
        assert_eq!(per_step, steps, "{grid}");
    }
    assert!(items > 20 * steps, "{items} data items");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Checks that every data item of `DIR/run.xmf` is a dataset of `run.h5`
/// of the stated dimensions; returns how many there are.
fn xdmf_items_in_file(dir: &std::path::Path) -> usize {
    let f = hdf5::File::open(dir.join("run.h5")).unwrap();
    let xmf = std::fs::read_to_string(dir.join("run.xmf")).unwrap();
    let mut items = 0;
    for piece in xmf.split("<DataItem ").skip(1) {
        let dims = piece
            .split("Dimensions=\"")
            .nth(1)
            .unwrap()
            .split('"')
            .next()
            .unwrap();
        let dims: Vec<usize> = dims.split(' ').map(|d| d.parse().unwrap()).collect();
        let path = piece
            .split("run.h5:")
            .nth(1)
            .unwrap()
            .split('<')
            .next()
            .unwrap();
        let shape = f
            .dataset(path)
            .unwrap_or_else(|e| panic!("{path}: {e}"))
            .shape();
        assert_eq!(shape, dims, "{path}");
        items += 1;
    }
    items
}

/// The scene's `[output] fields` chooses what a step writes: only the
/// particles here, so no surface or contacts in run.h5 or run.xmf, a
/// smaller file, and a render that needs the surface is refused; a name
/// no field has is refused at its line; a resumed run must write what the
/// run it continues wrote.
#[test]
fn output_fields_choose_what_each_step_writes() {
    let dir = temp("fields");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let hopper = std::fs::read_to_string(scene("hopper.toml")).unwrap();
    let with = |fields: &str, name: &str| {
        let text = format!("{hopper}\n[output]\nfields = {fields}\n");
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        path.to_str().unwrap().to_string()
    };
    let run = |scene: &str, out: &str, extra: &[&str]| {
        let out = dir.join(out);
        let o = out.to_str().unwrap().to_string();
        let args = [
            &["run", scene, "--steps", "2000", "--quiet", "--output", &o][..],
            extra,
        ]
        .concat();
        let (code, _, err) = tridem(&args);
        (code, err, out)
    };
    let all = with(r#"["surface", "particles", "contacts"]"#, "all.toml");
    let few = with(r#"["particles"]"#, "few.toml");
    let (code, err, whole) = run(&all, "whole", &[]);
    assert_eq!(code, 0, "{err}");
    let (code, err, lean) = run(&few, "lean", &[]);
    assert_eq!(code, 0, "{err}");
    let f = hdf5::File::open(lean.join("run.h5")).unwrap();
    let g = f.group("steps/2").unwrap();
    assert!(g.dataset("speeds").is_ok() && g.dataset("positions").is_ok());
    assert!(g.group("surface").is_err() && g.group("contact_forces").is_err());
    assert!(
        f.group("surface").is_err(),
        "no connectivity without the surface"
    );
    let xmf = std::fs::read_to_string(lean.join("run.xmf")).unwrap();
    assert!(xmf.contains("<Grid Name=\"particles\""));
    assert!(!xmf.contains("<Grid Name=\"surface\"") && !xmf.contains("<Grid Name=\"contacts\""));
    assert!(xdmf_items_in_file(&lean) > 0);
    let size = |d: &std::path::Path| std::fs::metadata(d.join("run.h5")).unwrap().len();
    assert!(
        2 * size(&lean) < size(&whole),
        "{} against {}",
        size(&lean),
        size(&whole)
    );
    // The states are the same whatever is written.
    let w = hdf5::File::open(whole.join("run.h5")).unwrap();
    let p = |f: &hdf5::File| read2(&f.group("steps/2").unwrap(), "positions");
    assert_eq!(p(&f), p(&w));
    drop((g, f, w));
    let (code, _, err) = tridem(&["render", lean.to_str().unwrap()]);
    assert_eq!(code, 2);
    assert!(err.contains("without the surface field"), "{err}");
    // Resumed with other fields: refused, the file untouched.
    let before = std::fs::read(lean.join("run.h5")).unwrap();
    let c = lean.join("checkpoint.h5");
    let (code, err, _) = run(&all, "lean", &["--resume", c.to_str().unwrap()]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("output fields [particles]"), "{err}");
    assert_eq!(std::fs::read(lean.join("run.h5")).unwrap(), before);
    let bad = with(r#"["particles", "stress"]"#, "bad.toml");
    let (code, err, out) = run(&bad, "bad", &[]);
    assert_eq!(code, 2);
    let line = hopper.lines().count() + 2;
    assert!(
        err.contains(&format!(
            "bad.toml:{line}: output.fields: unknown output field `stress`"
        )) && err.contains("surface, particles, contacts"),
        "{err}"
    );
    assert!(!out.exists(), "a refused run writes nothing");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `tridem plot DIR --energy` draws the books; their plotted sum stays
/// within 1% of the largest kinetic energy of the run, the tolerance of the
/// energy books' own test, on a collision resolved in many steps (the two
/// particles at dt = 1e-5 s; at coarser steps the books close less well,
/// `scripts/energy-table.sh`).
#[test]
fn the_plotted_energy_books_add_up_to_a_constant() {
    let dir = temp("plot");
    let _ = std::fs::remove_dir_all(&dir);
    let (code, _, err) = tridem(&[
        "run",
        &scene("two-particles.toml"),
        "--set",
        "simulation.dt=1e-5",
        "--set",
        "simulation.output_every=100",
        "--steps",
        "5000",
        "--output",
        dir.to_str().unwrap(),
        "--quiet",
    ]);
    assert_eq!(code, 0, "{err}");
    let d = dir.to_str().unwrap();
    let (code, _, err) = tridem(&["plot", d, "--energy", "--series", "contacts"]);
    assert_eq!(code, 0, "{err}");
    for file in [
        "energy.svg",
        "energy.png",
        "series-contacts.svg",
        "series-contacts.png",
    ] {
        let n = std::fs::metadata(dir.join(file)).map_or(0, |m| m.len());
        assert!(n > 1000, "{file}: {n} bytes");
    }
    let csv = std::fs::read_to_string(dir.join("energy.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    assert!(rows.len() >= 3);
    let (total, kt, kr) = (
        col("total"),
        col("kinetic_translation"),
        col("kinetic_rotation"),
    );
    let kinetic = rows.iter().map(|r| r[kt] + r[kr]).fold(0.0, f64::max);
    assert!(kinetic > 0.0);
    for r in &rows {
        let sum: f64 = r[1..]
            .iter()
            .enumerate()
            .filter(|(i, _)| i + 1 != total)
            .map(|(_, x)| x)
            .sum();
        assert!(
            (sum - r[total]).abs() <= 1e-9 * kinetic,
            "total is not the sum of the books"
        );
        assert!(
            (r[total] - rows[0][total]).abs() <= 0.01 * kinetic,
            "books drift: {r:?}"
        );
    }
    let (code, _, err) = tridem(&["plot", d, "--series", "no-such"]);
    assert_eq!(code, 2);
    assert!(
        err.contains("no series `no-such`") && err.contains("total"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `tridem render DIR` writes a PNG of the asked size, with a picture in it
/// (a blank one compresses to a few kilobytes), for one step or all; a
/// step the run does not have is refused.
#[test]
fn render_draws_a_picture_of_a_step() {
    let dir = hopper_run("render");
    let d = dir.to_str().unwrap();
    let png = dir.join("picture.png");
    let (code, _, err) = tridem(&[
        "render",
        d,
        "--contacts",
        "--color-by",
        "force",
        "--width",
        "640",
        "--height",
        "480",
        "--output",
        png.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(&bytes[1..4], b"PNG");
    let be = |at: usize| u32::from_be_bytes(bytes[at..at + 4].try_into().unwrap());
    assert_eq!((be(16), be(20)), (640, 480), "IHDR width and height");
    assert!(
        bytes.len() > 20_000,
        "{} bytes: a blank picture?",
        bytes.len()
    );
    let frames = dir.join("frames");
    let (code, _, err) = tridem(&["render", d, "--all", "--output", frames.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let steps = hdf5::File::open(dir.join("run.h5"))
        .unwrap()
        .group("steps")
        .unwrap()
        .len();
    assert_eq!(std::fs::read_dir(&frames).unwrap().count() as u64, steps);
    let (code, _, err) = tridem(&["render", d, "--step", "99"]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("--step 99") && err.contains("output steps 0 to"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `tridem chart` draws a CSV's columns, one series per value of --by, with
/// error bars from --error, and refuses a column the file lacks or a cell
/// that is no number, naming the file and its line.
#[test]
fn chart_draws_columns_of_a_csv_and_names_what_is_wrong() {
    let dir = temp("chart");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let csv = dir.join("counts.csv");
    std::fs::write(
        &csv,
        "partitioner,ranks,ghosts\nrcb,2,400\nrcb,4,470\nmetis,4,1970\nmetis,2,1000\n",
    )
    .unwrap();
    let (c, svg) = (csv.to_str().unwrap(), dir.join("ghosts.svg"));
    let args = [
        "chart",
        c,
        "--x",
        "ranks",
        "--y",
        "ghosts",
        "--by",
        "partitioner",
    ];
    let (code, _, err) =
        tridem(&[&args[..], &["--log-x", "--output", svg.to_str().unwrap()]].concat());
    assert_eq!(code, 0, "{err}");
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(
        text.contains("rcb") && text.contains("metis"),
        "both series named"
    );
    let png = std::fs::read(svg.with_extension("png")).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    let (code, _, err) = tridem(&[
        "chart", c, "--x", "ranks", "--y", "nope", "--output", "x.svg",
    ]);
    assert_eq!(code, 2);
    assert!(
        err.contains("counts.csv") && err.contains("no column nope") && err.contains("ghosts"),
        "{err}"
    );
    std::fs::write(&csv, "ranks,ghosts\n2,400\n4,many\n").unwrap();
    let (code, _, err) = tridem(&[
        "chart", c, "--x", "ranks", "--y", "ghosts", "--output", "x.svg",
    ]);
    assert_eq!(code, 2);
    assert!(err.contains("line 3") && err.contains("ghosts"), "{err}");
    // Error bars: one per point with an error cell, none where it is empty;
    // a cell that is no number is refused like any other.
    std::fs::write(&csv, "ranks,ghosts,spread\n2,400,30\n4,470,\n8,500,10\n").unwrap();
    let draw = |error: &[&str]| {
        let base = ["chart", c, "--x", "ranks", "--y", "ghosts", "--output"];
        let (code, _, err) = tridem(&[&base[..], &[svg.to_str().unwrap()], error].concat());
        assert_eq!(code, 0, "{err}");
        std::fs::read_to_string(&svg).unwrap()
    };
    let lines = |t: &str| t.matches("<polyline").count() + t.matches("<line").count();
    let (bare, barred) = (draw(&[]), draw(&["--error", "spread"]));
    assert!(lines(&barred) > lines(&bare), "error bars drawn");
    std::fs::write(&csv, "ranks,ghosts,spread\n2,400,wide\n").unwrap();
    let (code, _, err) = tridem(&[
        "chart", c, "--x", "ranks", "--y", "ghosts", "--error", "spread", "--output", "x.svg",
    ]);
    assert_eq!(code, 2);
    assert!(err.contains("line 2") && err.contains("error"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The surface of a scene larger than the blocks it is written in (the
/// boulders: 400,000 triangles): its connectivity is every body's mesh, as
/// the scene builds it, with the vertices numbered body after body, and
/// each step's points are the meshes placed at the step's poses.
#[test]
fn the_surface_is_every_body_mesh_in_order_across_blocks() {
    let dir = common::run_into("boulders.toml", 1, temp("surface"));
    let s = Scene::load(std::path::Path::new(&scene("boulders.toml"))).unwrap();
    let f = hdf5::File::open(dir.join("run.h5")).unwrap();
    let root = f.group("/").unwrap();
    let triangles: Array2<u32> = root
        .dataset("surface/triangles")
        .unwrap()
        .read_2d()
        .unwrap();
    let body: Array1<u32> = read1(&root, "surface/body");
    let material: Array1<u32> = read1(&root, "surface/material");
    let g = f.group("steps/0").unwrap();
    let (x, q, points) = (
        read2(&g, "positions"),
        read2(&g, "orientations"),
        read2(&g, "surface/points"),
    );
    let (mut t, mut first) = (0usize, 0usize);
    for (i, b) in s.world.bodies.iter().enumerate() {
        let mesh = &s.world.shapes[b.shape];
        for tri in &mesh.triangles {
            let row: Vec<u32> = tri.iter().map(|&v| v + first as u32).collect();
            assert_eq!(triangles.row(t).to_vec(), row, "triangle {t}");
            assert_eq!((body[t], material[t]), (i as u32, b.material as u32));
            t += 1;
        }
        let qi = DQuat::from_xyzw(q[[i, 0]], q[[i, 1]], q[[i, 2]], q[[i, 3]]);
        for (k, &v) in mesh.vertices.iter().enumerate() {
            let p = vec3(&x, i) + qi * v;
            let d = (vec3(&points, first + k) - p).length();
            assert!(d <= 1e-12 * p.length(), "point {} of body {i}", first + k);
        }
        first += mesh.vertices.len();
    }
    assert!(t > 2 * 8192, "the scene fills more than two blocks");
    assert_eq!((triangles.nrows(), points.nrows()), (t, first));
    let _ = std::fs::remove_dir_all(&dir);
}
