//! Run under mpirun by zoltan-sys's tests: a tiny RCB partition through the raw
//! bindings. Every rank owns `PER_RANK` points on the x axis, interleaved across
//! ranks so that the initial distribution is as bad as possible; each rank
//! reports `obj=<gid>,<x>,<part>` for its points after partitioning.
use mpi::traits::*;
use mpi_harness::Reporter;
use std::ffi::CString;
use std::os::raw::{c_int, c_void};
use zoltan_sys::*;

const PER_RANK: usize = 12;

struct Points {
    gids: Vec<u32>,
    xyz: Vec<[f64; 3]>,
}

/// # Safety
/// Zoltan calls the four callbacks with the `data` registered with them, a
/// `*mut Points` that `main` keeps alive and unmoved until `Zoltan_Destroy`,
/// and with `ierr` and the output arrays valid for the counts it gives.
unsafe extern "C" fn num_obj(data: *mut c_void, ierr: *mut c_int) -> c_int {
    // SAFETY: `data` is the registered `Points` (see above); `ierr` is valid.
    let pts = &*(data as *const Points);
    *ierr = ZOLTAN_OK;
    pts.gids.len() as c_int
}

unsafe extern "C" fn obj_list(
    data: *mut c_void,
    _num_gid: c_int,
    _num_lid: c_int,
    gids: ZOLTAN_ID_PTR,
    lids: ZOLTAN_ID_PTR,
    _wgt_dim: c_int,
    _wgts: *mut f32,
    ierr: *mut c_int,
) {
    // SAFETY: `data` is the registered `Points`; Zoltan sized `gids` and
    // `lids` for the object count `num_obj` returned.
    let pts = &*(data as *const Points);
    for (i, &g) in pts.gids.iter().enumerate() {
        *gids.add(i) = g;
        *lids.add(i) = i as u32;
    }
    *ierr = ZOLTAN_OK;
}

unsafe extern "C" fn num_geom(_data: *mut c_void, ierr: *mut c_int) -> c_int {
    // SAFETY: Zoltan passes a valid `ierr`.
    *ierr = ZOLTAN_OK;
    3
}

unsafe extern "C" fn geom_multi(
    data: *mut c_void,
    _num_gid: c_int,
    _num_lid: c_int,
    num_obj: c_int,
    _gids: ZOLTAN_ID_PTR,
    lids: ZOLTAN_ID_PTR,
    num_dim: c_int,
    geom: *mut f64,
    ierr: *mut c_int,
) {
    // SAFETY: `data` is the registered `Points`; `lids` holds `num_obj` of
    // this rank's local ids, and `geom` room for `num_obj * num_dim` numbers.
    let pts = &*(data as *const Points);
    for i in 0..num_obj as usize {
        let p = pts.xyz[*lids.add(i) as usize];
        for (d, &coord) in p.iter().enumerate().take(num_dim as usize) {
            *geom.add(i * num_dim as usize + d) = coord;
        }
    }
    *ierr = ZOLTAN_OK;
}

fn set(zz: *mut Zoltan_Struct, k: &str, v: &str) {
    let (k, v) = (CString::new(k).unwrap(), CString::new(v).unwrap());
    // SAFETY: `zz` is a live handle from `Zoltan_Create`; both strings are
    // NUL-terminated and outlive the call.
    let rc = unsafe { Zoltan_Set_Param(zz, k.as_ptr(), v.as_ptr()) };
    assert_eq!(rc, ZOLTAN_OK, "Zoltan_Set_Param");
}

fn main() {
    let universe = mpi::initialize().expect("MPI init");
    let world = universe.world();
    let (rank, size) = (world.rank() as usize, world.size() as usize);
    let mut out = Reporter::new(rank);
    let n = PER_RANK * size;

    // Global id g sits at x = g; rank r owns g = r, r + size, r + 2 size, ...
    let gids: Vec<u32> = (0..PER_RANK).map(|i| (i * size + rank) as u32).collect();
    let xyz = gids
        .iter()
        .map(|&g| [g as f64, 0.25 + 1e-3 * (g % 3) as f64, 0.5])
        .collect();
    let mut pts = Points { gids, xyz };

    let mut ver = 0f32;
    // SAFETY: MPI is initialised (`universe` lives to the end of `main`);
    // Zoltan takes no arguments from us (argc 0, argv null).
    unsafe { Zoltan_Initialize(0, std::ptr::null_mut(), &mut ver) };
    // SAFETY: `world` is a valid communicator for as long as `zz` lives.
    let mut zz = unsafe { Zoltan_Create(world.as_raw()) };
    set(zz, "DEBUG_LEVEL", "0");
    set(zz, "LB_METHOD", "RCB");
    set(zz, "RETURN_LISTS", "EXPORT");
    set(zz, "NUM_GID_ENTRIES", "1");
    set(zz, "NUM_LID_ENTRIES", "1");
    set(zz, "OBJ_WEIGHT_DIM", "0");
    let data = &mut pts as *mut Points as *mut c_void;
    // SAFETY: `pts` outlives `zz` and is not moved while Zoltan may call
    // back; each callback has the signature Zoltan expects for its slot.
    unsafe {
        Zoltan_Set_Num_Obj_Fn(zz, Some(num_obj), data);
        Zoltan_Set_Obj_List_Fn(zz, Some(obj_list), data);
        Zoltan_Set_Num_Geom_Fn(zz, Some(num_geom), data);
        Zoltan_Set_Geom_Multi_Fn(zz, Some(geom_multi), data);
    }

    let (mut changes, mut ngid, mut nlid, mut nimp, mut nexp) = (0, 0, 0, 0, 0);
    let mut imp_g: ZOLTAN_ID_PTR = std::ptr::null_mut();
    let mut imp_l: ZOLTAN_ID_PTR = std::ptr::null_mut();
    let mut imp_p: *mut c_int = std::ptr::null_mut();
    let mut imp_t: *mut c_int = std::ptr::null_mut();
    let mut exp_g: ZOLTAN_ID_PTR = std::ptr::null_mut();
    let mut exp_l: ZOLTAN_ID_PTR = std::ptr::null_mut();
    let mut exp_p: *mut c_int = std::ptr::null_mut();
    let mut exp_t: *mut c_int = std::ptr::null_mut();
    // SAFETY: `zz` is live with its callbacks registered; every out-pointer
    // is a valid local that Zoltan fills (the lists it allocates are freed
    // below with Zoltan_LB_Free_Part).
    let rc = unsafe {
        Zoltan_LB_Partition(
            zz,
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
    out.kv("partition_rc", rc);
    out.kv("num_export", nexp);

    let mut part = [rank as i32; PER_RANK];
    for i in 0..nexp.max(0) as usize {
        // SAFETY: the export lists hold `nexp` entries.
        let lid = unsafe { *exp_l.add(i) } as usize;
        // SAFETY: as above.
        part[lid] = unsafe { *exp_t.add(i) };
    }
    for (i, &g) in pts.gids.iter().enumerate() {
        out.line(&format!("obj={g},{},{}", pts.xyz[i][0], part[i]));
    }
    out.kv("total", n);
    // SAFETY: the lists came from Zoltan_LB_Partition and are freed once;
    // `zz` is destroyed last, and nothing uses it after.
    unsafe {
        Zoltan_LB_Free_Part(&mut imp_g, &mut imp_l, &mut imp_p, &mut imp_t);
        Zoltan_LB_Free_Part(&mut exp_g, &mut exp_l, &mut exp_p, &mut exp_t);
        Zoltan_Destroy(&mut zz);
    }
}
