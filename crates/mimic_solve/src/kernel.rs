//! Which vector width the per-frame kernels run at ([`VectorKernel`]): chosen once per CPU, or
//! forced for A/B benchmarks and tests.

/// Which vector kernel the per-frame passes run: [`crate::normals::VertexFans::normals_packed_by`]
/// and [`crate::deform::MovingDeform::deform_packed_by`] (benchmarks and tests; the other entry
/// points pick [`VectorKernel::best`]).
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
    /// The fastest kernel this CPU runs (runtime-detected, once): AVX-512 where the CPU has it
    /// at full width, AVX2 on CPUs that run 512-bit operations as two 256-bit halves (AMD Zen 4,
    /// where the 16-lane kernel measured 5-10 % slower than the 8-lane one: docs/performance.md),
    /// else portable.
    pub fn best() -> Self {
        static BEST: std::sync::OnceLock<VectorKernel> = std::sync::OnceLock::new();
        *BEST.get_or_init(|| {
            #[cfg(target_arch = "x86_64")]
            if Self::Avx512.supported() && !splits_512_bit_ops() {
                return Self::Avx512;
            }
            if Self::Avx2.supported() {
                Self::Avx2
            } else {
                Self::Portable
            }
        })
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

    /// `self` where this CPU runs it, else the best kernel it runs ([`VectorKernel::best`]).
    pub fn available(self) -> Self {
        if self.supported() { self } else { Self::best() }
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
