//! Run under mpirun by experiments' tests: the contacts of the DEM split
//! across real MPI ranks against one process's.
//!
//! Every rank steps the hopper scene on its own to STEPS (the reference),
//! and the same scene split across the ranks by BACKEND, repartitioning
//! every 10 steps (`distributed::DistributedSimulation`: owned particles
//! integrated by their rank, ghost bodies exchanged while the contacts among
//! owned bodies are found, each contact computed on one rank). Each rank
//! reports the contacts it computed and the ghosts it sent and received;
//! rank 0 compares the gathered contacts with the reference, contact by
//! contact, to the bit.
//!
//! Usage: contacts_mpi BACKEND STEPS
use dem::frame::FrameContact;
use dem::scene::Scene;
use dem::simulation::Simulation;
use distributed::{DistributedSimulation, Exchange, Settings, Start};
use mpi::traits::*;
use mpi_harness::Reporter;

/// A contact and its forces as bits, for comparison.
fn bits(c: &FrameContact) -> Vec<u64> {
    let mut v = vec![u64::from(c.a), u64::from(c.b)];
    let reals = [c.point, c.normal, c.normal_force, c.tangential_force]
        .into_iter()
        .flat_map(|p| p.to_array());
    v.extend(reals.chain([c.depth]).map(f64::to_bits));
    v
}

fn main() {
    let universe = mpi::initialize().expect("MPI init");
    let comm = universe.world();
    let mut out = Reporter::new(comm.rank() as usize);
    let args: Vec<String> = std::env::args().collect();
    let backend: partition::Backend = args[1].parse().expect("backend");
    let steps: u64 = args[2].parse().expect("steps");

    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/hopper.toml");
    let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let mut reference = Simulation::new(&scene);
    for _ in 0..steps {
        reference.step();
    }
    let settings = Settings {
        partitioner: backend,
        repartition_every: Some(10),
        repartition_when: None,
        exchange: Exchange::Nonblocking,
        skin: scene
            .effects
            .get::<dem::effects::ContactParams>()
            .map_or(0.0, |c| c.skin),
        // The partitions follow the work: bodies change ranks as they pile up.
        weights: distributed::Weights::Pairs,
        reuse: true,
    };
    let share = dem::scene::Deal {
        rank: comm.rank() as u32,
        ranks: comm.size() as u32,
    };
    let mut mine = Scene::load_dealt(&path, share).unwrap_or_else(|e| panic!("{e}"));
    let mut dist = DistributedSimulation::new(&comm, &mut mine, Start::Fresh, settings)
        .unwrap_or_else(|e| panic!("{e}"));
    let (mut sent, mut received) = (0, 0);
    for _ in 0..steps {
        dist.step(false).unwrap_or_else(|e| panic!("{e}"));
        sent = dist.metrics().ghosts_sent;
        received = dist.metrics().ghosts_received;
    }
    out.kv("owned_particles", dist.owned().len());
    out.kv("last_contacts", dist.metrics().contacts);
    out.kv("ghosts_sent", sent);
    out.kv("ghosts_received", received);
    let Some(split) = dist
        .gather(true)
        .and_then(|mut g| g.show(|frame| frame.contacts.iter().map(bits).collect::<Vec<_>>()))
    else {
        return;
    };
    let one: Vec<Vec<u64>> = reference.frame().contacts.iter().map(bits).collect();
    let differ = one.iter().zip(&split).filter(|(x, y)| x != y).count();
    out.kv("one_node_contacts", one.len());
    out.kv("gathered_contacts", split.len());
    out.kv("contacts_differ", differ + one.len().abs_diff(split.len()));
}
