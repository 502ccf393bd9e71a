//! `run.xmf` as ParaView reads it: ParaView's own readers, run by `pvbatch`
//! (installed by `scripts/install-deps.sh --render`, which the test command
//! runs), open the hopper's output, and every grid's cells, points and
//! attributes at the first and the last output step must be the datasets of
//! `run.h5` that the index names, value for value; speed must be the length
//! of velocity as ParaView holds them. Both readers are checked: the XDMF 2
//! reader ParaView offers first for `.xmf`, and the XDMF 3 one ("Xdmf3 Reader
//! (T)"), which draws no cell of a point set without its connectivity.
mod common;

use common::hopper_run_into;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The grids of `run.xmf`, in the file's order (the readers' block order).
const GRIDS: [&str; 4] = ["surface", "particles", "contacts", "contact_points"];

/// Prints, as JSON, for each reader and for the first and last times: per
/// block, its cell count, its points and every point and cell array, flat.
const READ: &str = r#"
import json, struct, sys
from paraview.simple import XDMFReader, Xdmf3ReaderT
from paraview import servermanager as sm
from vtk.numpy_interface import dataset_adapter as dsa

def flat(a):
    # Each value's IEEE bits, which JSON carries exactly.
    if a is None:
        return []
    return [struct.unpack("<Q", struct.pack("<d", float(x)))[0] for x in a.ravel()]

out = {}
for name, make in (("xdmf2", lambda p: XDMFReader(FileNames=[p])),
                   ("xdmf3", lambda p: Xdmf3ReaderT(FileName=[p]))):
    r = make(sys.argv[1])
    times = list(r.TimestepValues)
    steps = []
    for t in (times[0], times[-1]):
        r.UpdatePipeline(t)
        d = sm.Fetch(r)
        blocks = []
        for i in range(d.GetNumberOfBlocks()):
            b = d.GetBlock(i)
            if b is None or b.GetNumberOfPoints() == 0:
                blocks.append({"cells": 0, "points": [], "arrays": {}})
                continue
            w = dsa.WrapDataObject(b)
            arrays = {k: flat(w.PointData[k]) for k in w.PointData.keys()}
            arrays.update({k: flat(w.CellData[k]) for k in w.CellData.keys()})
            blocks.append({"cells": b.GetNumberOfCells(), "points": flat(w.Points),
                           "arrays": arrays})
        steps.append({"time": t, "blocks": blocks})
    out[name] = {"times": len(times), "steps": steps}
json.dump(out, open(sys.argv[2], "w"))
"#;

fn pvbatch() -> PathBuf {
    let found = std::env::var_os("PATH").and_then(|paths| {
        std::env::split_paths(&paths)
            .map(|p| p.join("pvbatch"))
            .find(|p| p.is_file())
    });
    found.expect(
        "pvbatch not found: ParaView is needed to check run.xmf as ParaView reads it \
         (scripts/install-deps.sh --render installs it; scripts/test.sh does)",
    )
}

/// A dataset of `run.h5`, whatever its number type, as flat f64s.
fn dataset(file: &hdf5::File, path: &str) -> Vec<f64> {
    let ds = file.dataset(path).unwrap();
    if let Ok(v) = ds.read_raw::<f64>() {
        return v;
    }
    if let Ok(v) = ds.read_raw::<u32>() {
        return v.into_iter().map(f64::from).collect();
    }
    ds.read_raw::<u8>()
        .unwrap()
        .into_iter()
        .map(f64::from)
        .collect()
}

/// The grid `name` of output step `k` in `run.xmf`: its element count, its
/// geometry's dataset and each attribute's (name, dataset).
fn grid(xmf: &str, name: &str, k: usize) -> (usize, String, Vec<(String, String)>) {
    let start = xmf
        .find(&format!("<Grid Name=\"{name}{k}\""))
        .unwrap_or_else(|| panic!("no grid {name}{k}"));
    let text = &xmf[start..start + xmf[start..].find("</Grid>").unwrap()];
    let path = |piece: &str| {
        let at = piece.find("run.h5:/").unwrap() + "run.h5:/".len();
        piece[at..at + piece[at..].find('<').unwrap()].to_string()
    };
    let between = |s: &str, a: &str, b: &str| {
        let at = s.find(a).unwrap() + a.len();
        s[at..at + s[at..].find(b).unwrap()].to_string()
    };
    let elements = between(text, "NumberOfElements=\"", "\"").parse().unwrap();
    let geometry = path(&text[text.find("<Geometry").unwrap()..]);
    let attributes = text
        .split("<Attribute ")
        .skip(1)
        .map(|a| (between(a, "Name=\"", "\""), path(a)))
        .collect();
    (elements, geometry, attributes)
}

fn read_in_paraview(dir: &Path) -> Value {
    let script = dir.join("read.py");
    std::fs::write(&script, READ).unwrap();
    let json = dir.join("paraview.json");
    let out = Command::new(pvbatch())
        .arg(&script)
        .arg(dir.join("run.xmf"))
        .arg(&json)
        .current_dir(dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "pvbatch: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap()
}

/// Values sent as their IEEE bits (JSON parsers may round decimals).
fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| f64::from_bits(x.as_u64().unwrap()))
        .collect()
}

/// Value for value: the count, then the first difference.
fn same(got: &[f64], want: &[f64], what: &str) {
    assert_eq!(got.len(), want.len(), "{what}: how many values");
    if let Some(i) = (0..got.len()).find(|&i| got[i].to_bits() != want[i].to_bits()) {
        panic!(
            "{what}: value {i} is {} in ParaView, {} in run.h5",
            got[i], want[i]
        );
    }
}

#[test]
fn paraview_reads_every_grid_and_attribute_of_run_xmf() {
    let dir = hopper_run_into(
        std::env::temp_dir().join(format!("tridem-paraview-{}", std::process::id())),
    );
    let seen = read_in_paraview(&dir);
    let xmf = std::fs::read_to_string(dir.join("run.xmf")).unwrap();
    let file = hdf5::File::open(dir.join("run.h5")).unwrap();
    let last = file.group("steps").unwrap().len() as usize - 1;
    let mut contacts_seen = 0;
    for reader in ["xdmf2", "xdmf3"] {
        let r = &seen[reader];
        assert_eq!(r["times"].as_u64().unwrap() as usize, last + 1, "{reader}");
        for (s, k) in [0, last].into_iter().enumerate() {
            let blocks = r["steps"][s]["blocks"].as_array().unwrap();
            assert_eq!(blocks.len(), GRIDS.len(), "{reader}: grids");
            for (g, name) in GRIDS.iter().enumerate() {
                let (elements, geometry, attributes) = grid(&xmf, name, k);
                let b = &blocks[g];
                let at = format!("{reader}, {name}, step {k}");
                assert_eq!(
                    b["cells"].as_u64().unwrap() as usize,
                    elements,
                    "{at}: cells"
                );
                if elements == 0 {
                    continue;
                }
                same(
                    &floats(&b["points"]),
                    &dataset(&file, &geometry),
                    &format!("{at}: points"),
                );
                for (attribute, path) in &attributes {
                    let got = b["arrays"]
                        .get(attribute)
                        .unwrap_or_else(|| panic!("{at}: ParaView has no attribute `{attribute}`"));
                    same(
                        &floats(got),
                        &dataset(&file, path),
                        &format!("{at}: `{attribute}`"),
                    );
                }
                if *name == "particles" {
                    let v = floats(&b["arrays"]["velocity"]);
                    let speed = floats(&b["arrays"]["speed"]);
                    for (i, s) in speed.iter().enumerate() {
                        let w = &v[3 * i..3 * i + 3];
                        let norm = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
                        assert!((s - norm).abs() <= 1e-12 * norm, "{at}: speed {i}");
                    }
                }
                if *name == "contacts" {
                    contacts_seen += elements;
                }
            }
        }
    }
    assert!(
        contacts_seen > 0,
        "no contact at the last step: nothing read"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
