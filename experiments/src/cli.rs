//! Command-line interface: one subcommand per experiment.

use crate::bounds;
use crate::stats::Statistic;
use clap::{Args, Parser, Subcommand};
use dem::distance::{Method, PenaltyParams, Schedule};
use std::path::PathBuf;

#[derive(Parser, Debug)]
#[command(
    name = "tridem",
    version,
    about = "DEM with triangulated particles, and load balancing it across MPI ranks"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Print the versions of Zoltan, MPI, HDF5 and METIS, and the ranks and threads in use.
    #[command(after_help = "Examples:\n  \
        tridem info\n  \
        mpirun -np 2 tridem info --json")]
    Info(InfoArgs),
    /// Distance between triangle pairs read as CSV (18 numbers per row: the
    /// three vertices of A, then of B) from FILE or stdin.
    ///
    /// Prints one line per pair: distance,px,py,pz,qx,qy,qz,solver, with p on
    /// A and q on B the closest points, and solver the kernel that answered
    /// (brute or penalty).
    #[command(after_help = "Examples:\n  \
        echo 0,0,0,1,0,0,0,1,0,0,0,1,1,0,1,0,1,1 | tridem distance --header\n  \
        tridem distance --method brute dem/tests/data/triangle-pairs.csv")]
    Distance(DistanceArgs),
    /// Benchmark the triangle-distance kernels, or sweep accuracy against time (--accuracy).
    #[command(after_help = "Examples:\n  \
        tridem kernels --pairs 1e6 --threads 2 --schedule guided\n  \
        tridem kernels --accuracy --pairs 1e5 --output out/kernels")]
    Kernels(KernelsArgs),
    /// Point-to-point latency and bandwidth between ranks 0 and 1 (run under
    /// mpirun): the inputs of the communication model in docs/distributed.md.
    #[command(after_help = "Examples:\n  \
        mpirun -np 2 tridem pingpong\n  \
        mpirun -np 2 tridem pingpong --json")]
    Pingpong(PingpongArgs),
    /// Partition a synthetic workload with one partitioner (run under mpirun).
    #[command(after_help = "Examples:\n  \
        mpirun -np 4 tridem partition --partitioner zoltan-rcb --workload hopper --items 1e6 --steps 20\n  \
        mpirun -np 4 tridem partition --partitioner metis --json >> out/partition.jsonl")]
    Partition(PartitionArgs),
    /// Run a DEM scene (TOML): on this node, or under `mpirun -np P` split across P ranks.
    ///
    /// The scene format is in docs/dem.md ("Scenes") and in the `dem::scene`
    /// module's documentation; scenes/ has examples.
    #[command(after_help = "Examples:\n  \
        tridem run scenes/hopper.toml --output out/hopper\n  \
        tridem run scenes/hopper.toml --output out/hopper --resume out/hopper/checkpoint.h5\n  \
        tridem run scenes/hopper.toml --steps 1000 --set kernel.method=brute --json\n  \
        mpirun -np 4 tridem run scenes/silo.toml --partitioner rcb --repartition-every 100 \\\n      \
        --metrics out/silo/metrics.jsonl --output out/silo")]
    Run(RunArgs),
    /// Thread scaling of a DEM scene: runs at each thread count, alternating, and the
    /// ratio of the median times, measured side by side in one invocation.
    #[command(after_help = "Examples:\n  \
        tridem scaling scenes/hopper.toml --threads 1,2 --repeat 5\n  \
        tridem scaling scenes/hopper-400.toml --statistic min --json")]
    Scaling(ScalingArgs),
    /// Plot the JSON lines of `tridem partition --json` runs (time and ghosts per partitioner).
    #[command(after_help = "Example:\n  \
        tridem partition-plot out/partition.jsonl --output out/partition.svg")]
    PartitionPlot(PartitionPlotArgs),
    /// Plot a run's per-step scalars from its output (DIR/run.h5): the
    /// energy books over time (--energy), or any named series (--series).
    ///
    /// Writes DIR/NAME.svg, DIR/NAME.png and DIR/NAME.csv (the plotted
    /// numbers) for each plot; --list prints the series the run has.
    #[command(after_help = "Examples:\n  \
        tridem plot out/hopper --energy\n  \
        tridem plot out/hopper --series contacts --series kinetic_translation\n  \
        tridem plot out/hopper --list")]
    Plot(PlotArgs),
    /// Plot columns of a CSV file against one another: one line per value
    /// of --by, a marker at every point of a series of up to 16, error bars
    /// from --error (SVG and PNG).
    #[command(after_help = "Example:\n  \
        tridem chart out/counts.csv --x ranks --y ghosts_max --by partitioner --log-x \\\n      \
        --output out/ghosts.svg")]
    Chart(ChartArgs),
    /// A picture (PNG) of an output step of a run (DIR/run.h5): the
    /// particles coloured by a field, the obstacles translucent, and with
    /// --contacts the contact network (line width by normal force).
    #[command(after_help = "Examples:\n  \
        tridem render out/hopper\n  \
        tridem render out/hopper --step 3 --color-by force --contacts --output hopper.png\n  \
        tridem render out/hopper --all --output out/hopper/frames")]
    Render(RenderArgs),
    /// A study on real runs of a scene: repartition frequency, partitioners,
    /// the ghost exchange (under mpirun), thread scheduling, or what kernel
    /// accuracy costs; metrics, a summary CSV, figures (SVG and PNG) and a table.
    #[command(after_help = "Examples:\n  \
        tridem study partitioners --ranks 4 --steps 3000\n  \
        tridem study exchange --ranks 2,4\n  \
        tridem study scheduling --threads 1,2\n  \
        tridem study accuracy --output out/study-accuracy --overwrite")]
    Study(StudyArgs),
}

/// The studies of `tridem study`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum StudyName {
    /// Repartitioning every K steps: time by section, imbalance, a fitted cost model.
    RepartitionFrequency,
    /// Zoltan RCB, RIB, HSFC, METIS and the native RCB on the same run.
    Partitioners,
    /// Blocking against non-blocking ghost exchange, over rank counts.
    Exchange,
    /// Static, dynamic and guided sharing of body pairs among threads, with
    /// whole-batch and failed-pairs fallback: time, idle time, fallbacks per task.
    Scheduling,
    /// Kernel settings against the deviation of the trajectories from a
    /// brute-force run, and their time per step.
    Accuracy,
}

impl StudyName {
    pub fn name(self) -> &'static str {
        match self {
            StudyName::RepartitionFrequency => "repartition-frequency",
            StudyName::Partitioners => "partitioners",
            StudyName::Exchange => "exchange",
            StudyName::Scheduling => "scheduling",
            StudyName::Accuracy => "accuracy",
        }
    }

    /// Steps per run unless --steps says.
    pub fn default_steps(self) -> u64 {
        match self {
            StudyName::Accuracy => 500,
            _ => 3000,
        }
    }

    /// Whether the study's runs are distributed (under mpirun) or on one node.
    pub fn distributed(self) -> bool {
        !matches!(self, StudyName::Scheduling | StudyName::Accuracy)
    }
}

#[derive(Args, Debug)]
pub struct StudyArgs {
    pub name: StudyName,
    /// The scene every run steps (default: scenes/collapse.toml for
    /// repartition-frequency and partitioners, where the ranks' work parts as
    /// the column spreads; scenes/silo-1000.toml for the others).
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Ranks (the exchange study runs each count; the other distributed
    /// studies the first; scheduling and accuracy run on one node).
    #[arg(long, value_delimiter = ',', default_value = "2", value_parser = bounds::ranks)]
    pub ranks: Vec<usize>,
    /// Threads per rank (default 1); the scheduling study runs each count
    /// given (default 1 up to all cores).
    #[arg(long, value_delimiter = ',', value_parser = bounds::threads)]
    pub threads: Vec<usize>,
    /// Steps per run (default 3000: 0.15 s of the scene;
    /// accuracy: 500, before the trajectories of every setting have parted
    /// chaotically), after the --settle steps.
    #[arg(long, value_parser = bounds::steps)]
    pub steps: Option<u64>,
    /// Steps the scene runs once, with brute force on every core, before
    /// the study; every run then resumes from its final state (default:
    /// accuracy 5000, so that its runs step the dense phase, thousands of
    /// contacts per step; the others 0, from the scene's start).
    #[arg(long, value_parser = bounds::steps)]
    pub settle: Option<u64>,
    /// The repartitioning intervals K of repartition-frequency (0: never).
    #[arg(long, value_delimiter = ',', default_value = "1,5,20,100,0", value_parser = bounds::steps)]
    pub every: Vec<u64>,
    /// The imbalance thresholds τ of repartition-frequency's adaptive runs
    /// (repartition once the busy time's max/mean over 20 steps exceeds τ).
    #[arg(long, value_delimiter = ',', default_value = "1.1,1.3")]
    pub when: Vec<f64>,
    /// Runs of each setting, taken in turn (ABCABC...): the tables give
    /// their median and least and most, the figures error bars.
    #[arg(long, default_value_t = 5, value_parser = bounds::every)]
    pub repeat: u64,
    /// Repartition every K steps in the other studies.
    #[arg(long, default_value_t = 20)]
    pub repartition_every: u64,
    /// A metrics line every N steps.
    #[arg(long, default_value_t = 10, value_parser = bounds::every)]
    pub metrics_every: u64,
    /// Where the runs' metrics, summary.csv and the figures go (default: out/study-NAME).
    #[arg(long)]
    pub output: Option<PathBuf>,
    /// Replace an earlier study in the output directory.
    #[arg(long)]
    pub overwrite: bool,
}

impl StudyArgs {
    pub fn steps(&self) -> u64 {
        self.steps.unwrap_or(self.name.default_steps())
    }

    pub fn settle(&self) -> u64 {
        self.settle.unwrap_or(match self.name {
            StudyName::Accuracy => 5000,
            _ => 0,
        })
    }

    pub fn scene(&self) -> PathBuf {
        self.scene.clone().unwrap_or_else(|| {
            PathBuf::from(match self.name {
                StudyName::RepartitionFrequency | StudyName::Partitioners => "scenes/collapse.toml",
                _ => "scenes/silo-1000.toml",
            })
        })
    }
}

#[derive(Args, Debug)]
pub struct PartitionPlotArgs {
    /// JSON lines from `tridem partition --json`.
    pub input: PathBuf,
    /// The SVG to write.
    #[arg(long)]
    pub output: PathBuf,
}

#[derive(Args, Debug)]
pub struct PlotArgs {
    /// A run's output directory (`tridem run --output DIR`).
    pub dir: PathBuf,
    /// The energy books: kinetic (translation, rotation), each effect's
    /// stored and dissipated energy, and their sum.
    #[arg(long)]
    pub energy: bool,
    /// A per-step scalar by name (repeatable; --list names them).
    #[arg(long)]
    pub series: Vec<String>,
    /// Print the names of the run's per-step scalars, one per line.
    #[arg(long, exclusive = true)]
    pub list: bool,
}

#[derive(Args, Debug)]
pub struct ChartArgs {
    /// A CSV file with a header line.
    pub csv: PathBuf,
    /// The column on the x axis.
    #[arg(long)]
    pub x: String,
    /// The column on the y axis.
    #[arg(long)]
    pub y: String,
    /// The column whose values name the series (default: one series).
    #[arg(long)]
    pub by: Option<String>,
    /// The column of each point's error (the half-width of its error bar;
    /// an empty cell: no bar).
    #[arg(long)]
    pub error: Option<String>,
    /// A logarithmic x axis.
    #[arg(long)]
    pub log_x: bool,
    /// Where the y axis starts (default 0; an imbalance starts at 1).
    #[arg(long)]
    pub y_from: Option<f64>,
    /// The caption (default: y against x).
    #[arg(long)]
    pub title: Option<String>,
    /// The SVG to write (a PNG beside it).
    #[arg(long)]
    pub output: PathBuf,
}

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// A run's output directory (`tridem run --output DIR`).
    pub dir: PathBuf,
    /// The output step to draw (default: the last).
    #[arg(long, conflicts_with = "all")]
    pub step: Option<usize>,
    /// Every output step, one PNG each.
    #[arg(long)]
    pub all: bool,
    /// What colours the particles.
    #[arg(long, value_enum, default_value = "speed")]
    pub color_by: ColourBy,
    /// Where the camera looks from.
    #[arg(long, value_enum, default_value = "iso")]
    pub view: View,
    /// Draw the contact network.
    #[arg(long)]
    pub contacts: bool,
    /// Frame the particles (obstacles may reach out of the picture) or
    /// everything.
    #[arg(long)]
    pub whole_scene: bool,
    /// The PNG (one step) or the directory of PNGs (default: DIR/render-step-K.png).
    #[arg(long)]
    pub output: Option<PathBuf>,
    #[arg(long, default_value_t = 1200, value_parser = clap::value_parser!(u32).range(64..=8192))]
    pub width: u32,
    #[arg(long, default_value_t = 900, value_parser = clap::value_parser!(u32).range(64..=8192))]
    pub height: u32,
}

/// What colours the particles of `tridem render`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ColourBy {
    /// |v| (m/s), from the slowest particle to the fastest.
    Speed,
    /// A colour per body.
    Body,
    /// A colour per material.
    Material,
    /// The sum of the normal forces of the particle's contacts (N).
    Force,
}

/// Where `tridem render`'s camera looks from.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum View {
    /// From above, in front and to the side.
    Iso,
    /// Along +y.
    Front,
    /// Along -x.
    Side,
    /// Down.
    Top,
}

#[derive(Args, Debug)]
pub struct ScalingArgs {
    /// The scene file.
    pub scene: PathBuf,
    /// Steps per run (default: end_time / dt of the scene).
    #[arg(long)]
    pub steps: Option<u64>,
    /// Thread counts to compare, the first being the reference.
    #[arg(long, value_delimiter = ',', default_value = "1,2", value_parser = bounds::threads)]
    pub threads: Vec<usize>,
    /// Runs per thread count (rounds alternate between thread counts).
    #[arg(long, default_value_t = 5, value_parser = bounds::repeat)]
    pub repeat: usize,
    /// What each time is: the median of the runs, or the minimum (on a
    /// machine whose speed swings, the least disturbed run). Speed-ups are
    /// ratios of this statistic.
    #[arg(long, value_enum, default_value_t = Statistic::Median)]
    pub statistic: Statistic,
    /// Kernel calls per thread of the reference workload: the scene's
    /// distance kernel on a small set of random pairs, run by every thread
    /// on its own right after each run, so the report shows what speed-up
    /// the machine delivered to plain parallel work in the same minutes (0:
    /// no reference).
    #[arg(long, default_value_t = 200_000, value_parser = bounds::steps_usize)]
    pub reference_pairs: usize,
    /// Print one JSON object per thread count instead of a table.
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct RunArgs {
    /// The scene file.
    pub scene: PathBuf,
    /// Steps to run (default: end_time / dt of the scene).
    #[arg(long, value_parser = bounds::steps)]
    pub steps: Option<u64>,
    /// Set a scene value over the file's, as section.key=value with a TOML
    /// value (repeatable), e.g. --set kernel.schedule=dynamic
    /// --set kernel.iterations=4.
    #[arg(long = "set", value_name = "SECTION.KEY=VALUE")]
    pub overrides: Vec<String>,
    /// Write HDF5 + XDMF output to this directory, and at each output step
    /// a checkpoint, DIR/checkpoint.h5.
    #[arg(long, value_name = "DIR")]
    pub output: Option<PathBuf>,
    /// Go on from a checkpoint of a run of the same scene, bit for bit as if
    /// it had not stopped; with --output to the run's directory, its output
    /// goes on in the same file. --steps counts the steps still to run.
    #[arg(long, value_name = "CHECKPOINT")]
    pub resume: Option<PathBuf>,
    /// Replace the output of an earlier run in --output DIR (refused otherwise,
    /// so that no run's output is lost by a repeated command).
    #[arg(long)]
    pub overwrite: bool,
    /// Threads (default: all cores).
    #[arg(long, value_parser = bounds::threads)]
    pub threads: Option<usize>,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// Under mpirun: how particles are assigned to ranks (default: the
    /// scene's `[parallel]` partitioner, else zoltan-rcb).
    #[arg(long, value_enum)]
    pub partitioner: Option<partition::Backend>,
    /// Under mpirun: repartition every K steps (0: only at the start;
    /// default: the scene's `[parallel]` repartition_every, else 0).
    #[arg(long)]
    pub repartition_every: Option<u64>,
    /// Under mpirun: ghost exchange overlapping the detection among owned
    /// bodies (nonblocking) or completed before it (blocking; default: the
    /// scene's, else nonblocking).
    #[arg(long, value_enum)]
    pub exchange: Option<distributed::Exchange>,
    /// Under mpirun: also repartition once the ranks' busy time over the
    /// last 20 steps is more imbalanced (max/mean) than this (default: the
    /// scene's `[parallel] repartition_when`, else never).
    #[arg(long)]
    pub repartition_when: Option<f64>,
    /// Under mpirun: what a particle weighs for the partitioner: its
    /// triangles, its contacts' cost (pairs), or its share of its rank's
    /// measured time (default: the scene's `[parallel]` weights, else pairs).
    #[arg(long, value_enum)]
    pub weights: Option<distributed::Weights>,
    /// Under mpirun: partition from scratch every time, not building on the
    /// previous partition (cut axes and positions, part numbers); for
    /// measuring what that reuse saves in migration.
    #[arg(long)]
    pub fresh_partitions: bool,
    /// Under mpirun: write per-rank metrics as JSON lines to FILE.
    #[arg(long)]
    pub metrics: Option<PathBuf>,
    /// A metrics line every N steps, summing their counts and seconds (with --metrics).
    #[arg(long, default_value_t = 1, value_parser = bounds::every)]
    pub metrics_every: u64,
}

#[derive(Args, Debug)]
pub struct PartitionArgs {
    /// Print the partitioners' names, one per line, and nothing else (the
    /// list scripts read).
    #[arg(long, exclusive = true)]
    pub list: bool,
    /// How items are assigned to ranks.
    #[arg(long, value_enum, required_unless_present = "list")]
    pub partitioner: Option<partition::Backend>,
    /// Where the items are.
    #[arg(long, value_enum, default_value = "uniform")]
    pub workload: partition::workload::Workload,
    /// Items (small triangles) over all ranks.
    #[arg(long, default_value_t = 100_000, value_parser = bounds::items)]
    pub items: u64,
    /// Time steps of the workload's motion.
    #[arg(long, default_value_t = 1, value_parser = bounds::every_usize)]
    pub steps: usize,
    /// Repartition every K steps.
    #[arg(long, default_value_t = 1, value_parser = bounds::every_usize)]
    pub every: usize,
    /// Contact halo for ghosts and the METIS graph (default: a quarter of the triangle size).
    #[arg(long)]
    pub halo: Option<f64>,
    /// Threads per rank (default: the cores available to the rank).
    #[arg(long, value_parser = bounds::threads)]
    pub threads: Option<usize>,
    /// One JSON object per partitioning step instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Also write a CSV of the steps to this directory.
    #[arg(long)]
    pub output: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub struct InfoArgs {
    /// Print as one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct PingpongArgs {
    /// Round trips per message size (the median is kept).
    #[arg(long, default_value_t = 200, value_parser = bounds::every)]
    pub repeat: u64,
    /// Print as one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct DistanceArgs {
    /// Which computation answers.
    #[arg(long, value_enum, default_value = "hybrid")]
    pub method: Method,
    /// Pairs per SIMD batch: 1, 2, 4, 8, 16, 32 or 64.
    #[arg(long, default_value_t = 8)]
    pub batch: usize,
    /// Rounds of the penalty kernel's exact finish (0: none). More rounds
    /// certify a few more pairs at a cost: see `tridem kernels --accuracy`.
    #[arg(long, default_value_t = PenaltyParams::default().finish_rounds, value_parser = bounds::finish_rounds)]
    pub finish_rounds: usize,
    /// First print a header line naming the columns.
    #[arg(long)]
    pub header: bool,
    /// CSV input; stdin when absent.
    pub file: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub struct KernelsArgs {
    /// Number of random pairs (vertices uniform in the unit cube).
    #[arg(long, default_value_t = 1_000_000, value_parser = bounds::items_usize)]
    pub pairs: usize,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Threads (default: all cores).
    #[arg(long, value_parser = bounds::threads)]
    pub threads: Option<usize>,
    /// How batches are shared among threads (static by default: random pairs
    /// are uniform work; the DEM's body pairs are not, and default to guided).
    #[arg(long, value_enum, default_value = "static")]
    pub schedule: Schedule,
    /// Batches per share with dynamic scheduling (smallest share with guided).
    #[arg(long, default_value_t = 16, value_parser = bounds::grain)]
    pub grain: usize,
    /// Pairs per SIMD batch: 1, 2, 4, 8, 16, 32 or 64.
    #[arg(long, default_value_t = 8)]
    pub batch: usize,
    /// Timed repetitions per measurement (summarised by --statistic).
    #[arg(long, default_value_t = 5, value_parser = bounds::repeat)]
    pub repeat: usize,
    /// What each time is: the median of the repetitions, or the minimum (on a
    /// machine whose speed swings, the least disturbed run).
    #[arg(long, value_enum, default_value_t = Statistic::Median)]
    pub statistic: Statistic,
    /// Print a JSON array instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Print one JSON object per row and line (JSON lines), to append to a file.
    #[arg(long, conflicts_with = "json")]
    pub jsonl: bool,
    /// Sweep iterations, penalty r, tolerance and batch size: error against time.
    #[arg(long)]
    pub accuracy: bool,
    /// Where --accuracy writes its CSV and SVG plot.
    #[arg(long, default_value = "out/kernels")]
    pub output: PathBuf,
}
