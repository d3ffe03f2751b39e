//! Area-weighted vertex normals: the reference face-by-face pass ([`vertex_normals`]) and a
//! vertex-by-vertex gather over precomputed triangle fans ([`VertexFans`]) for the per-frame path.

use glam::{Vec3, Vec3A, Vec3Swizzles};

/// Area-weighted vertex normals: each vertex gets the normalised sum of the un-normalised normals
/// `(b - a) x (c - a)` of its triangles (counter-clockwise seen from outside points outwards).
///
/// Allocates nothing. Vertices in no triangle, or whose summed normal has zero length (e.g. only
/// degenerate triangles), get `Vec3::ZERO`. Triangles naming a vertex outside `positions` are skipped.
///
/// # Panics
/// If `out.len() != positions.len()`.
pub fn vertex_normals(positions: &[Vec3], triangles: &[[u32; 3]], out: &mut [Vec3]) {
    assert_eq!(
        out.len(),
        positions.len(),
        "vertex_normals: output length differs from positions"
    );
    out.fill(Vec3::ZERO);
    for t in triangles {
        let (ia, ib, ic) = (t[0] as usize, t[1] as usize, t[2] as usize);
        let (Some(a), Some(b), Some(c)) = (positions.get(ia), positions.get(ib), positions.get(ic))
        else {
            continue;
        };
        let n = (*b - *a).cross(*c - *a);
        out[ia] += n;
        out[ib] += n;
        out[ic] += n;
    }
    for n in out.iter_mut() {
        *n = n.normalize_or_zero();
    }
}

#[cfg(target_arch = "x86_64")]
mod avx512;

/// Vertices gathered together by [`VertexFans`]: one AVX-512 register of f32 lanes (two AVX
/// registers on the AVX2 path).
const GROUP: usize = 16;

/// Lanes of one AVX register of f32: the AVX2 path runs a group as two halves of this many.
#[cfg(target_arch = "x86_64")]
const HALF: usize = 8;

/// Which fan kernel [`VertexFans::normals_packed_by`] runs (benchmarks and tests; the other
/// entry points pick [`FanKernel::best`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FanKernel {
    /// One fan at a time, any CPU.
    Portable,
    /// 8 fans in the lanes of an AVX register (AVX2 + FMA).
    Avx2,
    /// 16 fans in the lanes of an AVX-512 register (AVX-512F).
    Avx512,
}

impl FanKernel {
    /// The fastest kernel this CPU runs (runtime-detected, once): AVX-512 where the CPU has it
    /// at full width, AVX2 on CPUs that run 512-bit operations as two 256-bit halves (AMD Zen 4,
    /// where the 16-lane kernel measured 5-10 % slower than the 8-lane one: docs/performance.md),
    /// else portable.
    pub fn best() -> Self {
        static BEST: std::sync::OnceLock<FanKernel> = std::sync::OnceLock::new();
        *BEST.get_or_init(|| {
            #[cfg(target_arch = "x86_64")]
            {
                if crate::basis::avx2_fma()
                    && std::arch::is_x86_feature_detected!("avx512f")
                    && !splits_512_bit_ops()
                {
                    return Self::Avx512;
                }
                if crate::basis::avx2_fma() {
                    return Self::Avx2;
                }
            }
            Self::Portable
        })
    }

    /// Whether this CPU runs `self`.
    pub fn supported(self) -> bool {
        match self {
            Self::Portable => true,
            #[cfg(target_arch = "x86_64")]
            Self::Avx2 => crate::basis::avx2_fma(),
            #[cfg(target_arch = "x86_64")]
            Self::Avx512 => {
                crate::basis::avx2_fma() && std::arch::is_x86_feature_detected!("avx512f")
            }
            #[cfg(not(target_arch = "x86_64"))]
            Self::Avx2 | Self::Avx512 => false,
        }
    }

    /// `self` where this CPU runs it, else the best kernel it runs ([`FanKernel::best`]).
    pub fn available(self) -> Self {
        if self.supported() { self } else { Self::best() }
    }
}

/// True on AMD family 19h (Zen 3 and Zen 4; only Zen 4 has AVX-512), whose 512-bit operations
/// issue as two 256-bit halves, so a 16-lane kernel does the 8-lane one's work in the same ops.
#[cfg(target_arch = "x86_64")]
fn splits_512_bit_ops() -> bool {
    // SAFETY: CPUID exists on every x86_64 CPU, with leaves 0 and 1 (a safe function in newer
    // Rust, an unsafe one at the MSRV).
    #[allow(
        unused_unsafe,
        reason = "__cpuid is safe in newer Rust, unsafe at the MSRV"
    )]
    let (vendor, signature) = unsafe {
        use std::arch::x86_64::__cpuid;
        (__cpuid(0), __cpuid(1).eax)
    };
    let amd = (vendor.ebx, vendor.edx, vendor.ecx) == (0x6874_7541, 0x6974_6e65, 0x444d_4163);
    // Family: the base field (bits 8-11) plus the extended one (bits 20-27) when the base is 0xF.
    let base = (signature >> 8) & 0xF;
    let family = if base == 0xF {
        base + ((signature >> 20) & 0xFF)
    } else {
        base
    };
    amd && family == 0x19
}

/// Triangle fans around the first `count` vertices of a mesh, for gathering their area-weighted
/// normals vertex by vertex (the same normals as [`vertex_normals`], up to f32 rounding).
///
/// Vertex `v`'s fan is a list of neighbours `w_0, w_1, ..., w_r` such that each consecutive pair
/// `(w_l, w_{l+1})` closes a triangle `(v, w_l, w_{l+1})` in the mesh's orientation. Where the
/// triangles around `v` do not form one chain (boundary, non-manifold), the chains are joined by
/// `v` itself, and a list that does not end at `w_0` ends with `v`: every list is a closed
/// polygon, each pair through `v` a degenerate triangle. The area vector of a closed polygon,
/// `sum_l (p[w_l] - o) x (p[w_{l+1}] - o)`, is the same for every origin `o`: with `o = p[v]` it is
/// the sum of the fan's triangles' cross products at `v`'s corner (the area-weighted normal); the
/// kernels take `o = p[w_0]`, whose difference vector is zero, so they read no centre and skip a
/// step. Padding past a list's end repeats `w_0` (zero difference vector, adds exactly nothing).
/// A closed fan of `k` triangles reads `k + 1` neighbours, and no sum is scattered to memory.
///
/// Fans are stored in groups of 16 vertices of (nearly) equal fan length, step-major (entry `l`
/// of the 16 fans side by side), so that [`VertexFans::normals`] can run the 16 fans in the lanes
/// of one AVX-512 register (or of two AVX registers), with no data-dependent branch inside a group.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VertexFans {
    /// Per group: first entry in `entries`, steps (entries per lane), lanes in use (1..=16).
    groups: Vec<[u32; 3]>,
    /// 16 centre vertices per group (unused lanes repeat the first).
    centres: Vec<u32>,
    /// Per group, `steps * 16` neighbours, step-major.
    entries: Vec<u32>,
    /// Vertices with a fan.
    count: usize,
    /// Positions needed: one past the largest vertex any fan names.
    position_count: usize,
}

impl VertexFans {
    /// Fans of vertices `0..count` from `triangles` over `vertex_count` positions; triangles naming
    /// a vertex `>= vertex_count` are skipped, as in [`vertex_normals`].
    pub fn new(count: usize, vertex_count: usize, triangles: &[[u32; 3]]) -> Self {
        let count = count.min(vertex_count);
        let fans = chain_fans(count, vertex_count, triangles);
        // Group by fan length (stable, so neighbouring vertices stay together).
        let mut order: Vec<usize> = (0..count).collect();
        order.sort_by_key(|&v| fans[v].len());
        let mut groups = Vec::with_capacity(count.div_ceil(GROUP));
        let mut centres = Vec::with_capacity(count.div_ceil(GROUP) * GROUP);
        let mut entries = Vec::new();
        for chunk in order.chunks(GROUP) {
            let steps = chunk.iter().map(|&v| fans[v].len()).max().unwrap_or(0);
            groups.push([entries.len() as u32, steps as u32, chunk.len() as u32]);
            let lane = |k: usize| chunk.get(k).copied().unwrap_or(chunk[0]);
            centres.extend((0..GROUP).map(|k| lane(k) as u32));
            for l in 0..steps {
                for k in 0..GROUP {
                    let v = lane(k);
                    // Past its end, a fan is padded with its first entry (its origin): zero
                    // difference vector; an empty fan with its own centre.
                    let pad = fans[v].first().copied().unwrap_or(v as u32);
                    entries.push(fans[v].get(l).copied().unwrap_or(pad));
                }
            }
        }
        let position_count = entries
            .iter()
            .map(|&w| w as usize + 1)
            .max()
            .unwrap_or(0)
            .max(count);
        Self {
            groups,
            centres,
            entries,
            count,
            position_count,
        }
    }

    /// Number of vertices with a fan (`0..count`).
    pub fn count(&self) -> usize {
        self.count
    }

    /// Number of positions [`VertexFans::normals`] reads.
    pub fn position_count(&self) -> usize {
        self.position_count
    }

    /// Fan entries over all lanes, padding included: the neighbour reads of one call.
    pub fn entry_count(&self) -> usize {
        self.entries.len()
    }

    /// Calls `write(v, normal)` once for every vertex `v < count()` (in no particular order) with
    /// its normalised area-weighted normal, zero where the sum has no finite, non-zero length
    /// (as `normalize_or_zero`; the vectorised path also gives zero for sums whose squared length
    /// is subnormal, below 1.2e-38); allocates nothing. 16 fans at a time with AVX-512F, 8 with
    /// AVX2 + FMA where the CPU has them (the same sums bit for bit; each normalised by a
    /// Newton-refined reciprocal square root, within 4 eps), else one by one.
    ///
    /// # Panics
    /// If `positions.len() < position_count()`.
    pub fn normals(&self, positions: &[Vec3A], mut write: impl FnMut(usize, Vec3)) {
        assert!(
            positions.len() >= self.position_count,
            "VertexFans::normals: {} positions, fans name {}",
            positions.len(),
            self.position_count
        );
        #[cfg(target_arch = "x86_64")]
        {
            let p = positions.as_ptr().cast::<f32>();
            // SAFETY: the kernel's CPU features are checked by `best`; every centre and entry is
            // below position_count <= positions.len() (asserted), each a 16-byte Vec3A at 4
            // floats a vertex, and each group's entries lie in `entries` by construction.
            match FanKernel::best() {
                FanKernel::Avx512 => return unsafe { self.normals_avx512::<4>(p, &mut write) },
                FanKernel::Avx2 => return unsafe { self.normals_avx2::<false, 4>(p, &mut write) },
                FanKernel::Portable => {}
            }
        }
        self.normals_portable(positions, &mut write);
    }

    /// [`VertexFans::normals`] on positions packed 3 floats a vertex (`positions[3 v..3 v + 3]`,
    /// one float of padding after the last), as [`crate::deform::MovingDeform::deform_packed`]
    /// writes them: the same loads (the fourth float of each, the next vertex's x, is dropped by
    /// the transpose) on a quarter less memory, so the same normals bit for bit as
    /// [`VertexFans::normals`] on the same positions.
    ///
    /// # Panics
    /// If `positions.len() < 3 * position_count() + 1`.
    pub fn normals_packed(&self, positions: &[f32], write: impl FnMut(usize, Vec3)) {
        self.normals_packed_by(FanKernel::best(), positions, write);
    }

    /// [`VertexFans::normals_packed`] by a given kernel ([`FanKernel::available`]: the best one
    /// the CPU runs where it lacks `kernel`), for A/B comparisons and tests.
    ///
    /// # Panics
    /// As [`VertexFans::normals_packed`].
    pub fn normals_packed_by(
        &self,
        kernel: FanKernel,
        positions: &[f32],
        mut write: impl FnMut(usize, Vec3),
    ) {
        assert!(
            positions.len() > 3 * self.position_count,
            "VertexFans::normals_packed: {} floats, fans name {} positions (3 floats each and 1 of padding)",
            positions.len(),
            self.position_count
        );
        #[cfg(target_arch = "x86_64")]
        {
            let p = positions.as_ptr();
            // SAFETY: the kernel's CPU features are checked by `available`; every centre and
            // entry v is below position_count, and the 4 floats at 3 v lie within positions
            // (asserted: 3 position_count + 1 floats); each group's entries lie in `entries` by
            // construction.
            match kernel.available() {
                FanKernel::Avx512 => return unsafe { self.normals_avx512::<3>(p, &mut write) },
                FanKernel::Avx2 => return unsafe { self.normals_avx2::<false, 3>(p, &mut write) },
                FanKernel::Portable => {}
            }
        }
        self.normals_packed_portable(positions, &mut write);
    }

    /// [`VertexFans::normals_packed`] one fan at a time, on any CPU.
    fn normals_packed_portable(&self, positions: &[f32], write: &mut impl FnMut(usize, Vec3)) {
        for (g, &[first, steps, lanes]) in self.groups.iter().enumerate() {
            let entries = &self.entries[first as usize..][..steps as usize * GROUP];
            let at = |v: usize| Vec3A::from_slice(&positions[3 * v..3 * v + 3]);
            for k in 0..lanes as usize {
                let v = self.centres[g * GROUP + k] as usize;
                let acc = fan_sum(entries.iter().skip(k).step_by(GROUP), at);
                write(v, Vec3::from(acc.normalize_or_zero()));
            }
        }
    }

    /// [`VertexFans::normals`] with the neighbours fetched by AVX2 gathers (one per axis and
    /// step) instead of 8 loads and a transpose: kept for the benchmarks' A/B comparison. Same
    /// sums in the same order, so the same normals bit for bit.
    ///
    /// # Panics
    /// As [`VertexFans::normals`].
    pub fn normals_gather(&self, positions: &[Vec3A], mut write: impl FnMut(usize, Vec3)) {
        assert!(
            positions.len() >= self.position_count,
            "VertexFans::normals_gather: {} positions, fans name {}",
            positions.len(),
            self.position_count
        );
        #[cfg(target_arch = "x86_64")]
        if crate::basis::avx2_fma() {
            // SAFETY: as in `normals`.
            unsafe { self.normals_avx2::<true, 4>(positions.as_ptr().cast(), &mut write) };
            return;
        }
        self.normals_portable(positions, &mut write);
    }

    /// [`VertexFans::normals`] one fan at a time, on any CPU.
    fn normals_portable(&self, positions: &[Vec3A], write: &mut impl FnMut(usize, Vec3)) {
        for (g, &[first, steps, lanes]) in self.groups.iter().enumerate() {
            let entries = &self.entries[first as usize..][..steps as usize * GROUP];
            for k in 0..lanes as usize {
                let v = self.centres[g * GROUP + k] as usize;
                let fan = entries.iter().skip(k).step_by(GROUP);
                let acc = fan_sum(fan, |w| positions[w]);
                write(v, Vec3::from(acc.normalize_or_zero()));
            }
        }
    }

    /// [`VertexFans::normals`] with the fans of a group, 8 at a time (each half of the group), in
    /// the lanes of AVX registers: per step,
    /// 8 neighbour loads transposed to x, y, z registers, 8 cross products, one vector square root
    /// and division per group for the normalisation.
    ///
    /// `STRIDE` floats a vertex (4: `Vec3A`, 3: packed), x, y, z first; `GATHER` fetches by AVX2
    /// gathers (`STRIDE` 4 only).
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA, and `base` must be valid for reading 4 floats at
    /// `STRIDE * v` for every `v < self.position_count`.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn normals_avx2<const GATHER: bool, const STRIDE: usize>(
        &self,
        base: *const f32,
        write: &mut impl FnMut(usize, Vec3),
    ) {
        use std::arch::x86_64::*;
        // 8 positions named by `idx` as x, y, z registers (lane k = idx[k]).
        // SAFETY (of the caller): every index read below is < position_count, and 4 floats at
        // STRIDE * index are readable.
        // 8 positions named by `idx[0..8]` as x, y, z registers (lane k = idx[k]). Called
        // directly in this function's body (not through an iterator adaptor) so that it is
        // inlined with the AVX2 features: an adaptor's closure is compiled without them and
        // called once per step, with every live register spilled around the call.
        let load8 = |idx: *const u32| -> (__m256, __m256, __m256) {
            // SAFETY: idx points at 8 indices below position_count (the caller's range);
            // 4 floats at STRIDE * v are readable for each.
            unsafe {
                if GATHER && STRIDE == 4 {
                    // The gathers read f32 4 * idx[k] + axis of `positions`.
                    let i = _mm256_slli_epi32::<2>(_mm256_loadu_si256(idx.cast()));
                    return (
                        _mm256_i32gather_ps::<4>(base, i),
                        _mm256_i32gather_ps::<4>(base.add(1), i),
                        _mm256_i32gather_ps::<4>(base.add(2), i),
                    );
                }
                let at = |k: usize| base.add(*idx.add(k) as usize * STRIDE);
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
        for (g, &[first, steps, lanes]) in self.groups.iter().enumerate() {
            let entries = &self.entries[first as usize..][..steps as usize * GROUP];
            for h in 0..(lanes as usize).div_ceil(HALF) {
                let centre = &self.centres[g * GROUP + h * HALF..][..HALF];
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
                        // a x b, each component one multiply and one fused multiply-subtract.
                        let cx = _mm256_fmsub_ps(ay, bz, _mm256_mul_ps(az, by));
                        let cy = _mm256_fmsub_ps(az, bx, _mm256_mul_ps(ax, bz));
                        let cz = _mm256_fmsub_ps(ax, by, _mm256_mul_ps(ay, bx));
                        sx = _mm256_add_ps(sx, cx);
                        sy = _mm256_add_ps(sy, cy);
                        sz = _mm256_add_ps(sz, cz);
                        (ax, ay, az) = (bx, by, bz);
                    }
                }
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
        }
    }
}

/// The un-normalised fan sum `sum_l (p[w_l] - p[w_0]) x (p[w_l+1] - p[w_0])`, the first entry as
/// origin (see [`VertexFans`]), one fan at a time (the portable paths), in x, y, z order.
fn fan_sum<'a>(mut fan: impl Iterator<Item = &'a u32>, at: impl Fn(usize) -> Vec3A) -> Vec3A {
    let mut acc = Vec3A::ZERO;
    // The first entry is the origin (its difference vector is zero), as in the vector kernels.
    if let (Some(&w0), Some(&w1)) = (fan.next(), fan.next()) {
        let c = at(w0 as usize);
        // a x b = (a * b.yzx - a.yzx * b).yzx: sum the inner vectors, rotate at the end.
        let mut a = at(w1 as usize) - c;
        let mut a_r = a.yzx();
        for &w in fan {
            let b = at(w as usize) - c;
            let b_r = b.yzx();
            acc += a * b_r - a_r * b;
            a = b;
            a_r = b_r;
        }
    }
    acc.yzx()
}

/// Per vertex `v < count`, its triangles `(v, w1, w2)` chained into fans `w_0, w_1, ...` (see
/// [`VertexFans`]), chains joined by `v` itself.
fn chain_fans(count: usize, vertex_count: usize, triangles: &[[u32; 3]]) -> Vec<Vec<u32>> {
    let mut pairs: Vec<Vec<(u32, u32)>> = vec![Vec::new(); count];
    let valid = |t: &&[u32; 3]| t.iter().all(|&v| (v as usize) < vertex_count);
    for t in triangles.iter().filter(valid) {
        for c in 0..3 {
            if let Some(p) = pairs.get_mut(t[c] as usize) {
                p.push((t[(c + 1) % 3], t[(c + 2) % 3]));
            }
        }
    }
    let mut used = Vec::new();
    pairs
        .iter()
        .enumerate()
        .map(|(v, mine)| {
            let mut fan = Vec::with_capacity(mine.len() + 1);
            used.clear();
            used.resize(mine.len(), false);
            loop {
                // Start an open chain where one begins (a first neighbour that closes no other
                // unused triangle), else anywhere (a closed fan).
                let open = (0..mine.len()).find(|&a| {
                    !used[a]
                        && !(0..mine.len()).any(|b| !used[b] && b != a && mine[b].1 == mine[a].0)
                });
                let Some(a) = open.or_else(|| (0..mine.len()).find(|&a| !used[a])) else {
                    break;
                };
                if !fan.is_empty() {
                    fan.push(v as u32); // separator: zero difference vector
                }
                used[a] = true;
                fan.push(mine[a].0);
                fan.push(mine[a].1);
                let mut cur = mine[a].1;
                while let Some(b) = (0..mine.len()).find(|&b| !used[b] && mine[b].0 == cur) {
                    used[b] = true;
                    cur = mine[b].1;
                    fan.push(cur);
                }
            }
            // A list that does not end where it starts (an open chain, or several) ends with `v`
            // itself, so that it is a closed polygon whose sum does not depend on the origin.
            if fan.first() != fan.last() {
                fan.push(v as u32);
            }
            fan
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::test_meshes::{grid, lcg, tri_lattice};

    /// Area-weighted normals in f64 with, per vertex, the bound on the f32 error of either method:
    /// each of the `k` triangle cross products at `v` is off by at most `(6 + k) eps L_t^2` (edge
    /// differences, products and the running sum each rounded; `L_t` the longest edge), and
    /// normalising a sum `N` perturbed by `delta` moves it by at most `2 |delta| / |N|`, plus the
    /// normalisation's own error (a Newton-refined reciprocal square root in the vectorised path,
    /// within 4 eps; sqrt and division elsewhere): `tol_v = 2 (6 + k_v) eps sum_t L_t^2 / |N_v| + 8 eps`.
    fn reference(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<(glam::DVec3, f64)> {
        let n = positions.len();
        let mut sum = vec![glam::DVec3::ZERO; n];
        let mut scale = vec![0f64; n];
        let mut k = vec![0usize; n];
        for t in triangles
            .iter()
            .filter(|t| t.iter().all(|&v| (v as usize) < n))
        {
            let [a, b, c] = t.map(|v| positions[v as usize].as_dvec3());
            let nt = (b - a).cross(c - a);
            let l2 = (b - a)
                .length_squared()
                .max((c - a).length_squared())
                .max((c - b).length_squared());
            for &v in t {
                sum[v as usize] += nt;
                scale[v as usize] += l2;
                k[v as usize] += 1;
            }
        }
        let eps = f32::EPSILON as f64;
        sum.iter()
            .zip(&scale)
            .zip(&k)
            .map(|((s, l2), &k)| {
                let len = s.length();
                // The fan kernels' difference vectors run from a neighbour, not the centre:
                // up to two edges long, so their products' rounding is bounded with 4 l2.
                let tol = if len > 0.0 {
                    2.0 * (6 + k) as f64 * eps * 4.0 * l2 / len + 8.0 * eps
                } else {
                    f64::INFINITY
                };
                (
                    if len > 0.0 {
                        *s / len
                    } else {
                        glam::DVec3::ZERO
                    },
                    tol,
                )
            })
            .collect()
    }

    /// Both fan paths (vectorised where the CPU has it, and portable) and `vertex_normals` against
    /// the f64 reference, every vertex of `0..count` within its stated tolerance.
    fn check_fans(positions: &[Vec3], triangles: &[[u32; 3]], count: usize) {
        let truth = reference(positions, triangles);
        let mut face = vec![Vec3::ZERO; positions.len()];
        vertex_normals(positions, triangles, &mut face);
        let pa: Vec<Vec3A> = positions.iter().map(|p| Vec3A::from(*p)).collect();
        let fans = VertexFans::new(count, positions.len(), triangles);
        assert_eq!(fans.count(), count);
        let mut fast = vec![Vec3::NAN; count];
        let mut seen = vec![0; count];
        fans.normals(&pa, |v, n| {
            fast[v] = n;
            seen[v] += 1;
        });
        assert!(seen.iter().all(|&c| c == 1), "each fan vertex written once");
        let mut portable = vec![Vec3::NAN; count];
        fans.normals_portable(&pa, &mut |v, n| portable[v] = n);
        // The gather variant loads the same values into the same lanes: the same sums.
        let mut gathered = vec![Vec3::NAN; count];
        fans.normals_gather(&pa, |v, n| gathered[v] = n);
        // So do the packed positions (3 floats a vertex, 1 of padding, NaN here: never used).
        let mut packed: Vec<f32> = positions.iter().flat_map(|p| p.to_array()).collect();
        packed.push(f32::NAN);
        let mut from_packed = vec![Vec3::NAN; count];
        fans.normals_packed(&packed, |v, n| from_packed[v] = n);
        let mut packed_portable = vec![Vec3::NAN; count];
        fans.normals_packed_portable(&packed, &mut |v, n| packed_portable[v] = n);
        // Each kernel by name (the best one the CPU has where it lacks one): every vertex
        // written once, each within the reference's bound below; the AVX-512 and AVX2 kernels
        // sum the same terms in the same order, so they differ only by their normalisations,
        // each within 4 eps relative plus the final product's eps / 2 per component: at most
        // 9 eps per component of a unit normal.
        let by_kernel = [FanKernel::Portable, FanKernel::Avx2, FanKernel::Avx512].map(|k| {
            let mut out = vec![Vec3::NAN; count];
            let mut seen = vec![0; count];
            fans.normals_packed_by(k, &packed, |v, n| {
                out[v] = n;
                seen[v] += 1;
            });
            assert!(
                seen.iter().all(|&c| c == 1),
                "{k:?}: each vertex written once"
            );
            out
        });
        let [by_portable, by_avx2, by_avx512] = &by_kernel;
        let tol = 9.0 * f32::EPSILON;
        for v in 0..count {
            let (a, b) = (by_avx512[v], by_avx2[v]);
            assert!(
                (a - b).abs().max_element() <= tol || (a.is_nan() && b.is_nan()),
                "AVX-512 vs AVX2 v={v}: {a} vs {b}"
            );
            assert!(
                (a == Vec3::ZERO) == (b == Vec3::ZERO),
                "AVX-512 vs AVX2 zero v={v}: {a} vs {b}"
            );
            let (a, b) = (by_portable[v], portable[v]);
            assert!(
                a == b || (a.is_nan() && b.is_nan()),
                "portable by name v={v}"
            );
        }
        for v in 0..count {
            let (a, b) = (packed_portable[v], portable[v]);
            assert!(
                a == b || (a.is_nan() && b.is_nan()),
                "packed portable v={v}: {a} vs {b}"
            );
        }
        // The gathers are the AVX2 kernel's loads: its normals bit for bit; the packed positions
        // (best kernel) give the Vec3A positions' (best kernel) bit for bit.
        for v in 0..count {
            for (what, other, want) in [
                ("gather", gathered[v], by_avx2[v]),
                ("packed", from_packed[v], fast[v]),
            ] {
                assert!(
                    other == want || (other.is_nan() && want.is_nan()),
                    "{what} v={v}: {other} vs {want}"
                );
            }
        }
        for v in 0..count {
            let (t, tol) = truth[v];
            for (what, got) in [
                ("fans", fast[v]),
                ("portable", portable[v]),
                ("face", face[v]),
                ("avx2", by_avx2[v]),
                ("avx512", by_avx512[v]),
            ] {
                if tol.is_finite() && tol < 0.1 {
                    let err = (got.as_dvec3() - t).length();
                    assert!(
                        err <= tol,
                        "{what} v={v}: {got} vs {t}, err {err:e} > tol {tol:e}"
                    );
                } else {
                    // Sum (nearly) zero: only ask for a finite result of length 0 or 1.
                    let l = got.length();
                    assert!(l == 0.0 || (l - 1.0).abs() < 1e-5, "{what} v={v}: {got}");
                }
            }
        }
    }

    #[test]
    fn fans_match_reference_on_generated_meshes() {
        // Open sheets (boundary fans), bumps, jitter, and a sheet far from the origin.
        let g = grid(23, 17, 0.4, 0.3, 3);
        check_fans(&g.positions, &g.triangles, g.positions.len());
        let t = tri_lattice(19, 21, 0.25, 5);
        check_fans(&t.positions, &t.triangles, t.positions.len());
        let far: Vec<Vec3> = g
            .positions
            .iter()
            .map(|p| *p * 0.01 + Vec3::new(100.0, -50.0, 30.0))
            .collect();
        check_fans(&far, &g.triangles, far.len());
        // Only some vertices with fans; their neighbours beyond `count` are read, not written.
        check_fans(&g.positions, &g.triangles, 100);
        // Random triangles over random points: non-manifold fans of any shape.
        let mut seed = 11u64;
        let p: Vec<Vec3> = (0..60)
            .map(|_| Vec3::new(lcg(&mut seed), lcg(&mut seed), lcg(&mut seed)))
            .collect();
        let tris: Vec<[u32; 3]> = (0..300)
            .map(|_| [0; 3].map(|_| ((lcg(&mut seed) + 1.0) * 30.0) as u32 % 60))
            .collect();
        check_fans(&p, &tris, p.len());
    }

    #[test]
    fn fans_match_reference_on_a_closed_mesh() {
        // A UV sphere: closed fans everywhere, poles of high valence.
        let (rings, segs) = (12u32, 20u32);
        let mut p = vec![Vec3::Z, -Vec3::Z];
        for r in 1..rings {
            let th = std::f32::consts::PI * r as f32 / rings as f32;
            for s in 0..segs {
                let ph = std::f32::consts::TAU * s as f32 / segs as f32;
                p.push(Vec3::new(
                    th.sin() * ph.cos(),
                    th.sin() * ph.sin(),
                    th.cos(),
                ));
            }
        }
        let at = |r: u32, s: u32| 2 + (r - 1) * segs + s % segs;
        let mut t = Vec::new();
        for s in 0..segs {
            t.push([0, at(1, s), at(1, s + 1)]);
            t.push([1, at(rings - 1, s + 1), at(rings - 1, s)]);
            for r in 1..rings - 1 {
                t.push([at(r, s), at(r + 1, s), at(r + 1, s + 1)]);
                t.push([at(r, s), at(r + 1, s + 1), at(r, s + 1)]);
            }
        }
        check_fans(&p, &t, p.len());
        // Outward: the normal at a vertex of a unit sphere is close to its position.
        let pa: Vec<Vec3A> = p.iter().map(|q| Vec3A::from(*q)).collect();
        VertexFans::new(p.len(), p.len(), &t).normals(&pa, |v, n| {
            assert!(n.dot(p[v]) > 0.95, "v={v}: {n} at {}", p[v]);
        });
    }

    #[test]
    fn fans_give_zero_for_degenerate_isolated_and_bad() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::new(2.0, 0.0, 0.0), Vec3::ONE];
        let t = [[0, 1, 2], [0, 1, 7], [1, 1, 2]];
        let pa: Vec<Vec3A> = p.iter().map(|q| Vec3A::from(*q)).collect();
        let fans = VertexFans::new(4, 4, &t);
        assert_eq!(fans.position_count(), 4);
        let mut out = [Vec3::ONE; 4];
        fans.normals(&pa, |v, n| out[v] = n);
        assert!(out.iter().all(|n| *n == Vec3::ZERO), "{out:?}");
        let mut out = [Vec3::ONE; 4];
        fans.normals_portable(&pa, &mut |v, n| out[v] = n);
        assert!(out.iter().all(|n| *n == Vec3::ZERO), "{out:?}");
        let mut packed: Vec<f32> = p.iter().flat_map(|q| q.to_array()).collect();
        packed.push(0.0);
        for k in [FanKernel::Portable, FanKernel::Avx2, FanKernel::Avx512] {
            let mut out = [Vec3::ONE; 4];
            fans.normals_packed_by(k, &packed, |v, n| out[v] = n);
            assert!(out.iter().all(|n| *n == Vec3::ZERO), "{k:?}: {out:?}");
        }
        let none = VertexFans::new(0, 0, &[]);
        none.normals(&[], |_, _| unreachable!("no fans"));
    }

    #[test]
    fn kernel_choice_runs_only_what_the_cpu_has() {
        let best = FanKernel::best();
        assert!(best.supported(), "{best:?}");
        assert!(FanKernel::Portable.supported());
        for k in [FanKernel::Portable, FanKernel::Avx2, FanKernel::Avx512] {
            let expected = if k.supported() { k } else { best };
            assert_eq!(k.available(), expected, "{k:?}");
        }
        // The AVX2 kernel needs AVX2 and FMA, the AVX-512 one AVX-512F on top.
        assert!(!FanKernel::Avx512.supported() || FanKernel::Avx2.supported());
    }

    #[test]
    fn flat_quad_points_up_and_weights_by_area() {
        // Two triangles of a unit square in the xy plane, CCW seen from +z.
        let p = [
            Vec3::ZERO,
            Vec3::X,
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::Y,
            Vec3::new(5.0, 5.0, 5.0),
        ];
        let t = [[0, 1, 2], [0, 2, 3]];
        let mut out = [Vec3::NAN; 5];
        vertex_normals(&p, &t, &mut out);
        for n in &out[..4] {
            assert!((*n - Vec3::Z).length() < 1e-6);
        }
        assert_eq!(out[4], Vec3::ZERO, "isolated vertex gets zero");
    }

    #[test]
    fn area_weighting_on_a_roof() {
        // Vertex 0 is shared by a big triangle in the xy plane (area 2) and a small one in the xz
        // plane (area 0.5): the normal is (2 z + 0.5 (-y)) normalised... computed analytically.
        let p = [
            Vec3::ZERO,
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
        ];
        // (p1 - p0) x (p2 - p0) = 4 z (twice the area 2); (p3 - p0) x (p1 - p0) = (0,0,1)x(2,0,0) = 2 y.
        let t = [[0, 1, 2], [0, 3, 1]];
        let mut out = [Vec3::ZERO; 4];
        vertex_normals(&p, &t, &mut out);
        let expect = Vec3::new(0.0, 2.0, 4.0).normalize();
        assert!((out[0] - expect).length() < 1e-6, "{}", out[0]);
    }

    #[test]
    fn degenerate_and_bad_triangles_give_zero_not_nan() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::new(2.0, 0.0, 0.0)];
        let t = [[0, 1, 2], [0, 1, 7]];
        let mut out = [Vec3::ONE; 3];
        vertex_normals(&p, &t, &mut out);
        assert!(out.iter().all(|n| *n == Vec3::ZERO));
    }
}
