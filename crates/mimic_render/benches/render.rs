//! Headless frames per second on the ICT rig: morph + normals compute passes, draw, and the RGBA
//! readback, at 256x256 and 512x512; and the deform passes alone with a positions readback.
//!
//! `cargo bench -p mimic_render --bench render` (lavapipe unless a GPU is present).

#![allow(
    clippy::unwrap_used,
    reason = "a bench: a failed unwrap is the failure report"
)]

use criterion::{Criterion, criterion_group, criterion_main};
use glam::Vec3;
use mimic_render::{Camera, Deform, Renderer, View};
use std::hint::black_box;
use std::path::PathBuf;

fn bench(c: &mut Criterion) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../configs/rigs/ict-face.toml");
    let rig = mimic_assets::load_rig(&path).expect("ICT rig");
    let basis = mimic_solve::build_basis(&rig, &rig.solver).expect("ICT basis");
    let m = basis.control_count();
    // A mid-size expression: every control moved by up to 5 mm.
    let d: Vec<Vec3> = (0..m)
        .map(|j| {
            let t = j as f32;
            Vec3::new((t * 0.7).sin(), (t * 1.3).cos(), (t * 0.4).sin()) * 0.5
        })
        .collect();
    let (lo, hi) = rig.mesh.bounds().expect("mesh");
    let mut group = c.benchmark_group("render_ict");
    group.sample_size(20);
    for size in [256u32, 512] {
        let r = Renderer::new(size, size).expect("adapter");
        eprintln!("adapter: {}", r.adapter());
        let gpu = r
            .upload_rig(&rig.mesh.positions, &rig.mesh.triangles, Some(&basis))
            .expect("upload");
        let view = View::lit(Camera::front(lo, hi));
        group.bench_function(format!("frame_{size}x{size}"), |b| {
            b.iter(|| black_box(r.render(&gpu, Deform::Controls(&d), &view).expect("render")))
        });
        if size == 256 {
            group.bench_function("deform_and_read_positions", |b| {
                b.iter(|| {
                    r.deform(&gpu, Deform::Controls(&d)).expect("deform");
                    black_box(r.read_positions(&gpu).expect("read"))
                })
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
