//! `mimic replay`: a recorded performance (or a Live Link Face take, `replay/take.rs`) onto a
//! rig, written as OBJ frames, one binary file or one GLB (docs/gltf.md); `--weights` writes the
//! weights per frame (`replay/weights_out.rs`).

mod sink;
mod take;
mod weights_out;

use crate::cmd::setup::{BlendshapeArgs, Mode, PipelineArgs, RigArgs, prepare_with};
use anyhow::{Context, bail};
use indicatif::{ProgressBar, ProgressStyle};
use mimic_assets::load_morph_targets;
use mimic_capture::{FileSource, Pace, RecordingReader, Replay, ReplayOptions};
use mimic_gltf::{basis_morphs, basis_weights, head_translation, target_morphs};
use mimic_retarget::frame_metrics::{max_vertex_motion, region_motion};
use mimic_retarget::{
    BlendshapeFitter, FrameOutput, FrameStatus, StageSamples, WeightStats, WeightSummary,
    elapsed_ns,
};
use mimic_types::{MorphTarget, Region, Rig};
use serde_json::json;
use sink::{Sink, write_frame};
use std::fs::File;
use std::io::{BufWriter, IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;
use weights_out::{WeightsFormat, WeightsOut};

/// Output file format.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutFormat {
    /// One OBJ per frame (frame_000000.obj ...) with normals, UVs and the rig's materials (one
    /// `.mtl` beside them), for Blender and friends.
    Obj,
    /// One `frames.bin` (see docs/frames-format.md).
    Bin,
    /// One GLB: the rig, its morph targets and the take as an animation (docs/gltf.md).
    Glb,
}

/// Arguments of `mimic replay`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Recording (v1 JSON Lines) to replay, or a Live Link Face CSV take (its weights drive the
    /// rig's morph targets through `--namemap`, at its `Timecode` pace).
    pub recording: PathBuf,
    #[command(flatten)]
    pub rig: RigArgs,
    #[command(flatten)]
    pub pipeline: PipelineArgs,
    #[command(flatten)]
    pub blend: BlendshapeArgs,
    /// Directory for the deformed frames (nothing is written without it); with `--format glb`
    /// the GLB file (a path not ending in `.glb` is a directory, and gets `take.glb`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Leave the head pose out of the GLB (`--format glb`): the face animates in place.
    #[arg(long)]
    pub no_pose: bool,
    /// Hold each GLB key until the next (glTF STEP) instead of interpolating linearly.
    #[arg(long)]
    pub step_keys: bool,
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
    /// Layout of `--weights`: mimic's (`frame,t_us,status,label,<targets>`) or a Live Link Face
    /// take (`Timecode`, the 61 curves in the app's order; the rig's weights as ARKit curves).
    #[arg(long, value_enum, default_value = "mimic")]
    pub weights_format: WeightsFormat,
    /// Name map between ARKit curves and the rig's morph targets, for Live Link takes and
    /// `--weights-format livelink` (default: configs/namemaps/arkit.toml).
    #[arg(long, value_name = "TOML")]
    pub namemap: Option<PathBuf>,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
}

impl Args {
    /// The `--namemap` file, or the shipped ARKit map.
    fn namemap_path(&self) -> PathBuf {
        self.namemap
            .clone()
            .unwrap_or_else(|| self.rig.config_dirs().root.join("namemaps/arkit.toml"))
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

/// Runs `mimic replay`.
pub fn run(args: Args) -> anyhow::Result<()> {
    if (args.no_pose || args.step_keys) && args.format != OutFormat::Glb {
        bail!("--no-pose and --step-keys are options of --format glb");
    }
    if mimic_trackers::take::is_take_file(&args.recording)? {
        return take::run(&args);
    }
    let mut reader = RecordingReader::open(&args.recording, None)?;
    // Normals are written by the binary and OBJ formats (a GLB's targets carry none).
    let settings = mimic_retarget::RetargetSettings {
        normals: matches!(args.format, OutFormat::Bin | OutFormat::Obj) && args.out.is_some(),
        // Blendshape mode blends the mesh itself: skip `B d`.
        positions: args.blend.mode == Mode::Freeform,
        ..args.pipeline.settings()
    };
    let mut prepared = prepare_with(&args.rig, settings, &reader.header().layout)?;
    let rig = &prepared.rig;
    let mut blend = Blend::new(&args, rig)?;
    let options = ReplayOptions {
        pace: if args.realtime {
            Pace::Recorded { speed: args.speed }
        } else {
            Pace::AsFastAsPossible
        },
        ..ReplayOptions::default()
    };
    reader.expect_points(prepared.layout.point_count)?;
    let mut replay = Replay::new(FileSource::from_reader(reader), options)?;

    let mut sink = Sink::open(&args, rig, blend.as_ref().map(|b| b.fitter.target_count()))?;
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
    let mut samples = StageSamples::default();
    let mut non_finite_frames = 0usize;
    let mut frame_index = 0usize;
    // A progress bar on a terminal only (hidden when stderr is not one, or with --json).
    let bar = if std::io::stderr().is_terminal() && !args.json {
        let bar = ProgressBar::new_spinner();
        bar.set_style(
            ProgressStyle::with_template("{spinner} replay: {pos} frames in {elapsed} {msg}")
                .unwrap_or_else(|_| ProgressStyle::default_spinner()),
        );
        bar
    } else {
        ProgressBar::hidden()
    };
    let wall = Instant::now();
    runtime.block_on(async {
        while let Some(item) = replay.next().await {
            let rf = item?;
            let t = Instant::now();
            let status = prepared.retargeter.step(&rf.frame, &mut out);
            let elapsed = elapsed_ns(t);
            if let Some(b) = blend.as_mut() {
                b.frame(frame_index, status_code(status), rf.label, &mut out)?;
            }
            if status == FrameStatus::Tracked {
                samples.push(elapsed, &out.times);
            }
            if !out.positions.iter().all(|p| p.is_finite()) {
                non_finite_frames += 1;
            }
            if let Some(w) = metrics.as_mut() {
                let [top, middle, bottom] = region_motion(&out.displacements, &regions);
                let max_vertex = max_vertex_motion(&out.positions, &rest);
                let label = rf.label.map(|l| l.to_string()).unwrap_or_default();
                writeln!(
                    w,
                    "{frame_index},{},{},{label},{top:.6},{middle:.6},{bottom:.6},{max_vertex:.6}",
                    rf.frame.timestamp_us,
                    status_code(status),
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
            if let Sink::Glb(g) = &mut sink
                && frame_index.is_multiple_of(args.every.max(1))
            {
                match blend.as_ref() {
                    Some(b) => g.weights.copy_from_slice(b.fitter.weights()),
                    None => basis_weights(&out.displacements, g.scale, &mut g.weights),
                }
                if status == FrameStatus::Tracked
                    && let Some(map) = prepared.retargeter.source_to_target()
                {
                    let f = &rf.frame;
                    let points = (0..f.points.len())
                        .filter(|i| f.is_valid(*i))
                        .map(|i| f.points[i]);
                    if let Some(t) = head_translation(points, &out.pose, map.linear) {
                        g.translation = t * g.scale;
                    }
                }
                g.take.push(
                    out.timestamp_us,
                    &g.weights,
                    (out.target_rotation, g.translation),
                );
            } else if frame_index.is_multiple_of(args.every.max(1)) {
                write_frame(
                    &mut sink,
                    frame_index,
                    &out,
                    &prepared.rig.mesh,
                    &prepared.rig.name,
                )?;
            }
            frame_index += 1;
            bar.set_position(frame_index as u64);
            if args.max_frames.is_some_and(|m| frame_index >= m) {
                break;
            }
        }
        anyhow::Ok(())
    })?;
    bar.set_message(match &sink {
        Sink::Glb(g) => format!("writing {}", g.path.display()),
        _ => String::new(),
    });
    let wall_s = wall.elapsed().as_secs_f64();
    let files = sink.written();
    let mut out_bytes: u64 = 0;
    let mut gltf = None;
    match sink {
        Sink::Bin { writer, path, .. } => {
            writer.finish()?;
            out_bytes = std::fs::metadata(&path).map_or(0, |m| m.len());
        }
        Sink::Glb(g) => {
            let started = Instant::now();
            let morphs = match &blend {
                Some(b) => target_morphs(&b.targets, g.scale),
                None => {
                    let names: Vec<String> =
                        rig.controls.iter().map(|c| c.fdp.to_string()).collect();
                    basis_morphs(prepared.retargeter.basis(), &names)
                }
            };
            let file = File::create(&g.path).with_context(|| g.path.display().to_string())?;
            let mut w = BufWriter::new(file);
            let written = mimic_gltf::write_rig_glb(
                &args.rig.rig_path(),
                &prepared.rig,
                &morphs,
                Some(&g.take),
                mimic_render::SKIN_ALBEDO,
                &mut w,
            )
            .with_context(|| g.path.display().to_string())?;
            w.flush().with_context(|| g.path.display().to_string())?;
            out_bytes = written.bytes as u64;
            gltf = Some((
                g.path,
                written,
                g.take.skipped(),
                started.elapsed().as_secs_f64(),
            ));
        }
        Sink::Obj { frames, .. } => out_bytes = frames.bytes(),
        Sink::None => {}
    }
    bar.finish_and_clear();
    for w in [metrics, controls_csv].into_iter().flatten() {
        w.into_inner().map_err(|e| e.into_error())?;
    }
    let blendshapes = blend.map(|b| b.finish()).transpose()?;

    let read = replay.source().reader().stats().clone();
    let stats = prepared.retargeter.stats();
    let (stages, step) = samples.summary();
    let (step_median, step_p99) = (step.median_us, step.p99_us);
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
        "gated": stats.gated,
        "clamped": stats.clamped,
        "jumps": stats.jumps,
        "filled_controls": stats.filled_controls,
        "frames_with_non_finite_vertices": non_finite_frames,
        "source_to_target": map.map(|m| json!({"scale": m.scale, "mirrored": m.mirrored, "rms_residual": m.rms_residual})),
        "stages": stages,
        "step": step,
        "processing_frames_per_second": step.per_second(),
        "wall_s": wall_s,
        "frames_written": files,
        "bytes_written": out_bytes,
        "out": args.out.as_ref().map(|p| p.display().to_string()),
        "blendshapes": blendshapes,
        "gltf": gltf.as_ref().map(|(path, w, skipped, secs)| json!({
            "path": path.display().to_string(), "summary": w, "skipped_frames": skipped, "write_s": secs,
        })),
    });
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        println!(
            "{}: {} frames in ({} rejected, {} lost, {} gated, {} clamped, {} jumps, {} calibrating), {} controls filled; rig {} ({} moving vertices), basis {:.0} ms",
            args.recording.display(),
            read.accepted,
            read.rejected.total(),
            stats.lost,
            stats.gated,
            stats.clamped,
            stats.jumps,
            stats.calibrating,
            stats.filled_controls,
            prepared.rig.name,
            prepared.retargeter.moving_vertex_count(),
            prepared.basis_time.as_secs_f64() * 1e3
        );
        print!("{stages}");
        println!(
            "  {:<10} median {step_median:>8.1} us   p99 {step_p99:>8.1} us   ({:.0} frames/s of processing)",
            "step",
            step.per_second()
        );
        if let Some((path, w, skipped, secs)) = &gltf {
            println!(
                "  wrote {}: {} keys over {:.2} s, {} vertices, {} morph targets ({} sparse), {:.1} MB in {secs:.2} s{}",
                path.display(),
                w.keys,
                w.duration_s,
                w.vertices,
                w.targets,
                w.sparse_targets,
                w.bytes as f64 / 1e6,
                if *skipped > 0 {
                    format!("; {skipped} frames skipped (time not after the previous key)")
                } else {
                    String::new()
                }
            );
        } else if let Some(dir) = &args.out {
            println!(
                "  wrote {files} frames ({:.1} MB) to {}",
                out_bytes as f64 / 1e6,
                dir.display()
            );
        }
    }
    Ok(())
}

/// The blendshape stage of a replay: fitter, weights CSV and running statistics.
struct Blend {
    fitter: BlendshapeFitter,
    /// The rig's morph targets (written into a GLB).
    targets: Vec<MorphTarget>,
    csv: Option<WeightsOut>,
    stats: WeightStats,
}

impl Blend {
    /// The blendshape stage for `rig` (of `--rig`), or `None` in free-form mode.
    fn new(replay: &Args, rig: &Rig) -> anyhow::Result<Option<Self>> {
        let args: &BlendshapeArgs = &replay.blend;
        let rig_path: &Path = &replay.rig.rig_path();
        if args.mode == Mode::Freeform {
            if args.weights.is_some() {
                bail!("--weights needs --mode blendshapes");
            }
            return Ok(None);
        }
        let targets = load_morph_targets(rig_path, rig)?;
        let fitter = BlendshapeFitter::new(rig, &targets, &args.settings())
            .with_context(|| format!("blendshapes of rig `{}`", rig.name))?;
        let csv = match &args.weights {
            Some(p) => Some(WeightsOut::create(
                p,
                replay.weights_format,
                fitter.names(),
                &replay.namemap_path(),
            )?),
            None => None,
        };
        let stats = WeightStats::new(fitter.target_count());
        Ok(Some(Self {
            fitter,
            targets,
            csv,
            stats,
        }))
    }

    /// Replaces `out`'s mesh with the blend fitted to its displacements and writes the CSV row.
    fn frame(
        &mut self,
        index: usize,
        status_code: u32,
        label: Option<i64>,
        out: &mut FrameOutput,
    ) -> anyhow::Result<()> {
        let tracked = out.status == FrameStatus::Tracked;
        let started = Instant::now();
        let w = self.fitter.apply(out);
        if tracked {
            self.stats.push(w, elapsed_ns(started));
        }
        if let Some(csv) = self.csv.as_mut() {
            csv.row(
                index,
                out.timestamp_us,
                status_code,
                label,
                w,
                out.pose.rotation,
            )?;
        }
        Ok(())
    }

    /// Flushes the CSV; returns the summary (per target: mean and max weight over tracked frames).
    fn finish(mut self) -> anyhow::Result<WeightSummary> {
        if let Some(csv) = self.csv {
            csv.finish()?;
        }
        Ok(self
            .stats
            .summary(self.fitter.names(), self.fitter.ridges()))
    }
}
