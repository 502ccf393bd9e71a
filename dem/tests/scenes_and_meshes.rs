//! Bad input is refused with the file, line and cause; meshes must be closed,
//! consistently oriented and non-degenerate.
use dem::effects::ContactParams;
use dem::mesh::{box_mesh, MeshError, TriMesh};
use dem::scene::Scene;
use glam::DVec3;
use std::path::Path;

const BASE: &str = r#"
[simulation]
dt = 1e-5
end_time = 0.1

[effects]
gravity = { g = [0.0, 0.0, -9.81] }
contact = {}

[[materials]]
name = "m"
density = 1000.0
stiffness = 1e4
restitution = 0.5
halo = 1e-4

[[particles]]
material = "m"
shape = { kind = "tetrahedron", radius = 0.01 }
placement = { kind = "single", position = [0.0, 0.0, 0.0] }
"#;

fn parse(text: &str) -> Result<Scene, dem::scene::SceneError> {
    Scene::parse(text, "scene.toml", Path::new("."))
}

#[test]
fn the_base_scene_parses() {
    let s = parse(BASE).unwrap();
    assert_eq!(s.effects.names(), vec!["gravity", "contact"]);
    assert!(s.stable_dt.unwrap() > s.dt);
}

#[test]
fn unknown_effect_is_an_error_with_its_line() {
    let text = BASE.replace("contact = {}", "contact = {}\nmagnetism = {}");
    let e = parse(&text).unwrap_err();
    assert_eq!(e.file, "scene.toml");
    assert_eq!(e.line, 9, "{e}");
    assert!(e.cause.contains("magnetism"), "{e}");
}

#[test]
fn parameters_of_undeclared_effects_are_errors() {
    let e = parse(&BASE.replace("halo = 1e-4", "halo = 1e-4\nfriction = 0.3")).unwrap_err();
    assert!(e.cause.contains("friction effect"), "{e}");
    // The material's table starts on line 10.
    assert_eq!(e.line, 10, "{e}");
    let no_contact = BASE.replace("contact = {}\n", "");
    let e = parse(&no_contact).unwrap_err();
    assert!(
        e.cause.contains("does not declare the contact effect"),
        "{e}"
    );
}

#[test]
fn the_contact_skin_is_read_and_bad_ones_refused() {
    let skin = |s: &dem::scene::Scene| s.effects.get::<ContactParams>().unwrap().skin;
    assert_eq!(skin(&parse(BASE).unwrap()), 0.0);
    let s = parse(&BASE.replace("contact = {}", "contact = { skin = 2e-4 }")).unwrap();
    assert_eq!(skin(&s), 2e-4);
    for bad in ["-1e-3", "nan", "inf"] {
        let text = BASE.replace("contact = {}", &format!("contact = {{ skin = {bad} }}"));
        let e = parse(&text).unwrap_err();
        assert!(
            e.cause.contains("contact") && e.cause.contains("skin"),
            "{bad}: {e}"
        );
        // Refused where written (line 8).
        assert_eq!(e.line, 8, "{e}");
    }
    let text = BASE.replace("contact = {}", "contact = { skim = 1e-3 }");
    let e = parse(&text).unwrap_err();
    assert!(e.cause.contains("skim"), "{e}");
}

#[test]
fn malformed_toml_names_the_line() {
    let text = BASE.replace("end_time = 0.1", "end_time = = 0.1");
    let e = parse(&text).unwrap_err();
    assert_eq!(e.line, 4, "{e}");
}

#[test]
fn nan_and_negative_values_are_refused() {
    let e = parse(&BASE.replace("density = 1000.0", "density = nan")).unwrap_err();
    assert!(e.cause.contains("density"), "{e}");
    let e = parse(&BASE.replace("dt = 1e-5", "dt = -1e-5")).unwrap_err();
    assert!(e.cause.contains("dt"), "{e}");
}

#[test]
fn a_step_above_the_stable_one_is_refused_or_warned() {
    let text = BASE.replace("dt = 1e-5", "dt = 1e-2");
    let e = parse(&text).unwrap_err();
    assert!(e.cause.contains("stable step"), "{e}");
    assert_eq!(e.line, 2);
    let allowed = text.replace("end_time = 0.1", "end_time = 0.1\nallow_unstable_dt = true");
    let s = parse(&allowed).unwrap();
    assert_eq!(s.warnings.len(), 1);
}

#[test]
fn kernel_settings_are_read_and_bad_ones_refused() {
    let text = format!("{BASE}\n[kernel]\nschedule = \"dynamic\"\ngrain = 4\nbatch = 16\n");
    let s = parse(&text).unwrap();
    assert_eq!(s.kernel.threading.grain, 4);
    assert_eq!(
        s.kernel.threading.schedule,
        dem::distance::Schedule::Dynamic
    );
    assert_eq!(s.kernel.batch, 16);
    // [kernel] is on line 22 of the text.
    let e = parse(&text.replace("grain = 4", "grain = 0")).unwrap_err();
    assert!(e.cause.contains("kernel.grain"), "{e}");
    assert_eq!(e.line, 22, "{e}");
    let e = parse(&text.replace("batch = 16", "batch = 12")).unwrap_err();
    assert!(e.cause.contains("kernel.batch"), "{e}");
    let e = parse(&text.replace("\"dynamic\"", "\"eager\"")).unwrap_err();
    assert!(e.cause.contains("unknown schedule `eager`"), "{e}");
    assert_eq!(e.line, 22, "{e}");
    // The penalty kernel's iterations and finish rounds, for the methods that run it.
    let tuned = parse(&format!("{text}iterations = 6\nfinish_rounds = 0\n")).unwrap();
    assert_eq!(tuned.kernel.penalty.max_iterations, 6);
    assert_eq!(tuned.kernel.penalty.finish_rounds, 0);
    let default = dem::distance::PenaltyParams::default();
    assert_eq!(s.kernel.penalty, default);
    for (bad, what) in [
        ("iterations = 0\n", "kernel.iterations must be between 1"),
        ("iterations = 256\n", "kernel.iterations must be between 1"),
        (
            "finish_rounds = 9\n",
            "kernel.finish_rounds must be between 0",
        ),
        (
            "method = \"brute\"\nfinish_rounds = 1\n",
            "method = \"brute\" does not run",
        ),
    ] {
        let e = parse(&format!("{text}{bad}")).unwrap_err();
        assert!(e.cause.contains(what), "{bad}: {e}");
        assert_eq!(e.line, 22, "{e}");
    }
    let guided = parse(&text.replace("\"dynamic\"", "\"guided\"")).unwrap();
    assert_eq!(
        guided.kernel.threading.schedule,
        dem::distance::Schedule::Guided
    );
}

#[test]
fn unknown_material_is_reported_at_the_particle() {
    let e = parse(&BASE.replace("material = \"m\"", "material = \"wood\"")).unwrap_err();
    assert!(e.cause.contains("unknown material `wood`"), "{e}");
    // The particle's table starts on line 17.
    assert_eq!(e.line, 17, "{e}");
}

#[test]
fn missing_scene_file_names_the_file() {
    let e = Scene::load(Path::new("/nonexistent/scene.toml")).unwrap_err();
    assert!(e.to_string().starts_with("/nonexistent/scene.toml"), "{e}");
}

#[test]
fn open_inconsistent_and_degenerate_meshes_are_refused() {
    let b = box_mesh(DVec3::ONE).unwrap();
    let mut open = b.triangles.clone();
    open.pop();
    assert!(matches!(
        TriMesh::new(b.vertices.clone(), open),
        Err(MeshError::Open(..))
    ));
    let mut flipped = b.triangles.clone();
    flipped[3].swap(1, 2);
    assert!(matches!(
        TriMesh::new(b.vertices.clone(), flipped),
        Err(MeshError::Inconsistent(..))
    ));
    let mut degenerate = b.vertices.clone();
    degenerate[7] = (degenerate[5] + degenerate[6]) * 0.5;
    let e = TriMesh::new(degenerate, b.triangles.clone()).unwrap_err();
    assert!(
        matches!(e, MeshError::Degenerate(_) | MeshError::Open(..)),
        "{e}"
    );
    let mut nan = b.vertices.clone();
    nan[0].x = f64::NAN;
    assert_eq!(
        TriMesh::new(nan, b.triangles.clone()),
        Err(MeshError::NonFinite(0))
    );
    // Inward-facing but consistent: turned outward.
    let inward: Vec<[u32; 3]> = b.triangles.iter().map(|t| [t[0], t[2], t[1]]).collect();
    let m = TriMesh::new(b.vertices.clone(), inward).unwrap();
    assert!(m.signed_volume() > 0.0);
}

#[test]
fn obj_and_stl_meshes_load_and_bad_ones_name_the_file() {
    let dir = std::env::temp_dir().join(format!("tridem-mesh-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let b = box_mesh(DVec3::new(1.0, 2.0, 3.0)).unwrap();
    let mut obj = String::new();
    for v in &b.vertices {
        obj.push_str(&format!("v {} {} {}\n", v.x, v.y, v.z));
    }
    for t in &b.triangles {
        obj.push_str(&format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1));
    }
    let p = dir.join("box.obj");
    std::fs::write(&p, &obj).unwrap();
    let m = dem::mesh::load_mesh(&p).unwrap();
    assert!((m.signed_volume() - 6.0).abs() < 1e-12);
    // An open OBJ (last face missing) is refused, naming the file.
    let open: String = obj
        .lines()
        .take(obj.lines().count() - 1)
        .map(|l| format!("{l}\n"))
        .collect();
    let p2 = dir.join("open.obj");
    std::fs::write(&p2, open).unwrap();
    let e = dem::mesh::load_mesh(&p2).unwrap_err().to_string();
    assert!(e.contains("open.obj") && e.contains("open"), "{e}");
    // Coordinates are read in double precision: a 1 cm cube 100 km from
    // the origin keeps its size to 1e-10 m (single precision would make it
    // 1.56 cm wide).
    let far = box_mesh(DVec3::splat(0.01))
        .unwrap()
        .translated(DVec3::splat(1e5));
    let mut obj = String::new();
    for v in &far.vertices {
        obj.push_str(&format!("v {:?} {:?} {:?}\n", v.x, v.y, v.z));
    }
    for t in &far.triangles {
        obj.push_str(&format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1));
    }
    let p3 = dir.join("far.obj");
    std::fs::write(&p3, &obj).unwrap();
    let (lo, hi) = dem::mesh::load_mesh(&p3).unwrap().bounds();
    for k in 0..3 {
        assert!((hi[k] - lo[k] - 0.01).abs() < 1e-10, "{lo} .. {hi}");
    }
    let _ = std::fs::remove_dir_all(dir);
}

/// A scene loaded in shares: the shares' particles are the whole scene's,
/// each once, with the whole scene's ids and states; every share keeps the
/// obstacles; and what each share knows of the whole (counts, fingerprint,
/// the lines that placed bodies, the stable step) is what the whole scene
/// says of itself.
#[test]
fn shares_of_a_scene_make_up_the_whole_scene() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes");
    for file in ["hopper.toml", "mixed.toml", "silo-1000.toml"] {
        let path = dir.join(file);
        let whole = Scene::load(&path).unwrap();
        let w = &whole.world;
        let mut seen = vec![0; w.bodies.len()];
        for ranks in [1, 3, 4] {
            seen.iter_mut().for_each(|s| *s = 0);
            for rank in 0..ranks {
                let share = dem::scene::Deal { rank, ranks };
                let part = Scene::load_dealt(&path, share).unwrap();
                assert_eq!(part.fingerprint(), w.fingerprint(), "{file}");
                assert_eq!(part.census.bodies(), w.bodies.len());
                assert_eq!(part.census.particles(), w.dynamic_count());
                assert_eq!(part.particle_triangles(), w.particle_triangles());
                assert_eq!(
                    part.stable_dt.map(f64::to_bits),
                    whole.stable_dt.map(f64::to_bits)
                );
                for (i, b) in part.world.bodies.iter().enumerate() {
                    let id = part.world.id(i) as usize;
                    seen[id] += 1;
                    let a = &w.bodies[id];
                    assert_eq!((b.x, b.q, b.v, b.l, b.shape), (a.x, a.q, a.v, a.l, a.shape));
                    assert!(b.is_static() || id as u32 % ranks == rank);
                    assert_eq!(part.body_name(id), whole.body_name(id));
                }
            }
            for (id, &n) in seen.iter().enumerate() {
                let expected = if w.bodies[id].is_static() { ranks } else { 1 };
                assert_eq!(n, expected, "{file}: body {id} on {n} of {ranks} shares");
            }
        }
        // The first particle and the last obstacle name their tables' lines.
        let text = std::fs::read_to_string(&path).unwrap();
        let line_of = |table: &str| {
            let lines: Vec<usize> = (1..)
                .zip(text.lines())
                .filter(|(_, l)| l.trim() == table)
                .map(|(n, _)| n)
                .collect();
            lines.clone()
        };
        let first = line_of("[[particles]]")[0];
        let last = *line_of("[[obstacles]]").last().unwrap();
        assert_eq!(whole.body_name(0), format!("body 0 (line {first})"));
        let n = w.bodies.len() - 1;
        assert_eq!(whole.body_name(n), format!("body {n} (line {last})"));
        let shapes: Vec<usize> = whole.census.shapes().collect();
        let direct: Vec<usize> = w.bodies.iter().map(|b| b.shape).collect();
        assert_eq!(shapes, direct, "{file}");
    }
}

/// A drum's shell is an obstacle like any other; bad dimensions are refused
/// with the key at fault.
#[test]
fn tubes_are_read_and_bad_ones_refused() {
    let tube = |shape: &str| {
        format!(
            "{BASE}\n[[obstacles]]\nmaterial = \"m\"\nshape = {{ kind = \"tube\", {shape} }}\nposition = [0.0, 0.0, 0.0]\n"
        )
    };
    let s = parse(&tube("inner_radius = 0.1, thickness = 0.01, length = 0.05")).unwrap();
    let mesh = &s.world.shapes[s.world.bodies[1].shape];
    assert_eq!(mesh.triangles.len(), 8 * 48, "48 sides by default");
    // At the obstacle's table (line 22), or at the value itself (line 24)
    // when it is no number at all.
    let dims = "inner_radius = 0.1, thickness = 0.01";
    for (bad, what, line) in [
        (
            "inner_radius = 0.0, thickness = 0.01, length = 0.05",
            "shape.inner_radius",
            22,
        ),
        (
            "inner_radius = 0.1, thickness = -1.0, length = 0.05",
            "shape.thickness",
            22,
        ),
        (&format!("{dims}, length = 0.0"), "shape.length", 22),
        (
            &format!("{dims}, end_inner_radius = -0.1, length = 0.05"),
            "shape.end_inner_radius",
            22,
        ),
        (&format!("{dims}, length = nan"), "shape.length", 24),
        (
            &format!("{dims}, length = 0.05, segments = 2"),
            "shape.segments",
            22,
        ),
        (
            &format!("{dims}, length = 0.05, segments = 1000000"),
            "shape.segments",
            22,
        ),
    ] {
        let e = parse(&tube(bad)).unwrap_err();
        assert!(e.cause.contains(what), "{bad}: {e}");
        assert_eq!(e.line, line, "{bad}: {e}");
    }
}

/// Every shape kind at lengths whose triangles' areas underflow f64 (or
/// whose coordinates, volume or inertia overflow it) is refused at the
/// particle's or obstacle's table, never a panic; at the sizes a scene may
/// use, 1e-6 to 1e6 in metres, the same shapes are read.
#[test]
fn shapes_beyond_what_f64_carries_are_refused_with_their_line() {
    let dir = std::env::temp_dir().join(format!("tridem-sizes-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    std::fs::write(dir.join("tet.obj"), obj).unwrap();
    let shapes = |l: f64| {
        [
            format!("{{ kind = \"hull\", triangles = 20, radius = {l:e}, seed = 1 }}"),
            format!("{{ kind = \"tetrahedron\", radius = {l:e} }}"),
            format!("{{ kind = \"box\", size = [{l:e}, {l:e}, {l:e}], subdivide = 1 }}"),
            format!("{{ kind = \"mesh\", file = \"tet.obj\", scale = {l:e} }}"),
        ]
    };
    // A particle of the shape, its halo a fifth of its size (the halo may
    // be no more than half its thickness), placed at the origin.
    let scene = |shape: &str, l: f64| {
        format!(
            "[simulation]\ndt = 1e-5\nend_time = 0.1\nallow_unstable_dt = true\n\n\
             [effects]\ncontact = {{}}\n\n\
             [[materials]]\nname = \"m\"\ndensity = 1000.0\nstiffness = 1e4\nrestitution = 0.5\nhalo = {:e}\n\n\
             [[particles]]\nmaterial = \"m\"\nshape = {shape}\nplacement = {{ kind = \"single\", position = [0.0, 0.0, 0.0] }}\n",
            0.05 * l
        )
    };
    let parse_in = |text: &str| Scene::parse(text, "scene.toml", &dir);
    for l in [1e-6, 1.0, 1e6] {
        for shape in shapes(l) {
            parse_in(&scene(&shape, l)).unwrap_or_else(|e| panic!("{shape}: {e}"));
        }
    }
    for l in [1e-300, 1e-200, 1e-120, 1e-100, 1e100, 1e200, 1e300] {
        for shape in shapes(l) {
            let text = scene(&shape, l);
            let e = std::panic::catch_unwind(|| parse_in(&text))
                .unwrap_or_else(|_| panic!("{shape} panicked"))
                .expect_err(&shape);
            assert_eq!(e.line, 16, "{shape}: {e}");
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Far from the origin f64 rounds coordinates coarsely: a body placed where
/// the rounding is a sizeable part of its halo is refused, naming how far
/// it reaches; the same scene a million sizes out is read.
#[test]
fn bodies_placed_where_rounding_swallows_the_halo_are_refused() {
    let at = |x: f64| {
        BASE.replace(
            "position = [0.0, 0.0, 0.0]",
            &format!("position = [{x:e}, 0.0, 0.0]"),
        )
    };
    for x in [1e4, -1e6] {
        parse(&at(x)).unwrap_or_else(|e| panic!("{x}: {e}"));
    }
    for x in [1e12, -1e15, 1e300] {
        let e = parse(&at(x)).unwrap_err();
        assert_eq!(e.line, 17, "{x}: {e}");
        assert!(e.cause.contains("from the origin"), "{x}: {e}");
    }
    let obstacle = |x: f64| {
        format!(
            "{BASE}\n[[obstacles]]\nmaterial = \"m\"\nshape = {{ kind = \"box\", size = [1.0, 1.0, 0.1] }}\nposition = [0.0, {x:e}, -1.0]\n"
        )
    };
    parse(&obstacle(1e5)).unwrap();
    let e = parse(&obstacle(1e13)).unwrap_err();
    assert_eq!(e.line, 22, "{e}");
    assert!(e.cause.contains("from the origin"), "{e}");
}

/// Contact stiffnesses combine as springs in series, k_a k_b / (k_a + k_b):
/// stiffnesses whose product or sum overflows f64 are refused at the
/// material, with the two stiffnesses named, rather than giving a contact
/// law (and a stable step) of no number.
#[test]
fn stiffnesses_whose_series_overflows_are_refused() {
    let with = |k: &str| {
        BASE.replace("stiffness = 1e4", &format!("stiffness = {k}"))
            .replace("end_time = 0.1", "end_time = 0.1\nallow_unstable_dt = true")
    };
    let s = parse(&with("1e150")).unwrap();
    assert_eq!(s.world.materials[0].stiffness, Some(1e150));
    for k in ["1e300", "1.7e308"] {
        let e = parse(&with(k)).unwrap_err();
        assert_eq!(e.line, 11, "{k}: {e}");
        assert!(e.cause.contains("contact stiffness"), "{k}: {e}");
    }
}

/// OBJ files as exporters write them: faces with normal and texture
/// indices (`f 1/1/1 ...`, `f 1//1 ...`), and one surface split into groups,
/// objects or material runs. Each is the same closed mesh as the plain
/// file: its eight corners once each, its twelve triangles, its volume.
#[test]
fn obj_exports_with_normals_and_groups_read_as_one_closed_mesh() {
    let dir = std::env::temp_dir().join(format!("tridem-obj-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let b = box_mesh(DVec3::new(1.0, 2.0, 3.0)).unwrap();
    let corners: String = b
        .vertices
        .iter()
        .map(|v| format!("v {} {} {}\n", v.x, v.y, v.z))
        .collect();
    let extra = "vt 0 0\nvt 1 0\nvt 0 1\n";
    let normals: String = (0..b.triangles.len())
        .map(|k| format!("vn 0 0 {}\n", k + 1))
        .collect();
    // Each face: its corners (1-based), written by `corner(face, index)`,
    // with a line before every fourth face (a group, an object, a material).
    let write = |name: &str, corner: &dyn Fn(usize, u32) -> String, split: &str| {
        let mut text = format!("{corners}{extra}{normals}");
        for (k, t) in b.triangles.iter().enumerate() {
            if k % 4 == 0 && !split.is_empty() {
                text.push_str(&format!("{split} part{k}\n"));
            }
            let c: Vec<String> = t.iter().map(|&i| corner(k, i + 1)).collect();
            text.push_str(&format!("f {}\n", c.join(" ")));
        }
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        dem::mesh::load_mesh(&p).unwrap_or_else(|e| panic!("{name}: {e}"))
    };
    let plain = |_: usize, i: u32| format!("{i}");
    let with_normal = |k: usize, i: u32| format!("{i}//{}", k + 1);
    let with_both = |k: usize, i: u32| format!("{i}/{}/{}", i % 3 + 1, k + 1);
    let reference = write("plain.obj", &plain, "");
    for (name, corner, split) in [
        (
            "normals.obj",
            &with_normal as &dyn Fn(usize, u32) -> String,
            "",
        ),
        ("texcoords.obj", &with_both, ""),
        ("groups.obj", &plain, "g"),
        ("objects.obj", &plain, "o"),
        ("objects-normals.obj", &with_normal, "o"),
        ("materials.obj", &with_both, "usemtl"),
    ] {
        let m = write(name, corner, split);
        assert_eq!(m.vertices.len(), 8, "{name}");
        assert_eq!(m.triangles.len(), 12, "{name}");
        assert_eq!(m.signed_volume(), reference.signed_volume(), "{name}");
        assert!((m.signed_volume() - 6.0).abs() < 1e-12, "{name}");
    }
    let _ = std::fs::remove_dir_all(dir);
}

/// STL files as exporters write them: ASCII with its keywords in capitals
/// and CRLF line ends, and binary with a header that starts with "solid"
/// (as many CAD exporters write it). Each reads as the unit tetrahedron,
/// of volume 1/6.
#[test]
fn stl_exports_in_capitals_or_with_a_solid_header_read_as_the_same_mesh() {
    let dir = std::env::temp_dir().join(format!("tridem-stl-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let v = [
        [0.0f32; 3],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    let faces = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    let mut ascii = String::from("SOLID T\r\n");
    for f in faces {
        ascii.push_str("  FACET NORMAL 0 0 0\r\n    OUTER LOOP\r\n");
        for i in f {
            let [x, y, z] = v[i];
            ascii.push_str(&format!("      VERTEX {x:E} {y:E} {z:E}\r\n"));
        }
        ascii.push_str("    ENDLOOP\r\n  ENDFACET\r\n");
    }
    ascii.push_str("ENDSOLID T\r\n");
    let mut binary = b"solid written by a CAD program".to_vec();
    binary.resize(80, b' ');
    binary.extend(4u32.to_le_bytes());
    for f in faces {
        binary.extend([0u8; 12]);
        for i in f {
            binary.extend(v[i].iter().flat_map(|c| c.to_le_bytes()));
        }
        binary.extend([0u8; 2]);
    }
    for (name, bytes) in [
        ("capitals.stl", ascii.into_bytes()),
        ("solid-header.stl", binary),
    ] {
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        let m = dem::mesh::load_mesh(&p).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(m.vertices.len(), 4, "{name}");
        assert!((m.signed_volume() - 1.0 / 6.0).abs() < 1e-15, "{name}");
    }
    let _ = std::fs::remove_dir_all(dir);
}

/// A particle whose surface crosses half its thickness in one step can pass
/// through a wall between two detections, whether it moves or spins that
/// fast: a tetrahedron of circumradius 1 cm spinning at 1e5 rad/s sweeps
/// 1 cm per 1e-5 s step, and is warned of; at 10 rad/s, or moving at
/// 1 m/s, it is not.
#[test]
fn a_particle_spinning_through_its_thickness_in_a_step_is_warned_of() {
    let with = |motion: &str| {
        let text = BASE.replace(
            "placement = { kind = \"single\", position = [0.0, 0.0, 0.0] }",
            &format!("placement = {{ kind = \"single\", position = [0.0, 0.0, 0.0] }}\n{motion}"),
        );
        parse(&text).unwrap().warnings
    };
    let fast = with("angular_velocity = [0.0, 1e5, 0.0]");
    assert_eq!(fast.len(), 1, "{fast:?}");
    assert!(
        fast[0].contains("spin") && fast[0].contains("scene.toml:17"),
        "{fast:?}"
    );
    for slow in [
        "angular_velocity = [0.0, 10.0, 0.0]",
        "velocity = [1.0, 0.0, 0.0]",
    ] {
        assert!(with(slow).is_empty(), "{slow}: {:?}", with(slow));
    }
}

/// A placement that places no particle, or places them outside the box it
/// names, and a rotation f64 cannot turn by, are refused at the particle's
/// line; the same placements made sound are read.
#[test]
fn placements_that_place_nothing_or_outside_their_box_are_refused() {
    let line = BASE.lines().position(|l| l == "[[particles]]").unwrap() + 1;
    let placed = |placement: &str| {
        let text = BASE.replace(
            r#"placement = { kind = "single", position = [0.0, 0.0, 0.0] }"#,
            placement,
        );
        parse(&text)
    };
    let refused = |placement: &str, cause: &str| {
        let e = placed(placement)
            .err()
            .unwrap_or_else(|| panic!("accepted: {placement}"));
        assert_eq!(e.line, line, "{e}");
        assert!(e.cause.contains(cause), "{placement}: {e}");
    };
    let lattice = |count: &str| {
        format!(
            r#"placement = {{ kind = "lattice", count = {count}, spacing = 0.03, origin = [0.0, 0.0, 0.0] }}"#
        )
    };
    refused(&lattice("[0, 2, 2]"), "along x");
    refused(&lattice("[2, 2, 0]"), "along z");
    assert_eq!(placed(&lattice("[1, 2, 2]")).unwrap().world.bodies.len(), 4);
    let random = |count: usize, lo: &str, hi: &str| {
        format!(r#"placement = {{ kind = "random", count = {count}, lo = {lo}, hi = {hi} }}"#)
    };
    refused(
        &random(0, "[0.0, 0.0, 0.0]", "[1.0, 1.0, 1.0]"),
        "count = 0",
    );
    // lo above hi, and a box thinner than a particle (diameter 0.02).
    refused(&random(5, "[0.0, 0.0, 0.0]", "[-1.0, 1.0, 1.0]"), "along x");
    refused(&random(5, "[0.0, 0.0, 0.0]", "[1.0, 0.01, 1.0]"), "along y");
    let scene = placed(&random(5, "[0.0, 0.0, 0.0]", "[1.0, 1.0, 0.02]")).unwrap();
    for b in &scene.world.bodies {
        assert!(
            b.x.z == 0.01,
            "a flat box's particles lie in its middle: {}",
            b.x
        );
    }
    let single = r#"placement = { kind = "single", position = [0.0, 0.0, 0.0] }"#;
    for angle in ["1e300", "1e7"] {
        refused(
            &format!("{single}\nrotation = [{angle}, 0.0, 0.0]"),
            "modulo 2π",
        );
    }
    // A turn by 5 rad about (0.6, 0, 0.8), as Rodrigues' formula turns y.
    let q = placed(&format!("{single}\nrotation = [3.0, 0.0, 4.0]"))
        .unwrap()
        .world
        .bodies[0]
        .q;
    let (k, v, angle) = (DVec3::new(0.6, 0.0, 0.8), DVec3::Y, 5.0f64);
    let rodrigues = v * angle.cos() + k.cross(v) * angle.sin() + k * k.dot(v) * (1.0 - angle.cos());
    assert!((q * v - rodrigues).length() < 1e-12, "{q}");
    let wall = "\n[[obstacles]]\nmaterial = \"m\"\nshape = { kind = \"box\", size = [1.0, 1.0, 0.1] }\nposition = [0.0, 0.0, -1.0]\n";
    let e = parse(&format!("{BASE}{wall}rotation = [0.0, 1e300, 0.0]\n")).unwrap_err();
    assert_eq!(e.line, BASE.lines().count() + 2, "{e}");
    assert!(e.cause.contains("modulo 2π"), "{e}");
}
