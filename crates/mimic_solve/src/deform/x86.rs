//! [`MovingDeform`]'s x86 kernels: AVX2 + FMA (8 rows a register) and AVX-512F (16 and 8), one
//! store loop shared by both, and the blocked sums they run.

use super::{BLOCK, MovingDeform, SCATTERED};
use glam::{Vec3, Vec3A};

impl MovingDeform {
    /// [`MovingDeform::deform`] with AVX2 + FMA: per block, 9 accumulators (24 rows x 3 axes),
    /// one broadcast of each kept control's coordinates, the rest added in registers, then the
    /// rows transposed to `Vec3A` for `compact` and to packed `Vec3` for `positions`.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA; `compact.len() == rows.len()`, `positions.len() >=
    /// vertex_count` and `d.len() == control_count`.
    #[target_feature(enable = "avx2,fma,f16c")]
    pub(super) unsafe fn deform_avx2<const HALF: bool>(
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
            // `rest` holds 3 * BLOCK values (`block_rows`' contract); `dst` points at BLOCK Vec3A
            // (the block's compact rows when full, else `spare`); a run's 24 positions lie below
            // vertex_count <= positions.len().
            unsafe {
                let rows = block_rows::<HALF>(weights, cols, dp, rest, PendingRows::NONE);
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

    /// The kept columns `kept` of a block as the AVX2 kernels read them: `BLOCK` f32 (or, with
    /// `HALF`, binary16) weights per column, from the start of the first.
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
    #[target_feature(enable = "avx2,fma,f16c")]
    pub(super) unsafe fn deform_packed_avx2<const HALF: bool>(
        &self,
        d: &[Vec3],
        compact: &mut [f32],
        positions: &mut [Vec3],
    ) {
        // SAFETY: the block function's contract is `block_rows`' (the loop passes it BLOCK
        // weights a kept column, in-bound columns and 3 * BLOCK rest values); AVX2, FMA and
        // F16C as this function's (caller); shapes as this function's.
        unsafe {
            self.packed_blocks::<HALF>(d, compact, positions, |w, c, dp, r, pending| {
                block_rows::<HALF>(w, c, dp, r, pending)
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
    #[target_feature(enable = "avx512f,avx2,fma,f16c")]
    pub(super) unsafe fn deform_packed_avx512<const HALF: bool>(
        &self,
        d: &[Vec3],
        compact: &mut [f32],
        positions: &mut [Vec3],
    ) {
        // SAFETY: as in `deform_packed_avx2`, with AVX-512F (caller).
        unsafe {
            self.packed_blocks::<HALF>(d, compact, positions, |w, c, dp, r, pending| {
                block_rows_avx512::<HALF>(w, c, dp, r, pending)
            });
        }
    }

    /// The packed kernels' loop over blocks: `rows_of` sums a block's 24 rows (as
    /// [`block_rows`] does), stored packed to `compact` and, for a run of consecutive vertices,
    /// from the same registers to `positions`. A scattered block's rows are copied from
    /// `compact` to their mesh positions while the next block is summed (`rows_of` is handed
    /// them as [`PendingRows`]), the last block's after the loop. Inlined into each kernel, so
    /// `rows_of` runs with that kernel's CPU features.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA, and `rows_of` must be safe to call with a block's
    /// weights, kept columns, `d`, rest values and pending rows (`block_rows`' contract);
    /// `compact.len() == 3 * rows.len()`, `positions.len() >= vertex_count` and `d.len() ==
    /// control_count`.
    #[inline(always)]
    unsafe fn packed_blocks<const HALF: bool>(
        &self,
        d: &[Vec3],
        compact: &mut [f32],
        positions: &mut [Vec3],
        rows_of: impl Fn(
            *const u8,
            &[u32],
            *const f32,
            &[f32],
            PendingRows,
        ) -> [[std::arch::x86_64::__m256; 3]; 3],
    ) {
        const L: usize = 8;
        let mut spare = [0f32; 3 * BLOCK];
        let dp = d.as_ptr().cast::<f32>();
        let p = positions.as_mut_ptr().cast::<f32>();
        let mut pending = PendingRows::NONE;
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
            let rows = rows_of(weights, cols, dp, rest, pending);
            let run = self.runs[b];
            // SAFETY: `dst` points at 3 * BLOCK floats (the block's packed compact rows when
            // full, else `spare`); a run's 24 vertices lie below vertex_count <= positions.len()
            // (3 floats each); AVX2 (caller).
            unsafe {
                for (g, &[x, y, z]) in rows.iter().enumerate() {
                    crate::basis::store_xyz8(dst.add(g * 3 * L), x, y, z);
                    if run != SCATTERED {
                        crate::basis::store_xyz8(p.add(3 * (run as usize + g * L)), x, y, z);
                    }
                }
            }
            if !full {
                out.copy_from_slice(&spare[..out.len()]);
            }
            // This block's mesh vertices (fewer than BLOCK in a last, partial block).
            let vertices = &self.rows[b * BLOCK..][..out.len() / 3];
            pending = if run == SCATTERED {
                PendingRows {
                    src: out.as_ptr(),
                    vertices,
                    dst: p,
                }
            } else {
                PendingRows::NONE
            };
        }
        // SAFETY: the last block's rows, as every other's (see `PendingRows`).
        unsafe { pending.copy_from(0) };
    }
}

/// The rows of a scattered block still to be copied from their packed compact rows to their
/// mesh positions, copied while the next block is summed: one per kept column, on the load and
/// store ports the sums leave idle (copied straight after their own block, the same stores took
/// about a fifth of the deform). Each row is two overlapping 8-byte moves, `(x, y)` to `3 v` and
/// `(y, z)` to `3 v + 1`: no shuffle, and the rows' compact stores are long retired by then (a
/// load straight after them could not be forwarded from the one row in 8 that straddles two).
#[derive(Clone, Copy)]
pub(super) struct PendingRows<'a> {
    /// The rows' packed compact positions, 3 floats a row.
    src: *const f32,
    /// Their mesh vertices, at most [`BLOCK`].
    vertices: &'a [u32],
    /// The mesh positions, 3 floats a vertex.
    dst: *mut f32,
}

impl PendingRows<'_> {
    /// No rows.
    const NONE: Self = Self {
        src: std::ptr::null(),
        vertices: &[],
        dst: std::ptr::null_mut(),
    };

    /// Copies row `r` to its mesh position.
    ///
    /// # Safety
    /// `r < vertices.len()`; `src` holds `3 * vertices.len()` floats and `dst` 3 floats at
    /// `3 v` for every `v` in `vertices`, not overlapping `src`.
    #[inline(always)]
    unsafe fn copy(&self, r: usize) {
        // SAFETY: as the function's contract: floats 3 r..3 r + 3 of `src`, 3 v..3 v + 3 of
        // `dst`.
        unsafe {
            let v = *self.vertices.get_unchecked(r) as usize;
            let (s, d) = (self.src.add(3 * r), self.dst.add(3 * v));
            let xy = s.cast::<u64>().read_unaligned();
            let yz = s.add(1).cast::<u64>().read_unaligned();
            d.cast::<u64>().write_unaligned(xy);
            d.add(1).cast::<u64>().write_unaligned(yz);
        }
    }

    /// Copies row `r` if there is one (one a kept column of the next block's sums).
    ///
    /// # Safety
    /// As [`PendingRows::copy`], for any `r`.
    #[inline(always)]
    unsafe fn copy_if_any(&self, r: usize) {
        if r < self.vertices.len() {
            // SAFETY: r < vertices.len(); the rest as this function's contract.
            unsafe { self.copy(r) };
        }
    }

    /// Copies rows `first..` (those the next block's columns did not take).
    ///
    /// # Safety
    /// As [`PendingRows::copy`], for every row from `first`.
    #[inline(always)]
    unsafe fn copy_from(&self, first: usize) {
        for r in first..self.vertices.len() {
            // SAFETY: r < vertices.len(); the rest as this function's contract.
            unsafe { self.copy(r) };
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
#[target_feature(enable = "avx512f,avx2,fma,f16c")]
#[inline]
unsafe fn block_rows_avx512<const HALF: bool>(
    weights: *const u8,
    cols: &[u32],
    dp: *const f32,
    rest: &[f32],
    pending: PendingRows,
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
    // The high 8 lanes of a 512-bit register (AVX-512F only: through the 64-bit view).
    let high = |v: __m512| _mm256_castpd_ps(_mm512_extractf64x4_pd::<1>(_mm512_castps_pd(v)));
    // SAFETY: as in `block_rows` (the same reads: BLOCK weights a column, 3 f32 of `dp` a
    // column, 3 * BLOCK of `rest`).
    unsafe {
        let mut col = weights;
        let mut acc16 = [_mm512_setzero_ps(); 3];
        let mut acc8 = [_mm256_setzero_ps(); 3];
        for (c, &j) in cols.iter().enumerate() {
            pending.copy_if_any(c);
            let c16 = wide(col);
            let c8 = load8::<HALF>(col.add(2 * L * size));
            let dj = dp.add(3 * j as usize);
            for a in 0..3 {
                let v = _mm512_set1_ps(*dj.add(a));
                acc16[a] = _mm512_fmadd_ps(c16, v, acc16[a]);
                acc8[a] = _mm256_fmadd_ps(c8, _mm512_castps512_ps256(v), acc8[a]);
            }
            col = col.add(BLOCK * size);
        }
        pending.copy_from(cols.len());
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
pub(super) fn avx2_fma_f16c() -> bool {
    crate::basis::avx2_fma() && std::arch::is_x86_feature_detected!("f16c")
}

/// 8 weights at `p` as f32: f32 as they are, or (with `HALF`) binary16 converted exactly.
///
/// # Safety
/// The CPU must support AVX2 and F16C; `p` must point at 8 readable weights.
#[target_feature(enable = "avx2,fma,f16c")]
#[inline]
unsafe fn load8<const HALF: bool>(p: *const u8) -> std::arch::x86_64::__m256 {
    use std::arch::x86_64::*;
    // SAFETY: 8 weights (16 or 32 bytes) are readable at p (caller).
    unsafe {
        if HALF {
            _mm256_cvtph_ps(_mm_loadu_si128(p.cast()))
        } else {
            _mm256_loadu_ps(p.cast())
        }
    }
}

/// One block's 24 rows of [`MovingDeform`]: `rest + sum_j B[., j] d_j` over the block's kept
/// columns `cols` (BLOCK weights each at `weights`: f32, or binary16 with `HALF`, converted
/// exactly to f32 in registers), as x, y, z registers of its three groups of 8.
///
/// # Safety
/// The CPU must support AVX2, FMA and F16C; `weights` points at `BLOCK * cols.len()` weights,
/// `rest.len() == 3 * BLOCK`, and `dp` points at `3 * (max(cols) + 1)` f32 (the controls'
/// `Vec3`s).
#[target_feature(enable = "avx2,fma,f16c")]
#[inline]
unsafe fn block_rows<const HALF: bool>(
    weights: *const u8,
    cols: &[u32],
    dp: *const f32,
    rest: &[f32],
    pending: PendingRows,
) -> [[std::arch::x86_64::__m256; 3]; 3] {
    use std::arch::x86_64::*;
    const L: usize = 8;
    let size = if HALF { 2 } else { 4 };
    // SAFETY: `weights` holds BLOCK weights per column, read 24 at a time from `col`, which
    // advances by BLOCK weights per column; `dp` reads 3 f32 per column below its bound; `rest`
    // holds 3 * BLOCK values (caller).
    unsafe {
        let mut col = weights;
        let mut acc = [_mm256_setzero_ps(); 9];
        for (c, &j) in cols.iter().enumerate() {
            // One pending row a column, while the sums wait on their multiply-adds.
            pending.copy_if_any(c);
            let c = [
                load8::<HALF>(col),
                load8::<HALF>(col.add(L * size)),
                load8::<HALF>(col.add(2 * L * size)),
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
        pending.copy_from(cols.len());
        // Written out, not through `array::map`: a closure passed to a core function is
        // compiled without AVX2 and called per element, spilling every register.
        let rp = rest.as_ptr();
        let mut rows = [[_mm256_setzero_ps(); 3]; 3];
        for g in 0..3 {
            for a in 0..3 {
                rows[g][a] =
                    _mm256_add_ps(_mm256_loadu_ps(rp.add(a * BLOCK + g * L)), acc[3 * g + a]);
            }
        }
        rows
    }
}

/// Writes 8 rows given as x, y, z registers as 8 `Vec3A` (x, y, z, 0) at `dst`.
///
/// # Safety
/// The CPU must support AVX2; `dst` must be valid for writing 32 f32.
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
