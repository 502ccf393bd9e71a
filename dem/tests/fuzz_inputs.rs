//! No input makes the readers panic: the scene parser and the OBJ and STL
//! (ASCII and binary) loaders, fed thousands of mutations of valid files
//! (bytes flipped, cut, repeated, and tokens that break numbers and
//! structure), return a value or an error, never a panic.
use dem::mesh::load_mesh;
use dem::scene::Scene;
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;

const TOKENS: [&str; 16] = [
    "nan",
    "inf",
    "-inf",
    "-1",
    "0",
    "1e308",
    "-0.0",
    "\"",
    "'",
    "[",
    "]",
    "{",
    "}",
    "=",
    "\n",
    "[[particles]]",
];

/// One mutation of `input`: a byte changed, a range cut or repeated, or a
/// token put in.
fn mutate(input: &[u8], rng: &mut Xoshiro256PlusPlus) -> Vec<u8> {
    let mut v = input.to_vec();
    for _ in 0..rng.random_range(1..4) {
        if v.is_empty() {
            v.push(b'x');
        }
        let at = rng.random_range(0..v.len());
        match rng.random_range(0..4) {
            0 => v[at] = rng.random(),
            1 => {
                let end = (at + rng.random_range(1..16)).min(v.len());
                v.drain(at..end);
            }
            2 => {
                let end = (at + rng.random_range(1..16)).min(v.len());
                let piece = v[at..end].to_vec();
                v.splice(at..at, piece);
            }
            _ => {
                let t = TOKENS[rng.random_range(0..TOKENS.len())];
                v.splice(at..at, t.bytes());
            }
        }
    }
    v
}

fn no_panic(what: &str, input: &[u8], f: impl FnOnce()) {
    if catch_unwind(AssertUnwindSafe(f)).is_err() {
        panic!("{what} panicked on:\n{}", String::from_utf8_lossy(input));
    }
}

#[test]
fn the_scene_parser_never_panics() {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes");
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(11);
    for name in ["drop.toml", "two-particles.toml", "hopper.toml"] {
        let text = std::fs::read(scenes.join(name)).unwrap();
        for _ in 0..400 {
            let bad = mutate(&text, &mut rng);
            let s = String::from_utf8_lossy(&bad).into_owned();
            no_panic(name, &bad, || {
                let _ = Scene::parse(&s, name, &scenes);
            });
        }
    }
}

fn obj() -> Vec<u8> {
    b"# a tetrahedron\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
        .to_vec()
}

fn stl_ascii() -> Vec<u8> {
    let tri = |a: [f32; 3], b: [f32; 3], c: [f32; 3]| {
        format!(
            "facet normal 0 0 0\n outer loop\n  vertex {} {} {}\n  vertex {} {} {}\n  vertex {} {} {}\n endloop\nendfacet\n",
            a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2]
        )
    };
    let (o, x, y, z) = ([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
    format!(
        "solid t\n{}{}{}{}endsolid t\n",
        tri(o, y, x),
        tri(o, x, z),
        tri(o, z, y),
        tri(x, y, z)
    )
    .into_bytes()
}

fn stl_binary() -> Vec<u8> {
    let mut v = vec![0u8; 80];
    v.extend(4u32.to_le_bytes());
    let (o, x, y, z) = ([0f32; 3], [1f32, 0., 0.], [0f32, 1., 0.], [0f32, 0., 1.]);
    for t in [[o, y, x], [o, x, z], [o, z, y], [x, y, z]] {
        v.extend([0u8; 12]);
        for p in t {
            for c in p {
                v.extend(c.to_le_bytes());
            }
        }
        v.extend([0u8; 2]);
    }
    v
}

#[test]
fn the_mesh_loaders_never_panic() {
    let dir = std::env::temp_dir().join(format!("tridem-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(12);
    for (ext, valid) in [("obj", obj()), ("stl", stl_ascii()), ("stl", stl_binary())] {
        let path = dir.join(format!("mesh.{ext}"));
        std::fs::write(&path, &valid).unwrap();
        assert!(load_mesh(&path).is_ok(), "the valid {ext} loads");
        for _ in 0..400 {
            let bad = mutate(&valid, &mut rng);
            std::fs::write(&path, &bad).unwrap();
            no_panic(ext, &bad, || {
                let _ = load_mesh(&path);
            });
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
