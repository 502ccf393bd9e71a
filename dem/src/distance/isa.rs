//! The instruction sets the SIMD kernels are compiled for, and run-time choice
//! among them.
//!
//! Each kernel is written once as loops over lanes and compiled three times:
//! inside `#[target_feature]` wrappers for AVX-512 and AVX2, and for the build's
//! baseline. [`Isa::detect`] picks the best one this CPU runs.
//!
//! The SIMD entry points are `unsafe`: run on a CPU without their
//! instructions, they are undefined behaviour. What makes calling them
//! sound is a [`Supported`]: proof that this CPU runs an instruction set,
//! which only [`Isa::supported`] makes (lowering the request to what the CPU
//! has). Every function that dispatches to SIMD code takes one, so no caller
//! can hand it an instruction set the CPU lacks.

/// Instruction sets the kernels can run on, best first.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Isa {
    Avx512,
    Avx2,
    /// Whatever the build's baseline target has (SSE2 on x86_64).
    Baseline,
}

impl Isa {
    /// The best instruction set this CPU supports.
    pub fn detect() -> Isa {
        #[cfg(target_arch = "x86_64")]
        {
            // The AVX-512 kernels are also compiled with AVX2 and FMA, and a
            // proof of AVX-512 must imply one of AVX2 (`Supported::at_most`).
            let avx2 =
                std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma");
            if avx2
                && std::is_x86_feature_detected!("avx512f")
                && std::is_x86_feature_detected!("avx512dq")
                && std::is_x86_feature_detected!("avx512vl")
            {
                return Isa::Avx512;
            }
            if avx2 {
                return Isa::Avx2;
            }
        }
        Isa::Baseline
    }

    pub fn name(self) -> &'static str {
        match self {
            Isa::Avx512 => "avx512",
            Isa::Avx2 => "avx2",
            Isa::Baseline => "baseline",
        }
    }

    fn rank(self) -> u8 {
        match self {
            Isa::Avx512 => 2,
            Isa::Avx2 => 1,
            Isa::Baseline => 0,
        }
    }

    /// This instruction set, or the detected one if this CPU lacks it.
    pub fn available(self) -> Isa {
        let have = Isa::detect();
        if self.rank() > have.rank() {
            have
        } else {
            self
        }
    }

    /// Proof that this CPU runs this instruction set, or the detected one
    /// if it lacks it (see the module doc).
    pub fn supported(self) -> Supported {
        Supported(self.available())
    }
}

/// Proof that this CPU runs an instruction set: made only by
/// [`Isa::supported`] (the field is private), taken by every function that
/// dispatches to SIMD code. It cannot be made by hand:
///
/// ```compile_fail
/// let claimed = dem::distance::Supported(dem::distance::Isa::Avx512);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Supported(Isa);

impl Supported {
    /// The instruction set this CPU is proved to run.
    pub fn isa(self) -> Isa {
        self.0
    }

    /// The lower of this and `isa`: a CPU that runs an instruction set runs
    /// the ones below it ([`Isa::detect`] requires AVX2 for AVX-512).
    pub fn at_most(self, isa: Isa) -> Supported {
        if isa.rank() < self.0.rank() {
            Supported(isa)
        } else {
            self
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ALL: [Isa; 3] = [Isa::Avx512, Isa::Avx2, Isa::Baseline];

    #[test]
    fn a_proof_never_claims_more_than_the_cpu_has() {
        let have = Isa::detect();
        for isa in ALL {
            let proved = isa.supported().isa();
            assert!(proved.rank() <= have.rank() && proved.rank() <= isa.rank());
            assert!(
                proved == isa || proved == have,
                "{isa:?} proved as {proved:?}"
            );
            for lower in ALL {
                let l = isa.supported().at_most(lower).isa();
                assert!(l.rank() <= proved.rank() && l.rank() <= lower.rank());
            }
        }
        assert_eq!(Isa::Baseline.supported().isa(), Isa::Baseline);
    }
}
