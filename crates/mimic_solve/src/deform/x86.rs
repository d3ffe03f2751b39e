//! [`MovingDeform`]'s AVX2 + FMA kernel (8 rows a register): the loop over blocks, the blocked
//! sums it runs and the scattered rows' deferred copies.

use super::{BLOCK, MovingDeform, SCATTERED};
use glam::Vec3;

impl MovingDeform {
    /// [`MovingDeform::deform_packed`] with AVX2 + FMA: per block, 9 accumulators (24 rows x 3
    /// axes), one broadcast of each kept control's coordinates, the rest added in registers
    /// ([`block_rows`]); the rows stored packed (x, y, z) to `compact` and, for a run of
    /// consecutive vertices, the same three registers to `positions`. A scattered block's rows
    /// are copied from `compact` to their mesh positions while the next block is summed
    /// ([`PendingRows`]), the last block's after the loop.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA; `compact.len() == 3 * rows.len()`, `positions.len() >=
    /// vertex_count` and `d.len() == control_count`.
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn deform_packed_avx2(
        &self,
        d: &[Vec3],
        compact: &mut [f32],
        positions: &mut [Vec3],
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
            let weights = self.values[kept.start * BLOCK..kept.end * BLOCK].as_ptr();
            let cols = &self.cols[kept];
            let rest = &self.rest[b * 3 * BLOCK..][..3 * BLOCK];
            let run = self.runs[b];
            // SAFETY: `block_rows`' contract: BLOCK weights a kept column, columns below
            // control_count == d.len(), 3 * BLOCK rest values, the pending rows as
            // `PendingRows` says; `dst` points at 3 * BLOCK floats (the block's packed compact
            // rows when full, else `spare`); a run's 24 vertices lie below vertex_count <=
            // positions.len() (3 floats each); AVX2 and FMA (caller).
            unsafe {
                let rows = block_rows(weights, cols, dp, rest, pending);
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

/// One block's 24 rows of [`MovingDeform`]: `rest + sum_j B[., j] d_j` over the block's kept
/// columns `cols` (BLOCK weights each at `weights`), as x, y, z registers of its three groups
/// of 8; one pending row of the previous block copied a column.
///
/// # Safety
/// The CPU must support AVX2 and FMA; `weights` points at `BLOCK * cols.len()` weights,
/// `rest.len() == 3 * BLOCK`, and `dp` points at `3 * (max(cols) + 1)` f32 (the controls'
/// `Vec3`s); `pending` as [`PendingRows::copy`].
#[target_feature(enable = "avx2,fma")]
#[inline]
unsafe fn block_rows(
    weights: *const f32,
    cols: &[u32],
    dp: *const f32,
    rest: &[f32],
    pending: PendingRows,
) -> [[std::arch::x86_64::__m256; 3]; 3] {
    use std::arch::x86_64::*;
    const L: usize = 8;
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
                _mm256_loadu_ps(col),
                _mm256_loadu_ps(col.add(L)),
                _mm256_loadu_ps(col.add(2 * L)),
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
            col = col.add(BLOCK);
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
