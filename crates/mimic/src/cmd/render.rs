//! `mimic render`: frames of a recording retargeted onto a rig, rendered headless to PNG.

use crate::cmd::setup::{PipelineArgs, RigArgs, prepare_with};
use anyhow::{Context, bail};
use glam::Vec3;
use mimic_capture::RecordingReader;
use mimic_render::{Camera, Deform, Image, Renderer, SKIN_ALBEDO, Shading, View};
use mimic_retarget::RetargetSettings;
use mimic_types::{Fdp, LandmarkFrame};
use std::path::{Path, PathBuf};

/// Vertex ranges hidden by default per rig: ICT-FaceKit's parts that its own renderer draws
/// (partly) see-through (configs/meshes/ict-facekit/SOURCE.md), which opaque would cover the eyes:
/// the sclera shells (21451-22220, 23021-23790; their texture is clear over the cornea, and the
/// iris mesh inside them is the whole eyeball), the lacrimal fluid, eye blend and eye occlusion
/// shells (24591-25350, `Tf 0`) and the alpha-mapped eyelash cards (25351-26718, `Tf 0`).
const HIDDEN_BY_RIG: &[(&str, &[(u32, u32)])] = &[(
    "ict-face",
    &[(21451, 22220), (23021, 23790), (24591, 26718)],
)];

/// Materials per rig that keep the skin albedo instead of their MTL colour: ICT-FaceKit's face and
/// back of the head have a flat grey `Kd` (0.6) that multiplies a skin texture not shipped here.
const SKIN_MATERIALS_BY_RIG: &[(&str, &[&str])] = &[("ict-face", &["M_Face", "M_BackHead"])];

/// Eyeballs per rig, as (eyeball material, white-of-the-eye material): ICT-FaceKit's iris meshes
/// are whole eyeballs, textured. Here a vertex within [`IRIS_DEGREES`] of the eyeball's front (+z
/// from the centre of its vertices) takes the eyeball material's `Kd` (the iris), within
/// [`PUPIL_DEGREES`] black, and the rest the white's `Kd`.
const EYEBALLS_BY_RIG: &[(&str, &[(&str, &str)])] = &[(
    "ict-face",
    &[
        ("M_IrisLeft", "M_ScleraLeft"),
        ("M_IrisRight", "M_ScleraRight"),
    ],
)];
/// Half-angle of the iris seen from the eyeball's centre (a 12 mm iris on a 24 mm eye: 30 degrees).
const IRIS_DEGREES: f32 = 30.0;
/// Half-angle of the pupil.
const PUPIL_DEGREES: f32 = 11.0;

/// Per-vertex albedo of a rig from its mesh's MTL materials (`Kd`; skin for the rig's skin
/// materials and for vertices of no material; eyeballs as [`EYEBALLS_BY_RIG`] says), or `None`
/// when the mesh names no materials.
pub(crate) fn material_colors(
    rig_path: &Path,
    rig_name: &str,
    positions: &[Vec3],
    triangles: &[[u32; 3]],
) -> anyhow::Result<Option<Vec<[f32; 3]>>> {
    let materials = mimic_assets::load_rig_materials(rig_path)?;
    if materials.materials.is_empty() || materials.triangle_material.len() != triangles.len() {
        return Ok(None);
    }
    let skin: &[&str] = SKIN_MATERIALS_BY_RIG
        .iter()
        .find(|(name, _)| *name == rig_name)
        .map_or(&[], |(_, m)| m);
    let mut colors = materials.vertex_colors(positions.len(), triangles, SKIN_ALBEDO, |m| {
        if skin.contains(&m.name.as_str()) {
            SKIN_ALBEDO
        } else {
            m.diffuse
        }
    });
    let eyeballs: &[(&str, &str)] = EYEBALLS_BY_RIG
        .iter()
        .find(|(name, _)| *name == rig_name)
        .map_or(&[], |(_, e)| e);
    for (ball, white) in eyeballs {
        let (Some(b), Some(w)) = (materials.find(ball), materials.find(white)) else {
            continue;
        };
        let mut vertices: Vec<u32> = triangles
            .iter()
            .zip(&materials.triangle_material)
            .filter(|(_, m)| **m == Some(b))
            .flat_map(|(t, _)| t.iter().copied())
            .collect();
        vertices.sort_unstable();
        vertices.dedup();
        let points: Vec<Vec3> = vertices
            .iter()
            .filter_map(|&v| positions.get(v as usize).copied())
            .collect();
        if points.is_empty() {
            continue;
        }
        let centre = points.iter().copied().sum::<Vec3>() / points.len() as f32;
        let (iris, pupil) = (
            IRIS_DEGREES.to_radians().cos(),
            PUPIL_DEGREES.to_radians().cos(),
        );
        for (&v, p) in vertices.iter().zip(&points) {
            let cos = (*p - centre).normalize_or_zero().dot(Vec3::Z);
            colors[v as usize] = if cos >= pupil {
                [0.02, 0.02, 0.02]
            } else if cos >= iris {
                materials.materials[b].diffuse
            } else {
                materials.materials[w].diffuse
            };
        }
    }
    Ok(Some(colors))
}

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
    /// Turn the head by the performer's head rotation.
    #[arg(long)]
    pub pose: bool,
    /// Vertex ranges whose triangles are not drawn, e.g. 100-200,300-310, or `none` (default: per rig).
    #[arg(long)]
    pub hide: Option<String>,
    /// Skin colour everywhere instead of the mesh's material colours (teeth, gums, eyes, lashes).
    #[arg(long)]
    pub no_materials: bool,
}

pub(crate) fn parse_size(s: &str) -> anyhow::Result<(u32, u32)> {
    let (w, h) = s
        .split_once('x')
        .with_context(|| format!("--size `{s}`: expected WIDTHxHEIGHT, e.g. 512x512"))?;
    Ok((
        w.trim()
            .parse()
            .with_context(|| format!("--size width `{w}`"))?,
        h.trim()
            .parse()
            .with_context(|| format!("--size height `{h}`"))?,
    ))
}

pub(crate) fn parse_hidden(arg: Option<&str>, rig: &str) -> anyhow::Result<Vec<(u32, u32)>> {
    let Some(s) = arg else {
        return Ok(HIDDEN_BY_RIG
            .iter()
            .find(|(name, _)| *name == rig)
            .map(|(_, r)| r.to_vec())
            .unwrap_or_default());
    };
    if s.trim() == "none" {
        return Ok(Vec::new());
    }
    s.split(',')
        .map(|part| {
            let (a, b) = part.split_once('-').unwrap_or((part, part));
            let a: u32 = a
                .trim()
                .parse()
                .with_context(|| format!("--hide `{part}`"))?;
            let b: u32 = b
                .trim()
                .parse()
                .with_context(|| format!("--hide `{part}`"))?;
            Ok((a.min(b), a.max(b)))
        })
        .collect()
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
    let header = RecordingReader::open(&args.recording, None)?
        .header()
        .clone();
    // The GPU computes u = B d and the normals: the pipeline only needs d.
    let settings = RetargetSettings {
        positions: false,
        normals: false,
        ..args.pipeline.settings()
    };
    let mut prepared = prepare_with(&args.rig, settings, &header.layout)?;
    let rig = &prepared.rig;
    let hidden = parse_hidden(args.hide.as_deref(), &rig.name)?;
    let shown: Vec<[u32; 3]> = rig
        .mesh
        .triangles
        .iter()
        .filter(|t| {
            !t.iter()
                .any(|v| hidden.iter().any(|(a, b)| (*a..=*b).contains(v)))
        })
        .copied()
        .collect();
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
            let fdp: Fdp = name
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
    let gpu = renderer.upload_rig(&rig.mesh.positions, &shown, Some(&basis))?;
    if !args.no_materials {
        let rig_path = args.rig.config_dirs().rig_path(&args.rig.rig);
        let (p, t) = (&rig.mesh.positions, &rig.mesh.triangles);
        if let Some(colors) = material_colors(&rig_path, &rig.name, p, t)? {
            renderer.set_albedo(&gpu, &colors)?;
        }
    }
    let pivot = (lo + hi) * 0.5;
    let mut view = View::lit(Camera::front(lo, hi));
    view.shading = shading;

    // Read the accepted frames (a sheet needs the count first; recordings are small).
    let mut reader = RecordingReader::open(&args.recording, Some(prepared.layout.point_count))?;
    let mut frames: Vec<LandmarkFrame> = Vec::new();
    let mut rejected = 0usize;
    while let Some(item) = reader.next_frame() {
        match item {
            Ok(rf) => frames.push(rf.frame),
            Err(_) => rejected += 1,
        }
    }
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
    for (index, frame) in frames.iter().enumerate().take(last + 1) {
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
        let image = renderer.render(&gpu, Deform::Controls(d), &view)?;
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

    #[test]
    fn hidden_ranges_parse_and_default_per_rig() {
        assert_eq!(
            parse_hidden(Some("5-3,7"), "x").unwrap(),
            vec![(3, 5), (7, 7)]
        );
        assert!(parse_hidden(Some("none"), "ict-face").unwrap().is_empty());
        assert_eq!(
            parse_hidden(None, "ict-face").unwrap(),
            vec![(21451, 22220), (23021, 23790), (24591, 26718)]
        );
        assert!(parse_hidden(None, "candide3").unwrap().is_empty());
        assert!(parse_hidden(Some("1-x"), "x").is_err());
        assert_eq!(parse_size("640x480").unwrap(), (640, 480));
        assert!(parse_size("640").is_err());
    }

    #[test]
    fn the_hidden_ict_ranges_are_its_see_through_eye_parts() {
        let configs = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs");
        let path = mimic_assets::ConfigDirs::locate(Some(&configs)).rig_path("ict-face");
        let mats = mimic_assets::load_rig_materials(&path).unwrap();
        let mesh = mimic_assets::load_obj(&mimic_assets::rig_mesh_path(&path).unwrap()).unwrap();
        let hidden = parse_hidden(None, "ict-face").unwrap();
        let in_hidden = |v: &u32| hidden.iter().any(|(a, b)| (*a..=*b).contains(v));
        for (tri, m) in mesh.triangles.iter().zip(&mats.triangle_material) {
            let name = &mats.materials[m.unwrap()].name;
            let shell = [
                "M_ScleraLeft",
                "M_ScleraRight",
                "M_LacrimalFluid",
                "M_EyeBlend",
                "M_EyeOcclusion",
                "M_EyeLashes",
            ]
            .contains(&name.as_str());
            // Their triangles lie wholly in the ranges; no other triangle touches them.
            assert_eq!(tri.iter().all(in_hidden), shell, "{name} {tri:?}");
            assert_eq!(tri.iter().any(in_hidden), shell, "{name} {tri:?}");
        }
        // Colours: gums red, teeth light, the face skin.
        let colors = material_colors(&path, "ict-face", &mesh.positions, &mesh.triangles)
            .unwrap()
            .unwrap();
        let of = |name: &str| {
            let k = mats.find(name).unwrap();
            let t = mats
                .triangle_material
                .iter()
                .position(|m| *m == Some(k))
                .unwrap();
            colors[mesh.triangles[t][0] as usize]
        };
        assert_eq!(of("M_GumsTongue"), [0.30, 0.03, 0.06]);
        assert_eq!(of("M_Teeth"), [0.8, 0.8, 0.8]);
        assert_eq!(of("M_Face"), SKIN_ALBEDO);
        // Each eyeball: a black pupil, an iris of the iris Kd, the rest the sclera's Kd.
        for ball in ["M_IrisLeft", "M_IrisRight"] {
            let k = mats.find(ball).unwrap();
            let mut seen: Vec<[f32; 3]> = Vec::new();
            for (t, m) in mesh.triangles.iter().zip(&mats.triangle_material) {
                if *m == Some(k) {
                    for &v in t {
                        if !seen.contains(&colors[v as usize]) {
                            seen.push(colors[v as usize]);
                        }
                    }
                }
            }
            seen.sort_by(|a, b| a[0].total_cmp(&b[0]));
            assert_eq!(seen, vec![[0.02; 3], [0.2; 3], [0.6; 3]], "{ball}");
        }
    }
}
