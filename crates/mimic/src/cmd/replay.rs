//! `mimic replay`: a recorded performance onto a rig, written as OBJ frames or one binary file.

use crate::cmd::setup::{PipelineArgs, RigArgs, prepare_with};
use anyhow::Context;
use mimic_assets::{FramesWriter, write_obj};
use mimic_capture::{Pace, Replay, ReplayOptions};
use mimic_retarget::{FrameOutput, FrameStatus, Stage};
use mimic_types::Region;
use serde_json::json;
use std::fs::File;
use std::io::{BufWriter, IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Output file format.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutFormat {
    /// One OBJ per frame (frame_000000.obj ...), for Blender and friends.
    Obj,
    /// One `frames.bin` (see docs/frames-format.md).
    Bin,
}

/// Arguments of `mimic replay`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Recording (v1 JSON Lines) to replay.
    pub recording: PathBuf,
    #[command(flatten)]
    pub rig: RigArgs,
    #[command(flatten)]
    pub pipeline: PipelineArgs,
    #[command(flatten)]
    pub blend: crate::cmd::morph::BlendshapeArgs,
    /// Directory for the deformed frames (nothing is written without it).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Format of the deformed frames.
    #[arg(long, value_enum, default_value = "obj")]
    pub format: OutFormat,
    /// Write only every N-th frame.
    #[arg(long, default_value_t = 1)]
    pub every: usize,
    /// Per-frame metrics as CSV (time, status, label, control motion per region).
    #[arg(long)]
    pub metrics: Option<PathBuf>,
    /// Per-frame control displacements (target units) as CSV: one x, y, z column triple per control.
    #[arg(long)]
    pub controls: Option<PathBuf>,
    /// Replay at the recorded pace instead of as fast as possible.
    #[arg(long)]
    pub realtime: bool,
    /// Speed factor for --realtime.
    #[arg(long, default_value_t = 1.0)]
    pub speed: f64,
    /// Stop after this many frames.
    #[arg(long)]
    pub max_frames: Option<usize>,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Where deformed frames go.
enum Sink {
    None,
    Obj {
        dir: PathBuf,
        written: usize,
    },
    Bin {
        writer: FramesWriter<BufWriter<File>>,
        path: PathBuf,
        written: usize,
    },
}

impl Sink {
    fn written(&self) -> usize {
        match self {
            Sink::None => 0,
            Sink::Obj { written, .. } | Sink::Bin { written, .. } => *written,
        }
    }
}

fn status_code(s: FrameStatus) -> u32 {
    match s {
        FrameStatus::Calibrating => 0,
        FrameStatus::Tracked => 1,
        FrameStatus::Lost => 2,
        FrameStatus::Rejected => 3,
    }
}

/// Prints one `median / p99` line per pipeline stage from a `{stage: {median_us, p99_us}}` object.
pub fn print_stages(stages: &serde_json::Value) {
    for s in Stage::ALL {
        let v = &stages[s.name()];
        println!(
            "  {:<10} median {:>8.1} us   p99 {:>8.1} us",
            s.name(),
            v["median_us"].as_f64().unwrap_or(0.0),
            v["p99_us"].as_f64().unwrap_or(0.0)
        );
    }
}

/// Median and 99th percentile of nanosecond samples, in microseconds.
pub fn median_p99_us(samples: &mut [u32]) -> (f64, f64) {
    if samples.is_empty() {
        return (0.0, 0.0);
    }
    samples.sort_unstable();
    let at = |q: f64| samples[((samples.len() - 1) as f64 * q).round() as usize] as f64 / 1000.0;
    (at(0.5), at(0.99))
}

/// Runs `mimic replay`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let header = mimic_capture::RecordingReader::open(&args.recording, None)?
        .header()
        .clone();
    // Normals are only written by the binary format; OBJ readers recompute their own.
    let settings = mimic_retarget::RetargetSettings {
        normals: args.format == OutFormat::Bin && args.out.is_some(),
        // Blendshape mode blends the mesh itself: skip `B d`.
        positions: args.blend.mode == crate::cmd::morph::Mode::Freeform,
        ..args.pipeline.settings()
    };
    let mut prepared = prepare_with(&args.rig, settings, &header.layout)?;
    let rig = &prepared.rig;
    let rig_path = args.rig.config_dirs().rig_path(&args.rig.rig);
    let mut blend = args.blend.blend(&rig_path, rig)?;
    let options = ReplayOptions {
        pace: if args.realtime {
            Pace::Recorded { speed: args.speed }
        } else {
            Pace::AsFastAsPossible
        },
        ..ReplayOptions::default()
    };
    let mut replay = Replay::open(&args.recording, Some(prepared.layout.point_count), options)?;

    let mut sink = match (&args.out, args.format) {
        (None, _) => Sink::None,
        (Some(dir), format) => {
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
            match format {
                OutFormat::Obj => Sink::Obj {
                    dir: dir.clone(),
                    written: 0,
                },
                OutFormat::Bin => {
                    let path = dir.join("frames.bin");
                    let file = File::create(&path).with_context(|| path.display().to_string())?;
                    let writer = FramesWriter::new(
                        BufWriter::new(file),
                        rig.mesh.vertex_count(),
                        &rig.mesh.triangles,
                        true,
                    )?;
                    Sink::Bin {
                        writer,
                        path,
                        written: 0,
                    }
                }
            }
        }
    };
    let mut metrics = match &args.metrics {
        Some(p) => {
            let mut w = BufWriter::new(File::create(p).with_context(|| p.display().to_string())?);
            writeln!(w, "frame,t_us,status,label,top,middle,bottom,max_vertex")?;
            Some(w)
        }
        None => None,
    };
    let mut controls_csv = match &args.controls {
        Some(p) => {
            let mut w = BufWriter::new(File::create(p).with_context(|| p.display().to_string())?);
            write!(w, "frame,t_us,status")?;
            for c in &rig.controls {
                write!(w, ",{0}_x,{0}_y,{0}_z", c.fdp)?;
            }
            writeln!(w)?;
            Some(w)
        }
        None => None,
    };
    let regions: Vec<Region> = rig.controls.iter().map(|c| c.region).collect();
    let rest = rig.mesh.positions.clone();

    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_time()
        .build()?;
    let mut out: FrameOutput = prepared.retargeter.new_output();
    let mut stage_ns: [Vec<u32>; 5] = Default::default();
    let mut step_ns: Vec<u32> = Vec::new();
    let mut non_finite_frames = 0usize;
    let mut frame_index = 0usize;
    let progress = std::io::stderr().is_terminal() && !args.json;
    let wall = Instant::now();
    runtime.block_on(async {
        while let Some(item) = replay.next().await {
            let rf = item?;
            let t = Instant::now();
            let status = prepared.retargeter.step(&rf.frame, &mut out);
            let elapsed = u32::try_from(t.elapsed().as_nanos()).unwrap_or(u32::MAX);
            if let Some(b) = blend.as_mut() {
                b.frame(frame_index, status_code(status), rf.label, &mut out)?;
            }
            if status == FrameStatus::Tracked {
                step_ns.push(elapsed);
                for s in Stage::ALL {
                    stage_ns[s as usize].push(out.times.get(s));
                }
            }
            if !out.positions.iter().all(|p| p.is_finite()) {
                non_finite_frames += 1;
            }
            if let Some(w) = metrics.as_mut() {
                let mut sum = [0f32; 3];
                let mut count = [0u32; 3];
                for (d, r) in out.displacements.iter().zip(&regions) {
                    sum[r.index()] += d.length();
                    count[r.index()] += 1;
                }
                let mean = |k: usize| {
                    if count[k] > 0 {
                        sum[k] / count[k] as f32
                    } else {
                        0.0
                    }
                };
                let max_vertex = out
                    .positions
                    .iter()
                    .zip(&rest)
                    .map(|(p, r)| p.distance(*r))
                    .fold(0f32, f32::max);
                let label = rf.label.map(|l| l.to_string()).unwrap_or_default();
                writeln!(
                    w,
                    "{frame_index},{},{},{label},{:.6},{:.6},{:.6},{:.6}",
                    rf.frame.timestamp_us,
                    status_code(status),
                    mean(0),
                    mean(1),
                    mean(2),
                    max_vertex
                )?;
            }
            if let Some(w) = controls_csv.as_mut() {
                write!(
                    w,
                    "{frame_index},{},{}",
                    rf.frame.timestamp_us,
                    status_code(status)
                )?;
                for d in &out.displacements {
                    write!(w, ",{:.5},{:.5},{:.5}", d.x, d.y, d.z)?;
                }
                writeln!(w)?;
            }
            if frame_index.is_multiple_of(args.every.max(1)) {
                write_frame(
                    &mut sink,
                    frame_index,
                    &out,
                    &prepared.rig.mesh.triangles,
                    &prepared.rig.name,
                )?;
            }
            frame_index += 1;
            if progress && frame_index.is_multiple_of(50) {
                let fps = frame_index as f64 / wall.elapsed().as_secs_f64();
                eprint!("\rreplay: {frame_index} frames ({fps:.0} frames/s)");
            }
            if args.max_frames.is_some_and(|m| frame_index >= m) {
                break;
            }
        }
        anyhow::Ok(())
    })?;
    if progress {
        eprintln!();
    }
    let wall_s = wall.elapsed().as_secs_f64();
    let files = sink.written();
    if let Sink::Bin { writer, .. } = sink {
        writer.finish()?;
    }
    for w in [metrics, controls_csv].into_iter().flatten() {
        w.into_inner().map_err(|e| e.into_error())?;
    }
    let blendshapes = blend.map(|b| b.finish()).transpose()?;

    let read = replay.source().reader().stats().clone();
    let stats = prepared.retargeter.stats();
    let mut stages = serde_json::Map::new();
    for s in Stage::ALL {
        let (median, p99) = median_p99_us(&mut stage_ns[s as usize]);
        stages.insert(s.name().into(), json!({"median_us": median, "p99_us": p99}));
    }
    let (step_median, step_p99) = median_p99_us(&mut step_ns);
    let map = prepared.retargeter.source_to_target().copied();
    let summary = json!({
        "recording": args.recording.display().to_string(),
        "layout": prepared.layout.name,
        "rig": prepared.rig.name,
        "solver": serde_json::to_value(prepared.solver)?,
        "basis_setup_ms": prepared.basis_time.as_secs_f64() * 1e3,
        "moving_vertices": prepared.retargeter.moving_vertex_count(),
        "frames_in": read.accepted,
        "rejected": read.rejected.total(),
        "rejected_by_reason": serde_json::to_value(&read.rejected)?,
        "invalid_points": read.invalid_points,
        "calibrating": stats.calibrating,
        "tracked": stats.tracked,
        "lost": stats.lost,
        "filled_controls": stats.filled_controls,
        "frames_with_non_finite_vertices": non_finite_frames,
        "source_to_target": map.map(|m| json!({"scale": m.scale, "mirrored": m.mirrored, "rms_residual": m.rms_residual})),
        "stages": stages,
        "step": {"median_us": step_median, "p99_us": step_p99},
        "processing_frames_per_second": if step_median > 0.0 { 1e6 / step_median } else { 0.0 },
        "wall_s": wall_s,
        "frames_written": files,
        "out": args.out.as_ref().map(|p| p.display().to_string()),
        "blendshapes": blendshapes,
    });
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        println!(
            "{}: {} frames in ({} rejected, {} lost, {} calibrating), {} controls filled; rig {} ({} moving vertices), basis {:.0} ms",
            args.recording.display(),
            read.accepted,
            read.rejected.total(),
            stats.lost,
            stats.calibrating,
            stats.filled_controls,
            prepared.rig.name,
            prepared.retargeter.moving_vertex_count(),
            prepared.basis_time.as_secs_f64() * 1e3
        );
        print_stages(&summary["stages"]);
        println!(
            "  {:<10} median {step_median:>8.1} us   p99 {step_p99:>8.1} us   ({:.0} frames/s of processing)",
            "step",
            if step_median > 0.0 {
                1e6 / step_median
            } else {
                0.0
            }
        );
        if let Some(dir) = &args.out {
            println!("  wrote {files} frames to {}", dir.display());
        }
    }
    Ok(())
}

fn write_frame(
    sink: &mut Sink,
    index: usize,
    out: &FrameOutput,
    triangles: &[[u32; 3]],
    rig: &str,
) -> anyhow::Result<()> {
    match sink {
        Sink::None => {}
        Sink::Obj { dir, written } => {
            let path = obj_frame_path(dir, index);
            let file = File::create(&path).with_context(|| path.display().to_string())?;
            let mut w = BufWriter::new(file);
            let header = format!(
                "mimic replay onto rig {rig}: frame {index}, t = {} us",
                out.timestamp_us
            );
            write_obj(&mut w, &header, &out.positions, None, triangles)?;
            w.flush().with_context(|| path.display().to_string())?;
            *written += 1;
        }
        Sink::Bin {
            writer,
            path,
            written,
        } => {
            writer
                .write_frame(
                    out.timestamp_us,
                    status_code(out.status),
                    &out.pose,
                    &out.positions,
                    &out.normals,
                )
                .with_context(|| path.display().to_string())?;
            *written += 1;
        }
    }
    Ok(())
}

/// Path of the OBJ of frame `index` in `dir` as `replay --format obj` names it.
pub fn obj_frame_path(dir: &Path, index: usize) -> PathBuf {
    dir.join(format!("frame_{index:06}.obj"))
}
