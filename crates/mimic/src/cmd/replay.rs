//! `mimic replay`: a recorded performance (or a Live Link Face take, `replay/take.rs`) onto a
//! rig through the one frame loop (`mimic_retarget::FrameLoop`), its outputs picked from the flags
//! (`replay/outputs.rs`: OBJ frames, one binary file or one GLB, the CSVs), the summary printed by
//! `replay/summary.rs` (docs/replay.md).

mod outputs;
mod summary;
mod take;

use crate::cmd::setup::{BlendshapeArgs, Mode, PipelineArgs, RigArgs, prepare_with};
use anyhow::{Context, bail};
use indicatif::{ProgressBar, ProgressStyle};
use mimic_assets::load_morph_targets;
use mimic_capture::{FileSource, Pace, RecordingReader, Replay, ReplayOptions};
use mimic_retarget::summary::ReplaySummary;
use mimic_retarget::{BlendshapeFitter, FrameLoop};
use mimic_rig::speech_mouth::speech_drive;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Instant;

/// The layout of `--weights`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum WeightsFormat {
    /// `frame,t_us,status,label` and one column per morph target of the rig.
    Mimic,
    /// A Live Link Face CSV take (`Timecode`, `BlendShapeCount`, the 61 curves).
    Livelink,
}

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
    /// One VRM: the rig's VRM avatar as `glb`, its expressions bound (docs/avatars.md).
    Vrm,
}

/// Arguments of `mimic replay`.
#[derive(clap::Args, Debug)]
#[command(after_long_help = mimic_retarget::summary::TERMS)]
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
    /// (`vrm`) the file (a path not ending in `.glb` (`.vrm`) is a directory: `take.glb`).
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
    /// Print the per-stage timings (median and p99 of each stage of the step) too.
    #[arg(long)]
    pub detail: bool,
    /// Speech (WAV) whose lip sync drives the mouth; the rest of the face follows the recording.
    #[arg(long, value_name = "WAV")]
    pub audio: Option<PathBuf>,
    /// Seconds after the recording's first frame at which the audio starts (negative: before).
    #[arg(
        long,
        default_value_t = 0.0,
        allow_hyphen_values = true,
        requires = "audio"
    )]
    pub audio_offset: f64,
    /// The words of `--audio` (text, or a file of it): phones aligned to them, not recognised.
    #[arg(long, requires = "audio")]
    pub transcript: Option<String>,
}

impl Args {
    /// The `--namemap` file, or the shipped ARKit map.
    fn namemap_path(&self) -> PathBuf {
        self.namemap
            .clone()
            .unwrap_or_else(|| self.rig.config_dirs().root.join("namemaps/arkit.toml"))
    }
}

/// Runs `mimic replay`.
pub fn run(args: Args) -> anyhow::Result<()> {
    if (args.no_pose || args.step_keys) && !matches!(args.format, OutFormat::Glb | OutFormat::Vrm) {
        bail!("--no-pose and --step-keys are options of --format glb and vrm");
    }
    if mimic_trackers::weights_take::is_replayable_take(&args.recording)? {
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
    let rig = prepared.rig.clone();
    if let Some(wav) = &args.audio {
        let (root, words) = (args.rig.config_dirs().root, args.transcript.as_deref());
        let (drive, line) = speech_drive(&root, &rig, wav, words, args.audio_offset)?;
        eprintln!("{line}");
        prepared.retargeter.set_mouth(Some(drive));
    }
    let (fitter, targets) = match blend_fitter(&args, &rig)? {
        Some((fitter, targets)) => (Some(fitter), targets),
        None => (None, Vec::new()),
    };
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
    let (layout, solver, basis_time) = (
        prepared.layout.name.clone(),
        prepared.solver,
        prepared.basis_time,
    );
    let mut frames = FrameLoop::landmarks(prepared.retargeter, fitter);
    let header = format!("mimic replay onto rig {}", rig.name);
    outputs::add(&args, &rig, &targets, &header, &mut frames)?;

    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_time()
        .build()?;
    let bar = progress_bar(args.json);
    let wall = Instant::now();
    runtime.block_on(async {
        while let Some(item) = replay.next().await {
            let rf = item?;
            frames.step(&rf.frame, rf.label)?;
            bar.set_position(frames.frames() as u64);
            if args.max_frames.is_some_and(|m| frames.frames() >= m) {
                break;
            }
        }
        anyhow::Ok(())
    })?;
    let wall_s = wall.elapsed().as_secs_f64();
    let retargeter = frames.retargeter().context("a landmark loop")?;
    let summary = ReplaySummary {
        recording: &args.recording,
        layout,
        rig: rig.name.clone(),
        solver,
        basis_time,
        moving_vertices: retargeter.moving_vertex_count(),
        read: summary::read_figures(replay.source().reader().stats())?,
        stats: retargeter.stats(),
        source_to_target: retargeter.source_to_target().copied(),
        wall_s,
        out: args.out.as_deref(),
    };
    let report = frames.finish()?;
    bar.finish_and_clear();
    summary::print(&args, &summary, report)
}

/// The blend-shape fit of `--mode blendshapes` for `rig` and the rig's morph targets, or
/// `None` in free-form mode.
fn blend_fitter(
    args: &Args,
    rig: &mimic_types::Rig,
) -> anyhow::Result<Option<(BlendshapeFitter, Vec<mimic_types::MorphTarget>)>> {
    let blend: &BlendshapeArgs = &args.blend;
    if blend.mode == Mode::Freeform {
        if blend.weights.is_some() {
            bail!("--weights needs --mode blendshapes");
        }
        return Ok(None);
    }
    let targets = load_morph_targets(&args.rig.rig_path(), rig)?;
    let fitter = BlendshapeFitter::new(rig, &targets, &blend.settings(&args.rig.rig_path())?)
        .with_context(|| format!("blendshapes of rig `{}`", rig.name))?;
    Ok(Some((fitter, targets)))
}

/// A progress spinner on a terminal only (hidden when stderr is not one, or with `--json`).
fn progress_bar(json: bool) -> ProgressBar {
    if std::io::stderr().is_terminal() && !json {
        let bar = ProgressBar::new_spinner();
        bar.set_style(
            ProgressStyle::with_template("{spinner} replay: {pos} frames in {elapsed} {msg}")
                .unwrap_or_else(|_| ProgressStyle::default_spinner()),
        );
        bar
    } else {
        ProgressBar::hidden()
    }
}
