//! Many sessions morphed in one GPU dispatch (`mimic_bench::BatchMorph`, what
//! `mimic bench --gpu` times): the 3k-vertex benchmark face (`ict-face-3k`, its RBF basis), 1 and
//! 64 sessions, morph and normals passes, weights uploaded every dispatch, waited for.
//!
//! `cargo bench -p mimic_bench --bench batch` (lavapipe unless a GPU is present). Without an
//! adapter it says so and times nothing; `cargo test --benches` smoke-runs it.

#![allow(
    clippy::unwrap_used,
    reason = "a bench: a failed unwrap is the failure report"
)]

use criterion::{Criterion, criterion_group, criterion_main};
use glam::Vec3;
use mimic_bench::{BatchError, BatchMorph};
use mimic_render::RenderError;
use std::path::PathBuf;

fn bench(c: &mut Criterion) {
    let path =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../configs/rigs/ict-face-3k.toml");
    let rig = mimic_assets::load_rig(&path).expect("ict-face-3k rig");
    let basis = mimic_solve::build_basis(&rig, &rig.solver).expect("ict-face-3k basis");
    let m = basis.control_count();
    let sessions_list: &[usize] = if cfg!(debug_assertions) {
        &[1, 4]
    } else {
        &[1, 64]
    };
    for &sessions in sessions_list {
        let mut batch =
            match BatchMorph::new(&basis, &rig.mesh.positions, &rig.mesh.triangles, sessions) {
                Ok(b) => b,
                Err(BatchError::Render(
                    e @ (RenderError::NoAdapter(_) | RenderError::NoDevice(_)),
                )) => {
                    eprintln!("batch bench: {e}; nothing timed");
                    return;
                }
                Err(e) => panic!("{e}"),
            };
        eprintln!("adapter: {}", batch.adapter());
        // A different mid-size expression per session: every control moved by up to 5 mm.
        let d: Vec<Vec3> = (0..sessions * m)
            .map(|k| {
                let t = k as f32;
                Vec3::new((t * 0.7).sin(), (t * 1.3).cos(), (t * 0.4).sin()) * 0.5
            })
            .collect();
        c.bench_function(&format!("batch_morph/ict-face-3k/{sessions}"), |b| {
            b.iter(|| batch.run(&d).expect("dispatch"))
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
        Criterion::default().sample_size(20)
    }
}

criterion_group! {
    name = benches;
    config = config();
    targets = bench
}
criterion_main!(benches);
