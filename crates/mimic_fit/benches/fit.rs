//! Criterion benchmark of the CANDIDE-3 fitter: one warm-started frame, and a cold start, on a
//! synthetic CANDIDE-3 performance seen through the `kinect-gfe100` correspondences (70 points,
//! 0.5 px pixel noise, depth missing on a third of the points). Inputs are built outside the timed
//! closures.

#![allow(
    clippy::unwrap_used,
    reason = "a bench: a failed unwrap is the failure report"
)]

use criterion::{Criterion, criterion_group, criterion_main};
use glam::{DQuat, DVec2, DVec3};
use mimic_fit::{AUV_COUNT, Camera, Candide3, FitSettings, Fitter, PointObservation, Pose};
use std::hint::black_box;
use std::path::PathBuf;

fn setup() -> (Fitter, Vec<Vec<PointObservation>>) {
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let bytes = std::fs::read(repo.join("configs/models/candide3/candide3.wfm")).unwrap();
    let model = Candide3::parse(&String::from_utf8_lossy(&bytes)).unwrap();
    let layout =
        mimic_assets::load_layout(&repo.join("configs/layouts/kinect-gfe100.toml")).unwrap();
    let corr = layout.candide_correspondences;
    let camera = Camera::KINECT_V1_COLOUR;
    let fitter = Fitter::new(
        model,
        &corr,
        layout.point_count,
        camera,
        FitSettings::default(),
    )
    .unwrap();
    let mut rng = mimic_testkit::Lcg::new(7);
    let mut noise = || rng.next_f64();
    let mut verts = Vec::new();
    let frames = (0..60)
        .map(|i| {
            let t = i as f64 / 15.0;
            let pose = Pose {
                rotation: DQuat::from_rotation_y(0.2 * t.sin()),
                translation: DVec3::new(0.0, 0.0, -1.2),
                scale: 0.095,
            };
            let au: Vec<f64> = (0..AUV_COUNT)
                .map(|k| 0.3 * (t + k as f64).sin().max(0.0))
                .collect();
            fitter.vertices(&pose, &au, &[], &mut verts);
            let mut frame = vec![PointObservation::default(); layout.point_count];
            for c in &corr {
                let x: DVec3 = c
                    .blend()
                    .unwrap()
                    .iter()
                    .map(|&(v, w)| verts[v] * f64::from(w))
                    .sum();
                let pixel = camera.project(x) + DVec2::new(noise(), noise()) * 0.5;
                let position = (noise() > -0.33).then(|| camera.back_project(pixel, -x.z));
                frame[c.point] = PointObservation {
                    pixel: Some(pixel),
                    position,
                };
            }
            frame
        })
        .collect();
    (fitter, frames)
}

fn bench(c: &mut Criterion) {
    let (mut fitter, frames) = setup();
    let mut g = c.benchmark_group("candide3_fit");
    let mut i = 0;
    g.bench_function("warm_frame", |b| {
        b.iter(|| {
            i = (i + 1) % frames.len();
            black_box(fitter.fit(black_box(&frames[i])))
        })
    });
    g.bench_function("cold_frame", |b| {
        b.iter(|| {
            fitter.reset();
            black_box(fitter.fit(black_box(&frames[0])))
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
