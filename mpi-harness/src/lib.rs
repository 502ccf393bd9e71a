//! Run a program under `mpirun` from a test and collect what each rank reported.
//!
//! MPI can be initialised only once per process, so a multi-rank test cannot
//! run inside the test binary itself. Instead the test builds a small program
//! (a cargo example of the crate under test, which `cargo test` builds
//! alongside the tests), runs it on N ranks and checks every rank's report.
//!
//! A rank reports with [`Reporter`]: one line per call, written to a file per
//! rank in a directory the harness creates, so that output of different ranks
//! never interleaves and stray prints of libraries do not matter.
//!
//! ```no_run
//! let run = mpi_harness::MpiRun::new(mpi_harness::example_binary("rcb_tiny"))
//!     .ranks(2)
//!     .run()
//!     .expect("mpirun");
//! assert_eq!(run.reports.len(), 2);
//! ```

use std::ffi::OsString;
use std::fmt;
use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// Environment variable naming the directory where ranks write their reports.
pub const REPORT_DIR_VAR: &str = "MPI_HARNESS_REPORT_DIR";

/// Why a run could not be carried out or did not succeed.
#[derive(Debug)]
pub enum HarnessError {
    /// The launcher (`mpirun`, or `$MPIRUN`) could not be started.
    LauncherMissing {
        launcher: String,
        cause: std::io::Error,
    },
    /// The program to run does not exist (not built?).
    ProgramMissing(PathBuf),
    /// The run took longer than its timeout and was killed.
    Timeout {
        after: Duration,
        stdout: String,
        stderr: String,
    },
    /// mpirun exited with failure.
    Failed {
        code: Option<i32>,
        stdout: String,
        stderr: String,
    },
    /// A rank wrote no report at all.
    MissingReport {
        rank: usize,
        stderr: String,
    },
    Io(std::io::Error),
}

impl fmt::Display for HarnessError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            HarnessError::LauncherMissing { launcher, cause } => write!(
                f,
                "cannot start MPI launcher `{launcher}`: {cause}. Install openmpi-bin \
                 (scripts/install-deps.sh) or set MPIRUN to your launcher"
            ),
            HarnessError::ProgramMissing(p) => {
                write!(f, "program {} does not exist; was it built?", p.display())
            }
            HarnessError::Timeout {
                after,
                stdout,
                stderr,
            } => write!(
                f,
                "mpirun killed after {after:?}\n--- stdout\n{stdout}\n--- stderr\n{stderr}"
            ),
            HarnessError::Failed {
                code,
                stdout,
                stderr,
            } => write!(
                f,
                "mpirun failed with exit code {code:?}\n--- stdout\n{stdout}\n--- stderr\n{stderr}"
            ),
            HarnessError::MissingReport { rank, stderr } => {
                write!(f, "rank {rank} wrote no report\n--- stderr\n{stderr}")
            }
            HarnessError::Io(e) => write!(f, "I/O error: {e}"),
        }
    }
}

impl std::error::Error for HarnessError {}

impl From<std::io::Error> for HarnessError {
    fn from(e: std::io::Error) -> Self {
        HarnessError::Io(e)
    }
}

/// The path of a cargo example built in the same profile as the running test.
///
/// Test binaries live in `target/<profile>/deps/`, examples in
/// `target/<profile>/examples/`.
pub fn example_binary(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("current_exe");
    let profile_dir = exe
        .parent()
        .and_then(Path::parent)
        .expect("test binary is in target/<profile>/deps");
    profile_dir.join("examples").join(name)
}

/// The launcher command: `$MPIRUN` or `mpirun`.
pub fn launcher() -> String {
    std::env::var("MPIRUN").unwrap_or_else(|_| "mpirun".into())
}

/// The launcher's arguments for `ranks` processes: `mpirun --oversubscribe
/// -np N` (Open MPI on one machine, more ranks than cores allowed), or, when
/// `$MPIRUN` is SLURM's srun inside an allocation, `srun --mpi=pmix -n N`
/// (Debian's Open MPI needs PMIx to be started by srun; `$TRIDEM_SRUN_MPI`
/// names another plugin). Shared so that `tridem study` and the tests agree.
pub fn launch_args(ranks: usize) -> Vec<String> {
    if launcher().ends_with("srun") {
        let plugin = std::env::var("TRIDEM_SRUN_MPI").unwrap_or_else(|_| "pmix".into());
        vec![format!("--mpi={plugin}"), "-n".into(), ranks.to_string()]
    } else {
        vec!["--oversubscribe".into(), "-np".into(), ranks.to_string()]
    }
}

/// Environment for Open MPI on a single machine, possibly as root, in a
/// container; each call names a session directory of its own.
///
/// Open MPI 4 keeps a run's session files under `$TMPDIR/ompi.<host>.<uid>`,
/// and mpiruns started at the same moment (tests run in parallel) race to
/// create that directory: "mkdir ... File exists", then orte_init fails
/// (open-mpi/ompi#8510). A directory per launch avoids the race, whoever
/// starts the launcher.
pub fn open_mpi_local_env() -> Vec<(&'static str, OsString)> {
    vec![
        ("OMPI_ALLOW_RUN_AS_ROOT", "1".into()),
        ("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1".into()),
        // Containers often forbid the cross-memory-attach shared memory uses.
        ("OMPI_MCA_btl_vader_single_copy_mechanism", "none".into()),
        // No network beyond loopback here: keep Open MPI from probing interfaces.
        ("OMPI_MCA_btl", "self,vader".into()),
        ("OMPI_MCA_rmaps_base_oversubscribe", "1".into()),
        ("OMPI_MCA_orte_tmpdir_base", session_dir().into_os_string()),
    ]
}

/// A fresh directory for one launch's Open MPI session files.
fn session_dir() -> PathBuf {
    static NEXT: AtomicU64 = AtomicU64::new(0);
    let n = NEXT.fetch_add(1, Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("mpi-session-{}-{n}", std::process::id()));
    // A launcher that cannot use it says so itself, naming the directory.
    let _ = fs::create_dir_all(&dir);
    dir
}

/// A configured run of one program under mpirun.
pub struct MpiRun {
    program: PathBuf,
    ranks: usize,
    args: Vec<String>,
    env: Vec<(String, String)>,
    timeout: Duration,
    expect_reports: bool,
}

/// What one rank reported, line by line.
#[derive(Debug, Clone)]
pub struct RankReport {
    pub rank: usize,
    pub lines: Vec<String>,
}

impl RankReport {
    /// The value of the first `key=value` line with this key.
    pub fn value(&self, key: &str) -> Option<&str> {
        self.lines.iter().find_map(|l| {
            l.split_once('=')
                .filter(|(k, _)| k.trim() == key)
                .map(|(_, v)| v.trim())
        })
    }

    /// The value of `key`, parsed; panics with the rank's report if missing or malformed.
    pub fn parse<T: std::str::FromStr>(&self, key: &str) -> T {
        let v = self.value(key).unwrap_or_else(|| {
            panic!(
                "rank {} did not report `{key}`: {:?}",
                self.rank, self.lines
            )
        });
        v.parse()
            .unwrap_or_else(|_| panic!("rank {}: cannot parse `{key}={v}`", self.rank))
    }
}

/// The result of a successful run.
#[derive(Debug)]
pub struct RunOutput {
    /// One report per rank, indexed by rank.
    pub reports: Vec<RankReport>,
    pub stdout: String,
    pub stderr: String,
}

impl MpiRun {
    pub fn new(program: impl Into<PathBuf>) -> Self {
        MpiRun {
            program: program.into(),
            ranks: 1,
            args: Vec::new(),
            env: Vec::new(),
            timeout: Duration::from_secs(300),
            expect_reports: true,
        }
    }

    pub fn ranks(mut self, n: usize) -> Self {
        self.ranks = n;
        self
    }

    pub fn arg(mut self, a: impl Into<String>) -> Self {
        self.args.push(a.into());
        self
    }

    pub fn args<I, S>(mut self, args: I) -> Self
    where
        I: IntoIterator<Item = S>,
        S: Into<String>,
    {
        self.args.extend(args.into_iter().map(Into::into));
        self
    }

    pub fn env(mut self, k: impl Into<String>, v: impl Into<String>) -> Self {
        self.env.push((k.into(), v.into()));
        self
    }

    /// Whether every rank must write a report (default). Turn off to run a
    /// program that only prints, and check `RunOutput::stdout`.
    pub fn expect_reports(mut self, yes: bool) -> Self {
        self.expect_reports = yes;
        self
    }

    pub fn timeout(mut self, t: Duration) -> Self {
        self.timeout = t;
        self
    }

    /// Runs the program and returns every rank's report; fails if mpirun fails,
    /// times out, or a rank reported nothing.
    pub fn run(self) -> Result<RunOutput, HarnessError> {
        if !self.program.exists() {
            return Err(HarnessError::ProgramMissing(self.program));
        }
        let dir = tempdir()?;
        let launcher = launcher();
        let mut cmd = Command::new(&launcher);
        cmd.args(launch_args(self.ranks))
            .arg(&self.program)
            .args(&self.args)
            .env(REPORT_DIR_VAR, &dir)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        for (k, v) in open_mpi_local_env() {
            cmd.env(k, v);
        }
        for (k, v) in &self.env {
            cmd.env(k, v);
        }
        let mut child = cmd.spawn().map_err(|cause| HarnessError::LauncherMissing {
            launcher: launcher.clone(),
            cause,
        })?;

        // Drain the pipes on threads so a chatty program cannot fill them and stall.
        let out_pipe = child.stdout.take().unwrap();
        let err_pipe = child.stderr.take().unwrap();
        let out_thread = std::thread::spawn(move || read_all(out_pipe));
        let err_thread = std::thread::spawn(move || read_all(err_pipe));

        let start = Instant::now();
        let status = loop {
            if let Some(status) = child.try_wait()? {
                break Some(status);
            }
            if start.elapsed() > self.timeout {
                let _ = child.kill();
                let _ = child.wait();
                break None;
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        let stdout = out_thread.join().unwrap_or_default();
        let stderr = err_thread.join().unwrap_or_default();

        let result = match status {
            None => Err(HarnessError::Timeout {
                after: self.timeout,
                stdout,
                stderr,
            }),
            Some(s) if !s.success() => Err(HarnessError::Failed {
                code: s.code(),
                stdout,
                stderr,
            }),
            Some(_) if !self.expect_reports => Ok(RunOutput {
                reports: Vec::new(),
                stdout,
                stderr,
            }),
            Some(_) => collect_reports(&dir, self.ranks, stdout, stderr),
        };
        let _ = fs::remove_dir_all(&dir);
        result
    }
}

fn collect_reports(
    dir: &Path,
    ranks: usize,
    stdout: String,
    stderr: String,
) -> Result<RunOutput, HarnessError> {
    let mut reports = Vec::with_capacity(ranks);
    for rank in 0..ranks {
        let path = dir.join(format!("rank-{rank}.txt"));
        let text = match fs::read_to_string(&path) {
            Ok(t) => t,
            Err(_) => return Err(HarnessError::MissingReport { rank, stderr }),
        };
        reports.push(RankReport {
            rank,
            lines: text.lines().map(String::from).collect(),
        });
    }
    Ok(RunOutput {
        reports,
        stdout,
        stderr,
    })
}

fn read_all(mut r: impl std::io::Read) -> String {
    let mut buf = Vec::new();
    let _ = r.read_to_end(&mut buf);
    String::from_utf8_lossy(&buf).into_owned()
}

fn tempdir() -> std::io::Result<PathBuf> {
    use std::sync::atomic::{AtomicUsize, Ordering};
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("mpi-harness-{}-{n}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir)?;
    Ok(dir)
}

/// Used inside the program run by the harness: writes one rank's report.
///
/// Outside the harness (no report directory set) lines go to stdout prefixed
/// with the rank, so the same program is useful by hand.
pub struct Reporter {
    rank: usize,
    file: Option<fs::File>,
}

impl Reporter {
    pub fn new(rank: usize) -> Self {
        let file = std::env::var_os(REPORT_DIR_VAR).map(|dir| {
            fs::File::create(PathBuf::from(dir).join(format!("rank-{rank}.txt")))
                .expect("cannot create rank report file")
        });
        Reporter { rank, file }
    }

    /// Reports one `key=value` line.
    pub fn kv(&mut self, key: &str, value: impl fmt::Display) {
        self.line(&format!("{key}={value}"));
    }

    pub fn line(&mut self, line: &str) {
        match &mut self.file {
            Some(f) => {
                writeln!(f, "{line}").expect("cannot write rank report");
                f.flush().expect("cannot flush rank report");
            }
            None => println!("[rank {}] {line}", self.rank),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rank_report_parses_key_values() {
        let r = RankReport {
            rank: 1,
            lines: vec!["parts=3".into(), "name = rcb".into(), "noise".into()],
        };
        assert_eq!(r.value("name"), Some("rcb"));
        assert_eq!(r.parse::<u32>("parts"), 3);
        assert_eq!(r.value("missing"), None);
    }

    #[test]
    fn missing_launcher_is_a_clear_error() {
        // Point MPIRUN at something that cannot exist; the program must exist for
        // the launcher to be tried, so use this test binary itself.
        let me = std::env::current_exe().unwrap();
        std::env::set_var("MPIRUN", "/nonexistent/mpirun-for-test");
        let err = MpiRun::new(me).ranks(1).run().unwrap_err();
        std::env::remove_var("MPIRUN");
        let msg = err.to_string();
        assert!(matches!(err, HarnessError::LauncherMissing { .. }), "{msg}");
        assert!(msg.contains("/nonexistent/mpirun-for-test"), "{msg}");
    }
}
