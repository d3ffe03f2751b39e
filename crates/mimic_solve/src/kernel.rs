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
    /// The kernel the per-frame passes run unless told otherwise (runtime-detected, once): AVX2
    /// where the CPU has it, else portable. The 16-lane AVX-512 kernels are opt-in: on every CPU
    /// measured they were slower than the 8-lane ones once both were tuned (an Intel Xeon with
    /// AVX-512: deform 10-13 % and normals 2-7 % slower, the whole step 5-8 %; AMD Zen 4, which
    /// splits 512-bit operations in two: normals 5-10 %; docs/performance.md).
    pub fn best() -> Self {
        static BEST: std::sync::OnceLock<VectorKernel> = std::sync::OnceLock::new();
        *BEST.get_or_init(|| {
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

#[cfg(test)]
mod tests {
    use super::VectorKernel;

    #[test]
    fn kernel_choice_runs_only_what_the_cpu_has() {
        let best = VectorKernel::best();
        assert!(best.supported(), "{best:?}");
        // AVX2 by default wherever the CPU has it; AVX-512 only when asked for.
        let want = if VectorKernel::Avx2.supported() {
            VectorKernel::Avx2
        } else {
            VectorKernel::Portable
        };
        assert_eq!(best, want);
        assert!(VectorKernel::Portable.supported());
        for k in [
            VectorKernel::Portable,
            VectorKernel::Avx2,
            VectorKernel::Avx512,
        ] {
            let expected = if k.supported() { k } else { best };
            assert_eq!(k.available(), expected, "{k:?}");
        }
        // The AVX2 kernel needs AVX2 and FMA, the AVX-512 one AVX-512F on top.
        assert!(!VectorKernel::Avx512.supported() || VectorKernel::Avx2.supported());
    }
}
