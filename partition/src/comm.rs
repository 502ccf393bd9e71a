//! Collective helpers over rsmpi used by migration, ghosts and METIS.

use mpi::datatype::{Partition, PartitionMut};
use mpi::traits::*;
use mpi::Count;

/// Exclusive prefix sums of counts: the displacements of a varcount exchange.
pub fn displacements(counts: &[Count]) -> Vec<Count> {
    counts
        .iter()
        .scan(0, |acc, &c| {
            let d = *acc;
            *acc += c;
            Some(d)
        })
        .collect()
}

/// All-to-all of variable-sized blocks: `send` holds the blocks for ranks
/// 0..P in order, `send_counts[r]` elements for rank r. Returns what every rank
/// sent here, in rank order, and the counts received from each rank.
pub fn all_to_all_v<C, T>(comm: &C, send: &[T], send_counts: &[Count]) -> (Vec<T>, Vec<Count>)
where
    C: Communicator,
    T: Equivalence + Clone + Default,
{
    let size = comm.size() as usize;
    assert_eq!(send_counts.len(), size);
    let mut recv_counts = vec![0 as Count; size];
    comm.all_to_all_into(send_counts, &mut recv_counts[..]);
    let total: Count = recv_counts.iter().sum();
    let mut recv = vec![T::default(); total as usize];
    let sdispl = displacements(send_counts);
    let rdispl = displacements(&recv_counts);
    {
        let one = [T::default()];
        let s = Partition::new(never_empty(send, &one), send_counts, &sdispl[..]);
        let mut spare = [T::default()];
        let r = never_empty_mut(&mut recv, &mut spare);
        let mut r = PartitionMut::new(r, &recv_counts[..], &rdispl[..]);
        comm.all_to_all_varcount_into(&s, &mut r);
    }
    (recv, recv_counts)
}

/// Gathers variable-sized blocks from every rank to every rank, in rank order.
pub fn all_gather_v<C, T>(comm: &C, send: &[T]) -> Vec<T>
where
    C: Communicator,
    T: Equivalence + Clone + Default,
{
    let size = comm.size() as usize;
    let mut counts = vec![0 as Count; size];
    comm.all_gather_into(&(send.len() as Count), &mut counts[..]);
    let total: Count = counts.iter().sum();
    let mut recv = vec![T::default(); total as usize];
    let displs = displacements(&counts);
    {
        let one = [T::default()];
        // Sends send.len() elements, as the counts say, even from the spare.
        let send = &never_empty(send, &one)[..send.len()];
        let mut spare = [T::default()];
        let r = never_empty_mut(&mut recv, &mut spare);
        let mut r = PartitionMut::new(r, &counts[..], &displs[..]);
        comm.all_gather_varcount_into(send, &mut r);
    }
    recv
}

/// Gathers variable-sized blocks from every rank on `root`, in rank order:
/// `Some` there, `None` elsewhere. What the root receives is the sum of the
/// blocks; the other ranks hold only their own.
pub fn gather_v<C, T>(comm: &C, root: i32, send: &[T]) -> Option<Vec<T>>
where
    C: Communicator,
    T: Equivalence + Clone + Default,
{
    let size = comm.size() as usize;
    let process = comm.process_at_rank(root);
    let n = send.len() as Count;
    let one = [T::default()];
    let send = &never_empty(send, &one)[..n as usize];
    if comm.rank() != root {
        process.gather_into(&n);
        process.gather_varcount_into(send);
        return None;
    }
    let mut counts = vec![0 as Count; size];
    process.gather_into_root(&n, &mut counts[..]);
    let total: Count = counts.iter().sum();
    let mut recv = vec![T::default(); total as usize];
    let displs = displacements(&counts);
    {
        let mut spare = [T::default()];
        let r = never_empty_mut(&mut recv, &mut spare);
        let mut r = PartitionMut::new(r, &counts[..], &displs[..]);
        process.gather_varcount_into_root(send, &mut r);
    }
    Some(recv)
}

/// `buf`, or when it is empty, `spare` (whose counts stay zero). An empty
/// slice's pointer is dangling, and for a one-byte type it is 0x1: Open MPI's
/// `MPI_IN_PLACE`. A rank that sends or receives no bytes would then ask for
/// an in-place exchange (MPI_ERR_ARG, or its receive buffer read as data).
fn never_empty<'a, T>(buf: &'a [T], spare: &'a [T; 1]) -> &'a [T] {
    if buf.is_empty() {
        spare
    } else {
        buf
    }
}

fn never_empty_mut<'a, T>(buf: &'a mut [T], spare: &'a mut [T; 1]) -> &'a mut [T] {
    if buf.is_empty() {
        spare
    } else {
        buf
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn displacements_are_exclusive_prefix_sums() {
        assert_eq!(super::displacements(&[2, 0, 3, 1]), vec![0, 2, 2, 5]);
    }
}
