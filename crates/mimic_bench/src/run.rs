//! [`bench_rig`]: the step on one rig, timed per stage, with everything measured beside it.

use crate::report::{LoadAverage, RigReport, StepFigures};
use crate::{BenchError, Options, Recorded, Subject, baseline, kernels, load_average, sessions};
use mimic_retarget::{FrameStatus, Retargeter, Stage, StageSamples, elapsed_ns};
use std::sync::Arc;
use std::time::Instant;

/// Times `options.steps` tracked steps of `subject` over `recorded` (looped), then the
/// baselines, the kernel variants, and what `options` adds (sessions, numpy).
pub fn bench_rig(
    subject: &mut Subject<'_>,
    recorded: &Recorded,
    options: &Options,
) -> Result<RigReport, BenchError> {
    let load_start = load_average();
    let (mut samples, d) = time_steps(subject.retargeter, recorded, options.steps)?;
    let (stages, step) = samples.summary();
    let rig = subject.rig;
    let basis = subject.retargeter.basis();
    let input = baseline::Inputs {
        basis,
        positions: &rig.mesh.positions,
        triangles: &rig.mesh.triangles,
        d: &d,
    };
    let (baseline, floor) = baseline::run(
        &input,
        (options.steps / 4).max(50),
        stages.get(Stage::Deform).median_us,
        stages.get(Stage::Normals).median_us,
    );
    let numpy = if options.numpy {
        let moving = basis.moving_rows(rig.mesh.vertex_count());
        Some(crate::numpy::reference(basis, &moving.rows)?)
    } else {
        None
    };
    let kernels = kernels::run(subject, recorded, options.steps)?;
    let sessions = match options.sessions {
        Some(k) if k > 0 => Some(run_sessions(subject, recorded, options.steps, k)?),
        _ => None,
    };
    let record_cost = match (options.sessions, &options.record_cost) {
        (Some(k), Some(dir)) if k > 0 => {
            Some(run_record_cost(subject, recorded, options.steps, k, dir)?)
        }
        _ => None,
    };
    let basis = subject.retargeter.basis();
    Ok(RigReport {
        rig: rig.name.clone(),
        vertices: rig.mesh.vertex_count(),
        moving_vertices: subject.retargeter.moving_vertex_count(),
        controls: basis.control_count(),
        solver: serde_json::to_value(subject.solver)?,
        basis_setup_ms: subject.basis_time.as_secs_f64() * 1e3,
        recording: recorded.name.clone(),
        steps: samples.steps(),
        stages,
        step: StepFigures {
            median_us: step.median_us,
            p99_us: step.p99_us,
            frames_per_second: step.per_second(),
        },
        baseline,
        floor,
        numpy,
        vector_kernels_in_step: kernels,
        sessions,
        record_cost,
        load_average: LoadAverage {
            start: load_start,
            end: load_average(),
        },
    })
}

/// Steps `retargeter` over the looped frames until `steps` tracked steps are timed; returns
/// their samples and the last frame's control displacements (the baselines' input).
fn time_steps(
    retargeter: &mut Retargeter,
    recorded: &Recorded,
    steps: usize,
) -> Result<(StageSamples, Vec<glam::Vec3>), BenchError> {
    let frames = &recorded.frames;
    if frames.is_empty() {
        return Err(BenchError::NoFrames(recorded.name.clone()));
    }
    let span_us = recorded.span_us();
    let mut out = retargeter.new_output();
    let mut samples = StageSamples::with_capacity(steps);
    let mut k = 0usize;
    while samples.steps() < steps {
        if k >= 100 * steps.max(100) {
            return Err(BenchError::TooFewTracked(recorded.name.clone()));
        }
        let mut f = frames[k % frames.len()].clone();
        f.timestamp_us += (k / frames.len()) as i64 * span_us;
        let t = Instant::now();
        let status = retargeter.step(&f, &mut out);
        let ns = elapsed_ns(t);
        if status == FrameStatus::Tracked {
            samples.push(ns, &out.times);
        }
        k += 1;
    }
    Ok((samples, out.displacements))
}

/// 1 session against `count` at once, one shared basis, at least 20 000 steps a run (about
/// 0.2-2 s, so that thread start and timer noise do not count).
fn run_sessions(
    subject: &Subject<'_>,
    recorded: &Recorded,
    steps: usize,
    count: usize,
) -> Result<sessions::SessionsComparison, BenchError> {
    let basis = Arc::new(subject.retargeter.basis().clone());
    let make = || {
        let settings = subject.settings.clone();
        Retargeter::new(subject.rig, subject.layout, basis.clone(), settings)
    };
    let span = recorded.span_us();
    let steps = steps.max(20_000);
    Ok(sessions::compare_sessions(
        make,
        &recorded.frames,
        span,
        steps,
        count,
    )?)
}

/// `count` sessions at once with no recording and with each record mode, 3 rounds in turn, at
/// least 5 000 steps a session a run.
fn run_record_cost(
    subject: &Subject<'_>,
    recorded: &Recorded,
    steps: usize,
    count: usize,
    dir: &std::path::Path,
) -> Result<crate::record_cost::RecordCost, BenchError> {
    let basis = Arc::new(subject.retargeter.basis().clone());
    let make = || {
        let settings = subject.settings.clone();
        Retargeter::new(subject.rig, subject.layout, basis.clone(), settings)
    };
    Ok(crate::record_cost::compare_recording(
        make,
        &recorded.frames,
        recorded.span_us(),
        steps.max(5_000),
        count,
        dir,
        3,
    )?)
}
