//! Run under mpirun by partition's tests: the varcount exchanges of
//! `partition::comm` with bytes, where some ranks send or receive nothing
//! (an empty byte buffer must not read as MPI_IN_PLACE).
use mpi::traits::*;
use mpi_harness::Reporter;
use partition::comm::{all_gather_v, all_to_all_v};

fn main() {
    let universe = mpi::initialize().expect("MPI init");
    let world = universe.world();
    let (me, size) = (world.rank(), world.size() as usize);
    let mut out = Reporter::new(me as usize);

    // Everyone but the last rank sends me + 1 bytes of value me to rank 0;
    // only rank 0 receives anything.
    let last = size as i32 - 1;
    let mut counts = vec![0; size];
    let send: Vec<u8> = if me == last {
        Vec::new()
    } else {
        counts[0] = me + 1;
        vec![me as u8; me as usize + 1]
    };
    let (got, _) = all_to_all_v(&world, &send, &counts);
    let expected: Vec<u8> = if me == 0 {
        (0..last)
            .flat_map(|r| std::iter::repeat_n(r as u8, r as usize + 1))
            .collect()
    } else {
        Vec::new()
    };
    out.kv("all_to_all_v_bytes_ok", got == expected);

    // Only rank 0 contributes.
    let mine: Vec<u8> = if me == 0 { vec![7, 7] } else { Vec::new() };
    out.kv(
        "all_gather_v_bytes_ok",
        all_gather_v(&world, &mine) == vec![7, 7],
    );
}
