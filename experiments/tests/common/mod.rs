//! What the command-line tests share: running `tridem` as a user would.
// Each test file uses what it needs of this module.
#![allow(dead_code)]

use std::io::Write;
use std::process::{Command, Stdio};

/// `tridem ARGS`: exit status, standard output, standard error.
pub fn tridem(args: &[&str]) -> (i32, String, String) {
    tridem_with_input(args, "")
}

/// `tridem ARGS` with `stdin` on its standard input.
pub fn tridem_with_input(args: &[&str], stdin: &str) -> (i32, String, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_tridem"))
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // A command that does not read its input may have closed it already.
    let _ = child.stdin.take().unwrap().write_all(stdin.as_bytes());
    let out = child.wait_with_output().unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// A shipped scene's path.
pub fn scene(name: &str) -> String {
    format!("{}/../scenes/{name}", env!("CARGO_MANIFEST_DIR"))
}

/// The hopper run 4,000 steps into `dir` (emptied first): grains on the
/// funnel, in contact, with every output field.
pub fn hopper_run_into(dir: std::path::PathBuf) -> std::path::PathBuf {
    run_into("hopper.toml", 4000, dir)
}

/// A shipped scene run `steps` steps with output into `dir` (emptied
/// first).
pub fn run_into(name: &str, steps: u64, dir: std::path::PathBuf) -> std::path::PathBuf {
    let _ = std::fs::remove_dir_all(&dir);
    let (code, _, err) = tridem(&[
        "run",
        &scene(name),
        "--steps",
        &steps.to_string(),
        "--output",
        dir.to_str().unwrap(),
        "--quiet",
    ]);
    assert_eq!(code, 0, "{err}");
    dir
}
