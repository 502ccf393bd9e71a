//! An owned Zoltan_Struct.

use super::library::{initialize_on, ZoltanError};
use crate::{Aabb, Item};
use mpi::raw::AsRaw;
use mpi::topology::SimpleCommunicator;
use std::ffi::CString;
use std::marker::PhantomData;
use std::os::raw::{c_int, c_void};
use zoltan_sys as z;

/// Zoltan's geometric methods offered here.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    Rcb,
    Rib,
    Hsfc,
}

impl Method {
    fn param(self) -> &'static str {
        match self {
            Method::Rcb => "RCB",
            Method::Rib => "RIB",
            Method::Hsfc => "HSFC",
        }
    }
}

/// Typed Zoltan parameters (the ones tridem sets); anything else goes through
/// [`Zoltan::set_param`] by name.
#[derive(Debug, Clone, PartialEq)]
pub enum Param {
    /// 0 silences Zoltan; set before anything else.
    DebugLevel(u32),
    /// Keep the cuts for point and box queries.
    KeepCuts(bool),
    /// Start RCB from the previous cuts when repartitioning.
    RcbReuse(bool),
    /// Keep RCB's cut directions from the first partitioning on.
    RcbLockDirections(bool),
    /// Renumber the new parts to overlap the old assignment most.
    Remap(bool),
    /// Weights per object (0 or 1 here).
    ObjWeightDim(u32),
}

impl Param {
    fn name_value(&self) -> (&'static str, String) {
        let flag = |b: bool| if b { "1" } else { "0" }.to_string();
        match self {
            Param::DebugLevel(v) => ("DEBUG_LEVEL", v.to_string()),
            Param::KeepCuts(b) => ("KEEP_CUTS", flag(*b)),
            Param::RcbReuse(b) => ("RCB_REUSE", flag(*b)),
            Param::RcbLockDirections(b) => ("RCB_LOCK_DIRECTIONS", flag(*b)),
            Param::Remap(b) => ("REMAP", flag(*b)),
            Param::ObjWeightDim(v) => ("OBJ_WEIGHT_DIM", v.to_string()),
        }
    }
}

/// A Zoltan load-balancing structure, bound to a communicator that must
/// outlive it. Destroyed on drop.
pub struct Zoltan<'c> {
    zz: *mut z::Zoltan_Struct,
    rank: i32,
    size: i32,
    _comm: PhantomData<&'c SimpleCommunicator>,
}

fn check(rc: c_int, what: &str) -> Result<(), ZoltanError> {
    // ZOLTAN_WARN is informational; FATAL and MEMERR are errors.
    if rc == z::ZOLTAN_OK || rc == z::ZOLTAN_WARN {
        Ok(())
    } else {
        Err(ZoltanError::Call {
            what: what.to_string(),
            code: rc,
        })
    }
}

/// The items a partitioning call reads through Zoltan's query callbacks.
struct Query<'a> {
    items: &'a [Item],
}

/// The four query callbacks, registered on a Zoltan structure with a
/// [`Query`] as their data for as long as this guard lives. Dropping it
/// clears all four, so the structure never keeps a pointer to a query that
/// is gone, whichever way the partitioning ends; the borrow keeps the query
/// alive and unmoved until then.
struct Callbacks<'q> {
    zz: *mut z::Zoltan_Struct,
    _query: PhantomData<&'q mut Query<'q>>,
}

impl<'q> Callbacks<'q> {
    fn register(zz: *mut z::Zoltan_Struct, query: &'q mut Query<'_>) -> Callbacks<'q> {
        let data = query as *mut Query as *mut c_void;
        // SAFETY: `zz` is a live Zoltan structure (its owner outlives the
        // guard); `data` stays valid while the guard borrows the query, and
        // the guard unregisters it before that borrow ends.
        unsafe {
            z::Zoltan_Set_Num_Obj_Fn(zz, Some(num_obj), data);
            z::Zoltan_Set_Obj_List_Fn(zz, Some(obj_list), data);
            z::Zoltan_Set_Num_Geom_Fn(zz, Some(num_geom), data);
            z::Zoltan_Set_Geom_Multi_Fn(zz, Some(geom_multi), data);
        }
        Callbacks {
            zz,
            _query: PhantomData,
        }
    }
}

impl Drop for Callbacks<'_> {
    fn drop(&mut self) {
        // SAFETY: clearing a callback with a null data pointer is always valid.
        unsafe {
            z::Zoltan_Set_Num_Obj_Fn(self.zz, None, std::ptr::null_mut());
            z::Zoltan_Set_Obj_List_Fn(self.zz, None, std::ptr::null_mut());
            z::Zoltan_Set_Num_Geom_Fn(self.zz, None, std::ptr::null_mut());
            z::Zoltan_Set_Geom_Multi_Fn(self.zz, None, std::ptr::null_mut());
        }
    }
}

unsafe extern "C" fn num_obj(data: *mut c_void, ierr: *mut c_int) -> c_int {
    // SAFETY: `data` is the `Query` registered for the duration of LB_Partition.
    let q = unsafe { &*(data as *const Query) };
    unsafe { *ierr = z::ZOLTAN_OK };
    q.items.len() as c_int
}

#[allow(clippy::too_many_arguments)]
unsafe extern "C" fn obj_list(
    data: *mut c_void,
    _ngid: c_int,
    _nlid: c_int,
    gids: z::ZOLTAN_ID_PTR,
    lids: z::ZOLTAN_ID_PTR,
    wgt_dim: c_int,
    wgts: *mut f32,
    ierr: *mut c_int,
) {
    // SAFETY: Zoltan sized the arrays for num_obj entries (times wgt_dim for weights).
    unsafe {
        let q = &*(data as *const Query);
        for (i, it) in q.items.iter().enumerate() {
            // Zoltan's ids are 4 bytes here: the local index identifies the item,
            // the global id only needs to be unique (item ids are checked < 2^32).
            *gids.add(i) = it.id as u32;
            *lids.add(i) = i as u32;
            if wgt_dim > 0 {
                *wgts.add(i) = it.weight as f32;
            }
        }
        *ierr = z::ZOLTAN_OK;
    }
}

unsafe extern "C" fn num_geom(_data: *mut c_void, ierr: *mut c_int) -> c_int {
    // SAFETY: Zoltan passes a valid pointer to its error code.
    unsafe { *ierr = z::ZOLTAN_OK };
    3
}

#[allow(clippy::too_many_arguments)]
unsafe extern "C" fn geom_multi(
    data: *mut c_void,
    _ngid: c_int,
    _nlid: c_int,
    num_obj: c_int,
    _gids: z::ZOLTAN_ID_PTR,
    lids: z::ZOLTAN_ID_PTR,
    num_dim: c_int,
    geom: *mut f64,
    ierr: *mut c_int,
) {
    // SAFETY: `lids` holds num_obj local ids we gave; `geom` has num_obj * num_dim slots.
    unsafe {
        let q = &*(data as *const Query);
        for i in 0..num_obj as usize {
            let p = q.items[*lids.add(i) as usize].point;
            for (d, &x) in p.iter().enumerate().take(num_dim as usize) {
                *geom.add(i * num_dim as usize + d) = x;
            }
        }
        *ierr = z::ZOLTAN_OK;
    }
}

impl<'c> Zoltan<'c> {
    /// Creates a Zoltan structure on `comm` with the given method, keeping cuts
    /// for point and box queries, quiet, returning export lists, reusing the
    /// previous partition (see [`Zoltan::reuse`]).
    pub fn new(comm: &'c SimpleCommunicator, method: Method) -> Result<Self, ZoltanError> {
        use mpi::traits::Communicator;
        initialize_on(comm)?;
        // SAFETY: the communicator is valid for 'c, which the handle cannot outlive.
        let zz = unsafe { z::Zoltan_Create(comm.as_raw()) };
        if zz.is_null() {
            return Err(ZoltanError::Create);
        }
        let mut zo = Zoltan {
            zz,
            rank: comm.rank(),
            size: comm.size(),
            _comm: PhantomData,
        };
        // DEBUG_LEVEL first, or Zoltan prints while the rest are set.
        zo.set(Param::DebugLevel(0))?;
        zo.set_param("LB_METHOD", method.param())?;
        zo.set_param("NUM_GID_ENTRIES", "1")?;
        zo.set_param("NUM_LID_ENTRIES", "1")?;
        zo.set(Param::ObjWeightDim(1))?;
        zo.set_param("RETURN_LISTS", "EXPORT")?;
        zo.set(Param::KeepCuts(true))?;
        zo.reuse(method, true)?;
        Ok(zo)
    }

    /// Whether a repartitioning builds on the previous one: RCB keeps its cut
    /// directions and starts each cut's search from the old one, and every
    /// method renumbers its parts to overlap the old assignment most. Off,
    /// each partitioning starts from scratch.
    pub fn reuse(&mut self, method: Method, on: bool) -> Result<(), ZoltanError> {
        if method == Method::Rcb {
            self.set(Param::RcbReuse(on))?;
            self.set(Param::RcbLockDirections(on))?;
        }
        self.set(Param::Remap(on))
    }

    /// Sets a typed parameter.
    pub fn set(&mut self, p: Param) -> Result<(), ZoltanError> {
        let (name, value) = p.name_value();
        self.set_param(name, &value)
    }

    /// Sets a Zoltan parameter by name; an unknown name or bad value is an error.
    pub fn set_param(&mut self, name: &str, value: &str) -> Result<(), ZoltanError> {
        let (n, v) = (cstring(name)?, cstring(value)?);
        // SAFETY: zz is valid; both strings are NUL-terminated and live across the call.
        let rc = unsafe { z::Zoltan_Set_Param(self.zz, n.as_ptr(), v.as_ptr()) };
        check(rc, &format!("Zoltan_Set_Param({name}={value})"))
    }

    /// New owner rank of each item (collective).
    pub fn partition(&mut self, items: &[Item]) -> Result<Vec<i32>, ZoltanError> {
        if items.iter().any(|i| i.id > u32::MAX as u64) {
            return Err(ZoltanError::IdTooLarge);
        }
        let mut query = Query { items };
        let callbacks = Callbacks::register(self.zz, &mut query);
        let (mut changes, mut ngid, mut nlid, mut nimp, mut nexp) = (0, 0, 0, 0, 0);
        let mut imp_g: z::ZOLTAN_ID_PTR = std::ptr::null_mut();
        let mut imp_l: z::ZOLTAN_ID_PTR = std::ptr::null_mut();
        let mut imp_p: *mut c_int = std::ptr::null_mut();
        let mut imp_t: *mut c_int = std::ptr::null_mut();
        let mut exp_g: z::ZOLTAN_ID_PTR = std::ptr::null_mut();
        let mut exp_l: z::ZOLTAN_ID_PTR = std::ptr::null_mut();
        let mut exp_p: *mut c_int = std::ptr::null_mut();
        let mut exp_t: *mut c_int = std::ptr::null_mut();
        // SAFETY: the callbacks read `query` through `callbacks`, which lives
        // until after the call; the output pointers are Zoltan-allocated and
        // freed below with Zoltan_LB_Free_Part.
        let rc = unsafe {
            z::Zoltan_LB_Partition(
                self.zz,
                &mut changes,
                &mut ngid,
                &mut nlid,
                &mut nimp,
                &mut imp_g,
                &mut imp_l,
                &mut imp_p,
                &mut imp_t,
                &mut nexp,
                &mut exp_g,
                &mut exp_l,
                &mut exp_p,
                &mut exp_t,
            )
        };
        let mut owners = Vec::new();
        if rc == z::ZOLTAN_OK || rc == z::ZOLTAN_WARN {
            owners = vec![self.rank; items.len()];
            for i in 0..nexp.max(0) as usize {
                // SAFETY: Zoltan returned `nexp` entries in each export array.
                let (lid, proc_) = unsafe { (*exp_l.add(i) as usize, *exp_p.add(i)) };
                owners[lid] = proc_;
            }
        }
        // SAFETY: freeing what LB_Partition allocated (null pointers are accepted).
        unsafe {
            z::Zoltan_LB_Free_Part(&mut imp_g, &mut imp_l, &mut imp_p, &mut imp_t);
            z::Zoltan_LB_Free_Part(&mut exp_g, &mut exp_l, &mut exp_p, &mut exp_t);
        }
        drop(callbacks);
        check(rc, "Zoltan_LB_Partition")?;
        Ok(owners)
    }

    /// Rank owning the point (needs a prior partition, KEEP_CUTS).
    pub fn point_assign(&self, p: [f64; 3]) -> Result<i32, ZoltanError> {
        let mut coords = p;
        let (mut proc_, mut part) = (-1, -1);
        // SAFETY: coords has 3 entries; outputs are plain ints.
        let rc = unsafe {
            z::Zoltan_LB_Point_PP_Assign(self.zz, coords.as_mut_ptr(), &mut proc_, &mut part)
        };
        check(rc, "Zoltan_LB_Point_PP_Assign")?;
        Ok(proc_)
    }

    /// Ranks whose regions overlap the box, appended to `out`.
    pub fn box_assign(&self, b: &Aabb, out: &mut Vec<i32>) -> Result<(), ZoltanError> {
        let start = out.len();
        out.resize(start + self.size as usize, -1);
        let mut parts = vec![0; self.size as usize];
        let (mut nprocs, mut nparts) = (0, 0);
        // SAFETY: both output arrays have room for every rank/part.
        let rc = unsafe {
            z::Zoltan_LB_Box_PP_Assign(
                self.zz,
                b.lo[0],
                b.lo[1],
                b.lo[2],
                b.hi[0],
                b.hi[1],
                b.hi[2],
                out[start..].as_mut_ptr(),
                &mut nprocs,
                parts.as_mut_ptr(),
                &mut nparts,
            )
        };
        out.truncate(start + nprocs.max(0) as usize);
        check(rc, "Zoltan_LB_Box_PP_Assign")
    }

    /// The box of an RCB part, clamped to `domain` (Zoltan reports +-DBL_MAX on outer faces).
    pub fn rcb_box(&self, part: i32, domain: &Aabb) -> Result<Aabb, ZoltanError> {
        // On one rank Zoltan makes no cut and keeps no box: the part is the domain.
        if self.size == 1 {
            return Ok(*domain);
        }
        let mut ndim = 0;
        let (mut x0, mut y0, mut z0, mut x1, mut y1, mut z1) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        // SAFETY: plain outputs.
        let rc = unsafe {
            z::Zoltan_RCB_Box(
                self.zz, part, &mut ndim, &mut x0, &mut y0, &mut z0, &mut x1, &mut y1, &mut z1,
            )
        };
        check(rc, "Zoltan_RCB_Box")?;
        Ok(Aabb::new([x0, y0, z0], [x1, y1, z1]).clamped_to(domain))
    }
}

impl Drop for Zoltan<'_> {
    fn drop(&mut self) {
        // SAFETY: zz came from Zoltan_Create and is destroyed exactly once.
        unsafe { z::Zoltan_Destroy(&mut self.zz) };
    }
}

fn cstring(s: &str) -> Result<CString, ZoltanError> {
    CString::new(s).map_err(|_| ZoltanError::Call {
        what: format!("parameter `{s}` contains NUL"),
        code: z::ZOLTAN_FATAL,
    })
}
