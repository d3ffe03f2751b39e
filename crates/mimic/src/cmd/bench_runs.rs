//! `mimic bench`'s runs of several retargeters: one per fan kernel stepped alternately (an A/B
//! in the step), and many sessions at once (throughput).

use super::bench::Args;
use anyhow::Context;
use mimic_retarget::{FrameStatus, Stage, StageSamples, elapsed_ns};
use serde_json::json;
use std::time::Instant;

/// The step with each fan kernel (normals) the CPU has, two retargeters stepped alternately on
/// the same frames so that both see the same VM speed states; `None` where the CPU has no
/// AVX-512 (nothing to compare). Reports the median normals stage and whole step of each.
pub(crate) fn bench_fan_kernels(
    args: &Args,
    p: &crate::cmd::setup::Prepared,
    frames: &[mimic_types::LandmarkFrame],
    span_us: i64,
) -> anyhow::Result<Option<serde_json::Value>> {
    use mimic_solve::normals::FanKernel;
    if !FanKernel::Avx512.supported() {
        return Ok(None);
    }
    let basis = std::sync::Arc::new(p.retargeter.basis().clone());
    let kernels = [FanKernel::Avx2, FanKernel::Avx512];
    let mut runs = kernels.map(|k| {
        let mut settings = args.pipeline.settings();
        settings.fan_kernel = Some(k);
        mimic_retarget::Retargeter::new(&p.rig, &p.layout, basis.clone(), settings)
            .map(|r| (r.new_output(), r, StageSamples::with_capacity(args.steps)))
    });
    for r in &runs {
        if let Err(e) = r {
            anyhow::bail!("fan kernel retargeter: {e}");
        }
    }
    let mut runs: Vec<_> = runs.iter_mut().filter_map(|r| r.as_mut().ok()).collect();
    for k in 0..args.steps.max(100) {
        let mut f = frames[k % frames.len()].clone();
        f.timestamp_us += (k / frames.len()) as i64 * span_us;
        for (out, r, samples) in runs.iter_mut() {
            let t = Instant::now();
            let status = r.step(&f, out);
            let ns = elapsed_ns(t);
            if status == FrameStatus::Tracked {
                samples.push(ns, &out.times);
            }
        }
    }
    let mut report = serde_json::Map::new();
    for (kernel, (_, _, samples)) in kernels.iter().zip(runs.iter_mut()) {
        let (stages, step) = samples.summary();
        report.insert(
            format!("{kernel:?}"),
            json!({
                "normals_median_us": stages.get(Stage::Normals).median_us,
                "step_median_us": step.median_us,
            }),
        );
    }
    Ok(Some(serde_json::Value::Object(report)))
}

/// Steps 1 session, then `k` at once, then 1 and `k` again (A/B pairs), at least 20 000 steps
/// each, on the benchmark's frames; reports the best run of each.
pub(crate) fn bench_sessions(
    args: &Args,
    p: &crate::cmd::setup::Prepared,
    frames: &[mimic_types::LandmarkFrame],
    span_us: i64,
    k: usize,
) -> anyhow::Result<serde_json::Value> {
    let basis = std::sync::Arc::new(p.retargeter.basis().clone());
    let make = |count: usize| -> anyhow::Result<Vec<mimic_retarget::Retargeter>> {
        (0..count)
            .map(|_| {
                mimic_retarget::Retargeter::new(
                    &p.rig,
                    &p.layout,
                    basis.clone(),
                    args.pipeline.settings(),
                )
                .context("session retargeter")
            })
            .collect()
    };
    // Long enough (about 0.2-2 s a run) that thread start and timer noise do not count.
    let steps = args.steps.max(20_000);
    let mut one = Vec::new();
    let mut many = Vec::new();
    for _ in 0..2 {
        one.push(mimic_retarget::throughput::step_sessions(
            make(1)?,
            frames,
            span_us,
            steps,
        )?);
        many.push(mimic_retarget::throughput::step_sessions(
            make(k)?,
            frames,
            span_us,
            steps,
        )?);
    }
    let best = |v: &[mimic_retarget::throughput::SessionsReport]| {
        v.iter().map(|r| r.frames_per_second).fold(0f64, f64::max)
    };
    let (f1, fk) = (best(&one), best(&many));
    let cores = std::thread::available_parallelism().map_or(1, |c| c.get());
    Ok(json!({
        "sessions": k,
        "cores": cores,
        "steps_per_session": steps,
        "one_frames_per_second": f1,
        "many_frames_per_second": fk,
        "speedup": if f1 > 0.0 { fk / f1 } else { 0.0 },
        "per_core_frames_per_second": fk / k.min(cores) as f64,
        "runs": {"one": one, "many": many},
    }))
}
