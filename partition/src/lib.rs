//! Domain decomposition for tridem.
//!
//! One interface ([`Partitioner`]) over three backends: Trilinos Zoltan
//! (RCB, RIB, HSFC through the safe layer in [`zoltan`] over `zoltan-sys`),
//! METIS on the items' proximity graph ([`metis_graph`]), and a native
//! recursive coordinate bisection ([`rcb`]). Around them: migration of items
//! to their new owners ([`migrate`]), ghost exchange ([`ghosts`]) and the
//! metrics the experiments report ([`metrics`]).

mod aabb;
pub mod comm;
pub mod cut_tree;
pub mod ghosts;
mod item;
pub mod metis_graph;
pub mod metrics;
pub mod migrate;
pub mod rcb;
pub mod workload;
pub mod zoltan;

pub use aabb::Aabb;
pub use item::{Item, LocalItems};
use mpi::topology::SimpleCommunicator;

/// Why partitioning failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PartitionError {
    #[error("Zoltan: {0}")]
    Zoltan(#[from] zoltan::ZoltanError),
    #[error("METIS: {0}")]
    Metis(String),
    #[error("bad item: {0}")]
    BadItem(String),
}

/// A way to split items among the ranks of a communicator.
pub trait Partitioner {
    fn name(&self) -> &'static str;

    /// Collective: the new owner rank of each local item.
    fn partition(
        &mut self,
        comm: &SimpleCommunicator,
        items: &[Item],
    ) -> Result<Vec<i32>, PartitionError>;

    /// The rank that owns the region containing `p` (after a partitioning;
    /// before the first, every point belongs to rank 0). A point on a cut
    /// lies in the closed regions of both sides: this names one of them,
    /// and [`Partitioner::partition`] may have dealt an item there to the
    /// other, to split items at one coordinate evenly.
    fn owner(&self, p: [f64; 3]) -> Result<i32, PartitionError>;

    /// Appends the ranks whose regions overlap box `b` (after a partitioning).
    fn ranks_overlapping(&self, b: &Aabb, out: &mut Vec<i32>) -> Result<(), PartitionError>;
}

/// How a partitioner is set up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Setup {
    /// The contact halo: METIS joins items whose boxes inflated by it overlap.
    pub halo: f64,
    /// Repartitionings build on the previous partition, so that they move
    /// items in proportion to the drift: RCB keeps its cut axes and starts
    /// from its old cuts (Zoltan's `RCB_REUSE` and `RCB_LOCK_DIRECTIONS`),
    /// and parts are renumbered to overlap the old owners most (Zoltan's
    /// `REMAP`, the same matching for METIS). Off, every partitioning starts
    /// from scratch.
    pub reuse: bool,
}

impl Setup {
    /// Reusing the previous partition, with the contact halo `halo`.
    pub fn with_halo(halo: f64) -> Setup {
        Setup { halo, reuse: true }
    }
}

/// The backends, by the names the command line uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Backend {
    /// Zoltan's recursive coordinate bisection.
    ZoltanRcb,
    /// Zoltan's recursive inertial bisection.
    ZoltanRib,
    /// Zoltan's Hilbert space-filling curve.
    ZoltanHsfc,
    /// METIS on the graph of items within a halo of each other.
    Metis,
    /// The native recursive coordinate bisection.
    Rcb,
}

impl Backend {
    pub const ALL: [Backend; 5] = [
        Backend::ZoltanRcb,
        Backend::ZoltanRib,
        Backend::ZoltanHsfc,
        Backend::Metis,
        Backend::Rcb,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Backend::ZoltanRcb => "zoltan-rcb",
            Backend::ZoltanRib => "zoltan-rib",
            Backend::ZoltanHsfc => "zoltan-hsfc",
            Backend::Metis => "metis",
            Backend::Rcb => "rcb",
        }
    }

    /// Creates the partitioner on `comm` (Zoltan needs its communicator).
    pub fn create<'c>(
        self,
        comm: &'c SimpleCommunicator,
        setup: Setup,
    ) -> Result<Box<dyn Partitioner + 'c>, PartitionError> {
        let zoltan = |method| -> Result<Box<dyn Partitioner + 'c>, PartitionError> {
            let mut z = zoltan::ZoltanPartitioner::new(comm, method)?;
            z.reuse(setup.reuse)?;
            Ok(Box::new(z))
        };
        Ok(match self {
            Backend::ZoltanRcb => zoltan(zoltan::Method::Rcb)?,
            Backend::ZoltanRib => zoltan(zoltan::Method::Rib)?,
            Backend::ZoltanHsfc => zoltan(zoltan::Method::Hsfc)?,
            Backend::Metis => {
                let mut m = metis_graph::MetisPartitioner::with_halo(setup.halo);
                m.remap = setup.reuse;
                Box::new(m)
            }
            Backend::Rcb => {
                let mut r = rcb::Rcb::new();
                r.reuse_cuts = setup.reuse;
                Box::new(r)
            }
        })
    }
}

impl std::str::FromStr for Backend {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Backend::ALL
            .into_iter()
            .find(|b| b.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = Backend::ALL.iter().map(|b| b.name()).collect();
                format!("unknown partitioner `{s}` ({})", names.join(", "))
            })
    }
}
