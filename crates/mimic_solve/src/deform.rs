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

use crate::Basis;
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

    /// Bytes the kernel reads per call: the kept weights and the rest positions.
    pub fn bytes_read(&self) -> usize {
        (self.values.len() + self.rest.len()) * 4
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
        if crate::basis::avx2_fma() {
            // SAFETY: AVX2 and FMA are checked just above; the shapes are asserted above and
            // the blocked arrays were built for these rows and controls.
            unsafe { self.deform_avx2(d, compact, positions) };
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
        #[cfg(target_arch = "x86_64")]
        if crate::basis::avx2_fma() {
            // SAFETY: AVX2 and FMA are checked just above; the shapes are asserted above and
            // the blocked arrays were built for these rows and controls.
            unsafe { self.deform_packed_avx2(d, compact, positions) };
            return;
        }
        for (b, out) in compact.chunks_mut(3 * BLOCK).enumerate() {
            let kept = self.starts[b] as usize..self.starts[b + 1] as usize;
            let rest = &self.rest[b * 3 * BLOCK..][..3 * BLOCK];
            for (r, o) in out.chunks_exact_mut(3).enumerate() {
                let mut u = Vec3A::ZERO;
                for (k, &j) in self.cols[kept.clone()].iter().enumerate() {
                    let w = self.values[(kept.start + k) * BLOCK + r];
                    u += Vec3A::from(d[j as usize]) * w;
                }
                let p = Vec3A::new(rest[r], rest[BLOCK + r], rest[2 * BLOCK + r]) + u;
                o.copy_from_slice(&p.to_array());
                positions[self.rows[b * BLOCK + r] as usize] = Vec3::from(p);
            }
        }
    }

    /// [`MovingDeform::deform`] on any CPU: the same blocked sums, one row at a time.
    fn deform_portable(&self, d: &[Vec3], compact: &mut [Vec3A], positions: &mut [Vec3]) {
        for (b, out) in compact.chunks_mut(BLOCK).enumerate() {
            let kept = self.starts[b] as usize..self.starts[b + 1] as usize;
            let rest = &self.rest[b * 3 * BLOCK..][..3 * BLOCK];
            for (r, o) in out.iter_mut().enumerate() {
                let mut u = Vec3A::ZERO;
                for (k, &j) in self.cols[kept.clone()].iter().enumerate() {
                    let w = self.values[(kept.start + k) * BLOCK + r];
                    u += Vec3A::from(d[j as usize]) * w;
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
    #[target_feature(enable = "avx2,fma")]
    unsafe fn deform_avx2(&self, d: &[Vec3], compact: &mut [Vec3A], positions: &mut [Vec3]) {
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
            let values = &self.values[kept.start * BLOCK..kept.end * BLOCK];
            let cols = &self.cols[kept];
            let rest = &self.rest[b * 3 * BLOCK..][..3 * BLOCK];
            // SAFETY: `values` holds BLOCK weights per kept column; each kept column is <
            // control_count == d.len(), so `dp` reads 3 f32 of one Vec3 (repr(C) x, y, z);
            // `rest` holds 3 * BLOCK values (`block_rows`' contract); `dst` points at BLOCK Vec3A (the block's compact rows when full,
            // else `spare`); a run's 24 positions lie below vertex_count <= positions.len().
            unsafe {
                let rows = block_rows(values, cols, dp, rest);
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
    /// [`MovingDeform::deform_packed`] with AVX2 + FMA: [`MovingDeform::deform_avx2`]'s sums, the
    /// rows stored packed (x, y, z) to `compact` and, for a run of consecutive vertices, the same
    /// three registers to `positions`.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA; `compact.len() == 3 * rows.len()`, `positions.len() >=
    /// vertex_count` and `d.len() == control_count`.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn deform_packed_avx2(&self, d: &[Vec3], compact: &mut [f32], positions: &mut [Vec3]) {
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
            let values = &self.values[kept.start * BLOCK..kept.end * BLOCK];
            let cols = &self.cols[kept];
            let rest = &self.rest[b * 3 * BLOCK..][..3 * BLOCK];
            // SAFETY: as in `deform_avx2`; `dst` points at 3 * BLOCK floats (the block's packed
            // compact rows when full, else `spare`).
            unsafe {
                let rows = block_rows(values, cols, dp, rest);
                let run = self.runs[b];
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
            if self.runs[b] == SCATTERED {
                for (&i, p) in self.rows[b * BLOCK..].iter().zip(out.chunks_exact(3)) {
                    positions[i as usize] = Vec3::new(p[0], p[1], p[2]);
                }
            }
        }
    }
}

/// One block's 24 rows of [`MovingDeform`]: `rest + sum_j B[., j] d_j` over the block's kept
/// columns `cols` (BLOCK weights each in `values`), as x, y, z registers of its three groups of 8.
///
/// # Safety
/// The CPU must support AVX2 and FMA; `values.len() == BLOCK * cols.len()`, `rest.len() == 3 *
/// BLOCK`, and `dp` points at `3 * (max(cols) + 1)` f32 (the controls' `Vec3`s).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline]
unsafe fn block_rows(
    values: &[f32],
    cols: &[u32],
    dp: *const f32,
    rest: &[f32],
) -> [[std::arch::x86_64::__m256; 3]; 3] {
    use std::arch::x86_64::*;
    const L: usize = 8;
    // SAFETY: `values` holds BLOCK weights per column, read 24 at a time from `col`, which
    // advances by BLOCK per column; `dp` reads 3 f32 per column below its bound; `rest` holds
    // 3 * BLOCK values (caller).
    unsafe {
        let mut col = values.as_ptr();
        let mut acc = [_mm256_setzero_ps(); 9];
        for &j in cols {
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
#[target_feature(enable = "avx2,fma")]
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
mod tests {
    use super::*;
    use mimic_testkit::lcg;

    /// A basis in bands of rows with their own supports (like face regions), frozen rows
    /// between, rows of different bands interleaved so the sort has work to do.
    fn banded(n: usize, m: usize, seed: &mut u64) -> Vec<f32> {
        (0..n * m)
            .map(|k| {
                let (i, j) = (k / m, k % m);
                let w = lcg(seed);
                match i % 5 {
                    0 if j < m / 3 => w,
                    1 | 3 if j >= m / 3 && j < 2 * m / 3 + 1 => w,
                    4 if j >= m / 2 || j == 1 => w,
                    _ => 0.0,
                }
            })
            .collect()
    }

    #[test]
    fn deform_equals_rest_plus_apply_bit_for_bit() {
        let mut seed = 11u64;
        for &(n, m) in &[
            (1usize, 1usize),
            (23, 5),
            (24, 38),
            (70, 38),
            (203, 38),
            (61, 70),
        ] {
            let data = if m >= 5 {
                banded(n, m, &mut seed)
            } else {
                (0..n * m).map(|_| lcg(&mut seed)).collect()
            };
            let basis = Basis::from_row_major(n, m, data).unwrap();
            let rest: Vec<Vec3> = (0..n)
                .map(|_| Vec3::new(lcg(&mut seed), lcg(&mut seed), lcg(&mut seed)) * 10.0)
                .collect();
            let d: Vec<Vec3> = (0..m)
                .map(|_| Vec3::new(lcg(&mut seed), lcg(&mut seed), lcg(&mut seed)))
                .collect();
            let deform = MovingDeform::new(&basis, &rest);
            let moving = basis.moving_rows(n);
            let mut sorted = deform.rows().to_vec();
            sorted.sort_unstable();
            assert_eq!(sorted, moving.rows, "n={n} m={m}: the same moving rows");
            let mut u = vec![Vec3::ZERO; n];
            basis.apply(&d, &mut u);
            let mut compact = vec![Vec3A::NAN; deform.rows().len()];
            let mut positions = vec![Vec3::NAN; n];
            deform.deform(&d, &mut compact, &mut positions);
            for (k, &i) in deform.rows().iter().enumerate() {
                let i = i as usize;
                let want = Vec3::from(Vec3A::from(rest[i]) + Vec3A::from(u[i]));
                if m <= 64 {
                    // Same fused chains as Basis::apply (its AVX2 path, or both portable).
                    #[cfg(target_arch = "x86_64")]
                    if crate::basis::avx2_fma() {
                        assert_eq!(positions[i], want, "n={n} m={m} row {i}");
                    }
                }
                // Any path: within the f32 error of an m-term sum plus one add, m eps sum |w d|
                // + eps |p|, bounded by (m + 1) eps (sum_j |B_ij| |d_j| + |rest_i|).
                let bound: f32 = (0..m)
                    .map(|j| basis.row(i)[j].abs() * d[j].abs().max_element())
                    .sum::<f32>()
                    + rest[i].abs().max_element();
                let tol = (m + 2) as f32 * f32::EPSILON * bound;
                assert!((positions[i] - want).abs().max_element() <= tol, "row {i}");
                assert_eq!(Vec3::from(compact[k]), positions[i]);
            }
            // The packed variant: the same positions and compact rows, bit for bit.
            let mut packed = vec![f32::NAN; 3 * deform.rows().len()];
            let mut positions_p = vec![Vec3::NAN; n];
            deform.deform_packed(&d, &mut packed, &mut positions_p);
            for (k, &i) in deform.rows().iter().enumerate() {
                assert_eq!(
                    positions_p[i as usize], positions[i as usize],
                    "packed row {i}"
                );
                assert_eq!(&packed[3 * k..3 * k + 3], &positions[i as usize].to_array());
            }
            // Frozen rows are left alone.
            for (i, p) in positions.iter().enumerate() {
                if basis.row(i).iter().all(|w| *w == 0.0) {
                    assert!(p.is_nan());
                }
            }
        }
    }

    #[test]
    fn portable_path_matches() {
        let (n, m) = (130usize, 38usize);
        let mut seed = 5u64;
        let basis = Basis::from_row_major(n, m, banded(n, m, &mut seed)).unwrap();
        let rest: Vec<Vec3> = (0..n).map(|k| Vec3::splat(k as f32)).collect();
        let d: Vec<Vec3> = (0..m)
            .map(|_| Vec3::new(lcg(&mut seed), lcg(&mut seed), lcg(&mut seed)))
            .collect();
        let deform = MovingDeform::new(&basis, &rest);
        let (mut ca, mut pa) = (vec![Vec3A::ZERO; deform.rows().len()], vec![Vec3::ZERO; n]);
        let (mut cb, mut pb) = (ca.clone(), pa.clone());
        deform.deform(&d, &mut ca, &mut pa);
        deform.deform_portable(&d, &mut cb, &mut pb);
        for i in 0..n {
            // Same terms, fused or not: (m + 2) eps (sum |w d| + |rest|).
            let bound: f32 = (0..m)
                .map(|j| basis.row(i)[j].abs() * d[j].abs().max_element())
                .sum::<f32>()
                + rest[i].abs().max_element();
            let tol = 2.0 * (m + 2) as f32 * f32::EPSILON * bound;
            assert!((pa[i] - pb[i]).abs().max_element() <= tol, "row {i}");
        }
    }

    #[test]
    fn support_order_keeps_fewer_columns_than_index_order() {
        // Interleaved bands: blocks in index order keep the union of three supports.
        let (n, m) = (480usize, 38usize);
        let mut seed = 9u64;
        let basis = Basis::from_row_major(n, m, banded(n, m, &mut seed)).unwrap();
        let deform = MovingDeform::new(&basis, &vec![Vec3::ZERO; n]);
        let rows = basis.moving_rows(n).rows;
        let index_order_kept = rows
            .chunks(BLOCK)
            .map(|b| {
                (0..m)
                    .filter(|&j| b.iter().any(|&i| basis.row(i as usize)[j] != 0.0))
                    .count()
            })
            .sum::<usize>();
        assert!(
            (deform.cols.len() as f64) < 0.7 * index_order_kept as f64,
            "{} vs {index_order_kept}",
            deform.cols.len()
        );
        assert!(deform.kept_fraction() > 0.0 && deform.kept_fraction() < 1.0);
    }
}
