//! Criterion benchmark of the whole `Retargeter::step` (positions and normals) on the shipped
//! benchmark rigs: `ict-face-3k` (3 000 vertices, all moving, the source method's scale) and
//! `ict-face` (26 719 vertices, 12 223 moving), driven by the frames of
//! `recordings/a_yn_question.kinect121.jsonl` looped; and the deform kernel alone on the same
//! rigs (`mimic_solve::deform::MovingDeform`). `cargo test --benches` smoke-runs the same code.
//! `mimic bench` reports the same step per stage with in-process baselines (docs/performance.md).

#![allow(
    clippy::unwrap_used,
    reason = "a bench: a failed unwrap is the failure report"
)]

use criterion::{Criterion, criterion_group, criterion_main};
use glam::{Vec3, Vec3A};
use mimic_retarget::{FrameStatus, RetargetSettings, Retargeter};
use mimic_solve::build_basis;
use mimic_solve::deform::MovingDeform;
use mimic_types::LandmarkFrame;
use std::hint::black_box;
use std::path::PathBuf;
use std::sync::Arc;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn frames(point_count: usize) -> Vec<LandmarkFrame> {
    let path = repo().join("recordings/a_yn_question.kinect121.jsonl");
    let mut reader = mimic_capture::RecordingReader::open(&path, Some(point_count)).unwrap();
    let mut frames = Vec::new();
    while let Some(f) = reader.next_frame() {
        frames.push(f.unwrap().frame);
    }
    frames
}

fn step(c: &mut Criterion) {
    let layout = mimic_assets::load_layout(&repo().join("configs/layouts/kinect121.toml")).unwrap();
    let frames = frames(layout.point_count);
    let span = frames.last().unwrap().timestamp_us - frames[0].timestamp_us + 33_333;
    for name in ["ict-face-3k", "ict-face"] {
        let rig =
            mimic_assets::load_rig(&repo().join(format!("configs/rigs/{name}.toml"))).unwrap();
        let basis = Arc::new(build_basis(&rig, &rig.solver).unwrap());
        let settings = RetargetSettings {
            positions: true,
            normals: true,
            ..RetargetSettings::default()
        };
        let mut rt = Retargeter::new(&rig, &layout, basis.clone(), settings).unwrap();
        let mut out = rt.new_output();
        let mut frame = frames[0].clone();
        // Warm up: the neutral and the source-to-target fit.
        for f in &frames {
            frame.clone_from(f);
            frame.timestamp_us -= span;
            rt.step(&frame, &mut out);
        }
        let mut k = 0usize;
        c.bench_function(&format!("step/{name}"), |b| {
            b.iter(|| {
                let src = &frames[k % frames.len()];
                frame.clone_from(src);
                frame.timestamp_us = src.timestamp_us + (k / frames.len()) as i64 * span;
                k += 1;
                black_box(rt.step(&frame, &mut out) == FrameStatus::Tracked)
            })
        });
        let deform = MovingDeform::new(&basis, &rig.mesh.positions);
        let mut compact = vec![Vec3A::ZERO; deform.rows().len()];
        let mut positions = rig.mesh.positions.clone();
        let d: Vec<Vec3> = (0..basis.control_count())
            .map(|j| Vec3::new(0.01 * j as f32, -0.02, 0.005))
            .collect();
        c.bench_function(&format!("deform/{name}"), |b| {
            b.iter(|| deform.deform(black_box(&d), &mut compact, &mut positions))
        });
        let mut u = vec![Vec3::ZERO; basis.vertex_count()];
        c.bench_function(&format!("apply_every_vertex/{name}"), |b| {
            b.iter(|| basis.apply(black_box(&d), &mut u))
        });
        if let Some(steps) = std::env::var("MIMIC_BENCH_AB")
            .ok()
            .and_then(|v| v.parse().ok())
        {
            ab(name, &rig, &layout, &basis, &frames, steps);
        }
    }
}

/// `MIMIC_BENCH_AB=STEPS`: in one loop, interleaved (so each variant sees the same machine
/// state): the whole step with f32 and with f16 weights (two retargeters on the same frames, the
/// step's deform and normals stages of each), the deform kernel with both weights and by its AVX2
/// and AVX-512 kernels, the fan pass over every vertex by its AVX2 and AVX-512 kernels, the dense
/// baseline (`Basis::apply` over
/// every vertex), and one read of each deform's bytes (the floor); medians in us.
fn ab(
    name: &str,
    rig: &mimic_types::Rig,
    layout: &mimic_types::Layout,
    basis: &Arc<mimic_solve::Basis>,
    frames: &[LandmarkFrame],
    steps: usize,
) {
    use mimic_retarget::{Stage, StageSamples, elapsed_ns, median_p99_us};
    use mimic_solve::{VectorKernel, normals::VertexFans};
    use std::time::Instant;
    let n = rig.mesh.vertex_count();
    let span = frames.last().unwrap().timestamp_us - frames[0].timestamp_us + 33_333;
    let retargeter = |f16_weights: bool| {
        let settings = RetargetSettings {
            f16_weights,
            ..RetargetSettings::default()
        };
        let mut rt = Retargeter::new(rig, layout, basis.clone(), settings).unwrap();
        let mut out = rt.new_output();
        let mut frame = frames[0].clone();
        for f in frames {
            frame.clone_from(f);
            frame.timestamp_us -= span;
            rt.step(&frame, &mut out);
        }
        (rt, out)
    };
    let mut steppers = [retargeter(false), retargeter(true)];
    let mut stage_samples = [
        StageSamples::with_capacity(steps),
        StageSamples::with_capacity(steps),
    ];
    let d: Vec<Vec3> = steppers[0].1.displacements.clone();
    let full = MovingDeform::new(basis, &rig.mesh.positions);
    let half = MovingDeform::new(basis, &rig.mesh.positions)
        .with_f16_weights()
        .unwrap();
    let mut packed_rows = vec![0f32; 3 * full.rows().len()];
    let mut positions = rig.mesh.positions.clone();
    let fans = VertexFans::new(n, n, &rig.mesh.triangles);
    let mut packed: Vec<f32> = positions.iter().flat_map(|p| p.to_array()).collect();
    packed.push(0.0);
    let mut normals = vec![Vec3::ZERO; n];
    let mut u = vec![Vec3::ZERO; n];
    let floors = [full.bytes_read(), half.bytes_read()].map(|b| vec![1f32; b / 4]);
    let names = [
        "step, f32 weights",
        "step, f16 weights",
        "deform, f32 weights",
        "deform, f16 weights",
        "fans every vertex, AVX2",
        "fans every vertex, AVX-512",
        "dense: apply every vertex",
        "floor: read f32 deform bytes",
        "floor: read f16 deform bytes",
        "deform, f32 weights, AVX2",
        "deform, f32 weights, AVX-512",
    ];
    let mut t: [Vec<u32>; 11] = Default::default();
    let mut f16_max = 0f32;
    for k in 0..steps {
        for (w, (rt, out)) in steppers.iter_mut().enumerate() {
            let src = &frames[k % frames.len()];
            let mut frame = src.clone();
            frame.timestamp_us = src.timestamp_us + (k / frames.len()) as i64 * span;
            let s = Instant::now();
            let tracked = rt.step(&frame, out) == FrameStatus::Tracked;
            let ns = elapsed_ns(s);
            if tracked {
                t[w].push(ns);
                stage_samples[w].push(ns, &out.times);
            }
        }
        // How far the f16 weights move the mesh (rig units), untimed.
        let [(_, a), (_, b)] = &steppers;
        for (p, q) in a.positions.iter().zip(&b.positions) {
            f16_max = f16_max.max((*p - *q).abs().max_element());
        }
        let mut time = |k: usize, f: &mut dyn FnMut()| {
            let s = Instant::now();
            f();
            t[k].push(elapsed_ns(s));
        };
        time(2, &mut || {
            full.deform_packed(black_box(&d), &mut packed_rows, &mut positions)
        });
        time(3, &mut || {
            half.deform_packed(black_box(&d), &mut packed_rows, &mut positions)
        });
        time(4, &mut || {
            fans.normals_packed_by(VectorKernel::Avx2, &packed, |v, x| normals[v] = x)
        });
        time(5, &mut || {
            fans.normals_packed_by(VectorKernel::Avx512, &packed, |v, x| normals[v] = x)
        });
        time(6, &mut || basis.apply(black_box(&d), &mut u));
        time(7, &mut || {
            black_box(read_all(black_box(&floors[0])));
        });
        time(8, &mut || {
            black_box(read_all(black_box(&floors[1])));
        });
        time(9, &mut || {
            let d = black_box(&d);
            full.deform_packed_by(VectorKernel::Avx2, d, &mut packed_rows, &mut positions)
        });
        time(10, &mut || {
            let d = black_box(&d);
            full.deform_packed_by(VectorKernel::Avx512, d, &mut packed_rows, &mut positions)
        });
    }
    black_box((&normals, &positions, &packed_rows, &u));
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    eprintln!(
        "A/B on {name} ({} moving rows, {n} fans; f32 deform {} kB, f16 {} kB; kernels in \
         the step: deform {:?}, normals {:?}), {steps} interleaved steps, load {}, medians:",
        full.rows().len(),
        full.bytes_read() / 1000,
        half.bytes_read() / 1000,
        VectorKernel::best_for_deform(),
        VectorKernel::best_for_normals(),
        load.split_whitespace()
            .take(3)
            .collect::<Vec<_>>()
            .join(" ")
    );
    for (what, mut v) in names.iter().zip(t) {
        eprintln!("  {what:<32} {:>8.2} us", median_p99_us(&mut v).0);
    }
    eprintln!("  f16 against f32 weights: largest coordinate difference {f16_max:e} (rig units)");
    for (what, s) in ["f32", "f16"].iter().zip(&mut stage_samples) {
        let (stages, _) = s.summary();
        eprintln!(
            "  in the step, {what} weights: deform {:.2} us, normals {:.2} us",
            stages.get(Stage::Deform).median_us,
            stages.get(Stage::Normals).median_us
        );
    }
}

/// Sum of `v` in 16 independent partial sums (vectorised): one read of every value, the
/// bandwidth floor of a kernel that reads the same bytes (as `mimic bench`'s).
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

fn config() -> Criterion {
    if cfg!(debug_assertions) {
        Criterion::default()
            .sample_size(10)
            .warm_up_time(std::time::Duration::from_millis(10))
            .measurement_time(std::time::Duration::from_millis(50))
    } else {
        Criterion::default()
    }
}

criterion_group! {
    name = benches;
    config = config();
    targets = step
}
criterion_main!(benches);
