//! The instruction sets the SIMD kernels are compiled for, and run-time choice
//! among them.
//!
//! Each kernel is written once as loops over lanes and compiled three times:
//! inside `#[target_feature]` wrappers for AVX-512 and AVX2, and for the build's
//! baseline. [`Isa::detect`] picks the best one this CPU runs.

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
            if std::is_x86_feature_detected!("avx512f")
                && std::is_x86_feature_detected!("avx512dq")
                && std::is_x86_feature_detected!("avx512vl")
            {
                return Isa::Avx512;
            }
            if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
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

    /// This instruction set, or the detected one if this CPU lacks it: the
    /// kernels' `unsafe` dispatch relies on never running above what the CPU has.
    pub fn available(self) -> Isa {
        let have = Isa::detect();
        if self.rank() > have.rank() {
            have
        } else {
            self
        }
    }
}
