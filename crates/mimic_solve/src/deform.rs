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
//! - adds the rest positions in registers and writes the compact positions (16-byte `Vec3A`) and
//!   the mesh positions from the same registers: no intermediate `u`, no second pass;
//! - stores a block's mesh positions with three full-width stores when its rows are consecutive
//!   vertices of the mesh, one `Vec3` at a time otherwise (the packed kernels: copied from the
//!   compact rows while the next block is summed, on the load and store ports the sums leave
//!   idle).
//!
//! The sums are the same fused multiply-add chains as [`Basis::apply`]'s (ascending control
//! index, zero weights skipped), so the positions are bit-for-bit those of `rest + B d`.
//!
//! Opt-in, [`MovingDeform::with_f16_weights`] stores the weights as IEEE binary16 (half the
//! bytes read per frame), converted to f32 in registers (F16C): the same sums over the rounded
//! weights, so each coordinate moves by at most `sum_j (2^-11 |B_ij| + 2^-25) |d_j|` from the
//! f32 weights' result (plus the f32 rounding of both).

use crate::kernel::VectorKernel;
use crate::{Basis, SolveError};
use glam::{Vec3, Vec3A};

/// Rows per block: 3 AVX registers of f32.
const BLOCK: usize = 24;

/// Marks a block whose rows are not consecutive mesh vertices.
const SCATTERED: u32 = u32::MAX;

/// The moving rows of a basis, ordered by support and stored column-blocked with their rest
/// positions, for [`MovingDeform::deform`].
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
    /// `values` rounded to binary16 (bits), read instead of `values` when not empty
    /// ([`MovingDeform::with_f16_weights`]).
    half: Vec<u16>,
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
            half: Vec::new(),
        }
    }

    /// The same deform with its weights stored as IEEE binary16 (rounded to nearest), read by
    /// every later call instead of the f32 ones: half the weight bytes per frame, each
    /// coordinate within `sum_j (2^-11 |B_ij| + 2^-25) |d_j|` of the f32 weights' result (the
    /// rounding of each weight, relative 2^-11 or absolute 2^-25 below f16's normal range),
    /// plus the f32 rounding of both sums.
    ///
    /// # Errors
    /// [`SolveError::F16Range`] if a weight's magnitude exceeds f16's largest value (65 504).
    pub fn with_f16_weights(mut self) -> Result<Self, SolveError> {
        let max = f32::from(half::f16::MAX);
        if let Some(k) = self.values.iter().position(|w| w.abs() > max) {
            let (col, r) = (k / BLOCK, k % BLOCK);
            let block = self.starts.partition_point(|&s| s as usize <= col) - 1;
            return Err(SolveError::F16Range {
                vertex: self.rows[block * BLOCK + r],
                control: self.cols[col],
                weight: self.values[k],
            });
        }
        self.half = self
            .values
            .iter()
            .map(|&w| half::f16::from_f32(w).to_bits())
            .collect();
        Ok(self)
    }

    /// Whether the weights are read as binary16 ([`MovingDeform::with_f16_weights`]).
    pub fn f16_weights(&self) -> bool {
        !self.half.is_empty()
    }

    /// Kept weight `k` (over all blocks' kept columns) of row `r` of its block, as the kernels
    /// read it: f32, or its binary16 rounding.
    fn weight(&self, k: usize, r: usize) -> f32 {
        match self.half.get(k * BLOCK + r) {
            Some(&h) => f32::from(half::f16::from_bits(h)),
            None => self.values[k * BLOCK + r],
        }
    }

    /// Mesh vertex of each moving row, in the order of [`MovingDeform::deform`]'s compact output.
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

    /// Bytes the kernel reads per call: the kept weights (4 or 2 bytes each) and the rest
    /// positions.
    pub fn bytes_read(&self) -> usize {
        let weight = if self.f16_weights() { 2 } else { 4 };
        self.values.len() * weight + self.rest.len() * 4
    }

    /// `compact[k] = positions[rows()[k]] = rest + (B d)` for every moving row `k`; other
    /// positions are left as they are. Allocates nothing.
    ///
    /// # Panics
    /// If `d.len() != control_count()`, `compact.len() < rows().len()` or `positions` is shorter
    /// than the mesh the rows name: all fixed at setup, so programming errors.
    pub fn deform(&self, d: &[Vec3], compact: &mut [Vec3A], positions: &mut [Vec3]) {
        assert_eq!(
            d.len(),
            self.control_count,
            "MovingDeform::deform: {} control displacements for {} controls",
            d.len(),
            self.control_count
        );
        assert!(
            compact.len() >= self.rows.len() && positions.len() >= self.vertex_count,
            "MovingDeform::deform: outputs of {} and {} entries for {} rows of {} vertices",
            compact.len(),
            positions.len(),
            self.rows.len(),
            self.vertex_count
        );
        let compact = &mut compact[..self.rows.len()];
        #[cfg(target_arch = "x86_64")]
        if avx2_fma_f16c() {
            // SAFETY: AVX2, FMA and F16C are checked just above; the shapes are asserted above
            // and the blocked arrays (and `half`, when not empty) were built for these rows and
            // controls.
            unsafe {
                if self.f16_weights() {
                    self.deform_avx2::<true>(d, compact, positions);
                } else {
                    self.deform_avx2::<false>(d, compact, positions);
                }
            }
            return;
        }
        self.deform_portable(d, compact, positions);
    }

    /// [`MovingDeform::deform`] with the compact copy packed 3 floats a row
    /// (`compact[3 k..3 k + 3] = positions[rows()[k]]`, for the fan pass's packed reads,
    /// [`crate::normals::VertexFans::normals_packed`]): the same positions bit for bit, and the
    /// same registers stored twice where a block's rows are consecutive vertices. Allocates nothing.
    ///
    /// # Panics
    /// As [`MovingDeform::deform`], with `compact.len() < 3 * rows().len()`.
    pub fn deform_packed(&self, d: &[Vec3], compact: &mut [f32], positions: &mut [Vec3]) {
        self.deform_packed_by(VectorKernel::best_for_deform(), d, compact, positions);
    }

    /// [`MovingDeform::deform_packed`] by a given kernel (benchmarks and tests; one the CPU
    /// lacks runs the widest narrower one it has): 8 rows a register (AVX2), 16 and 8
    /// (AVX-512: a block's 24 rows in one 512-bit and one 256-bit register a coordinate), or one
    /// row at a time (portable). Every kernel sums the same fused chains, so the positions are
    /// the same bit for bit.
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
        if kernel != VectorKernel::Portable && avx2_fma_f16c() {
            let wide = kernel == VectorKernel::Avx512;
            // SAFETY: AVX2, FMA and F16C are checked just above, AVX-512F by `available` (it
            // runs `Avx512` only where the CPU has it); the shapes as in `deform`.
            unsafe {
                match (wide, self.f16_weights()) {
                    (true, true) => self.deform_packed_avx512::<true>(d, compact, positions),
                    (true, false) => self.deform_packed_avx512::<false>(d, compact, positions),
                    (false, true) => self.deform_packed_avx2::<true>(d, compact, positions),
                    (false, false) => self.deform_packed_avx2::<false>(d, compact, positions),
                }
            }
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
                    let w = Vec3A::splat(self.weight(kept.start + k, r));
                    u = w.mul_add(Vec3A::from(d[j as usize]), u);
                }
                let p = Vec3A::new(rest[r], rest[BLOCK + r], rest[2 * BLOCK + r]) + u;
                o.copy_from_slice(&p.to_array());
                positions[self.rows[b * BLOCK + r] as usize] = Vec3::from(p);
            }
        }
    }

    /// [`MovingDeform::deform`] on any CPU: the same blocked sums (over the weights as
    /// [`MovingDeform::weight`] reads them), one row at a time.
    fn deform_portable(&self, d: &[Vec3], compact: &mut [Vec3A], positions: &mut [Vec3]) {
        for (b, out) in compact.chunks_mut(BLOCK).enumerate() {
            let kept = self.starts[b] as usize..self.starts[b + 1] as usize;
            let rest = &self.rest[b * 3 * BLOCK..][..3 * BLOCK];
            for (r, o) in out.iter_mut().enumerate() {
                let mut u = Vec3A::ZERO;
                for (k, &j) in self.cols[kept.clone()].iter().enumerate() {
                    u += Vec3A::from(d[j as usize]) * self.weight(kept.start + k, r);
                }
                let rest = Vec3A::new(rest[r], rest[BLOCK + r], rest[2 * BLOCK + r]);
                *o = rest + u;
                positions[self.rows[b * BLOCK + r] as usize] = Vec3::from(*o);
            }
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod x86;
#[cfg(target_arch = "x86_64")]
use x86::avx2_fma_f16c;

#[cfg(test)]
mod tests;
