//! The picture of `mimic rig check` without a GPU: vertex colours by region, and markers,
//! FDP labels (a 3x5 pixel font) and a legend drawn into an RGBA8 image the renderer made.

use glam::{Mat4, Vec2, Vec3};
use mimic_types::{Region, Rig};

/// Linear RGB of each region in the picture (top, middle, bottom) and of frozen vertices.
pub const REGION_COLORS: [[f32; 3]; 3] =
    [[0.80, 0.30, 0.22], [0.25, 0.65, 0.25], [0.22, 0.38, 0.85]];
/// Linear RGB of frozen vertices.
pub const FROZEN_COLOR: [f32; 3] = [0.35, 0.35, 0.35];

/// Per-vertex albedo: the region colours blended by the rig's region weights at each height,
/// frozen vertices grey.
pub fn region_colors(rig: &Rig) -> Vec<[f32; 3]> {
    rig.mesh
        .positions
        .iter()
        .zip(&rig.frozen)
        .map(|(p, frozen)| {
            if *frozen {
                return FROZEN_COLOR;
            }
            let w = rig.regions.weights(p.y);
            let mut c = [0.0f32; 3];
            for (r, wr) in REGION_COLORS.iter().zip(w) {
                for k in 0..3 {
                    c[k] += r[k] * wr;
                }
            }
            c
        })
        .collect()
}

/// Triangles of the pieces that carry a control (what the picture draws: eyeballs, teeth and
/// lashes, which never move with the rig, are left out so they do not cover the face).
pub fn controlled_triangles(rig: &Rig) -> Vec<[u32; 3]> {
    let piece = crate::parts::pieces(&rig.mesh);
    let controlled: std::collections::BTreeSet<u32> = rig
        .controls
        .iter()
        .filter_map(|c| piece.get(c.vertex as usize).copied().flatten())
        .collect();
    rig.mesh
        .triangles
        .iter()
        .filter(|t| {
            piece
                .get(t[0] as usize)
                .copied()
                .flatten()
                .is_some_and(|p| controlled.contains(&p))
        })
        .copied()
        .collect()
}

/// Bounding box of the vertices that move (not frozen), or of the whole mesh when all are
/// frozen; `None` for an empty mesh.
pub fn free_bounds(rig: &Rig) -> Option<(Vec3, Vec3)> {
    let free = rig
        .mesh
        .positions
        .iter()
        .zip(&rig.frozen)
        .filter(|(_, f)| !**f)
        .map(|(p, _)| *p);
    let fold = |it: &mut dyn Iterator<Item = Vec3>| {
        it.fold(None, |acc: Option<(Vec3, Vec3)>, p| match acc {
            None => Some((p, p)),
            Some((lo, hi)) => Some((lo.min(p), hi.max(p))),
        })
    };
    fold(&mut free.into_iter()).or_else(|| rig.mesh.bounds())
}

/// Pixel position (x right, y down) of a rig point under `view_proj` in a `width` x `height`
/// image; `None` behind the camera.
pub fn project(view_proj: Mat4, p: Vec3, width: u32, height: u32) -> Option<Vec2> {
    let c = view_proj * p.extend(1.0);
    if c.w <= 0.0 {
        return None;
    }
    let n = c.truncate() / c.w;
    Some(Vec2::new(
        (n.x * 0.5 + 0.5) * width as f32,
        (0.5 - n.y * 0.5) * height as f32,
    ))
}

/// Rows of a 3x5 glyph, top first, bit 2 the left column.
fn glyph(c: char) -> [u8; 5] {
    match c {
        '0' => [7, 5, 5, 5, 7],
        '1' => [2, 6, 2, 2, 7],
        '2' => [7, 1, 7, 4, 7],
        '3' => [7, 1, 7, 1, 7],
        '4' => [5, 5, 7, 1, 1],
        '5' => [7, 4, 7, 1, 7],
        '6' => [7, 4, 7, 5, 7],
        '7' => [7, 1, 2, 2, 2],
        '8' => [7, 5, 7, 5, 7],
        '9' => [7, 5, 7, 1, 7],
        '.' => [0, 0, 0, 0, 2],
        'T' => [7, 2, 2, 2, 2],
        'O' => [7, 5, 5, 5, 7],
        'P' => [7, 5, 7, 4, 4],
        'M' => [5, 7, 7, 5, 5],
        'I' => [7, 2, 2, 2, 7],
        'D' => [6, 5, 5, 5, 6],
        'B' => [6, 5, 6, 5, 6],
        'F' => [7, 4, 6, 4, 4],
        'R' => [6, 5, 6, 5, 5],
        'Z' => [7, 1, 2, 4, 7],
        'E' => [7, 4, 6, 4, 7],
        'N' => [5, 7, 7, 7, 5],
        'L' => [4, 4, 4, 4, 7],
        _ => [0, 0, 0, 0, 0],
    }
}

/// An RGBA8 image being annotated (rows top to bottom).
pub struct Canvas<'a> {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height * 4` bytes.
    pub rgba: &'a mut [u8],
}

impl Canvas<'_> {
    /// Fills the pixel rectangle `[x0, x1) x [y0, y1)` (clipped to the image).
    pub fn rect(&mut self, x0: i32, y0: i32, x1: i32, y1: i32, rgba: [u8; 4]) {
        let (w, h) = (self.width as i32, self.height as i32);
        for y in y0.max(0)..y1.min(h) {
            for x in x0.max(0)..x1.min(w) {
                let at = (y as usize * self.width as usize + x as usize) * 4;
                if let Some(px) = self.rgba.get_mut(at..at + 4) {
                    px.copy_from_slice(&rgba);
                }
            }
        }
    }

    /// Width in pixels of `text` at `scale` (4 columns a glyph, the last without a gap).
    pub fn text_width(text: &str, scale: i32) -> i32 {
        (text.chars().count() as i32 * 4 - 1).max(0) * scale
    }

    /// Draws `text` (digits, `.` and the legend's capitals) with its top-left corner at
    /// `(x, y)`, each font pixel `scale` pixels, on a dark box for contrast.
    pub fn text(&mut self, x: i32, y: i32, text: &str, scale: i32, rgba: [u8; 4]) {
        let w = Self::text_width(text, scale);
        self.rect(
            x - scale,
            y - scale,
            x + w + scale,
            y + 6 * scale,
            [20, 20, 24, 255],
        );
        for (k, c) in text.chars().enumerate() {
            let gx = x + k as i32 * 4 * scale;
            for (row, bits) in glyph(c).iter().enumerate() {
                for col in 0..3 {
                    if bits & (4 >> col) != 0 {
                        let (px, py) = (gx + col * scale, y + row as i32 * scale);
                        self.rect(px, py, px + scale, py + scale, rgba);
                    }
                }
            }
        }
    }

    /// A square marker of half-size `r` with a dark rim, centred on `at`.
    pub fn marker(&mut self, at: Vec2, r: i32, rgba: [u8; 4]) {
        let (x, y) = (at.x.round() as i32, at.y.round() as i32);
        self.rect(
            x - r - 1,
            y - r - 1,
            x + r + 2,
            y + r + 2,
            [10, 10, 10, 255],
        );
        self.rect(x - r, y - r, x + r + 1, y + r + 1, rgba);
    }
}

/// Labels every control (marker at its projected rest position, FDP name beside it: to the
/// image's right for the subject's left half) and draws a legend of the region colours.
pub fn annotate(canvas: &mut Canvas<'_>, rig: &Rig, view_proj: Mat4) {
    let scale = (canvas.width.min(canvas.height) as i32 / 320).max(1);
    let centre = rig
        .controls
        .iter()
        .filter_map(|c| rig.mesh.positions.get(c.vertex as usize))
        .fold(Vec3::ZERO, |a, p| a + *p)
        / rig.controls.len().max(1) as f32;
    let centre_px = project(view_proj, centre, canvas.width, canvas.height);
    for c in &rig.controls {
        let Some(p) = rig.mesh.positions.get(c.vertex as usize) else {
            continue;
        };
        let Some(at) = project(view_proj, *p, canvas.width, canvas.height) else {
            continue;
        };
        let col = srgb8(REGION_COLORS[c.region.index()]);
        canvas.marker(at, 2 * scale, [255, 255, 255, 255]);
        canvas.marker(at, scale, col);
        let label = c.fdp.to_string();
        let w = Canvas::text_width(&label, scale);
        let right = centre_px.is_none_or(|m| at.x >= m.x);
        let x = if right {
            at.x as i32 + 4 * scale
        } else {
            at.x as i32 - 4 * scale - w
        };
        canvas.text(
            x,
            at.y as i32 - 3 * scale,
            &label,
            scale,
            [255, 255, 255, 255],
        );
    }
    let mut y = 4 * scale;
    let legend = [
        ("TOP", srgb8(REGION_COLORS[Region::Top.index()])),
        ("MIDDLE", srgb8(REGION_COLORS[Region::Middle.index()])),
        ("BOTTOM", srgb8(REGION_COLORS[Region::Bottom.index()])),
        ("FROZEN", srgb8(FROZEN_COLOR)),
    ];
    for (name, col) in legend {
        canvas.rect(4 * scale, y, 10 * scale, y + 5 * scale, col);
        canvas.text(13 * scale, y, name, scale, [255, 255, 255, 255]);
        y += 8 * scale;
    }
}

/// sRGB bytes of a linear colour.
pub fn srgb8(c: [f32; 3]) -> [u8; 4] {
    let enc = |v: f32| {
        let v = v.clamp(0.0, 1.0);
        let s = if v <= 0.003_130_8 {
            12.92 * v
        } else {
            1.055 * v.powf(1.0 / 2.4) - 0.055
        };
        (s * 255.0).round() as u8
    };
    [enc(c[0]), enc(c[1]), enc(c[2]), 255]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_and_markers_land_where_asked() {
        let (w, h) = (40u32, 20u32);
        let mut px = vec![0u8; (w * h * 4) as usize];
        let mut c = Canvas {
            width: w,
            height: h,
            rgba: &mut px,
        };
        c.text(2, 2, "1", 1, [255, 0, 0, 255]);
        let at = |px: &[u8], x: u32, y: u32| px[((y * w + x) * 4) as usize];
        // "1": rows 2,6,2,2,7: the middle column lit on the top row, all three on the bottom.
        assert_eq!(
            (at(&px, 3, 2), at(&px, 2, 2), at(&px, 2, 6)),
            (255, 20, 255)
        );
        let mut c = Canvas {
            width: w,
            height: h,
            rgba: &mut px,
        };
        c.marker(Vec2::new(30.0, 10.0), 2, [0, 255, 0, 255]);
        assert_eq!(px[((10 * w + 30) * 4 + 1) as usize], 255);
        assert_eq!(Canvas::text_width("8.3", 2), 22);
        // Projection: the identity maps clip (0, 0) to the image centre.
        let p = project(Mat4::IDENTITY, Vec3::ZERO, 100, 50).unwrap();
        assert_eq!(p, Vec2::new(50.0, 25.0));
        assert_eq!(srgb8([0.0, 1.0, 0.5]), [0, 255, 188, 255]);
    }
}
