//! Baselines run in the same process as the step, interleaved in one loop so that each sees the
//! same machine speed state: the dense product and the face-by-face normals over every vertex
//! (what a pipeline without the moving-part restriction would do), the same with today's kernels,
//! the previous deform, the deform kernel alone, and one plain read of the bytes it reads.

use glam::{Vec3, Vec3A};
use mimic_retarget::elapsed_ns;
use mimic_solve::deform::MovingDeform;
use mimic_solve::normals::VertexFans;
use mimic_solve::{Basis, VectorKernel};
use serde::Serialize;
use std::time::Instant;

/// Medians of the baselines, microseconds, and the ratios of the step's stages against them.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Baseline {
    /// What was run.
    pub what: &'static str,
    /// `Basis::apply` over every vertex (blocked, zero block-columns skipped).
    pub apply_median_us: f64,
    /// `Basis::apply_row_pairs` over every vertex: the dense product, every weight read.
    pub apply_row_pairs_median_us: f64,
    /// `vertex_normals` (face by face, scattered) over every vertex.
    pub normals_median_us: f64,
    /// The step's fan kernel over every vertex, on packed positions.
    pub normals_fans_median_us: f64,
    /// `apply_row_pairs / apply`.
    pub apply_kernel_speedup: f64,
    /// `normals / normals_fans`.
    pub normals_kernel_speedup: f64,
    /// The dense product over the step's deform stage.
    pub deform_speedup: f64,
    /// The face-by-face normals over the step's normals stage.
    pub normals_speedup: f64,
    /// The deform kernel the step runs.
    pub deform_kernel: String,
    /// The fan kernel the step runs.
    pub normals_kernel: String,
    /// The previous deform: the blocked product over the moving rows in index order, then a pass
    /// adding the rest positions and scattering.
    pub previous_deform_median_us: f64,
    /// The step's deform kernel alone.
    pub deform_kernel_median_us: f64,
}

/// The floor: one vectorised read of the bytes the deform kernel reads.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Floor {
    /// What was run.
    pub what: &'static str,
    /// Bytes read (kept weights and rest positions).
    pub bytes: usize,
    /// Kept block-columns over all (1 for a dense basis).
    pub kept_block_columns: f64,
    /// Median of one read, microseconds.
    pub read_median_us: f64,
}

/// A mesh's rest positions and triangles, and one frame's control displacements.
pub struct Inputs<'a> {
    /// The basis of the rig.
    pub basis: &'a Basis,
    /// Rest positions.
    pub positions: &'a [Vec3],
    /// Triangles.
    pub triangles: &'a [[u32; 3]],
    /// One frame's control displacements.
    pub d: &'a [Vec3],
}

/// `a / b`, 0 where `b` is not positive.
pub(crate) fn ratio(a: f64, b: f64) -> f64 {
    if b > 0.0 { a / b } else { 0.0 }
}

/// Runs every baseline `steps` times, interleaved; the ratios against the step come from its
/// `deform` and `normals` stage medians.
pub fn run(input: &Inputs<'_>, steps: usize, deform_m: f64, normals_m: f64) -> (Baseline, Floor) {
    let (basis, n) = (input.basis, input.positions.len());
    let d = input.d;
    let mut u = vec![Vec3::ZERO; n];
    let mut normals = vec![Vec3::ZERO; n];
    let fans = VertexFans::new(n, n, input.triangles);
    let moving = basis.moving_rows(n);
    let rest_rows: Vec<Vec3A> = moving
        .rows
        .iter()
        .map(|&i| input.positions[i as usize].into())
        .collect();
    let mut u_rows = vec![Vec3::ZERO; moving.rows.len()];
    let mut local = vec![Vec3A::ZERO; moving.rows.len()];
    let mut positions = input.positions.to_vec();
    let deform = MovingDeform::new(basis, input.positions);
    let floor_buf = vec![1f32; deform.bytes_read() / 4];
    let mut u_packed = vec![0f32; 3 * n + 1];
    let mut local_packed = vec![0f32; 3 * moving.rows.len()];
    let mut base: [Vec<u32>; 7] = Default::default();
    let timed = |k: usize, base: &mut [Vec<u32>; 7], f: &mut dyn FnMut()| {
        let t = Instant::now();
        f();
        base[k].push(elapsed_ns(t));
    };
    for _ in 0..steps {
        timed(0, &mut base, &mut || basis.apply(d, &mut u));
        timed(1, &mut base, &mut || basis.apply_row_pairs(d, &mut u));
        timed(2, &mut base, &mut || {
            mimic_solve::vertex_normals(&u, input.triangles, &mut normals)
        });
        u_packed
            .chunks_exact_mut(3)
            .zip(&u)
            .for_each(|(a, b)| a.copy_from_slice(&b.to_array()));
        timed(3, &mut base, &mut || {
            fans.normals_packed(&u_packed, |v, nv| normals[v] = nv)
        });
        timed(4, &mut base, &mut || {
            moving.basis.apply(d, &mut u_rows);
            let moved = moving.rows.iter().zip(&u_rows).zip(&rest_rows);
            for (((&i, u), rest), l) in moved.zip(&mut local) {
                let q = *rest + Vec3A::from(*u);
                *l = q;
                positions[i as usize] = Vec3::from(q);
            }
        });
        timed(5, &mut base, &mut || {
            deform.deform_packed(d, &mut local_packed, &mut positions)
        });
        timed(6, &mut base, &mut || {
            std::hint::black_box(read_all(std::hint::black_box(&floor_buf)));
        });
    }
    std::hint::black_box((&normals, &positions, &local));
    let [ba, ba_pairs, bn, bn_fans, prev_deform, deform_alone, floor] =
        base.map(|mut v| mimic_retarget::median_p99_us(&mut v).0);
    let baseline = Baseline {
        what: "dense B d over every vertex plus full-mesh normals, same process; apply and normals_fans with the current kernels, apply_row_pairs and normals with the previous ones",
        apply_median_us: ba,
        apply_row_pairs_median_us: ba_pairs,
        normals_median_us: bn,
        normals_fans_median_us: bn_fans,
        apply_kernel_speedup: ratio(ba_pairs, ba),
        normals_kernel_speedup: ratio(bn, bn_fans),
        deform_speedup: ratio(ba, deform_m),
        normals_speedup: ratio(bn, normals_m),
        deform_kernel: format!("{:?}", VectorKernel::best_for_deform()),
        normals_kernel: format!("{:?}", VectorKernel::best_for_normals()),
        previous_deform_median_us: prev_deform,
        deform_kernel_median_us: deform_alone,
    };
    let floor = Floor {
        what: "one vectorised read of the bytes the deform kernel reads (kept weights and rest positions), same process",
        bytes: deform.bytes_read(),
        kept_block_columns: deform.kept_fraction(),
        read_median_us: floor,
    };
    (baseline, floor)
}

/// Sum of `v` in 16 independent partial sums (vectorised): one read of every value, the
/// bandwidth floor of a kernel that reads the same bytes.
fn read_all(v: &[f32]) -> f32 {
    let mut acc = [0f32; 16];
    let mut chunks = v.chunks_exact(16);
    for c in &mut chunks {
        for (a, x) in acc.iter_mut().zip(c) {
            *a += *x;
        }
    }
    acc.iter().sum::<f32>() + chunks.remainder().iter().sum::<f32>()
}
