//! [`VertexFans`]' 8-lane kernel (AVX2 + FMA): each group of 16 fans as two halves of 8, in the
//! lanes of AVX registers.

use super::{Entry, GROUP, HALF, VertexFans};
use glam::{Vec3, Vec3A};

impl VertexFans {
    /// [`VertexFans::normals_packed`] with the fans of a group, 8 at a time (each half of the group), in
    /// the lanes of AVX registers: per step, 8 neighbour loads transposed to x, y, z registers and
    /// 8 cross products; per half one Newton-refined reciprocal square root, run (with the
    /// half's write-out) after the next half's steps.
    ///
    /// Kept for its figure: on the CI machine class (AMD EPYC Zen 2, 2 vCPUs, AVX2), 2026-12-07,
    /// `mimic bench` ran the step with the portable normals 9.8-10.3x as long as with this kernel
    /// on `ict-face-3k` and 9.4-9.8x on `ict-face` (medians of 3 runs; docs/performance.md,
    /// "Kernel variants").
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA, and `base` must be valid for reading 4 floats at
    /// `3 v` for every `v < self.position_count`; `stored` must be the packed offsets.
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn normals_avx2<E: Entry>(
        &self,
        stored: &[E],
        base: *const f32,
        write: &mut impl FnMut(usize, Vec3),
    ) {
        use std::arch::x86_64::*;
        // 8 positions named by `idx[0..8]` as x, y, z registers (lane k = vertex idx[k]). Called
        // directly in this function's body (not through an iterator adaptor) so that it is
        // inlined with the AVX2 features: an adaptor's closure is compiled without them and
        // called once per step, with every live register spilled around the call.
        let load8 = |idx: *const E| -> (__m256, __m256, __m256) {
            // SAFETY: idx points at 8 stored entries (offsets of packed positions) of vertices
            // below position_count (the caller's range); 4 floats are readable at each offset.
            unsafe {
                let at = |k: usize| base.add((*idx.add(k)).index());
                let r0 = _mm256_loadu2_m128(at(4), at(0));
                let r1 = _mm256_loadu2_m128(at(5), at(1));
                let r2 = _mm256_loadu2_m128(at(6), at(2));
                let r3 = _mm256_loadu2_m128(at(7), at(3));
                let t0 = _mm256_unpacklo_ps(r0, r1); // x0 x1 y0 y1 | x4 x5 y4 y5
                let t1 = _mm256_unpackhi_ps(r0, r1); // z0 z1 .. .. | z4 z5 .. ..
                let t2 = _mm256_unpacklo_ps(r2, r3); // x2 x3 y2 y3 | x6 x7 y6 y7
                let t3 = _mm256_unpackhi_ps(r2, r3); // z2 z3 .. .. | z6 z7 .. ..
                (
                    _mm256_shuffle_ps::<0x44>(t0, t2),
                    _mm256_shuffle_ps::<0xEE>(t0, t2),
                    _mm256_shuffle_ps::<0x44>(t1, t3),
                )
            }
        };
        // Each group of 16 as two halves of 8 lanes (the second only where it has lanes in use).
        // A half's sums are normalised and written after the next half's steps, so that the
        // latency of its sums' chain and of the normalisation hides behind independent loads.
        let mut halves = self
            .groups
            .iter()
            .enumerate()
            .flat_map(|(g, &[first, steps, lanes])| {
                (0..(lanes as usize).div_ceil(HALF)).map(move |h| (g, first, steps, lanes, h))
            });
        let mut pending: Option<(usize, usize, __m256, __m256, __m256)> = None;
        // A plain loop, not `for` over `halves` chained with a last `None`: that adaptor ran the
        // kernel 13-16 % slower.
        loop {
            let next = halves.next();
            // Explicit branches, not `Option::map`: a closure passed to a core function may be
            // compiled without AVX2 (see `load8`).
            let summed = if let Some((g, first, steps, lanes, h)) = next {
                let entries = &stored[first as usize..][..steps as usize * GROUP];
                let lanes = (lanes as usize - h * HALF).min(HALF);
                let (mut sx, mut sy, mut sz) = (
                    _mm256_setzero_ps(),
                    _mm256_setzero_ps(),
                    _mm256_setzero_ps(),
                );
                // Step l of this half: entries[l * GROUP + h * HALF..][..HALF].
                let half = entries.as_ptr().wrapping_add(h * HALF);
                if steps > 1 {
                    // Each fan's first entry is its origin (see `VertexFans`): its difference
                    // vector is zero, so the sum starts with entries 1 and 2.
                    let (px, py, pz) = load8(half);
                    // SAFETY: 1 < steps: the 8 entries at GROUP + h * HALF lie in `entries`.
                    let (qx, qy, qz) = load8(unsafe { half.add(GROUP) });
                    let (mut ax, mut ay, mut az) = (
                        _mm256_sub_ps(qx, px),
                        _mm256_sub_ps(qy, py),
                        _mm256_sub_ps(qz, pz),
                    );
                    for l in 2..steps as usize {
                        // SAFETY: l < steps, so the 8 entries at l * GROUP + h * HALF lie in
                        // `entries` (steps * GROUP long).
                        let (qx, qy, qz) = load8(unsafe { half.add(l * GROUP) });
                        let (bx, by, bz) = (
                            _mm256_sub_ps(qx, px),
                            _mm256_sub_ps(qy, py),
                            _mm256_sub_ps(qz, pz),
                        );
                        // s += a x b, each component two fused multiply-adds into the sum
                        // (`s + a.y b.z - a.z b.y`, rounded after each): no separate product.
                        sx = _mm256_fnmadd_ps(az, by, _mm256_fmadd_ps(ay, bz, sx));
                        sy = _mm256_fnmadd_ps(ax, bz, _mm256_fmadd_ps(az, bx, sy));
                        sz = _mm256_fnmadd_ps(ay, bx, _mm256_fmadd_ps(ax, by, sz));
                        (ax, ay, az) = (bx, by, bz);
                    }
                }
                Some((g * GROUP + h * HALF, lanes, sx, sy, sz))
            } else {
                None
            };
            // The previous half's sums (none before the first), and this one's kept for later.
            let done = std::mem::replace(&mut pending, summed);
            if let Some((c0, lanes, sx, sy, sz)) = done {
                let centre = &self.centres[c0..][..HALF];
                // 1 / length: the 12-bit reciprocal square root refined by one Newton step
                // (y (3 - x y^2) / 2, relative error within a few eps), and 0 where the squared length
                // is not a finite normal number (zero, subnormal, overflowed or NaN sums).
                let len2 = _mm256_fmadd_ps(sz, sz, _mm256_fmadd_ps(sy, sy, _mm256_mul_ps(sx, sx)));
                let y = _mm256_rsqrt_ps(len2);
                let xy2 = _mm256_mul_ps(_mm256_mul_ps(len2, y), y);
                let inv = _mm256_mul_ps(
                    _mm256_mul_ps(_mm256_set1_ps(0.5), y),
                    _mm256_sub_ps(_mm256_set1_ps(3.0), xy2),
                );
                let ok = _mm256_and_ps(
                    _mm256_cmp_ps::<_CMP_GE_OQ>(len2, _mm256_set1_ps(f32::MIN_POSITIVE)),
                    _mm256_cmp_ps::<_CMP_LT_OQ>(len2, _mm256_set1_ps(f32::INFINITY)),
                );
                let inv = _mm256_and_ps(inv, ok);
                let (nx, ny, nz) = (
                    _mm256_mul_ps(sx, inv),
                    _mm256_mul_ps(sy, inv),
                    _mm256_mul_ps(sz, inv),
                );
                // Back to one (x, y, z, 0) vector per lane.
                let zero = _mm256_setzero_ps();
                let t0 = _mm256_unpacklo_ps(nx, ny); // x0 y0 x1 y1 | x4 y4 x5 y5
                let t1 = _mm256_unpackhi_ps(nx, ny); // x2 y2 x3 y3 | x6 y6 x7 y7
                let t2 = _mm256_unpacklo_ps(nz, zero); // z0 0 z1 0 | z4 0 z5 0
                let t3 = _mm256_unpackhi_ps(nz, zero); // z2 0 z3 0 | z6 0 z7 0
                // Lane k in the low half of rows[k] (k < 4) or the high half of rows[k - 4],
                // written straight from the registers (no round trip through memory).
                let rows = [
                    _mm256_shuffle_ps::<0x44>(t0, t2),
                    _mm256_shuffle_ps::<0xEE>(t0, t2),
                    _mm256_shuffle_ps::<0x44>(t1, t3),
                    _mm256_shuffle_ps::<0xEE>(t1, t3),
                ];
                let low = |r: __m256| Vec3::from(Vec3A::from(_mm256_castps256_ps128(r)));
                let high = |r: __m256| Vec3::from(Vec3A::from(_mm256_extractf128_ps::<1>(r)));
                if lanes == HALF {
                    // Every lane in use (all but the last group's): unrolled, rows in registers.
                    write(centre[0] as usize, low(rows[0]));
                    write(centre[1] as usize, low(rows[1]));
                    write(centre[2] as usize, low(rows[2]));
                    write(centre[3] as usize, low(rows[3]));
                    write(centre[4] as usize, high(rows[0]));
                    write(centre[5] as usize, high(rows[1]));
                    write(centre[6] as usize, high(rows[2]));
                    write(centre[7] as usize, high(rows[3]));
                } else {
                    for (k, &v) in centre.iter().enumerate().take(lanes) {
                        let n = if k < 4 {
                            low(rows[k])
                        } else {
                            high(rows[k - 4])
                        };
                        write(v as usize, n);
                    }
                }
            }
            if next.is_none() {
                break;
            }
        }
    }
}
