//! Which vector width the per-frame kernels run at ([`VectorKernel`]): chosen once per CPU and
//! pass, or forced for A/B benchmarks and tests.

/// Which vector kernel a per-frame pass runs: [`crate::normals::VertexFans::normals_packed_by`]
/// and [`crate::deform::MovingDeform::deform_packed_by`] (benchmarks and tests; the other entry
/// points pick [`VectorKernel::best_for_normals`] and [`VectorKernel::best_for_deform`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VectorKernel {
    /// One fan (one row) at a time, any CPU.
    Portable,
    /// 8 fans (rows) in the lanes of an AVX register (AVX2 + FMA).
    Avx2,
    /// 16 fans (rows) in the lanes of an AVX-512 register (AVX-512F).
    Avx512,
}

impl VectorKernel {
    /// The normal pass's kernel unless told otherwise (runtime-detected, once): AVX-512 where the
    /// CPU runs 512-bit operations at full width (faster than AVX2 in the step: 4-8 % on an Intel
    /// Xeon, 20-23 % on AMD Zen 5), AVX2 where it splits them in two halves (AMD Zen 4, where the
    /// 16-lane kernel measured 5-10 % slower than the 8-lane one) or has no AVX-512, else
    /// portable (docs/performance.md).
    pub fn best_for_normals() -> Self {
        static BEST: std::sync::OnceLock<VectorKernel> = std::sync::OnceLock::new();
        *BEST.get_or_init(|| {
            #[cfg(target_arch = "x86_64")]
            if Self::Avx512.supported() && !splits_512_bit_ops() {
                return Self::Avx512;
            }
            Self::Avx2.available()
        })
    }

    /// The deform's kernel unless told otherwise: AVX2 where the CPU has it, else portable. The
    /// AVX-512 deform is opt-in: on an Intel Xeon with AVX-512 it measured 6-10 % slower than
    /// AVX2 in the step (its 512-bit multiply-adds leave one of the two AVX2 ports idle there).
    pub fn best_for_deform() -> Self {
        Self::Avx2.available()
    }

    /// Whether this CPU runs `self`.
    pub fn supported(self) -> bool {
        match self {
            Self::Portable => true,
            #[cfg(target_arch = "x86_64")]
            Self::Avx2 => crate::basis::avx2_fma(),
            #[cfg(target_arch = "x86_64")]
            Self::Avx512 => {
                crate::basis::avx2_fma() && std::arch::is_x86_feature_detected!("avx512f")
            }
            #[cfg(not(target_arch = "x86_64"))]
            Self::Avx2 | Self::Avx512 => false,
        }
    }

    /// `self` where this CPU runs it, else the widest narrower kernel it runs (AVX-512, then
    /// AVX2, then portable).
    pub fn available(self) -> Self {
        match self {
            _ if self.supported() => self,
            Self::Avx512 => Self::Avx2.available(),
            _ => Self::Portable,
        }
    }
}

/// True on AMD family 19h (Zen 3 and Zen 4; only Zen 4 has AVX-512), whose 512-bit operations
/// issue as two 256-bit halves, so a 16-lane kernel does the 8-lane one's work in the same ops.
#[cfg(target_arch = "x86_64")]
fn splits_512_bit_ops() -> bool {
    // SAFETY: CPUID exists on every x86_64 CPU, with leaves 0 and 1 (a safe function in newer
    // Rust, an unsafe one at the MSRV).
    #[allow(
        unused_unsafe,
        reason = "__cpuid is safe in newer Rust, unsafe at the MSRV"
    )]
    let (vendor, signature) = unsafe {
        use std::arch::x86_64::__cpuid;
        (__cpuid(0), __cpuid(1).eax)
    };
    let amd = (vendor.ebx, vendor.edx, vendor.ecx) == (0x6874_7541, 0x6974_6e65, 0x444d_4163);
    // Family: the base field (bits 8-11) plus the extended one (bits 20-27) when the base is 0xF.
    let base = (signature >> 8) & 0xF;
    let family = if base == 0xF {
        base + ((signature >> 20) & 0xFF)
    } else {
        base
    };
    amd && family == 0x19
}

#[cfg(test)]
mod tests {
    use super::VectorKernel;

    #[test]
    fn kernel_choice_runs_only_what_the_cpu_has() {
        let (normals, deform) = (
            VectorKernel::best_for_normals(),
            VectorKernel::best_for_deform(),
        );
        assert!(
            normals.supported() && deform.supported(),
            "{normals:?} {deform:?}"
        );
        // The deform: AVX2 wherever the CPU has it, AVX-512 only when asked for.
        let avx2 = if VectorKernel::Avx2.supported() {
            VectorKernel::Avx2
        } else {
            VectorKernel::Portable
        };
        assert_eq!(deform, avx2);
        // The normals: AVX-512 or the deform's.
        assert!(
            normals == VectorKernel::Avx512 || normals == avx2,
            "{normals:?}"
        );
        assert!(VectorKernel::Portable.supported());
        // A kernel the CPU lacks falls back to the widest narrower one it has.
        assert_eq!(VectorKernel::Portable.available(), VectorKernel::Portable);
        assert_eq!(VectorKernel::Avx2.available(), avx2);
        let avx512 = if VectorKernel::Avx512.supported() {
            VectorKernel::Avx512
        } else {
            avx2
        };
        assert_eq!(VectorKernel::Avx512.available(), avx512);
        // The AVX2 kernel needs AVX2 and FMA, the AVX-512 one AVX-512F on top.
        assert!(!VectorKernel::Avx512.supported() || VectorKernel::Avx2.supported());
    }
}
