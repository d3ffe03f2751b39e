//! `mimic bench`: arguments, then per rig what `mimic_bench` measures, printed as a plain
//! summary (`--detail` adds the developer figures, `--json` prints everything as JSON).

use crate::cmd::setup::{PipelineArgs, RigArgs, fit_candide3, prepare};
use anyhow::Context;
use mimic_assets::ConfigDirs;
use mimic_bench::gpu::GpuOutcome;
use mimic_bench::{Options, Recorded, Subject};
use mimic_fit::capture::{CaptureFrame, FitSummary};
use serde_json::json;
use std::path::PathBuf;

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
    /// Print the report as JSON (every figure).
    #[arg(long)]
    pub json: bool,
    /// Also print the developer figures: every stage's p99, the baselines, each kernel variant
    /// in the step, the floor, the load average.
    #[arg(long)]
    pub detail: bool,
    /// Rigs to run, one after the other (default: `ict-face-3k`, the source method's scale, then
    /// `--rig`).
    #[arg(long, value_delimiter = ',')]
    pub rigs: Vec<String>,
    /// Also step 1 and then N independent sessions at once (one named thread each, one basis
    /// shared; at least 20 000 steps each) and report frames/s and frames/s per core; with `--gpu`,
    /// the sessions in one GPU dispatch (default 100).
    #[arg(long)]
    pub sessions: Option<usize>,
    /// With --sessions: also step them while each writes its frames as a recording into DIR, in
    /// each of `mimic serve --record`'s modes (queued, written: the default, synced), against no
    /// recording (docs/reliability.md, "Crash loss").
    #[arg(long, value_name = "DIR", requires = "sessions")]
    pub record_cost: Option<PathBuf>,
    /// Also time numpy's `B @ D` (float32) over the same rows: runs `python3 tools/bench_numpy.py`.
    #[arg(long)]
    pub numpy: bool,
    /// Time the GPU pass instead: `--sessions` sessions (default 100) morphed in one wgpu compute
    /// dispatch (one basis, sessions x controls x 3 weights), positions and normals; reports the
    /// time per dispatch and sessions per frame at 60 fps. Without an adapter it says so and exits 0.
    #[arg(long)]
    pub gpu: bool,
    /// Dispatches timed by `--gpu`.
    #[arg(long, default_value_t = 50)]
    pub gpu_dispatches: usize,
}

/// Runs `mimic bench`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let rigs = if args.rigs.is_empty() {
        let mut r = vec!["ict-face-3k".to_string()];
        if args.rig.rig != "ict-face-3k" {
            r.push(args.rig.rig.clone());
        }
        r
    } else {
        args.rigs.clone()
    };
    let recording = mimic_capture::read_recording(&args.recording, None)?;
    let recorded = Recorded {
        name: args.recording.display().to_string(),
        frames: recording.frames.iter().map(|f| f.frame.clone()).collect(),
    };
    let options = Options {
        steps: args.steps,
        sessions: args.sessions,
        record_cost: args.record_cost.clone(),
        numpy: args.numpy,
    };
    let (mut reports, mut gpu) = (Vec::new(), Vec::new());
    for name in &rigs {
        let mut rig_args = args.rig.clone();
        rig_args.rig = name.clone();
        let mut p = prepare(&rig_args, &args.pipeline, &recording.header.layout)?;
        let mut subject = Subject {
            rig: &p.rig,
            layout: &p.layout,
            retargeter: &mut p.retargeter,
            settings: args.pipeline.settings(),
            solver: &p.solver,
            basis_time: p.basis_time,
        };
        if args.gpu {
            let (sessions, dispatches) = (args.sessions.unwrap_or(100), args.gpu_dispatches);
            match mimic_bench::gpu::bench_rig(&mut subject, &recorded, sessions, dispatches)? {
                GpuOutcome::NoGpu(why) => {
                    println!("mimic bench --gpu: {why}; no GPU to time, nothing measured");
                    return Ok(());
                }
                GpuOutcome::Measured(r) if !args.json => print!("{}", r.summary()),
                GpuOutcome::Measured(r) => gpu.push(r),
            }
            continue;
        }
        let report = mimic_bench::bench_rig(&mut subject, &recorded, &options)?;
        if !args.json {
            print!("{}", report.summary());
            if args.detail {
                print!("{}", report.detail());
            }
        }
        reports.push(report);
    }
    if args.gpu {
        if args.json {
            println!("{}", serde_json::to_string_pretty(&json!({ "gpu": gpu }))?);
        }
        return Ok(());
    }
    let fit = fit_throughput(&recording)?;
    if args.json {
        let report = json!({
            "rigs": reports,
            "fit": fit.as_ref().map(FitSummary::json),
            "build": if cfg!(debug_assertions) { "debug (not representative)" } else { "release" },
        });
        println!(
            "{}",
            serde_json::to_string_pretty(&report).context("report")?
        );
    } else if let Some(f) = &fit {
        println!("{}", f.speed_line());
    }
    Ok(())
}

/// CANDIDE-3 fitting speed on a recording whose layout lists correspondences (`None` otherwise):
/// its valid 3D points only (a recording keeps no pixels of depth-less points).
fn fit_throughput(recording: &mimic_capture::Recording) -> anyhow::Result<Option<FitSummary>> {
    let configs = ConfigDirs::locate(None);
    let layout = configs.load_layout_named(&recording.header.layout);
    if !layout.is_ok_and(|l| !l.candide_correspondences.is_empty()) {
        return Ok(None);
    }
    let frames: Vec<CaptureFrame> = recording
        .frames
        .iter()
        .map(|f| CaptureFrame::without_pixels(&f.frame, f.label))
        .collect();
    let odd = mimic_fit::OddParts::default();
    let fit = fit_candide3(&configs, &recording.header.layout, &frames, odd)?;
    Ok(Some(fit.summary))
}
