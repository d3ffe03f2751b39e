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
use glam::Vec3;
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
        let mut compact = vec![0f32; 3 * deform.rows().len()];
        let mut positions = rig.mesh.positions.clone();
        let d: Vec<Vec3> = (0..basis.control_count())
            .map(|j| Vec3::new(0.01 * j as f32, -0.02, 0.005))
            .collect();
        c.bench_function(&format!("deform/{name}"), |b| {
            b.iter(|| deform.deform_packed(black_box(&d), &mut compact, &mut positions))
        });
        let mut u = vec![Vec3::ZERO; basis.vertex_count()];
        c.bench_function(&format!("apply_every_vertex/{name}"), |b| {
            b.iter(|| basis.apply(black_box(&d), &mut u))
        });
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
