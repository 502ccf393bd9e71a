//! Zoltan's geometric methods behind the common [`Partitioner`] interface.

use super::{Method, Zoltan, ZoltanError};
use crate::{Aabb, Item, PartitionError, Partitioner};
use mpi::topology::SimpleCommunicator;

pub struct ZoltanPartitioner<'c> {
    zoltan: Zoltan<'c>,
    method: Method,
    partitioned: bool,
}

impl<'c> ZoltanPartitioner<'c> {
    pub fn new(comm: &'c SimpleCommunicator, method: Method) -> Result<Self, ZoltanError> {
        Ok(ZoltanPartitioner {
            zoltan: Zoltan::new(comm, method)?,
            method,
            partitioned: false,
        })
    }

    /// Whether repartitionings build on the previous partition (the default).
    pub fn reuse(&mut self, on: bool) -> Result<(), ZoltanError> {
        self.zoltan.reuse(self.method, on)
    }

    pub fn zoltan(&self) -> &Zoltan<'c> {
        &self.zoltan
    }
}

impl Partitioner for ZoltanPartitioner<'_> {
    fn name(&self) -> &'static str {
        match self.method {
            Method::Rcb => "zoltan-rcb",
            Method::Rib => "zoltan-rib",
            Method::Hsfc => "zoltan-hsfc",
        }
    }

    fn partition(
        &mut self,
        _comm: &SimpleCommunicator,
        items: &[Item],
    ) -> Result<Vec<i32>, PartitionError> {
        let mut owners = self.zoltan.partition(items)?;
        self.partitioned = true;
        // Zoltan may split items lying exactly on a cut between both sides to
        // balance them, while its point query sends the cut plane to one side.
        // Regions must own their points (ghost search relies on it), so the
        // point query has the last word; it differs only for items on a cut.
        for (o, it) in owners.iter_mut().zip(items) {
            *o = self.zoltan.point_assign(it.point)?;
        }
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
