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
//!   vertices of the mesh, one `Vec3` at a time otherwise.
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
        self.deform_packed_by(VectorKernel::best(), d, compact, positions);
    }

    /// [`MovingDeform::deform_packed`] by a given kernel (benchmarks and tests; one the CPU
    /// lacks runs the best it has): 8 rows a register (AVX2), 16 and 8 (AVX-512: a block's 24
    /// rows in one 512-bit and one 256-bit register a coordinate), or one row at a time
    /// (portable). Every kernel sums the same fused chains, so the positions are the same bit
    /// for bit.
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

    /// [`MovingDeform::deform`] with AVX2 + FMA: per block, 9 accumulators (24 rows x 3 axes),
    /// one broadcast of each kept control's coordinates, the rest added in registers, then the
    /// rows transposed to `Vec3A` for `compact` and to packed `Vec3` for `positions`.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA; `compact.len() == rows.len()`, `positions.len() >=
    /// vertex_count` and `d.len() == control_count`.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,f16c")]
    unsafe fn deform_avx2<const HALF: bool>(
        &self,
        d: &[Vec3],
        compact: &mut [Vec3A],
        positions: &mut [Vec3],
    ) {
        const L: usize = 8;
        let mut spare = [Vec3A::ZERO; BLOCK];
        let dp = d.as_ptr().cast::<f32>();
        for (b, out) in compact.chunks_mut(BLOCK).enumerate() {
            let full = out.len() == BLOCK;
            let dst: *mut f32 = if full {
                out.as_mut_ptr().cast()
            } else {
                spare.as_mut_ptr().cast()
            };
            let kept = self.starts[b] as usize..self.starts[b + 1] as usize;
            let weights = self.block_weights::<HALF>(kept.clone());
            let cols = &self.cols[kept];
            let rest = &self.rest[b * 3 * BLOCK..][..3 * BLOCK];
            // SAFETY: `values` holds BLOCK weights per kept column; each kept column is <
            // control_count == d.len(), so `dp` reads 3 f32 of one Vec3 (repr(C) x, y, z);
            // `rest` holds 3 * BLOCK values (`block_rows`' contract); `dst` points at BLOCK Vec3A (the block's compact rows when full,
            // else `spare`); a run's 24 positions lie below vertex_count <= positions.len().
            unsafe {
                let rows = block_rows::<HALF>(weights, cols, dp, rest);
                let run = self.runs[b];
                for (g, &[x, y, z]) in rows.iter().enumerate() {
                    store_vec3a8(dst.add(g * 4 * L), x, y, z);
                    if run != SCATTERED {
                        let p = positions.as_mut_ptr().cast::<f32>();
                        crate::basis::store_xyz8(p.add(3 * (run as usize + g * L)), x, y, z);
                    }
                }
            }
            if !full {
                out.copy_from_slice(&spare[..out.len()]);
            }
            if self.runs[b] == SCATTERED {
                for (&i, p) in self.rows[b * BLOCK..].iter().zip(out.iter()) {
                    positions[i as usize] = Vec3::from(*p);
                }
            }
        }
    }
}

impl MovingDeform {
    /// The kept columns `kept` of a block as the AVX2 kernels read them: `BLOCK` f32 (or, with
    /// `HALF`, binary16) weights per column, from the start of the first.
    #[cfg(target_arch = "x86_64")]
    fn block_weights<const HALF: bool>(&self, kept: std::ops::Range<usize>) -> *const u8 {
        if HALF {
            self.half[kept.start * BLOCK..kept.end * BLOCK]
                .as_ptr()
                .cast()
        } else {
            self.values[kept.start * BLOCK..kept.end * BLOCK]
                .as_ptr()
                .cast()
        }
    }

    /// [`MovingDeform::deform_packed`] with AVX2 + FMA: [`MovingDeform::deform_avx2`]'s sums, the
    /// rows stored packed (x, y, z) to `compact` and, for a run of consecutive vertices, the same
    /// three registers to `positions`.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA; `compact.len() == 3 * rows.len()`, `positions.len() >=
    /// vertex_count` and `d.len() == control_count`.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,f16c")]
    unsafe fn deform_packed_avx2<const HALF: bool>(
        &self,
        d: &[Vec3],
        compact: &mut [f32],
        positions: &mut [Vec3],
    ) {
        // SAFETY: the block function's contract is `block_rows`' (the loop passes it BLOCK
        // weights a kept column, in-bound columns and 3 * BLOCK rest values); AVX2, FMA and
        // F16C as this function's (caller); shapes as this function's.
        unsafe {
            self.packed_blocks::<HALF>(d, compact, positions, |w, c, dp, r| {
                block_rows::<HALF>(w, c, dp, r)
            });
        }
    }

    /// [`MovingDeform::deform_packed_avx2`] with each block's 24 rows in one 512-bit and one
    /// 256-bit register a coordinate ([`block_rows_avx512`]): 6 multiply-adds a kept column
    /// instead of 9, the same sums, stored by the same loop.
    ///
    /// # Safety
    /// The CPU must support AVX-512F, AVX2, FMA and F16C; shapes as in
    /// [`MovingDeform::deform_packed_avx2`].
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx2,fma,f16c")]
    unsafe fn deform_packed_avx512<const HALF: bool>(
        &self,
        d: &[Vec3],
        compact: &mut [f32],
        positions: &mut [Vec3],
    ) {
        // SAFETY: as in `deform_packed_avx2`, with AVX-512F (caller).
        unsafe {
            self.packed_blocks::<HALF>(d, compact, positions, |w, c, dp, r| {
                block_rows_avx512::<HALF>(w, c, dp, r)
            });
        }
    }

    /// The packed kernels' loop over blocks: `rows_of` sums a block's 24 rows (as
    /// [`block_rows`] does), stored packed to `compact` and, for a run of consecutive vertices,
    /// from the same registers to `positions`; scattered blocks are copied row by row. Inlined
    /// into each kernel, so `rows_of` runs with that kernel's CPU features.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA, and `rows_of` must be safe to call with a block's
    /// weights, kept columns, `d` and rest values (`block_rows`' contract); `compact.len() ==
    /// 3 * rows.len()`, `positions.len() >= vertex_count` and `d.len() == control_count`.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn packed_blocks<const HALF: bool>(
        &self,
        d: &[Vec3],
        compact: &mut [f32],
        positions: &mut [Vec3],
        rows_of: impl Fn(*const u8, &[u32], *const f32, &[f32]) -> [[std::arch::x86_64::__m256; 3]; 3],
    ) {
        const L: usize = 8;
        let mut spare = [0f32; 3 * BLOCK];
        let dp = d.as_ptr().cast::<f32>();
        for (b, out) in compact.chunks_mut(3 * BLOCK).enumerate() {
            let full = out.len() == 3 * BLOCK;
            let dst: *mut f32 = if full {
                out.as_mut_ptr()
            } else {
                spare.as_mut_ptr()
            };
            let kept = self.starts[b] as usize..self.starts[b + 1] as usize;
            let weights = self.block_weights::<HALF>(kept.clone());
            let cols = &self.cols[kept];
            let rest = &self.rest[b * 3 * BLOCK..][..3 * BLOCK];
            let rows = rows_of(weights, cols, dp, rest);
            let run = self.runs[b];
            // SAFETY: `dst` points at 3 * BLOCK floats (the block's packed compact rows when
            // full, else `spare`); a run's 24 positions lie below vertex_count <=
            // positions.len(); AVX2 (caller).
            unsafe {
                for (g, &[x, y, z]) in rows.iter().enumerate() {
                    crate::basis::store_xyz8(dst.add(g * 3 * L), x, y, z);
                    if run != SCATTERED {
                        let p = positions.as_mut_ptr().cast::<f32>();
                        crate::basis::store_xyz8(p.add(3 * (run as usize + g * L)), x, y, z);
                    }
                }
            }
            if !full {
                out.copy_from_slice(&spare[..out.len()]);
            }
            if run == SCATTERED {
                for (&i, p) in self.rows[b * BLOCK..].iter().zip(out.chunks_exact(3)) {
                    positions[i as usize] = Vec3::new(p[0], p[1], p[2]);
                }
            }
        }
    }
}

/// [`block_rows`] with AVX-512F: rows 0-15 of the block in a 512-bit register a coordinate,
/// rows 16-23 in a 256-bit one (one broadcast of each coordinate serves both), the rest added in
/// registers; returned as [`block_rows`] returns them (three groups of 8 rows, x, y, z). Each
/// lane runs the same chain of fused multiply-adds as [`block_rows`]'s, so the sums are the same
/// bit for bit.
///
/// # Safety
/// As [`block_rows`], and the CPU must support AVX-512F.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx2,fma,f16c")]
#[inline]
unsafe fn block_rows_avx512<const HALF: bool>(
    weights: *const u8,
    cols: &[u32],
    dp: *const f32,
    rest: &[f32],
) -> [[std::arch::x86_64::__m256; 3]; 3] {
    use std::arch::x86_64::*;
    const L: usize = 8;
    let size = if HALF { 2 } else { 4 };
    // SAFETY (of the callers below): p points at 16 (wide) or 8 readable weights.
    let wide = |p: *const u8| unsafe {
        if HALF {
            _mm512_cvtph_ps(_mm256_loadu_si256(p.cast()))
        } else {
            _mm512_loadu_ps(p.cast())
        }
    };
    let narrow = |p: *const u8| unsafe {
        if HALF {
            _mm256_cvtph_ps(_mm_loadu_si128(p.cast()))
        } else {
            _mm256_loadu_ps(p.cast())
        }
    };
    // The high 8 lanes of a 512-bit register (AVX-512F only: through the 64-bit view).
    let high = |v: __m512| _mm256_castpd_ps(_mm512_extractf64x4_pd::<1>(_mm512_castps_pd(v)));
    // SAFETY: as in `block_rows` (the same reads: BLOCK weights a column, 3 f32 of `dp` a
    // column, 3 * BLOCK of `rest`).
    unsafe {
        let mut col = weights;
        let mut acc16 = [_mm512_setzero_ps(); 3];
        let mut acc8 = [_mm256_setzero_ps(); 3];
        for &j in cols {
            let c16 = wide(col);
            let c8 = narrow(col.add(2 * L * size));
            let dj = dp.add(3 * j as usize);
            for a in 0..3 {
                let v = _mm512_set1_ps(*dj.add(a));
                acc16[a] = _mm512_fmadd_ps(c16, v, acc16[a]);
                acc8[a] = _mm256_fmadd_ps(c8, _mm512_castps512_ps256(v), acc8[a]);
            }
            col = col.add(BLOCK * size);
        }
        let rp = rest.as_ptr();
        let mut rows = [[_mm256_setzero_ps(); 3]; 3];
        for a in 0..3 {
            let r16 = _mm512_add_ps(_mm512_loadu_ps(rp.add(a * BLOCK)), acc16[a]);
            rows[0][a] = _mm512_castps512_ps256(r16);
            rows[1][a] = high(r16);
            rows[2][a] = _mm256_add_ps(_mm256_loadu_ps(rp.add(a * BLOCK + 2 * L)), acc8[a]);
        }
        rows
    }
}

/// Whether this CPU runs [`MovingDeform`]'s AVX2 kernels (AVX2, FMA and F16C; every CPU with
/// AVX2 has F16C).
#[cfg(target_arch = "x86_64")]
fn avx2_fma_f16c() -> bool {
    crate::basis::avx2_fma() && std::arch::is_x86_feature_detected!("f16c")
}

/// One block's 24 rows of [`MovingDeform`]: `rest + sum_j B[., j] d_j` over the block's kept
/// columns `cols` (BLOCK weights each at `weights`: f32, or binary16 with `HALF`, converted
/// exactly to f32 in registers), as x, y, z registers of its three groups of 8.
///
/// # Safety
/// The CPU must support AVX2, FMA and F16C; `weights` points at `BLOCK * cols.len()` weights,
/// `rest.len() == 3 * BLOCK`, and `dp` points at `3 * (max(cols) + 1)` f32 (the controls'
/// `Vec3`s).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,f16c")]
#[inline]
unsafe fn block_rows<const HALF: bool>(
    weights: *const u8,
    cols: &[u32],
    dp: *const f32,
    rest: &[f32],
) -> [[std::arch::x86_64::__m256; 3]; 3] {
    use std::arch::x86_64::*;
    const L: usize = 8;
    let size = if HALF { 2 } else { 4 };
    // 8 weights at `p` as f32.
    // SAFETY (of the caller): p points at 8 readable weights.
    let load = |p: *const u8| unsafe {
        if HALF {
            _mm256_cvtph_ps(_mm_loadu_si128(p.cast()))
        } else {
            _mm256_loadu_ps(p.cast())
        }
    };
    // SAFETY: `weights` holds BLOCK weights per column, read 24 at a time from `col`, which
    // advances by BLOCK weights per column; `dp` reads 3 f32 per column below its bound; `rest`
    // holds 3 * BLOCK values (caller).
    unsafe {
        let mut col = weights;
        let mut acc = [_mm256_setzero_ps(); 9];
        for &j in cols {
            let c = [
                load(col),
                load(col.add(L * size)),
                load(col.add(2 * L * size)),
            ];
            let dj = dp.add(3 * j as usize);
            let dv = [
                _mm256_broadcast_ss(&*dj),
                _mm256_broadcast_ss(&*dj.add(1)),
                _mm256_broadcast_ss(&*dj.add(2)),
            ];
            for g in 0..3 {
                for a in 0..3 {
                    acc[3 * g + a] = _mm256_fmadd_ps(c[g], dv[a], acc[3 * g + a]);
                }
            }
            col = col.add(BLOCK * size);
        }
        let rp = rest.as_ptr();
        [0, 1, 2].map(|g| {
            [0, 1, 2]
                .map(|a| _mm256_add_ps(_mm256_loadu_ps(rp.add(a * BLOCK + g * L)), acc[3 * g + a]))
        })
    }
}

/// Writes 8 rows given as x, y, z registers as 8 `Vec3A` (x, y, z, 0) at `dst`.
///
/// # Safety
/// The CPU must support AVX2; `dst` must be valid for writing 32 f32.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,f16c")]
unsafe fn store_vec3a8(
    dst: *mut f32,
    x: std::arch::x86_64::__m256,
    y: std::arch::x86_64::__m256,
    z: std::arch::x86_64::__m256,
) {
    use std::arch::x86_64::*;
    let zero = _mm256_setzero_ps();
    let t0 = _mm256_unpacklo_ps(x, y); // x0 y0 x1 y1 | x4 y4 x5 y5
    let t1 = _mm256_unpackhi_ps(x, y); // x2 y2 x3 y3 | x6 y6 x7 y7
    let t2 = _mm256_unpacklo_ps(z, zero); // z0 0 z1 0 | z4 0 z5 0
    let t3 = _mm256_unpackhi_ps(z, zero); // z2 0 z3 0 | z6 0 z7 0
    let r0 = _mm256_shuffle_ps::<0x44>(t0, t2); // row 0 | row 4
    let r1 = _mm256_shuffle_ps::<0xEE>(t0, t2); // row 1 | row 5
    let r2 = _mm256_shuffle_ps::<0x44>(t1, t3); // row 2 | row 6
    let r3 = _mm256_shuffle_ps::<0xEE>(t1, t3); // row 3 | row 7
    // SAFETY: dst is valid for 32 f32 (caller).
    unsafe {
        _mm256_storeu_ps(dst, _mm256_permute2f128_ps::<0x20>(r0, r1));
        _mm256_storeu_ps(dst.add(8), _mm256_permute2f128_ps::<0x20>(r2, r3));
        _mm256_storeu_ps(dst.add(16), _mm256_permute2f128_ps::<0x31>(r0, r1));
        _mm256_storeu_ps(dst.add(24), _mm256_permute2f128_ps::<0x31>(r2, r3));
    }
}

#[cfg(test)]
mod tests;
