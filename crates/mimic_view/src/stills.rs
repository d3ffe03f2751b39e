//! Still images of a replay (`mimic render`): the frames to draw ([`spread`] for a contact
//! sheet), the shading a `--heat` name asks for ([`shading_named`]), the heat map's legend
//! ([`legend`]), the replay drawn at chosen frames ([`render_stills`]), a plot of a frame's
//! landmarks ([`landmark_plot`]), the sheet of head and plot tiles ([`contact_sheet`]), and
//! where the images go ([`StillsOut`]); and a rig's neutral with its regions coloured and its
//! controls labelled ([`rig_picture`], `mimic rig check -o`; the drawing is `mimic_rig::picture`).

use crate::ViewError;
use glam::{Mat4, Vec3};
use mimic_render::overlay::legend_ticks;
use mimic_render::{Deform, Image, Overlay, Renderer, RigGpu, Shading, View};
use mimic_retarget::Retargeter;
use mimic_rig::picture::{Canvas, annotate, controlled_triangles, free_bounds, region_colors};
use mimic_types::{ControlName, LandmarkFrame, Layout, Rig};
use std::path::{Path, PathBuf};

/// `rig`'s neutral drawn by `renderer` (of `width` x `height`): the controlled pieces only,
/// coloured by region, framed on the free vertices, every control labelled.
pub fn rig_picture(
    renderer: &Renderer,
    rig: &Rig,
    (width, height): (u32, u32),
) -> Result<Image, ViewError> {
    let gpu = renderer.upload_rig(&rig.mesh.positions, &controlled_triangles(rig), None)?;
    renderer.set_albedo(&gpu, &region_colors(rig))?;
    let (lo, hi) = free_bounds(rig).ok_or(ViewError::EmptyMesh)?;
    let view = View::lit(mimic_render::Camera::framing(lo, hi, 0.0, 0.0));
    let mut image = renderer.render(&gpu, Deform::Rest, &view)?;
    let view_proj = view.camera.view_proj(width as f32 / height as f32);
    let rgba = &mut image.rgba;
    annotate(
        &mut Canvas {
            width,
            height,
            rgba,
        },
        rig,
        view_proj,
    );
    Ok(image)
}

/// The frames to render out of `total`: `n` spread for a sheet, else `frames`; a frame past the
/// end is the error.
pub fn wanted_frames(
    sheet: Option<usize>,
    frames: &[usize],
    total: usize,
) -> Result<Vec<usize>, ViewError> {
    let wanted: Vec<usize> = match sheet {
        Some(n) => spread(n, total),
        None => frames.to_vec(),
    };
    if let Some(&bad) = wanted.iter().find(|&&f| f >= total) {
        return Err(ViewError::Option(format!(
            "frame {bad} is past the end: the recording has {total} accepted frames"
        )));
    }
    Ok(wanted)
}

/// Where `mimic render` writes: frames as `frame_NNNNNN.png` in a folder, or one contact sheet
/// (`sheet.png` in the folder, or the path itself when it names a `.png`).
#[derive(Clone, Debug)]
pub struct StillsOut {
    out: PathBuf,
    sheet_file: bool,
}

impl StillsOut {
    /// The output `out` of frames, or with `sheet` of a contact sheet; its folder is created.
    pub fn create(out: &Path, sheet: bool) -> Result<Self, ViewError> {
        let sheet_file = sheet && out.extension().is_some_and(|e| e == "png");
        let dir = if sheet_file {
            out.parent().unwrap_or(Path::new("."))
        } else {
            out
        };
        if !dir.as_os_str().is_empty() {
            std::fs::create_dir_all(dir).map_err(|cause| ViewError::Folder {
                path: dir.to_path_buf(),
                cause,
            })?;
        }
        Ok(Self {
            out: out.to_path_buf(),
            sheet_file,
        })
    }

    /// The file of frame `index`.
    pub fn frame_path(&self, index: usize) -> PathBuf {
        self.out.join(format!("frame_{index:06}.png"))
    }

    /// Writes the contact sheet of `images` (index into `frames`, head), each beside the plot of
    /// its frame's landmarks (`layout`), tiles of `width` x `height`, `columns` pairs a row; the
    /// file written.
    pub fn write_sheet(
        &self,
        images: Vec<(usize, Image)>,
        frames: &[&LandmarkFrame],
        layout: &Layout,
        columns: usize,
        (width, height): (u32, u32),
    ) -> Result<PathBuf, ViewError> {
        let tiles: Vec<_> = images
            .into_iter()
            .map(|(i, image)| (image, landmark_plot(frames[i], layout, width, height)))
            .collect();
        let path = if self.sheet_file {
            self.out.clone()
        } else {
            self.out.join("sheet.png")
        };
        contact_sheet(&tiles, columns, width, height).save_png(&path)?;
        Ok(path)
    }
}

/// Frames to render for a sheet of `n` out of `total`: evenly spread, first and last included.
pub fn spread(n: usize, total: usize) -> Vec<usize> {
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

/// The shading `heat` names for `rig`: `None` lit skin, `displacement` (hottest at `scale`,
/// default 5% of the rig's diagonal) or `control:FDP` (that control's weights).
pub fn shading_named(
    rig: &Rig,
    heat: Option<&str>,
    scale: Option<f32>,
) -> Result<Shading, ViewError> {
    let Some(s) = heat else {
        return Ok(Shading::Lit);
    };
    if s == "displacement" {
        let (lo, hi) = rig
            .mesh
            .bounds()
            .ok_or_else(|| ViewError::Option("the rig's mesh is empty".into()))?;
        let full_scale = scale.unwrap_or(0.05 * (hi - lo).length());
        return Ok(Shading::Displacement { full_scale });
    }
    let name = s.strip_prefix("control:").ok_or_else(|| {
        ViewError::Option(format!(
            "--heat `{s}`: expected `displacement` or `control:FDP` (e.g. control:8.3)"
        ))
    })?;
    let fdp: ControlName = name
        .parse()
        .map_err(|e| ViewError::Option(format!("--heat `{s}`: {e}")))?;
    let control = rig
        .controls
        .iter()
        .position(|c| c.fdp == fdp)
        .ok_or_else(|| ViewError::Option(format!("rig `{}` has no control {fdp}", rig.name)))?;
    Ok(Shading::ControlWeight { control })
}

/// The colour legend of `shading` for a `size` image, labelled in the rig's `units`.
pub fn legend(shading: Shading, units: &str, size: (u32, u32)) -> Overlay {
    let (title, full) = match shading {
        Shading::Displacement { full_scale } => ("|P - P0|", Some(full_scale)),
        Shading::ControlWeight { .. } => ("weight", None),
        Shading::Lit => return Overlay::new(),
    };
    let mut o = Overlay::new();
    let scale = crate::hud::text_scale(size);
    o.legend(
        size,
        crate::hud::MARGIN,
        scale,
        title,
        &legend_ticks(full, units),
    );
    o
}

/// How [`render_stills`] draws: the uploaded rig, the view, the head turned by the performer's
/// rotation about `pivot` or not, and an overlay.
pub struct Stills<'a> {
    /// The renderer.
    pub renderer: &'a Renderer,
    /// The rig on the GPU (with its basis: the frames deform it by control displacements).
    pub gpu: &'a RigGpu,
    /// Camera and shading.
    pub view: View,
    /// The point the head turns about, with `pose`.
    pub pivot: Vec3,
    /// Turn the head by the performer's head rotation.
    pub pose: bool,
    /// Drawn over each image (the heat map's legend), if anything.
    pub overlay: Option<&'a Overlay>,
}

/// Steps `retargeter` through `frames` up to the last of `wanted` (indices into `frames`) and
/// draws the head at each wanted frame, in frame order.
pub fn render_stills(
    stills: &mut Stills<'_>,
    retargeter: &mut Retargeter,
    frames: &[&LandmarkFrame],
    wanted: &[usize],
) -> Result<Vec<(usize, Image)>, ViewError> {
    let last = wanted.iter().copied().max().unwrap_or(0);
    let mut out = retargeter.new_output();
    let mut images = Vec::new();
    for (index, &frame) in frames.iter().enumerate().take(last + 1) {
        retargeter.step(frame, &mut out);
        if !wanted.contains(&index) {
            continue;
        }
        stills.view.model = if stills.pose {
            View::head_rotation(out.target_rotation, stills.pivot)
        } else {
            Mat4::IDENTITY
        };
        let d: &[Vec3] = &out.displacements;
        let image = stills.renderer.render_with(
            stills.gpu,
            Deform::Controls(d),
            &stills.view,
            stills.overlay,
        )?;
        images.push((index, image));
    }
    Ok(images)
}

/// A `width` x `height` plot of `frame`'s source landmarks, the `layout`'s control points on top
/// in orange.
pub fn landmark_plot(frame: &LandmarkFrame, layout: &Layout, width: u32, height: u32) -> Image {
    let mut plot = Image::filled(width, height, [236, 236, 232, 255]);
    let all: Vec<[f32; 2]> = frame.points.iter().map(|p| [p.x, p.y]).collect();
    let radius = (width.min(height) as f32 / 160.0).max(1.0);
    plot.plot_points(&all, &all, 0.12, radius, [90, 90, 100, 255]);
    let marked: Vec<[f32; 2]> = layout
        .controls
        .iter()
        .flat_map(|c| c.points.iter().copied())
        .filter_map(|i| all.get(i).copied())
        .collect();
    plot.plot_points(&marked, &all, 0.12, radius * 1.4, [230, 110, 20, 255]);
    plot
}

/// One sheet of `(head, plot)` tile pairs of `width` x `height` each, `columns` pairs a row.
pub fn contact_sheet(tiles: &[(Image, Image)], columns: usize, width: u32, height: u32) -> Image {
    let cols = columns.clamp(1, tiles.len().max(1));
    let rows = tiles.len().div_ceil(cols);
    let mut sheet = Image::filled(
        width * 2 * cols as u32,
        height * rows as u32,
        [255, 255, 255, 255],
    );
    for (k, (image, plot)) in tiles.iter().enumerate() {
        let (x, y) = ((k % cols) as u32 * width * 2, (k / cols) as u32 * height);
        sheet.paste(image, x, y);
        sheet.paste(plot, x + width, y);
    }
    sheet
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
    fn a_sheet_holds_its_tiles_in_rows() {
        let tile = || (Image::filled(4, 3, [0; 4]), Image::filled(4, 3, [9; 4]));
        let sheet = contact_sheet(&[tile(), tile(), tile()], 2, 4, 3);
        assert_eq!((sheet.width, sheet.height), (16, 6));
    }
}

/// The box `mimic render` frames: the whole mesh, or with `face` the face alone (its controls'
/// box, widened by a quarter of its size on every side, so that a bust's face fills the tile).
pub fn framed_bounds(rig: &Rig, face: bool) -> Result<(Vec3, Vec3), ViewError> {
    let controls = rig.control_positions();
    if face && !controls.is_empty() {
        let (lo, hi) = controls
            .iter()
            .fold((Vec3::MAX, Vec3::MIN), |(l, h), p| (l.min(*p), h.max(*p)));
        let pad = (hi - lo) * 0.25;
        return Ok((lo - pad, hi + pad));
    }
    rig.mesh.bounds().ok_or(ViewError::EmptyMesh)
}

#[cfg(test)]
mod framing_tests {
    use super::*;

    #[test]
    fn the_face_box_holds_the_controls_inside_the_mesh_box() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs/rigs/ict-face.toml");
        let rig = mimic_assets::load_rig(&path).unwrap();
        let (lo, hi) = framed_bounds(&rig, false).unwrap();
        let (flo, fhi) = framed_bounds(&rig, true).unwrap();
        for p in rig.control_positions() {
            assert!(p.cmpge(flo).all() && p.cmple(fhi).all());
        }
        // The face's box is smaller than the bust's: the face fills more of the tile.
        assert!((fhi - flo).y < (hi - lo).y, "{flo} {fhi} vs {lo} {hi}");
    }
}
