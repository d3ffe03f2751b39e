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
            ab(name, &rig, &basis, steps);
        }
    }
}

/// `MIMIC_BENCH_AB=STEPS`: the fan pass's and the deform's variants interleaved in one loop (so
/// each sees the same machine state), over the moving rows and every vertex's fan; medians in us.
fn ab(name: &str, rig: &mimic_types::Rig, basis: &mimic_solve::Basis, steps: usize) {
    use mimic_solve::normals::VertexFans;
    use std::time::Instant;
    let n = rig.mesh.vertex_count();
    let deform = MovingDeform::new(basis, &rig.mesh.positions);
    let d: Vec<Vec3> = (0..basis.control_count())
        .map(|j| Vec3::new(0.01 * j as f32, -0.02, 0.005))
        .collect();
    let mut compact = vec![Vec3A::ZERO; deform.rows().len()];
    let mut packed_rows = vec![0f32; 3 * deform.rows().len()];
    let mut positions = rig.mesh.positions.clone();
    deform.deform(&d, &mut compact, &mut positions);
    let fans = VertexFans::new(n, n, &rig.mesh.triangles);
    let wide: Vec<Vec3A> = positions.iter().map(|p| Vec3A::from(*p)).collect();
    let mut packed: Vec<f32> = positions.iter().flat_map(|p| p.to_array()).collect();
    packed.push(0.0);
    let mut normals = vec![Vec3::ZERO; n];
    let mut t: [Vec<f64>; 4] = Default::default();
    let names = [
        "deform, Vec3A copy",
        "deform, packed copy",
        "fans, Vec3A positions",
        "fans, packed positions",
    ];
    for _ in 0..steps {
        let mut time = |k: usize, f: &mut dyn FnMut()| {
            let s = Instant::now();
            f();
            t[k].push(s.elapsed().as_secs_f64() * 1e6);
        };
        time(0, &mut || {
            deform.deform(black_box(&d), &mut compact, &mut positions)
        });
        time(1, &mut || {
            deform.deform_packed(black_box(&d), &mut packed_rows, &mut positions)
        });
        time(2, &mut || fans.normals(&wide, |v, x| normals[v] = x));
        time(3, &mut || {
            fans.normals_packed(&packed, |v, x| normals[v] = x)
        });
    }
    black_box((&normals, &positions, &compact, &packed_rows));
    eprintln!(
        "A/B on {name} ({} moving rows, {n} fans), {steps} interleaved steps, medians:",
        deform.rows().len()
    );
    for (what, mut v) in names.iter().zip(t) {
        v.sort_by(f64::total_cmp);
        eprintln!("  {what:<30} {:>8.2} us", v[v.len() / 2]);
    }
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
