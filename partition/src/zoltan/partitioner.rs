//! Zoltan's geometric methods behind the common [`Partitioner`] interface.

use super::{Method, Param, Zoltan, ZoltanError};
use crate::{Aabb, Item, PartitionError, Partitioner};
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

pub struct ZoltanPartitioner<'c> {
    zoltan: Zoltan<'c>,
    method: Method,
    partitioned: bool,
    reuse: bool,
    /// RCB with reuse: the axis Zoltan's directions were locked to (the
    /// longest of the domain when last unlocked).
    locked_axis: Option<usize>,
}

impl<'c> ZoltanPartitioner<'c> {
    pub fn new(comm: &'c SimpleCommunicator, method: Method) -> Result<Self, ZoltanError> {
        Ok(ZoltanPartitioner {
            zoltan: Zoltan::new(comm, method)?,
            method,
            partitioned: false,
            reuse: true,
            locked_axis: None,
        })
    }

    /// Whether repartitionings build on the previous partition (the default).
    pub fn reuse(&mut self, on: bool) -> Result<(), ZoltanError> {
        self.reuse = on;
        self.zoltan.reuse(self.method, on)
    }

    /// RCB with reuse: Zoltan locks every cut's direction for good, so the
    /// lock is lifted for one partitioning once the domain's extent along
    /// the locked axis is much shorter than its longest (the native RCB's
    /// rule, [`crate::rcb::keeps_axis`], applied to the whole domain).
    fn relock(&mut self, comm: &SimpleCommunicator, items: &[Item]) -> Result<(), ZoltanError> {
        if !(self.reuse && self.method == Method::Rcb) {
            return Ok(());
        }
        let ext = domain_extent(comm, items);
        let longest = crate::rcb::longest_axis(&ext);
        let keep = self
            .locked_axis
            .is_some_and(|d| crate::rcb::keeps_axis(&ext, d));
        if !keep {
            self.locked_axis = Some(longest);
        }
        self.zoltan.set(Param::RcbLockDirections(keep))
    }

    pub fn zoltan(&self) -> &Zoltan<'c> {
        &self.zoltan
    }
}

impl Partitioner for ZoltanPartitioner<'_> {
    fn name(&self) -> &'static str {
        let backend = match self.method {
            Method::Rcb => crate::Backend::ZoltanRcb,
            Method::Rib => crate::Backend::ZoltanRib,
            Method::Hsfc => crate::Backend::ZoltanHsfc,
        };
        backend.name()
    }

    fn partition(
        &mut self,
        comm: &SimpleCommunicator,
        items: &[Item],
    ) -> Result<Vec<i32>, PartitionError> {
        self.relock(comm, items)?;
        let owners = self.zoltan.partition(items)?;
        self.partitioned = true;
        Ok(owners)
    }

    fn owner(&self, p: [f64; 3]) -> Result<i32, PartitionError> {
        if !self.partitioned {
            return Ok(0);
        }
        Ok(self.zoltan.point_assign(p)?)
    }

    fn ranks_overlapping(&self, b: &Aabb, out: &mut Vec<i32>) -> Result<(), PartitionError> {
        if !self.partitioned {
            out.push(0);
            return Ok(());
        }
        Ok(self.zoltan.box_assign(b, out)?)
    }
}

/// The extent of all ranks' item points along each axis (collective).
fn domain_extent(comm: &SimpleCommunicator, items: &[Item]) -> [f64; 3] {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for it in items {
        for k in 0..3 {
            lo[k] = lo[k].min(it.point[k]);
            hi[k] = hi[k].max(it.point[k]);
        }
    }
    let (mut glo, mut ghi) = ([0.0f64; 3], [0.0f64; 3]);
    comm.all_reduce_into(&lo[..], &mut glo[..], SystemOperation::min());
    comm.all_reduce_into(&hi[..], &mut ghi[..], SystemOperation::max());
    [0, 1, 2].map(|k| (ghi[k] - glo[k]).max(0.0))
}
