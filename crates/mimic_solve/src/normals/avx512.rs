//! [`VertexFans`]' 16-lane kernel (AVX-512F): a whole group of 16 fans in the lanes of one
//! register, with the AVX2 kernel's arithmetic lane for lane (the same sums bit for bit) and a
//! 14-bit reciprocal square root refined by the same Newton step.

use super::{Entry, GROUP, VertexFans, float_offset};
use glam::Vec3;
use std::arch::x86_64::*;

impl VertexFans {
    /// [`VertexFans::normals`] with the 16 fans of a group in the lanes of AVX-512 registers: per
    /// step, 16 neighbour loads (4 per register, 128 bits each) transposed to x, y, z registers,
    /// 16 cross products, and per group one Newton-refined reciprocal square root, run (with the
    /// group's write-out) after the next group's steps.
    ///
    /// `STRIDE` floats a vertex (4: `Vec3A`, 3: packed), x, y, z first.
    ///
    /// # Safety
    /// The CPU must support AVX-512F, and `base` must be valid for reading 4 floats at
    /// `STRIDE * v` for every `v < self.position_count`; `stored` must be `self.entries` (vertex
    /// indices) for `STRIDE` 4, the packed offsets (either width) for 3.
    #[target_feature(enable = "avx512f")]
    pub(super) unsafe fn normals_avx512<const STRIDE: usize, E: Entry>(
        &self,
        stored: &[E],
        base: *const f32,
        write: &mut impl FnMut(usize, Vec3),
    ) {
        // 16 positions named by `idx[0..16]` as x, y, z registers (lane k = vertex idx[k]).
        let load16 = |idx: *const E| -> (__m512, __m512, __m512) {
            // Written out row by row, not through `array::map`: a closure passed to a core
            // function is compiled without AVX-512 and called per row, spilling every register.
            // SAFETY: idx points at 16 stored entries (offsets of packed positions, or vertex
            // indices) of vertices below position_count, and 4 floats are readable at each
            // vertex's offset (caller).
            let at =
                |k: usize| unsafe { _mm_loadu_ps(base.add(float_offset::<STRIDE>(*idx.add(k)))) };
            let row = |j: usize| {
                let r = _mm512_castps128_ps512(at(j));
                let r = _mm512_insertf32x4::<1>(r, at(j + 4));
                let r = _mm512_insertf32x4::<2>(r, at(j + 8));
                _mm512_insertf32x4::<3>(r, at(j + 12))
            };
            let (r0, r1, r2, r3) = (row(0), row(1), row(2), row(3));
            // Per 128-bit lane c (vertices 4c..4c + 4), as the AVX2 kernel's transpose.
            let t0 = _mm512_unpacklo_ps(r0, r1); // x0 x1 y0 y1
            let t1 = _mm512_unpackhi_ps(r0, r1); // z0 z1 .. ..
            let t2 = _mm512_unpacklo_ps(r2, r3); // x2 x3 y2 y3
            let t3 = _mm512_unpackhi_ps(r2, r3); // z2 z3 .. ..
            (
                _mm512_shuffle_ps::<0x44>(t0, t2),
                _mm512_shuffle_ps::<0xEE>(t0, t2),
                _mm512_shuffle_ps::<0x44>(t1, t3),
            )
        };
        // Row r of `rows` holds vertex 4c + r of the group at floats 4c..4c + 3.
        let mut rows = [[0f32; GROUP]; 4];
        // Group g's sums are normalised and written after group g + 1's steps, so that the
        // latency of its sums' chain and of the normalisation hides behind independent loads.
        let mut pending: Option<(usize, __m512, __m512, __m512)> = None;
        for g in 0..=self.groups.len() {
            // Explicit branches, not `Option::map`: a closure passed to a core function may be
            // compiled without AVX-512 (see `load16`).
            let summed = if let Some(&[first, steps, _]) = self.groups.get(g) {
                // Step l of the group: its 16 entries at `group.add(l * GROUP)`.
                let group = stored[first as usize..][..steps as usize * GROUP].as_ptr();
                let (mut sx, mut sy, mut sz) = (
                    _mm512_setzero_ps(),
                    _mm512_setzero_ps(),
                    _mm512_setzero_ps(),
                );
                if steps > 1 {
                    // Each fan's first entry is its origin (as the AVX2 kernel).
                    let (px, py, pz) = load16(group);
                    // SAFETY: 1 < steps: the 16 entries at GROUP lie in the group's steps * GROUP.
                    let (qx, qy, qz) = load16(unsafe { group.add(GROUP) });
                    let (mut ax, mut ay, mut az) = (
                        _mm512_sub_ps(qx, px),
                        _mm512_sub_ps(qy, py),
                        _mm512_sub_ps(qz, pz),
                    );
                    for l in 2..steps as usize {
                        // SAFETY: l < steps: the 16 entries at l * GROUP lie in the group's entries.
                        let (qx, qy, qz) = load16(unsafe { group.add(l * GROUP) });
                        let (bx, by, bz) = (
                            _mm512_sub_ps(qx, px),
                            _mm512_sub_ps(qy, py),
                            _mm512_sub_ps(qz, pz),
                        );
                        // s += a x b, each component two fused multiply-adds into the sum, as the
                        // AVX2 kernel's.
                        sx = _mm512_fnmadd_ps(az, by, _mm512_fmadd_ps(ay, bz, sx));
                        sy = _mm512_fnmadd_ps(ax, bz, _mm512_fmadd_ps(az, bx, sy));
                        sz = _mm512_fnmadd_ps(ay, bx, _mm512_fmadd_ps(ax, by, sz));
                        (ax, ay, az) = (bx, by, bz);
                    }
                }
                Some((g, sx, sy, sz))
            } else {
                None
            };
            // The previous group's sums (none before the first), and this one's kept for later.
            let done = std::mem::replace(&mut pending, summed);
            if let Some((g, sx, sy, sz)) = done {
                let [_, _, lanes] = self.groups[g];
                let centre = &self.centres[g * GROUP..][..GROUP];
                // 1 / length: the 14-bit reciprocal square root refined by one Newton step
                // (y (3 - x y^2) / 2: relative error (3/2) 2^-28 plus the rounding of its 5
                // operations, within 4 eps), and 0 where the squared length is not a finite normal
                // number, as the AVX2 kernel.
                let len2 = _mm512_fmadd_ps(sz, sz, _mm512_fmadd_ps(sy, sy, _mm512_mul_ps(sx, sx)));
                let y = _mm512_rsqrt14_ps(len2);
                let xy2 = _mm512_mul_ps(_mm512_mul_ps(len2, y), y);
                let inv = _mm512_mul_ps(
                    _mm512_mul_ps(_mm512_set1_ps(0.5), y),
                    _mm512_sub_ps(_mm512_set1_ps(3.0), xy2),
                );
                let ok = _mm512_cmp_ps_mask::<_CMP_GE_OQ>(len2, _mm512_set1_ps(f32::MIN_POSITIVE))
                    & _mm512_cmp_ps_mask::<_CMP_LT_OQ>(len2, _mm512_set1_ps(f32::INFINITY));
                let inv = _mm512_maskz_mov_ps(ok, inv);
                let (nx, ny, nz) = (
                    _mm512_mul_ps(sx, inv),
                    _mm512_mul_ps(sy, inv),
                    _mm512_mul_ps(sz, inv),
                );
                // Back to (x, y, z, 0) per vertex: 128-bit lane c of row r is vertex 4c + r.
                let zero = _mm512_setzero_ps();
                let t0 = _mm512_unpacklo_ps(nx, ny); // x0 y0 x1 y1
                let t1 = _mm512_unpackhi_ps(nx, ny); // x2 y2 x3 y3
                let t2 = _mm512_unpacklo_ps(nz, zero); // z0 0 z1 0
                let t3 = _mm512_unpackhi_ps(nz, zero); // z2 0 z3 0
                // SAFETY: each row of `rows` holds 16 f32.
                unsafe {
                    _mm512_storeu_ps(rows[0].as_mut_ptr(), _mm512_shuffle_ps::<0x44>(t0, t2));
                    _mm512_storeu_ps(rows[1].as_mut_ptr(), _mm512_shuffle_ps::<0xEE>(t0, t2));
                    _mm512_storeu_ps(rows[2].as_mut_ptr(), _mm512_shuffle_ps::<0x44>(t1, t3));
                    _mm512_storeu_ps(rows[3].as_mut_ptr(), _mm512_shuffle_ps::<0xEE>(t1, t3));
                }
                let mut put = |k: usize, v: u32| {
                    let n = &rows[k % 4][4 * (k / 4)..][..3];
                    write(v as usize, Vec3::new(n[0], n[1], n[2]));
                };
                if lanes as usize == GROUP {
                    // Every lane in use (all but the last group's): a loop of constant length, which
                    // the compiler unrolls, every offset into `rows` a constant.
                    centre.iter().enumerate().for_each(|(k, &v)| put(k, v));
                } else {
                    for (k, &v) in centre.iter().enumerate().take(lanes as usize) {
                        put(k, v);
                    }
                }
            }
        }
    }
}
