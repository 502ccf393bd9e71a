//! Process-wide initialisation of the Zoltan library.

use std::sync::OnceLock;

/// Errors of the Zoltan layer.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ZoltanError {
    #[error("Zoltan_Initialize failed with code {0}")]
    Initialize(i32),
    #[error(
        "Zoltan was built with a {library}-byte ZOLTAN_ID_TYPE but these bindings assume \
         {bindings} bytes; rebuild zoltan-sys against the same zoltan.h as the library"
    )]
    IdTypeMismatch { library: usize, bindings: usize },
    #[error("Zoltan_Create returned null")]
    Create,
    #[error("{what} failed with Zoltan code {code}")]
    Call { what: String, code: i32 },
    #[error("item ids must fit Zoltan's 4-byte global ids")]
    IdTooLarge,
}

/// The version Zoltan_Initialize reported, e.g. 3.9.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ZoltanVersion(pub f32);

impl std::fmt::Display for ZoltanVersion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:.2}", self.0)
    }
}

/// Initialises Zoltan once per process and checks that the library's global
/// id type has the width the bindings assume. Zoltan_Initialize needs MPI
/// initialised: the universe is the proof that it is.
pub fn initialize(_mpi: &mpi::environment::Universe) -> Result<ZoltanVersion, ZoltanError> {
    init_once()
}

/// [`initialize`], with a communicator as the proof that MPI is initialised.
pub(crate) fn initialize_on(
    _comm: &mpi::topology::SimpleCommunicator,
) -> Result<ZoltanVersion, ZoltanError> {
    init_once()
}

fn init_once() -> Result<ZoltanVersion, ZoltanError> {
    static INIT: OnceLock<Result<ZoltanVersion, ZoltanError>> = OnceLock::new();
    INIT.get_or_init(|| {
        let mut version = 0f32;
        // SAFETY: argc = 0 with a null argv is allowed when MPI is already
        // initialised, which both callers hold a proof of.
        let rc = unsafe { zoltan_sys::Zoltan_Initialize(0, std::ptr::null_mut(), &mut version) };
        if rc != zoltan_sys::ZOLTAN_OK {
            return Err(ZoltanError::Initialize(rc));
        }
        let mut name = std::ptr::null_mut();
        // SAFETY: Zoltan writes a pointer to a static string into `name`.
        let library = unsafe { zoltan_sys::Zoltan_get_global_id_type(&mut name) } as usize;
        check_id_width(library, zoltan_sys::BINDINGS_ID_TYPE_SIZE)?;
        Ok(ZoltanVersion(version))
    })
    .clone()
}

fn check_id_width(library: usize, bindings: usize) -> Result<(), ZoltanError> {
    if library == bindings {
        Ok(())
    } else {
        Err(ZoltanError::IdTypeMismatch { library, bindings })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn id_width_mismatch_is_reported() {
        assert_eq!(check_id_width(4, 4), Ok(()));
        let err = check_id_width(8, 4).unwrap_err();
        assert!(err.to_string().contains("8-byte"), "{err}");
    }
}
