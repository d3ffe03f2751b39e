//! `mimic render`: frames of a recording retargeted onto a rig, rendered headless to PNG (the
//! drawing is `mimic_view::stills`).

use crate::cmd::setup::{PipelineArgs, RigArgs, prepare_with};
use anyhow::bail;
use mimic_capture::RecordingReader;
use mimic_render::{Camera, Renderer, View};
use mimic_view::load_look;
use mimic_view::stills::{Stills, StillsOut, legend, render_stills, shading_named, wanted_frames};
use std::path::PathBuf;

/// Arguments of `mimic render`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Recording (v1 JSON Lines).
    pub recording: PathBuf,
    #[command(flatten)]
    pub rig: RigArgs,
    #[command(flatten)]
    pub pipeline: PipelineArgs,
    /// Frames to render (0-based indices of accepted frames), comma-separated, e.g. 0,30,60.
    #[arg(long, value_delimiter = ',')]
    pub frames: Vec<usize>,
    /// Instead of --frames: one contact sheet of N frames spread evenly over the recording, each the
    /// rendered head beside a plot of the frame's source landmarks (sheet.png).
    #[arg(long)]
    pub sheet: Option<usize>,
    /// Tiles (head + landmarks) per row of the contact sheet.
    #[arg(long, default_value_t = 3)]
    pub columns: usize,
    /// Output directory (frames as frame_NNNNNN.png, the sheet as sheet.png), or with --sheet a .png path.
    #[arg(short, long)]
    pub out: PathBuf,
    /// Image (or sheet tile) size, WIDTHxHEIGHT.
    #[arg(long, default_value = "512x512")]
    pub size: String,
    /// Heat map instead of lit skin: `displacement` (|u|) or `control:FDP` (that control's weights, e.g. control:8.3).
    #[arg(long)]
    pub heat: Option<String>,
    /// Displacement shown hottest by `--heat displacement`, rig units (default: 5% of the rig's diagonal).
    #[arg(long)]
    pub heat_scale: Option<f32>,
    /// With --heat: draw the colour legend (the ramp with its scale) in the bottom-right corner.
    #[arg(long, requires = "heat")]
    pub legend: bool,
    /// Turn the head by the performer's head rotation.
    #[arg(long)]
    pub pose: bool,
    /// Vertex ranges whose triangles are not drawn, e.g. 100-200,300-310, or `none` (default: the
    /// rig's `[look]`).
    #[arg(long)]
    pub hide: Option<String>,
    /// Skin colour everywhere instead of the mesh's material colours (teeth, gums, eyes, lashes).
    #[arg(long)]
    pub no_materials: bool,
    /// What the camera frames: the `whole` mesh, or the `face` alone (a bust's face fills the tile).
    #[arg(long, default_value = "whole", value_parser = ["whole", "face"])]
    pub frame: String,
}

/// Runs `mimic render`.
pub fn run(args: Args) -> anyhow::Result<()> {
    // SAFETY: no thread has started yet.
    unsafe { mimic_render::headless::quiet_headless_vulkan() };
    let (width, height) = mimic_types::parse::parse_size(&args.size).map_err(anyhow::Error::msg)?;
    if args.frames.is_empty() && args.sheet.is_none() {
        bail!("nothing to render: give --frames 0,30,60 or --sheet N");
    }
    let mut reader = RecordingReader::open(&args.recording, None)?;
    // The GPU computes u = B d and the normals: the pipeline only needs d.
    let settings = args.pipeline.settings().displacements_only();
    let mut prepared = prepare_with(&args.rig, settings, &reader.header().layout)?;
    let rig = &prepared.rig;
    let path = args.rig.rig_path();
    let look = load_look(&path, rig, args.hide.as_deref(), !args.no_materials)?;
    let (lo, hi) = mimic_view::stills::framed_bounds(rig, args.frame == "face")?;
    let shading = shading_named(rig, args.heat.as_deref(), args.heat_scale)?;
    let renderer = Renderer::new(width, height)?;
    tracing::info!(adapter = renderer.adapter(), "renderer");
    let basis = prepared.retargeter.basis().clone();
    let (rest, triangles) = (&rig.mesh.positions, &rig.mesh.triangles);
    let gpu = mimic_view::upload_with_look(&renderer, rest, triangles, Some(&basis), &look)?;
    let mut view = View::lit(Camera::front(lo, hi));
    view.shading = shading;
    let overlay = args
        .legend
        .then(|| legend(shading, &rig.units, (width, height)));
    // Read the accepted frames (a sheet needs the count first; recordings are small).
    reader.expect_points(prepared.layout.point_count)?;
    let recording = reader.read_all();
    let frames: Vec<_> = recording.frames.iter().map(|f| &f.frame).collect();
    let rejected = recording.stats.rejected.total();
    if rejected > 0 {
        tracing::warn!(rejected, "lines rejected by the reader were skipped");
    }
    let wanted = wanted_frames(args.sheet, &args.frames, frames.len())?;
    let out = StillsOut::create(&args.out, args.sheet.is_some())?;
    let mut stills = Stills {
        renderer: &renderer,
        gpu: &gpu,
        view,
        pivot: (lo + hi) * 0.5,
        pose: args.pose,
        overlay: overlay.as_ref(),
    };
    let images = render_stills(&mut stills, &mut prepared.retargeter, &frames, &wanted)?;
    if args.sheet.is_none() {
        for (index, image) in &images {
            let path = out.frame_path(*index);
            image.save_png(&path)?;
            println!("{}", path.display());
        }
        return Ok(());
    }
    let layout = &prepared.layout;
    let path = out.write_sheet(images, &frames, layout, args.columns, (width, height))?;
    let list: Vec<String> = wanted.iter().map(usize::to_string).collect();
    println!("{} (frames {})", path.display(), list.join(","));
    Ok(())
}
