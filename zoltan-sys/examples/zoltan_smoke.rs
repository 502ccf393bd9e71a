//! Run under mpirun by zoltan-sys's tests: Zoltan_Initialize, the id-type check,
//! Zoltan_Create on MPI_COMM_WORLD, a parameter set, Zoltan_Destroy.
use mpi::traits::*;
use mpi_harness::Reporter;
use std::ffi::{CStr, CString};
use zoltan_sys::*;

fn main() {
    let universe = mpi::initialize().expect("MPI init");
    let world = universe.world();
    let mut out = Reporter::new(world.rank() as usize);

    let mut version = 0f32;
    // SAFETY: MPI is initialised (`universe` lives to the end of `main`);
    // no arguments are passed (argc 0, argv null).
    let rc = unsafe { Zoltan_Initialize(0, std::ptr::null_mut(), &mut version) };
    out.kv("initialize_rc", rc);
    out.kv("zoltan_version", version);

    let mut name: *mut std::os::raw::c_char = std::ptr::null_mut();
    // SAFETY: `name` is a valid out-pointer; Zoltan points it at a static string.
    let id_size = unsafe { Zoltan_get_global_id_type(&mut name) };
    out.kv("library_id_size", id_size);
    out.kv("bindings_id_size", BINDINGS_ID_TYPE_SIZE);
    if !name.is_null() {
        out.kv(
            "id_type_name",
            // SAFETY: non-null, and a NUL-terminated static string of Zoltan's.
            unsafe { CStr::from_ptr(name) }.to_string_lossy(),
        );
    }

    // SAFETY: `world` is a valid communicator for as long as `zz` lives.
    let mut zz = unsafe { Zoltan_Create(world.as_raw()) };
    out.kv("created", !zz.is_null());
    let key = CString::new("DEBUG_LEVEL").unwrap();
    let val = CString::new("0").unwrap();
    // SAFETY: `zz` is live; the strings are NUL-terminated and outlive the call.
    out.kv("set_param_rc", unsafe {
        Zoltan_Set_Param(zz, key.as_ptr(), val.as_ptr())
    });
    let bad = CString::new("NO_SUCH_PARAMETER").unwrap();
    // SAFETY: as above.
    out.kv("bad_param_rc", unsafe {
        Zoltan_Set_Param(zz, bad.as_ptr(), val.as_ptr())
    });
    // SAFETY: `zz` came from Zoltan_Create, is destroyed once, and is null after.
    unsafe { Zoltan_Destroy(&mut zz) };
    out.kv("destroyed_to_null", zz.is_null());
    out.kv("ranks", world.size());
}
