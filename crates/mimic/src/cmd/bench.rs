//! `mimic bench`: per-stage timing of the retarget pipeline on a rig, with an in-process baseline.

use crate::cmd::setup::{PipelineArgs, RigArgs, fit_candide3, prepare};
use anyhow::Context;
use glam::Vec3;
use mimic_assets::ConfigDirs;
use mimic_fit::capture::{CaptureFrame, FitSummary};
use mimic_retarget::{FrameStatus, Stage, StageSamples, elapsed_ns, median_p99_us};
use serde_json::json;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `mimic bench`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub rig: RigArgs,
    #[command(flatten)]
    pub pipeline: PipelineArgs,
    /// Recording whose frames drive the benchmark (looped).
    #[arg(long, default_value = "recordings/a_affirmative.jsonl")]
    pub recording: PathBuf,
    /// Number of timed steps.
    #[arg(long, default_value_t = 3000)]
    pub steps: usize,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Runs `mimic bench`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let recording = mimic_capture::read_recording(&args.recording, None)?;
    let layout_name = recording.header.layout.clone();
    let frames: Vec<_> = recording.frames.iter().map(|f| f.frame.clone()).collect();
    anyhow::ensure!(
        !frames.is_empty(),
        "{}: no usable frames",
        args.recording.display()
    );
    let span_us =
        frames.last().map(|f| f.timestamp_us).unwrap_or(0) - frames[0].timestamp_us + 33_333;
    let mut p = prepare(&args.rig, &args.pipeline, &layout_name)?;
    let mut out = p.retargeter.new_output();
    let mut samples = StageSamples::with_capacity(args.steps);
    let mut k = 0usize;
    let mut guard = 0usize;
    while samples.steps() < args.steps {
        let src = &frames[k % frames.len()];
        let mut f = src.clone();
        f.timestamp_us += (k / frames.len()) as i64 * span_us;
        let t = Instant::now();
        let status = p.retargeter.step(&f, &mut out);
        let ns = elapsed_ns(t);
        if status == FrameStatus::Tracked {
            samples.push(ns, &out.times);
        }
        k += 1;
        guard += 1;
        anyhow::ensure!(
            guard < 100 * args.steps.max(100),
            "too few tracked frames in {}",
            args.recording.display()
        );
    }

    // Baselines in the same process: the dense product over every vertex of the rig and
    // full-mesh normals, as a pipeline without the moving-part restriction would do, each with the
    // current kernel and with the previous one (row-pair product, face-by-face scatter normals).
    let n = p.rig.mesh.vertex_count();
    let basis = p.retargeter.basis();
    let d = out.displacements.clone();
    let mut u = vec![Vec3::ZERO; n];
    let mut normals = vec![Vec3::ZERO; n];
    let fans = mimic_solve::normals::VertexFans::new(n, n, &p.rig.mesh.triangles);
    let mut u_a = vec![glam::Vec3A::ZERO; n];
    let baseline_steps = (args.steps / 4).max(50);
    let mut base: [Vec<u32>; 4] = Default::default();
    let ns = elapsed_ns;
    for _ in 0..baseline_steps {
        let t = Instant::now();
        basis.apply(&d, &mut u);
        base[0].push(ns(t));
        let t = Instant::now();
        basis.apply_row_pairs(&d, &mut u);
        base[1].push(ns(t));
        let t = Instant::now();
        mimic_solve::vertex_normals(&u, &p.rig.mesh.triangles, &mut normals);
        base[2].push(ns(t));
        u_a.iter_mut().zip(&u).for_each(|(a, b)| *a = (*b).into());
        let t = Instant::now();
        fans.normals(&u_a, |v, nv| normals[v] = nv);
        base[3].push(ns(t));
    }
    std::hint::black_box(&normals);
    let [ba, ba_pairs, bn, bn_fans] = base.map(|mut v| median_p99_us(&mut v).0);

    let steps = samples.steps();
    let (stages, step) = samples.summary();
    let (step_m, step_p99) = (step.median_us, step.p99_us);
    let deform_m = stages.get(Stage::Deform).median_us;
    let normals_m = stages.get(Stage::Normals).median_us;
    let fit = fit_throughput(&recording)?;
    let report = json!({
        "rig": p.rig.name,
        "vertices": n,
        "moving_vertices": p.retargeter.moving_vertex_count(),
        "controls": basis.control_count(),
        "solver": serde_json::to_value(p.solver)?,
        "basis_setup_ms": p.basis_time.as_secs_f64() * 1e3,
        "recording": args.recording.display().to_string(),
        "steps": steps,
        "stages": stages,
        "step": {"median_us": step_m, "p99_us": step_p99, "frames_per_second": step.per_second()},
        "baseline": {
            "what": "dense B d over every vertex plus full-mesh normals, same process; apply and normals_fans with the current kernels, apply_row_pairs and normals with the previous ones",
            "apply_median_us": ba,
            "apply_row_pairs_median_us": ba_pairs,
            "normals_median_us": bn,
            "normals_fans_median_us": bn_fans,
            "apply_kernel_speedup": if ba > 0.0 { ba_pairs / ba } else { 0.0 },
            "normals_kernel_speedup": if bn_fans > 0.0 { bn / bn_fans } else { 0.0 },
            "deform_speedup": if deform_m > 0.0 { ba / deform_m } else { 0.0 },
            "normals_speedup": if normals_m > 0.0 { bn / normals_m } else { 0.0 },
        },
        "fit": fit.as_ref().map(|f| json!({"model": "candide3", "frames": f.frames, "lost": f.lost, "frames_per_second": f.frames_per_s, "median_residual_px": f.median_residual_px})),
        "build": if cfg!(debug_assertions) { "debug (not representative)" } else { "release" },
    });
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&report).context("report")?
        );
    } else {
        println!(
            "rig {} ({} vertices, {} moving, {} controls), basis {:.0} ms, {} steps",
            p.rig.name,
            n,
            p.retargeter.moving_vertex_count(),
            basis.control_count(),
            p.basis_time.as_secs_f64() * 1e3,
            steps
        );
        print!("{stages}");
        println!(
            "  {:<10} median {step_m:>8.1} us  p99 {step_p99:>8.1} us  ({:.0} frames/s)",
            "step",
            1e6 / step_m.max(1e-9)
        );
        println!(
            "  baseline, every vertex: apply {ba:.1} us (previous row-pair kernel {ba_pairs:.1} us), normals by fans {bn_fans:.1} us (face scatter {bn:.1} us)"
        );
        if let Some(f) = &fit {
            println!(
                "  fit CANDIDE-3 to the recording: {:.0} frames/s ({} frames, median residual {:.2} px)",
                f.frames_per_s, f.frames, f.median_residual_px
            );
        }
    }
    Ok(())
}

/// CANDIDE-3 fitting speed on a recording whose layout lists correspondences (`None` otherwise):
/// its valid 3D points only (a recording keeps no pixels of depth-less points).
fn fit_throughput(recording: &mimic_capture::Recording) -> anyhow::Result<Option<FitSummary>> {
    let configs = ConfigDirs::locate(None);
    let has_correspondences = configs
        .load_layout_named(&recording.header.layout)
        .is_ok_and(|l| !l.candide_correspondences.is_empty());
    if !has_correspondences {
        return Ok(None);
    }
    let frames: Vec<CaptureFrame> = recording
        .frames
        .iter()
        .map(|f| CaptureFrame {
            landmarks: &f.frame,
            label: f.label,
            pixels: None,
        })
        .collect();
    let fit = fit_candide3(&configs, &recording.header.layout, &frames)?;
    Ok(Some(fit.summary))
}
