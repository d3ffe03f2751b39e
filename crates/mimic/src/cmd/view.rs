//! `mimic view`: a window replaying a recording through the retargeter, or following a live
//! `mimic serve` session (`--connect`), drawn with the GPU morph (`crates/mimic_view`).

use crate::cmd::setup::{PipelineArgs, RigArgs};
use anyhow::bail;
use mimic_capture::RecordingReader;
use mimic_render::Renderer;
use mimic_view::{HELP, LocalSetup, Look, LookFor, Options, Viewer, load_look};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Arguments of `mimic view`.
#[derive(clap::Args, Debug)]
#[command(after_help = HELP)]
pub struct Args {
    /// Recording (v1 JSON Lines) to replay locally at its recorded pace.
    #[arg(required_unless_present = "connect", conflicts_with = "connect")]
    pub recording: Option<PathBuf>,
    /// Follow a live `mimic serve` session as a viewer instead, e.g. 127.0.0.1:7878.
    #[arg(long)]
    pub connect: Option<String>,
    /// Token of a server started with one (default: the MIMIC_TOKEN environment variable).
    #[arg(long, requires = "connect")]
    pub token: Option<String>,
    /// Session to follow with --connect.
    #[arg(long, default_value = "a")]
    pub session: String,
    #[command(flatten)]
    pub rig: RigArgs,
    #[command(flatten)]
    pub pipeline: PipelineArgs,
    /// Window (or headless image) size, WIDTHxHEIGHT.
    #[arg(long, default_value = "800x800")]
    pub size: String,
    /// Start with the head turned by the performer's head rotation (key p).
    #[arg(long)]
    pub pose: bool,
    /// Start with the displacement heat map (key h).
    #[arg(long)]
    pub heat: bool,
    /// Displacement shown hottest by the heat map, rig units (default: 5% of the rig's diagonal).
    #[arg(long)]
    pub heat_scale: Option<f32>,
    /// Vertex ranges whose triangles are not drawn, e.g. 100-200, or `none` (default: the rig's
    /// `[look]`).
    #[arg(long)]
    pub hide: Option<String>,
    /// Skin colour everywhere instead of the mesh's material colours.
    #[arg(long)]
    pub no_materials: bool,
    /// Also print the title's readout (fps, latency) to stderr at each refresh.
    #[arg(long)]
    pub print_readout: bool,
    /// No window: run the same loop into an offscreen target for N images (local, on a simulated
    /// clock at the recording's pace) or until N live frames were drawn, print a summary, exit.
    #[arg(long, value_name = "N")]
    pub headless_frames: Option<usize>,
    /// With --headless-frames: keys pressed one per image from the second on, e.g. space,right,s,h.
    #[arg(long, value_delimiter = ',', requires = "headless_frames")]
    pub headless_keys: Vec<String>,
    /// With --headless-frames: write the last image here (PNG).
    #[arg(long, requires = "headless_frames")]
    pub headless_out: Option<PathBuf>,
    /// With --headless-frames: draw what the window draws over the head into the images too
    /// (readout, heat map legend, weights, key help); off, the images are the head alone.
    #[arg(long, requires = "headless_frames")]
    pub headless_overlay: bool,
    /// With --headless-frames and --connect: give up after this many seconds.
    #[arg(long, default_value_t = 60.0, requires = "headless_frames")]
    pub headless_timeout: f64,
}

/// The viewer following a live `mimic serve` session at `addr`.
fn live_viewer(args: &Args, addr: &str, options: Options) -> anyhow::Result<Viewer> {
    // Colour a live rig with the local configs' materials when they have that rig.
    let (rig_args, hide, materials) = (args.rig.clone(), args.hide.clone(), !args.no_materials);
    let look_for: LookFor = Box::new(move |name: &str, n: usize| {
        let local = RigArgs {
            rig: name.to_string(),
            ..rig_args.clone()
        };
        match local.load_rig() {
            Ok(rig) if rig.mesh.vertex_count() == n => {
                let path = local.rig_path();
                load_look(&path, &rig, hide.as_deref(), materials).unwrap_or_else(|e| {
                    tracing::warn!("rig `{name}`: {e:#}; drawing it in skin colour");
                    Look::default()
                })
            }
            _ => Look::default(),
        }
    });
    let token = mimic_stream::token_or_env(args.token.as_deref());
    let session = &args.session;
    Ok(Viewer::connect(
        addr,
        session,
        token.as_deref(),
        look_for,
        options,
    )?)
}

/// The viewer replaying `recording` locally.
fn local_viewer(args: &Args, recording: &Path, options: Options) -> anyhow::Result<Viewer> {
    let mut reader = RecordingReader::open(recording, None)?;
    let layout = args
        .rig
        .config_dirs()
        .load_layout_named(&reader.header().layout)?;
    let rig = args.rig.load_rig()?;
    let (basis, first, _) = args.rig.build_basis(&rig)?;
    // Lines the reader rejects are skipped, as `mimic render` does.
    reader.expect_points(layout.point_count)?;
    let frames = reader
        .read_all()
        .frames
        .into_iter()
        .map(|f| f.frame)
        .collect();
    let path = args.rig.rig_path();
    let look = load_look(&path, &rig, args.hide.as_deref(), !args.no_materials)?;
    // The GPU computes u = B d and the normals: the pipeline only needs d.
    let settings = args.pipeline.settings().displacements_only();
    // The rig's morph targets go on the number keys 1-9.
    let expressions = mimic_assets::load_morph_targets(&path, &rig)?;
    let setup = LocalSetup {
        rig,
        layout,
        settings,
        first: (first, basis),
        other: LocalSetup::other_solver(&first),
        frames,
        look,
        expressions,
    };
    Ok(Viewer::local(setup, options)?)
}

/// Runs `mimic view`.
pub fn run(args: Args) -> anyhow::Result<()> {
    if args.headless_frames.is_some() {
        // SAFETY: no thread has started yet.
        unsafe { mimic_render::headless::quiet_headless_vulkan() };
    }
    let (width, height) = mimic_types::parse::parse_size(&args.size).map_err(anyhow::Error::msg)?;
    let keys = mimic_view::keys::actions_named(&args.headless_keys)?;
    let options = Options {
        pose: args.pose,
        heat: args.heat,
        heat_scale: args.heat_scale,
        blocking_builds: args.headless_frames.is_some(),
        headless_overlay: args.headless_overlay,
    };
    let mut viewer = match (&args.connect, &args.recording) {
        (Some(addr), _) => live_viewer(&args, addr, options)?,
        (None, Some(recording)) => local_viewer(&args, recording, options)?,
        (None, None) => bail!("give a recording, or --connect ADDR"),
    };
    let Some(n) = args.headless_frames else {
        println!("{HELP}");
        mimic_view::run_window(viewer, width, height, args.print_readout)?;
        return Ok(());
    };
    let renderer = Renderer::new(width, height)?;
    // A local replay steps at 60 images per simulated second.
    let report = mimic_view::run_headless(
        &mut viewer,
        &renderer,
        n,
        &keys,
        Duration::from_micros(16_667),
        args.connect.is_some(),
        Duration::from_secs_f64(args.headless_timeout.max(0.0)),
    )?;
    if let (Some(path), Some(image)) = (&args.headless_out, &report.image) {
        image.save_png(path)?;
    }
    println!("{}", report.summary());
    Ok(())
}
