//! `mimic render`: frames of a recording retargeted onto a rig, rendered headless to PNG.

use crate::cmd::setup::{PipelineArgs, RigArgs, parse_size, prepare_with, rig_look};
use anyhow::{Context, bail};
use glam::Vec3;
use mimic_capture::RecordingReader;
use mimic_render::overlay::legend_ticks;
use mimic_render::{Camera, Deform, Image, Overlay, Renderer, Shading, View};
use mimic_retarget::RetargetSettings;
use mimic_types::ControlName;
use std::path::{Path, PathBuf};

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
}

/// The colour legend of `shading` for a `size` image, labelled in the rig's `units`.
fn legend(shading: Shading, units: &str, size: (u32, u32)) -> Overlay {
    let (title, full) = match shading {
        Shading::Displacement { full_scale } => ("|P - P0|", Some(full_scale)),
        Shading::ControlWeight { .. } => ("weight", None),
        Shading::Lit => return Overlay::new(),
    };
    let mut o = Overlay::new();
    let scale = mimic_view::hud::text_scale(size);
    o.legend(
        size,
        mimic_view::hud::MARGIN,
        scale,
        title,
        &legend_ticks(full, units),
    );
    o
}

/// Frames to render for a sheet of `n` out of `total`: evenly spread, first and last included.
fn spread(n: usize, total: usize) -> Vec<usize> {
    match (n, total) {
        (0, _) | (_, 0) => Vec::new(),
        (1, _) => vec![total / 2],
        _ => {
            let mut v: Vec<usize> = (0..n).map(|k| k * (total - 1) / (n - 1)).collect();
            v.dedup();
            v
        }
    }
}

/// Runs `mimic render`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let (width, height) = parse_size(&args.size)?;
    if args.frames.is_empty() && args.sheet.is_none() {
        bail!("nothing to render: give --frames 0,30,60 or --sheet N");
    }
    let mut reader = RecordingReader::open(&args.recording, None)?;
    // The GPU computes u = B d and the normals: the pipeline only needs d.
    let settings = RetargetSettings {
        positions: false,
        normals: false,
        ..args.pipeline.settings()
    };
    let mut prepared = prepare_with(&args.rig, settings, &reader.header().layout)?;
    let rig = &prepared.rig;
    let look = rig_look(&args.rig, rig, args.hide.as_deref(), !args.no_materials)?;
    let (lo, hi) = rig.mesh.bounds().context("the rig's mesh is empty")?;
    let shading = match args.heat.as_deref() {
        None => Shading::Lit,
        Some("displacement") => Shading::Displacement {
            full_scale: args.heat_scale.unwrap_or(0.05 * (hi - lo).length()),
        },
        Some(s) => {
            let name = s.strip_prefix("control:").with_context(|| {
                format!("--heat `{s}`: expected `displacement` or `control:FDP` (e.g. control:8.3)")
            })?;
            let fdp: ControlName = name
                .parse()
                .map_err(|e| anyhow::anyhow!("--heat `{s}`: {e}"))?;
            let control = rig
                .controls
                .iter()
                .position(|c| c.fdp == fdp)
                .with_context(|| format!("rig `{}` has no control {fdp}", rig.name))?;
            Shading::ControlWeight { control }
        }
    };

    let renderer = Renderer::new(width, height)?;
    tracing::info!(adapter = renderer.adapter(), "renderer");
    let basis = prepared.retargeter.basis().clone();
    let gpu = mimic_view::upload_with_look(
        &renderer,
        &rig.mesh.positions,
        &rig.mesh.triangles,
        Some(&basis),
        &look,
    )?;
    let pivot = (lo + hi) * 0.5;
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
    let wanted: Vec<usize> = match args.sheet {
        Some(n) => spread(n, frames.len()),
        None => args.frames.clone(),
    };
    if let Some(&bad) = wanted.iter().find(|&&f| f >= frames.len()) {
        bail!(
            "frame {bad} is past the end: the recording has {} accepted frames",
            frames.len()
        );
    }
    let sheet_file = args.sheet.is_some() && args.out.extension().is_some_and(|e| e == "png");
    let dir = if sheet_file {
        args.out.parent().unwrap_or(Path::new(".")).to_path_buf()
    } else {
        args.out.clone()
    };
    if !dir.as_os_str().is_empty() {
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    }

    let last = wanted.iter().copied().max().unwrap_or(0);
    let mut out = prepared.retargeter.new_output();
    let mut tiles: Vec<(usize, Image, Image)> = Vec::new();
    for (index, &frame) in frames.iter().enumerate().take(last + 1) {
        prepared.retargeter.step(frame, &mut out);
        if !wanted.contains(&index) {
            continue;
        }
        view.model = if args.pose {
            View::head_rotation(out.target_rotation, pivot)
        } else {
            glam::Mat4::IDENTITY
        };
        let d: &[Vec3] = &out.displacements;
        let image = renderer.render_with(&gpu, Deform::Controls(d), &view, overlay.as_ref())?;
        if args.sheet.is_some() {
            let mut plot = Image::filled(width, height, [236, 236, 232, 255]);
            let controls: Vec<usize> = prepared
                .layout
                .controls
                .iter()
                .flat_map(|c| c.points.iter().copied())
                .collect();
            let all: Vec<[f32; 2]> = frame.points.iter().map(|p| [p.x, p.y]).collect();
            let radius = (width.min(height) as f32 / 160.0).max(1.0);
            plot.plot_points(&all, &all, 0.12, radius, [90, 90, 100, 255]);
            // The layout's control points on top, in orange.
            let marked: Vec<[f32; 2]> = controls
                .iter()
                .filter_map(|&i| all.get(i).copied())
                .collect();
            plot.plot_points(&marked, &all, 0.12, radius * 1.4, [230, 110, 20, 255]);
            tiles.push((index, image, plot));
        } else {
            let path = args.out.join(format!("frame_{index:06}.png"));
            image.save_png(&path)?;
            println!("{}", path.display());
        }
    }
    if args.sheet.is_some() {
        let cols = args.columns.clamp(1, tiles.len().max(1));
        let rows = tiles.len().div_ceil(cols);
        let mut sheet = Image::filled(
            width * 2 * cols as u32,
            height * rows as u32,
            [255, 255, 255, 255],
        );
        for (k, (_, image, plot)) in tiles.iter().enumerate() {
            let (x, y) = ((k % cols) as u32 * width * 2, (k / cols) as u32 * height);
            sheet.paste(image, x, y);
            sheet.paste(plot, x + width, y);
        }
        let path = if sheet_file {
            args.out.clone()
        } else {
            args.out.join("sheet.png")
        };
        sheet.save_png(&path)?;
        let list: Vec<String> = tiles.iter().map(|(i, _, _)| i.to_string()).collect();
        println!("{} (frames {})", path.display(), list.join(","));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sheet_frames_spread_from_first_to_last() {
        assert_eq!(spread(4, 1062), vec![0, 353, 707, 1061]);
        assert_eq!(spread(1, 10), vec![5]);
        // More frames asked than exist: each frame once.
        assert_eq!(spread(5, 3), vec![0, 1, 2]);
        assert!(spread(0, 10).is_empty() && spread(3, 0).is_empty());
    }
}
