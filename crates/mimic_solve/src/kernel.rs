//! Which vector width the per-frame kernels run at ([`VectorKernel`]): chosen once per CPU, or
//! forced for A/B benchmarks and tests.

/// Which vector kernel a per-frame pass runs: [`crate::normals::VertexFans::normals_packed_by`]
/// and [`crate::deform::MovingDeform::deform_packed_by`] (benchmarks and tests; the other entry
/// points pick [`VectorKernel::best_for_normals`] and [`VectorKernel::best_for_deform`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VectorKernel {
    /// One fan (one row) at a time, any CPU.
    Portable,
    /// 8 fans (rows) in the lanes of an AVX register (AVX2 + FMA).
    Avx2,
}

impl VectorKernel {
    /// The normal pass's kernel unless told otherwise: AVX2 where the CPU has it, else portable.
    pub fn best_for_normals() -> Self {
        Self::Avx2.available()
    }

    /// The deform's kernel unless told otherwise: AVX2 where the CPU has it, else portable.
    pub fn best_for_deform() -> Self {
        Self::Avx2.available()
    }

    /// Whether this CPU runs `self`.
    pub fn supported(self) -> bool {
        match self {
            Self::Portable => true,
            #[cfg(target_arch = "x86_64")]
            Self::Avx2 => crate::basis::avx2_fma(),
            #[cfg(not(target_arch = "x86_64"))]
            Self::Avx2 => false,
        }
    }

    /// `self` where this CPU runs it, else portable.
    pub fn available(self) -> Self {
        if self.supported() {
            self
        } else {
            Self::Portable
        }
    }
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
        // The deform: AVX2 wherever the CPU has it.
        let avx2 = if VectorKernel::Avx2.supported() {
            VectorKernel::Avx2
        } else {
            VectorKernel::Portable
        };
        assert_eq!(deform, avx2);
        assert_eq!(normals, avx2, "{normals:?}");
        assert!(VectorKernel::Portable.supported());
        // A kernel the CPU lacks falls back to the widest narrower one it has.
        assert_eq!(VectorKernel::Portable.available(), VectorKernel::Portable);
        assert_eq!(VectorKernel::Avx2.available(), avx2);
    }
}
