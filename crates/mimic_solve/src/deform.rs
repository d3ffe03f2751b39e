//! The per-frame deform of a mesh's moving part in one pass: `p_i = rest_i + (B d)_i` over the
//! rows of `B` that are not all zero, written both to a compact copy (for the normal pass) and to
//! the mesh's own positions.
//!
//! Compared with [`Basis::apply`] on the moving rows followed by a pass adding the rest positions
//! and scattering the result ([`MovingDeform`] replaces exactly that), it
//! - orders the moving rows by their support (the set of controls with a non-zero weight, which
//!   face regions make few and shared by large groups of vertices), so that a block of 24 rows
//!   keeps only about as many columns as one row has non-zero weights, instead of the union over
//!   rows of different regions;
//! - adds the rest positions in registers and writes the compact positions (packed, 3 floats a
//!   row) and the mesh positions from the same registers: no intermediate `u`, no second pass;
//! - stores a block's mesh positions with three full-width stores when its rows are consecutive
//!   vertices of the mesh; a scattered block's rows are copied from the compact rows while the
//!   next block is summed, on the load and store ports the sums leave idle.
//!
//! The sums are the same fused multiply-add chains as [`Basis::apply`]'s (ascending control
//! index, zero weights skipped), so the positions are bit-for-bit those of `rest + B d`.
//!
//! Two kernels: AVX2 + FMA ([`VectorKernel::Avx2`], `deform/x86.rs`) and portable (any CPU).
//! The AVX2 one is kept because it is most of the step's speed: `mimic bench` on the CI machine
//! class (AMD EPYC Zen 2, 2 vCPUs, AVX2), 2026-12-07, the step with the portable deform ran
//! 17.5-18.3x the default's on `ict-face-3k` and 21.0-21.7x on `ict-face` (medians of 3 runs,
//! turns of 1 and 200 frames; docs/performance.md, "Kernel variants").

use crate::Basis;
use crate::kernel::VectorKernel;
use glam::{Vec3, Vec3A};

/// Rows per block: 3 AVX registers of f32.
const BLOCK: usize = 24;

/// Marks a block whose rows are not consecutive mesh vertices.
const SCATTERED: u32 = u32::MAX;

/// The moving rows of a basis, ordered by support and stored column-blocked with their rest
/// positions, for [`MovingDeform::deform_packed`].
#[derive(Clone, Debug, PartialEq)]
pub struct MovingDeform {
    /// Mesh vertex of each row, in kernel order.
    rows: Vec<u32>,
    /// Controls (columns of `B`).
    control_count: usize,
    /// Mesh positions needed: one past the largest row.
    vertex_count: usize,
    /// Block `b` keeps columns `cols[starts[b]..starts[b + 1]]`.
    starts: Vec<u32>,
    /// Column index of each kept column.
    cols: Vec<u32>,
    /// `values[k * BLOCK + r]`: weight of kept column `k` on row `r` of its block (0 past the end).
    values: Vec<f32>,
    /// Per block, `3 * BLOCK` rest coordinates: the block's x, then y, then z (0 past the end).
    rest: Vec<f32>,
    /// Per block, its first mesh vertex when its `BLOCK` rows are consecutive vertices, else
    /// [`SCATTERED`].
    runs: Vec<u32>,
}

impl MovingDeform {
    /// The rows among the first `rest.len()` of `basis` that are not all zero, with their rest
    /// positions `rest` (one per mesh vertex).
    pub fn new(basis: &Basis, rest: &[Vec3]) -> Self {
        let (n, m) = (basis.vertex_count().min(rest.len()), basis.control_count());
        let mut rows: Vec<u32> = (0..n)
            .filter(|&i| basis.row(i).iter().any(|w| *w != 0.0))
            .map(|i| i as u32)
            .collect();
        // Rows of equal support together (the first 64 controls' pattern, then the vertex
        // index, so that runs of consecutive vertices stay runs).
        let support = |i: u32| -> u64 {
            basis
                .row(i as usize)
                .iter()
                .take(64)
                .enumerate()
                .filter(|(_, w)| **w != 0.0)
                .fold(0u64, |s, (j, _)| s | 1 << j)
        };
        rows.sort_by_key(|&i| (support(i), i));
        let blocks = rows.len().div_ceil(BLOCK);
        let mut starts = Vec::with_capacity(blocks + 1);
        let mut cols = Vec::new();
        let mut values = Vec::new();
        let mut rest_blocked = Vec::with_capacity(blocks * 3 * BLOCK);
        let mut runs = Vec::with_capacity(blocks);
        starts.push(0);
        for block in rows.chunks(BLOCK) {
            for j in 0..m {
                if block.iter().any(|&i| basis.row(i as usize)[j] != 0.0) {
                    cols.push(j as u32);
                    values.extend(block.iter().map(|&i| basis.row(i as usize)[j]));
                    values.resize(cols.len() * BLOCK, 0.0);
                }
            }
            starts.push(cols.len() as u32);
            for a in [0usize, 1, 2] {
                rest_blocked.extend(block.iter().map(|&i| rest[i as usize][a]));
                rest_blocked.resize(rest_blocked.len().next_multiple_of(BLOCK), 0.0);
            }
            let consecutive = block.len() == BLOCK && block.windows(2).all(|w| w[1] == w[0] + 1);
            runs.push(if consecutive { block[0] } else { SCATTERED });
        }
        let vertex_count = rows.iter().map(|&i| i as usize + 1).max().unwrap_or(0);
        Self {
            rows,
            control_count: m,
            vertex_count,
            starts,
            cols,
            values,
            rest: rest_blocked,
            runs,
        }
    }

    /// Mesh vertex of each moving row, in the order of [`MovingDeform::deform_packed`]'s compact output.
    pub fn rows(&self) -> &[u32] {
        &self.rows
    }

    /// Number of controls.
    pub fn control_count(&self) -> usize {
        self.control_count
    }

    /// Kept block-columns over all block-columns (1 for a dense basis): the share of `B`'s
    /// moving rows the kernel reads.
    pub fn kept_fraction(&self) -> f64 {
        let all = self.runs.len() * self.control_count;
        if all == 0 {
            return 0.0;
        }
        self.cols.len() as f64 / all as f64
    }

    /// Bytes the kernel reads per call: the kept weights and the rest positions (4 bytes each).
    pub fn bytes_read(&self) -> usize {
        (self.values.len() + self.rest.len()) * 4
    }

    /// `compact[3 k..3 k + 3] = positions[rows()[k]] = rest + (B d)` for every moving row `k`
    /// (the compact copy packed 3 floats a row, for the fan pass's packed reads,
    /// [`crate::normals::VertexFans::normals_packed`]); other positions are left as they are.
    /// The same registers are stored twice where a block's rows are consecutive vertices.
    /// Allocates nothing.
    ///
    /// # Panics
    /// If `d.len() != control_count()`, `compact.len() < 3 * rows().len()` or `positions` is
    /// shorter than the mesh the rows name: all fixed at setup, so programming errors.
    pub fn deform_packed(&self, d: &[Vec3], compact: &mut [f32], positions: &mut [Vec3]) {
        self.deform_packed_by(VectorKernel::best_for_deform(), d, compact, positions);
    }

    /// [`MovingDeform::deform_packed`] by a given kernel (benchmarks and tests; one the CPU
    /// lacks runs the portable one): 8 rows a register (AVX2) or one row at a time (portable).
    /// Both sum the same fused chains, so the positions are the same bit for bit.
    ///
    /// # Panics
    /// As [`MovingDeform::deform_packed`].
    pub fn deform_packed_by(
        &self,
        kernel: VectorKernel,
        d: &[Vec3],
        compact: &mut [f32],
        positions: &mut [Vec3],
    ) {
        assert_eq!(
            d.len(),
            self.control_count,
            "MovingDeform::deform_packed: {} control displacements for {} controls",
            d.len(),
            self.control_count
        );
        assert!(
            compact.len() >= 3 * self.rows.len() && positions.len() >= self.vertex_count,
            "MovingDeform::deform_packed: outputs of {} floats and {} entries for {} rows of {} vertices",
            compact.len(),
            positions.len(),
            self.rows.len(),
            self.vertex_count
        );
        let compact = &mut compact[..3 * self.rows.len()];
        let kernel = kernel.available();
        #[cfg(target_arch = "x86_64")]
        if kernel == VectorKernel::Avx2 {
            // SAFETY: `available` runs `Avx2` only where the CPU has AVX2 and FMA; the shapes are
            // asserted above and the blocked arrays were built for these rows and controls.
            unsafe { self.deform_packed_avx2(d, compact, positions) };
            return;
        }
        for (b, out) in compact.chunks_mut(3 * BLOCK).enumerate() {
            let kept = self.starts[b] as usize..self.starts[b + 1] as usize;
            let rest = &self.rest[b * 3 * BLOCK..][..3 * BLOCK];
            for (r, o) in out.chunks_exact_mut(3).enumerate() {
                // The vector kernels' fused chains, one row at a time: the same sums bit for
                // bit (in software where a CPU has no FMA instruction: slow, but exact).
                let mut u = Vec3A::ZERO;
                for (k, &j) in self.cols[kept.clone()].iter().enumerate() {
                    let w = Vec3A::splat(self.values[(kept.start + k) * BLOCK + r]);
                    u = w.mul_add(Vec3A::from(d[j as usize]), u);
                }
                let p = Vec3A::new(rest[r], rest[BLOCK + r], rest[2 * BLOCK + r]) + u;
                o.copy_from_slice(&p.to_array());
                positions[self.rows[b * BLOCK + r] as usize] = Vec3::from(p);
            }
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod x86;

#[cfg(test)]
mod tests;
