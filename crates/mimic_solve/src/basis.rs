//! The deformation basis `B` (n vertices x m controls) and its per-frame application `u = B d`.

use glam::Vec3;

/// Controls up to which [`Basis::apply`] transposes `d` on the stack and takes the vectorised path.
const STACK_CONTROLS: usize = 64;

/// Lanes of the vectorised inner loop (one AVX register of f32).
const LANES: usize = 8;

/// An n x m deformation basis, f32, row-major: vertex `i` moves by `sum_j B[i, j] * d[j]`.
///
/// The same matrix serves x, y and z. Rows of frozen vertices are zero.
#[derive(Clone, Debug, PartialEq)]
pub struct Basis {
    vertex_count: usize,
    control_count: usize,
    data: Vec<f32>,
}

impl Basis {
    /// Wraps a row-major `vertex_count x control_count` matrix; `None` if the length does not match.
    pub fn from_row_major(
        vertex_count: usize,
        control_count: usize,
        data: Vec<f32>,
    ) -> Option<Self> {
        (vertex_count.checked_mul(control_count)? == data.len()).then_some(Self {
            vertex_count,
            control_count,
            data,
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
        let mut dx = [0f32; STACK_CONTROLS];
        let mut dy = [0f32; STACK_CONTROLS];
        let mut dz = [0f32; STACK_CONTROLS];
        for (j, v) in d.iter().enumerate() {
            dx[j] = v.x;
            dy[j] = v.y;
            dz[j] = v.z;
        }
        let (dx, dy, dz) = (&dx[..m], &dy[..m], &dz[..m]);
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the CPU supports AVX2 and FMA, checked just above; the function is otherwise safe.
            unsafe { apply_soa_avx2_fma(&self.data, m, dx, dy, dz, out) };
            return;
        }
        apply_soa::<false>(&self.data, m, dx, dy, dz, out);
    }
}

/// [`apply_soa`] compiled for AVX2 + FMA (8 lanes, fused multiply-add).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn apply_soa_avx2_fma(b: &[f32], m: usize, dx: &[f32], dy: &[f32], dz: &[f32], out: &mut [Vec3]) {
    apply_soa::<true>(b, m, dx, dy, dz, out);
}

/// Row-wise dot products of `B` with the three coordinate arrays of `d`, in `LANES` partial sums.
///
/// `FUSED` uses `mul_add`, which is only fast where the target has FMA.
#[inline(always)]
fn apply_soa<const FUSED: bool>(
    b: &[f32],
    m: usize,
    dx: &[f32],
    dy: &[f32],
    dz: &[f32],
    out: &mut [Vec3],
) {
    let full = m / LANES * LANES;
    let (dxh, dxt) = dx.split_at(full);
    let (dyh, dyt) = dy.split_at(full);
    let (dzh, dzt) = dz.split_at(full);
    let madd = |a: f32, b: f32, c: f32| if FUSED { a.mul_add(b, c) } else { a * b + c };
    for (row, o) in b.chunks_exact(m).zip(out.iter_mut()) {
        let (head, tail) = row.split_at(full);
        let mut ax = [0f32; LANES];
        let mut ay = [0f32; LANES];
        let mut az = [0f32; LANES];
        for (((r, x), y), z) in head
            .chunks_exact(LANES)
            .zip(dxh.chunks_exact(LANES))
            .zip(dyh.chunks_exact(LANES))
            .zip(dzh.chunks_exact(LANES))
        {
            for l in 0..LANES {
                ax[l] = madd(r[l], x[l], ax[l]);
                ay[l] = madd(r[l], y[l], ay[l]);
                az[l] = madd(r[l], z[l], az[l]);
            }
        }
        let mut s = Vec3::new(hsum(&ax), hsum(&ay), hsum(&az));
        for (((r, x), y), z) in tail.iter().zip(dxt).zip(dyt).zip(dzt) {
            s += Vec3::new(*x, *y, *z) * *r;
        }
        *o = s;
    }
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

    /// Deterministic pseudo-random values in [-1, 1) (64-bit LCG).
    fn lcg(seed: &mut u64) -> f32 {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*seed >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    }

    #[test]
    fn apply_matches_f64_reference_for_many_shapes() {
        let mut seed = 7u64;
        for &(n, m) in &[
            (1usize, 1usize),
            (5, 7),
            (13, 8),
            (33, 38),
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
                }
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
