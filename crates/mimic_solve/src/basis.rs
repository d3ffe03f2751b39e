//! The deformation basis `B` (n vertices x m controls) and its per-frame application `u = B d`.

use glam::Vec3;

/// Controls up to which [`Basis::apply`] transposes `d` on the stack and takes the vectorised path.
const STACK_CONTROLS: usize = 64;

/// Lanes of the vectorised inner loop (one AVX register of f32).
const LANES: usize = 8;

/// Rows per block of the column-blocked copy that [`Basis::apply`] reads: 3 AVX registers, so one
/// broadcast of `d_j` feeds 3 fused multiply-adds per axis and 9 accumulators keep both FMA
/// units busy past their latency.
const BLOCK: usize = 3 * LANES;

/// An n x m deformation basis, f32, row-major: vertex `i` moves by `sum_j B[i, j] * d[j]`.
///
/// The same matrix serves x, y and z. Rows of frozen vertices are zero. Besides the row-major
/// matrix ([`Basis::as_slice`], [`Basis::row`]) it keeps a column-blocked copy for
/// [`Basis::apply`]: blocks of 24 rows, each column of a block contiguous, columns that are zero
/// over the whole block left out (frozen vertices, controls of other face regions). That copy
/// takes at most `n * m * 4` bytes more, and on a head rig far less.
#[derive(Clone, Debug, PartialEq)]
pub struct Basis {
    vertex_count: usize,
    control_count: usize,
    data: Vec<f32>,
    /// The column-blocked copy that `apply` reads.
    blocked: Blocked,
}

/// The rows of a basis that are not all zero ([`Basis::moving_rows`]): on a head rig the face, the
/// only vertices a frame can move (the back of the head, teeth and eyeballs are frozen).
#[derive(Clone, Debug, PartialEq)]
pub struct MovingRows {
    /// Vertex index of each moving row, ascending.
    pub rows: Vec<u32>,
    /// `B` restricted to `rows`: its row `k` is row `rows[k]` of `B`.
    pub basis: Basis,
}

/// `B` in blocks of [`BLOCK`] rows, keeping only the columns that are non-zero in the block.
#[derive(Clone, Debug, PartialEq)]
struct Blocked {
    /// Block `b` keeps columns `cols[starts[b]..starts[b + 1]]`; `ceil(n / BLOCK) + 1` offsets.
    starts: Vec<u32>,
    /// Column index of each kept column (each `< m`).
    cols: Vec<u32>,
    /// `values[k * BLOCK + r] = B[b * BLOCK + r, cols[k]]` for kept column `k` of block `b`, zero
    /// past the last row.
    values: Vec<f32>,
}

impl Blocked {
    fn new(data: &[f32], n: usize, m: usize) -> Self {
        let blocks = n.div_ceil(BLOCK);
        let mut starts = Vec::with_capacity(blocks + 1);
        let mut cols = Vec::new();
        let mut values = Vec::new();
        starts.push(0);
        for b in 0..blocks {
            let rows = b * BLOCK..((b + 1) * BLOCK).min(n);
            for j in 0..m {
                if rows.clone().any(|i| data[i * m + j] != 0.0) {
                    cols.push(j as u32);
                    values.extend(rows.clone().map(|i| data[i * m + j]));
                    values.resize(cols.len() * BLOCK, 0.0);
                }
            }
            starts.push(cols.len() as u32);
        }
        Self {
            starts,
            cols,
            values,
        }
    }
}

impl Basis {
    /// Wraps a row-major `vertex_count x control_count` matrix; `None` if the length does not match.
    pub fn from_row_major(
        vertex_count: usize,
        control_count: usize,
        data: Vec<f32>,
    ) -> Option<Self> {
        if vertex_count.checked_mul(control_count)? != data.len() {
            return None;
        }
        let blocked = Blocked::new(&data, vertex_count, control_count);
        Some(Self {
            vertex_count,
            control_count,
            data,
            blocked,
        })
    }

    /// Number of vertices (rows).
    pub fn vertex_count(&self) -> usize {
        self.vertex_count
    }

    /// Number of controls (columns).
    pub fn control_count(&self) -> usize {
        self.control_count
    }

    /// Row `vertex` of `B`: the weights of every control on that vertex. Panics if `vertex` is out of range.
    pub fn row(&self, vertex: usize) -> &[f32] {
        let m = self.control_count;
        &self.data[vertex * m..(vertex + 1) * m]
    }

    /// The whole matrix, row-major (`n * m` values), e.g. for upload to the GPU.
    pub fn as_slice(&self) -> &[f32] {
        &self.data
    }

    /// The rows among the first `limit` that are not all zero (the vertices a frame can move),
    /// and `B` restricted to them.
    pub fn moving_rows(&self, limit: usize) -> MovingRows {
        let (n, m) = (self.vertex_count.min(limit), self.control_count);
        let rows: Vec<u32> = (0..n)
            .filter(|&i| self.row(i).iter().any(|w| *w != 0.0))
            .map(|i| i as u32)
            .collect();
        let mut data = Vec::with_capacity(rows.len() * m);
        for &i in &rows {
            data.extend_from_slice(self.row(i as usize));
        }
        let basis = Self::from_row_major(rows.len(), m, data)
            .unwrap_or_else(|| unreachable!("rows.len() * m values were copied"));
        MovingRows { rows, basis }
    }

    /// Displacements `out[i] = sum_j B[i, j] * d[j]`; allocates nothing.
    ///
    /// # Panics
    /// If `d.len() != control_count()` or `out.len() != vertex_count()`: both are fixed when the rig
    /// is set up, so a mismatch is a programming error, not bad input.
    pub fn apply(&self, d: &[Vec3], out: &mut [Vec3]) {
        let m = self.control_count;
        assert_eq!(
            d.len(),
            m,
            "Basis::apply: {} control displacements for {m} controls",
            d.len()
        );
        assert_eq!(
            out.len(),
            self.vertex_count,
            "Basis::apply: output has {} entries for {} vertices",
            out.len(),
            self.vertex_count
        );
        if m == 0 {
            out.fill(Vec3::ZERO);
            return;
        }
        if m > STACK_CONTROLS {
            apply_aos(&self.data, m, d, out);
            return;
        }
        let [dx, dy, dz] = split_axes(d);
        #[cfg(target_arch = "x86_64")]
        if avx2_fma() {
            // SAFETY: AVX2 and FMA are checked just above; `blocked` was built for n rows and m
            // columns, out.len() == n (asserted), and 0 < m <= STACK_CONTROLS here.
            unsafe { apply_blocked_avx2_fma(&self.blocked, &dx, &dy, &dz, out) };
            return;
        }
        apply_soa::<false>(&self.data, m, &dx[..m], &dy[..m], &dz[..m], out);
    }

    /// [`Basis::apply`] by the previous kernel, row-major, two rows at a time (AVX2 + FMA where
    /// the CPU has them): kept as the in-process baseline of the benchmarks.
    ///
    /// # Panics
    /// As [`Basis::apply`].
    pub fn apply_row_pairs(&self, d: &[Vec3], out: &mut [Vec3]) {
        let m = self.control_count;
        assert!(
            d.len() == m && out.len() == self.vertex_count,
            "Basis::apply_row_pairs: shapes"
        );
        if m == 0 || m > STACK_CONTROLS {
            self.apply(d, out);
            return;
        }
        let [dx, dy, dz] = split_axes(d);
        #[cfg(target_arch = "x86_64")]
        if avx2_fma() {
            // SAFETY: AVX2 and FMA are checked just above; data.len() == n * m by construction,
            // 0 < m <= STACK_CONTROLS here, and the stack arrays are zero past m.
            unsafe { apply_avx2_fma(&self.data, m, &dx, &dy, &dz, out) };
            return;
        }
        apply_soa::<false>(&self.data, m, &dx[..m], &dy[..m], &dz[..m], out);
    }
}

/// `d` split by axis into stack arrays, zero past `d.len()`; callers keep `d.len() <= STACK_CONTROLS`.
fn split_axes(d: &[Vec3]) -> [[f32; STACK_CONTROLS]; 3] {
    let mut axes = [[0f32; STACK_CONTROLS]; 3];
    for (j, v) in d.iter().enumerate().take(STACK_CONTROLS) {
        axes[0][j] = v.x;
        axes[1][j] = v.y;
        axes[2][j] = v.z;
    }
    axes
}

/// Whether this CPU runs the AVX2 + FMA kernels (runtime-detected, cached by std).
#[cfg(target_arch = "x86_64")]
pub(crate) fn avx2_fma() -> bool {
    std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
}

/// `u = B d` over the column-blocked copy: per block of 24 rows and per kept control `j`, `d_j`'s
/// coordinates are broadcast and multiply-added with the block's column `j` (3 registers) into 9
/// accumulators (rows x axes); no horizontal sums, no partial chunk, and columns that are zero
/// over the block cost nothing. The accumulators are transposed to (x, y, z) triples 8 rows at a
/// time. Skipping an all-zero column only drops `+0` terms, so the result equals the dense sum
/// for finite `d`.
///
/// # Safety
/// The CPU must support AVX2 and FMA; `blocked` must have been built for `out.len()` rows and
/// at most `STACK_CONTROLS` columns, and `dx`, `dy`, `dz` hold `STACK_CONTROLS` values.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn apply_blocked_avx2_fma(
    blocked: &Blocked,
    dx: &[f32; STACK_CONTROLS],
    dy: &[f32; STACK_CONTROLS],
    dz: &[f32; STACK_CONTROLS],
    out: &mut [Vec3],
) {
    use std::arch::x86_64::*;
    assert_eq!(blocked.starts.len(), out.len().div_ceil(BLOCK) + 1);
    // The last, partial block is written through this buffer.
    let mut spare = [Vec3::ZERO; BLOCK];
    for (b, rows) in out.chunks_mut(BLOCK).enumerate() {
        let full = rows.len() == BLOCK;
        let dst: *mut f32 = if full {
            rows.as_mut_ptr().cast()
        } else {
            spare.as_mut_ptr().cast()
        };
        let kept = blocked.starts[b] as usize..blocked.starts[b + 1] as usize;
        let values = &blocked.values[kept.start * BLOCK..kept.end * BLOCK];
        // SAFETY: `values` holds BLOCK values per kept column (sliced with bounds checks), read
        // 24 at a time from `col`, which advances by BLOCK per column; the d arrays are read with
        // bounds checks; dst points at BLOCK Vec3 = 3 * BLOCK f32 (the block's rows when the
        // block is full, else `spare`), and Vec3 is repr(C) x, y, z.
        unsafe {
            let mut col = values.as_ptr();
            let mut acc = [_mm256_setzero_ps(); 9];
            for &j in &blocked.cols[kept] {
                let j = j as usize;
                let c = [
                    _mm256_loadu_ps(col),
                    _mm256_loadu_ps(col.add(LANES)),
                    _mm256_loadu_ps(col.add(2 * LANES)),
                ];
                let dv = [
                    _mm256_broadcast_ss(&dx[j]),
                    _mm256_broadcast_ss(&dy[j]),
                    _mm256_broadcast_ss(&dz[j]),
                ];
                for g in 0..3 {
                    for a in 0..3 {
                        acc[3 * g + a] = _mm256_fmadd_ps(c[g], dv[a], acc[3 * g + a]);
                    }
                }
                col = col.add(BLOCK);
            }
            for g in 0..3 {
                store_xyz8(
                    dst.add(g * 3 * LANES),
                    acc[3 * g],
                    acc[3 * g + 1],
                    acc[3 * g + 2],
                );
            }
        }
        if !full {
            rows.copy_from_slice(&spare[..rows.len()]);
        }
    }
}

/// Writes 8 rows given as x, y, z registers as 24 interleaved f32 `x0 y0 z0 x1 ...` at `dst`:
/// each register permuted so that lane `k` lands at position `3k + axis (mod 8)`, then blended.
///
/// # Safety
/// The CPU must support AVX2; `dst` must be valid for writing 24 f32.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
pub(crate) unsafe fn store_xyz8(
    dst: *mut f32,
    x: std::arch::x86_64::__m256,
    y: std::arch::x86_64::__m256,
    z: std::arch::x86_64::__m256,
) {
    use std::arch::x86_64::*;
    let px = _mm256_permutevar8x32_ps(x, _mm256_setr_epi32(0, 3, 6, 1, 4, 7, 2, 5));
    let py = _mm256_permutevar8x32_ps(y, _mm256_setr_epi32(5, 0, 3, 6, 1, 4, 7, 2));
    let pz = _mm256_permutevar8x32_ps(z, _mm256_setr_epi32(2, 5, 0, 3, 6, 1, 4, 7));
    // out0 = x0 y0 z0 x1 y1 z1 x2 y2, out1 = z2 x3 y3 z3 x4 y4 z4 x5, out2 = y5 z5 x6 y6 z6 x7 y7 z7.
    let o0 = _mm256_blend_ps::<0x24>(_mm256_blend_ps::<0x92>(px, py), pz);
    let o1 = _mm256_blend_ps::<0x49>(_mm256_blend_ps::<0x24>(px, py), pz);
    let o2 = _mm256_blend_ps::<0x92>(_mm256_blend_ps::<0x49>(px, py), pz);
    // SAFETY: dst is valid for 24 f32 (caller).
    unsafe {
        _mm256_storeu_ps(dst, o0);
        _mm256_storeu_ps(dst.add(8), o1);
        _mm256_storeu_ps(dst.add(16), o2);
    }
}

/// `u = B d` with AVX2 + FMA: per row, 8-wide fused multiply-adds against the zero-padded
/// coordinate arrays, the last partial chunk read with a masked load (never past the row).
///
/// # Safety
/// The CPU must support AVX2 and FMA; `b.len() == out.len() * m`, `0 < m <= STACK_CONTROLS`, and
/// `dx`, `dy`, `dz` hold `STACK_CONTROLS` values (zero past `m`).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn apply_avx2_fma(
    b: &[f32],
    m: usize,
    dx: &[f32; STACK_CONTROLS],
    dy: &[f32; STACK_CONTROLS],
    dz: &[f32; STACK_CONTROLS],
    out: &mut [Vec3],
) {
    use std::arch::x86_64::*;
    debug_assert!(m > 0 && m <= STACK_CONTROLS && b.len() == out.len() * m);
    let full = m / LANES;
    let tail = m % LANES;
    // Lane l of the mask is set (sign bit) when l < tail.
    let lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    let mask = _mm256_cmpgt_epi32(_mm256_set1_epi32(tail as i32), lane);
    let (px, py, pz) = (dx.as_ptr(), dy.as_ptr(), dz.as_ptr());
    let base = b.as_ptr();
    // Rows go in pairs so that each chunk of d, once loaded, feeds two rows.
    let mut pairs = out.chunks_exact_mut(2);
    for (p, o) in (&mut pairs).enumerate() {
        // SAFETY: rows 2p and 2p + 1 span b[2p * m .. (2p + 2) * m], inside b; chunk c reads
        // [8c, 8c + 8) of a row with 8c + 8 <= m; the masked load touches only the `tail` values
        // left in the row; the d arrays hold STACK_CONTROLS >= 8 * ceil(m / 8) values.
        unsafe {
            let r0 = base.add(2 * p * m);
            let r1 = r0.add(m);
            let (mut x0, mut y0, mut z0) = (
                _mm256_setzero_ps(),
                _mm256_setzero_ps(),
                _mm256_setzero_ps(),
            );
            let (mut x1, mut y1, mut z1) = (
                _mm256_setzero_ps(),
                _mm256_setzero_ps(),
                _mm256_setzero_ps(),
            );
            for c in 0..full {
                let (vx, vy, vz) = (
                    _mm256_loadu_ps(px.add(c * LANES)),
                    _mm256_loadu_ps(py.add(c * LANES)),
                    _mm256_loadu_ps(pz.add(c * LANES)),
                );
                let a = _mm256_loadu_ps(r0.add(c * LANES));
                let b = _mm256_loadu_ps(r1.add(c * LANES));
                x0 = _mm256_fmadd_ps(a, vx, x0);
                y0 = _mm256_fmadd_ps(a, vy, y0);
                z0 = _mm256_fmadd_ps(a, vz, z0);
                x1 = _mm256_fmadd_ps(b, vx, x1);
                y1 = _mm256_fmadd_ps(b, vy, y1);
                z1 = _mm256_fmadd_ps(b, vz, z1);
            }
            if tail > 0 {
                let (vx, vy, vz) = (
                    _mm256_loadu_ps(px.add(full * LANES)),
                    _mm256_loadu_ps(py.add(full * LANES)),
                    _mm256_loadu_ps(pz.add(full * LANES)),
                );
                let a = _mm256_maskload_ps(r0.add(full * LANES), mask);
                let b = _mm256_maskload_ps(r1.add(full * LANES), mask);
                x0 = _mm256_fmadd_ps(a, vx, x0);
                y0 = _mm256_fmadd_ps(a, vy, y0);
                z0 = _mm256_fmadd_ps(a, vz, z0);
                x1 = _mm256_fmadd_ps(b, vx, x1);
                y1 = _mm256_fmadd_ps(b, vy, y1);
                z1 = _mm256_fmadd_ps(b, vz, z1);
            }
            // Reduce the six accumulators at once: two levels of horizontal adds leave, per
            // 128-bit half, [x0, y0, z0, x1] and [y1, z1, 0, 0]; adding the halves gives the six
            // sums in the order of the two Vec3s in memory (Vec3 is repr(C) x, y, z).
            let g1 = _mm256_hadd_ps(_mm256_hadd_ps(x0, y0), _mm256_hadd_ps(z0, x1));
            let g2 = _mm256_hadd_ps(_mm256_hadd_ps(y1, z1), _mm256_setzero_ps());
            let s1 = _mm_add_ps(_mm256_castps256_ps128(g1), _mm256_extractf128_ps::<1>(g1));
            let s2 = _mm_add_ps(_mm256_castps256_ps128(g2), _mm256_extractf128_ps::<1>(g2));
            let dst = o.as_mut_ptr().cast::<f32>();
            _mm_storeu_ps(dst, s1);
            _mm_storel_epi64(dst.add(4).cast::<__m128i>(), _mm_castps_si128(s2));
        }
    }
    if let [o] = pairs.into_remainder() {
        let last = out_len_minus_one(b.len(), m);
        // SAFETY: the last row spans b[last * m .. (last + 1) * m]; chunk and tail reads as above.
        unsafe {
            let r = base.add(last * m);
            let (mut x, mut y, mut z) = (
                _mm256_setzero_ps(),
                _mm256_setzero_ps(),
                _mm256_setzero_ps(),
            );
            for c in 0..full {
                let a = _mm256_loadu_ps(r.add(c * LANES));
                x = _mm256_fmadd_ps(a, _mm256_loadu_ps(px.add(c * LANES)), x);
                y = _mm256_fmadd_ps(a, _mm256_loadu_ps(py.add(c * LANES)), y);
                z = _mm256_fmadd_ps(a, _mm256_loadu_ps(pz.add(c * LANES)), z);
            }
            if tail > 0 {
                let a = _mm256_maskload_ps(r.add(full * LANES), mask);
                x = _mm256_fmadd_ps(a, _mm256_loadu_ps(px.add(full * LANES)), x);
                y = _mm256_fmadd_ps(a, _mm256_loadu_ps(py.add(full * LANES)), y);
                z = _mm256_fmadd_ps(a, _mm256_loadu_ps(pz.add(full * LANES)), z);
            }
            *o = Vec3::new(hsum256(x), hsum256(y), hsum256(z));
        }
    }
}

/// Index of the last row of a row-major matrix of `len` values with `m` columns (`len >= m > 0`).
#[cfg(target_arch = "x86_64")]
fn out_len_minus_one(len: usize, m: usize) -> usize {
    len / m - 1
}

/// Sum of the 8 lanes of an AVX register.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn hsum256(v: std::arch::x86_64::__m256) -> f32 {
    use std::arch::x86_64::*;
    let q = _mm_add_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps::<1>(v));
    let h = _mm_add_ps(q, _mm_movehl_ps(q, q));
    _mm_cvtss_f32(_mm_add_ss(h, _mm_movehdup_ps(h)))
}

/// Row-wise dot products of `B` with the three coordinate arrays of `d`.
///
/// One plain dot product per axis (each in `LANES` partial sums) is the shape LLVM vectorises
/// reliably; the row is read three times, from L1. `FUSED` uses `mul_add`, which is only fast where
/// the target has FMA.
#[inline(always)]
fn apply_soa<const FUSED: bool>(
    b: &[f32],
    m: usize,
    dx: &[f32],
    dy: &[f32],
    dz: &[f32],
    out: &mut [Vec3],
) {
    for (row, o) in b.chunks_exact(m).zip(out.iter_mut()) {
        *o = Vec3::new(
            dot::<FUSED>(row, dx),
            dot::<FUSED>(row, dy),
            dot::<FUSED>(row, dz),
        );
    }
}

/// Dot product of two equally long slices in `LANES` partial sums, then a 4-wide and a scalar tail.
#[inline(always)]
fn dot<const FUSED: bool>(a: &[f32], b: &[f32]) -> f32 {
    let madd = |x: f32, y: f32, acc: f32| {
        if FUSED {
            x.mul_add(y, acc)
        } else {
            x * y + acc
        }
    };
    let mut acc = [0f32; LANES];
    let mut ca = a.chunks_exact(LANES);
    let mut cb = b.chunks_exact(LANES);
    for (x, y) in (&mut ca).zip(&mut cb) {
        for l in 0..LANES {
            acc[l] = madd(x[l], y[l], acc[l]);
        }
    }
    let (ra, rb) = (ca.remainder(), cb.remainder());
    let mut quad = [0f32; 4];
    let mut qa = ra.chunks_exact(4);
    let mut qb = rb.chunks_exact(4);
    for (x, y) in (&mut qa).zip(&mut qb) {
        for l in 0..4 {
            quad[l] = madd(x[l], y[l], quad[l]);
        }
    }
    let mut s = hsum(&acc) + (quad[0] + quad[2]) + (quad[1] + quad[3]);
    for (x, y) in qa.remainder().iter().zip(qb.remainder()) {
        s = madd(*x, *y, s);
    }
    s
}

/// Sum of the lanes, pairwise (so it vectorises as a shuffle tree).
#[inline(always)]
fn hsum(a: &[f32; LANES]) -> f32 {
    let h = [a[0] + a[4], a[1] + a[5], a[2] + a[6], a[3] + a[7]];
    (h[0] + h[2]) + (h[1] + h[3])
}

/// Fallback for many controls: one Vec3 accumulator per row.
fn apply_aos(b: &[f32], m: usize, d: &[Vec3], out: &mut [Vec3]) {
    for (row, o) in b.chunks_exact(m).zip(out.iter_mut()) {
        *o = row
            .iter()
            .zip(d)
            .fold(Vec3::ZERO, |acc, (w, v)| acc + *v * *w);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use mimic_testkit::lcg;

    #[test]
    fn moving_rows_keep_the_non_zero_rows_in_order() {
        // Rows 0 and 3 are zero, row 2 has one non-zero weight.
        #[rustfmt::skip]
        let data = vec![
            0.0, 0.0, 0.0,
            0.5, -1.0, 0.25,
            0.0, 0.0, 2.0,
            0.0, 0.0, 0.0,
        ];
        let b = Basis::from_row_major(4, 3, data).unwrap();
        let moving = b.moving_rows(usize::MAX);
        assert_eq!(moving.rows, vec![1, 2]);
        assert_eq!(moving.basis.vertex_count(), 2);
        assert_eq!(moving.basis.row(0), b.row(1));
        assert_eq!(moving.basis.row(1), b.row(2));
        // The limit cuts the rows looked at.
        assert_eq!(b.moving_rows(2).rows, vec![1]);
        // The compact product is the full product at the moving rows.
        let d = [Vec3::new(1.0, 2.0, 3.0), Vec3::splat(-0.5), Vec3::X];
        let (mut full, mut compact) = (vec![Vec3::ZERO; 4], vec![Vec3::ZERO; 2]);
        b.apply(&d, &mut full);
        moving.basis.apply(&d, &mut compact);
        assert_eq!(compact, vec![full[1], full[2]]);
    }

    #[test]
    fn apply_matches_f64_reference_for_many_shapes() {
        let mut seed = 7u64;
        for &(n, m) in &[
            (1usize, 1usize),
            (5, 7),
            (13, 8),
            (33, 38),
            (24, 38),
            (49, 38),
            (100, 5),
            (10, 64),
            (4, 65),
            (3, 100),
        ] {
            let data: Vec<f32> = (0..n * m).map(|_| lcg(&mut seed)).collect();
            let d: Vec<Vec3> = (0..m)
                .map(|_| Vec3::new(lcg(&mut seed), lcg(&mut seed), lcg(&mut seed)))
                .collect();
            let b = Basis::from_row_major(n, m, data.clone()).unwrap();
            let mut out = vec![Vec3::splat(f32::NAN); n];
            b.apply(&d, &mut out);
            let mut pairs = vec![Vec3::splat(f32::NAN); n];
            b.apply_row_pairs(&d, &mut pairs);
            // The portable path too (apply takes the AVX2 one on CPUs that have it).
            let mut portable = vec![Vec3::splat(f32::NAN); n];
            let dx: Vec<f32> = d.iter().map(|v| v.x).collect();
            let dy: Vec<f32> = d.iter().map(|v| v.y).collect();
            let dz: Vec<f32> = d.iter().map(|v| v.z).collect();
            apply_soa::<false>(&data, m, &dx, &dy, &dz, &mut portable);
            for i in 0..n {
                for k in 0..3 {
                    let r: f64 = (0..m)
                        .map(|j| data[i * m + j] as f64 * d[j][k] as f64)
                        .sum();
                    assert!(
                        (portable[i][k] as f64 - r).abs() <= (m * m) as f64 * f32::EPSILON as f64
                    );
                }
            }
            for i in 0..n {
                let mut r = [0f64; 3];
                for j in 0..m {
                    let w = data[i * m + j] as f64;
                    r[0] += w * d[j].x as f64;
                    r[1] += w * d[j].y as f64;
                    r[2] += w * d[j].z as f64;
                }
                // f32 sums of m terms each |.| <= 1: error <= m * 2^-23 * m (generous bound m^2 eps).
                let tol = (m * m) as f64 * f32::EPSILON as f64;
                for k in 0..3 {
                    assert!(
                        (out[i][k] as f64 - r[k]).abs() <= tol,
                        "n={n} m={m} i={i} k={k}"
                    );
                    assert!(
                        (pairs[i][k] as f64 - r[k]).abs() <= tol,
                        "row pairs: n={n} m={m} i={i} k={k}"
                    );
                }
            }
        }
    }

    #[test]
    fn apply_skips_zero_columns_exactly() {
        // Rows in bands with disjoint non-zero columns (like face regions), frozen rows between,
        // 70 rows = 2 full blocks and a partial one: equal to the row-pair kernel's dense sums up
        // to reassociation, and exactly zero on frozen rows.
        let (n, m) = (70usize, 38usize);
        let mut seed = 3u64;
        let data: Vec<f32> = (0..n * m)
            .map(|k| {
                let (i, j) = (k / m, k % m);
                let w = lcg(&mut seed);
                match i {
                    0..=19 if j < 10 => w,
                    20..=29 => 0.0,
                    30..=59 if (10..30).contains(&j) => w,
                    60.. if j >= 30 || j == 3 => w,
                    _ => 0.0,
                }
            })
            .collect();
        let b = Basis::from_row_major(n, m, data.clone()).unwrap();
        assert!(b.blocked.cols.len() < 3 * m, "zero columns left out");
        let d: Vec<Vec3> = (0..m)
            .map(|_| Vec3::new(lcg(&mut seed), lcg(&mut seed), lcg(&mut seed)))
            .collect();
        let mut out = vec![Vec3::NAN; n];
        b.apply(&d, &mut out);
        for i in 0..n {
            let r: glam::DVec3 = (0..m)
                .map(|j| d[j].as_dvec3() * data[i * m + j] as f64)
                .sum();
            let tol = (m * m) as f64 * f32::EPSILON as f64;
            assert!(
                (out[i].as_dvec3() - r).abs().max_element() <= tol,
                "row {i}"
            );
            if (20..30).contains(&i) {
                assert_eq!(out[i], Vec3::ZERO);
            }
        }
    }

    #[test]
    fn from_row_major_checks_length() {
        assert!(Basis::from_row_major(2, 3, vec![0.0; 5]).is_none());
        let b = Basis::from_row_major(2, 3, vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0]).unwrap();
        assert_eq!(b.row(1), &[4.0, 5.0, 6.0]);
        assert_eq!(b.vertex_count(), 2);
        assert_eq!(b.control_count(), 3);
    }

    #[test]
    fn zero_controls_give_zero_displacement() {
        let b = Basis::from_row_major(3, 0, vec![]).unwrap();
        let mut out = vec![Vec3::ONE; 3];
        b.apply(&[], &mut out);
        assert!(out.iter().all(|v| *v == Vec3::ZERO));
    }
}
