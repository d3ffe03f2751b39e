//! RGBA8 images in memory: PNG in and out, pasting tiles, plotting points, comparing.

use crate::RenderError;
use std::fs::File;
use std::io::{BufReader, BufWriter};
use std::path::Path;

/// An 8-bit RGBA image, rows top to bottom, 4 bytes per pixel.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Pixels, `width * height * 4` bytes.
    pub rgba: Vec<u8>,
}

fn png_error(path: &Path, e: impl std::fmt::Display) -> RenderError {
    RenderError::Png {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

impl Image {
    /// An image filled with one colour.
    pub fn filled(width: u32, height: u32, rgba: [u8; 4]) -> Self {
        let n = width as usize * height as usize;
        Self {
            width,
            height,
            rgba: rgba.iter().copied().cycle().take(n * 4).collect(),
        }
    }

    /// Writes the image as an 8-bit RGBA PNG.
    pub fn save_png(&self, path: &Path) -> Result<(), RenderError> {
        let file = File::create(path).map_err(|e| png_error(path, e))?;
        let mut enc = png::Encoder::new(BufWriter::new(file), self.width, self.height);
        enc.set_color(png::ColorType::Rgba);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().map_err(|e| png_error(path, e))?;
        w.write_image_data(&self.rgba)
            .map_err(|e| png_error(path, e))?;
        w.finish().map_err(|e| png_error(path, e))
    }

    /// Reads an 8-bit RGBA or RGB PNG (RGB gets opaque alpha).
    pub fn load_png(path: &Path) -> Result<Self, RenderError> {
        let file = File::open(path).map_err(|e| png_error(path, e))?;
        let mut reader = png::Decoder::new(BufReader::new(file))
            .read_info()
            .map_err(|e| png_error(path, e))?;
        let size = reader
            .output_buffer_size()
            .ok_or_else(|| png_error(path, "image too large"))?;
        let mut buf = vec![0; size];
        let info = reader
            .next_frame(&mut buf)
            .map_err(|e| png_error(path, e))?;
        if info.bit_depth != png::BitDepth::Eight {
            return Err(png_error(path, "only 8-bit PNGs are read"));
        }
        let px = info.width as usize * info.height as usize;
        let rgba = match info.color_type {
            png::ColorType::Rgba => buf[..px * 4].to_vec(),
            png::ColorType::Rgb => buf[..px * 3]
                .chunks_exact(3)
                .flat_map(|c| [c[0], c[1], c[2], 255])
                .collect(),
            other => return Err(png_error(path, format!("colour type {other:?} not read"))),
        };
        Ok(Self {
            width: info.width,
            height: info.height,
            rgba,
        })
    }

    /// Copies `tile` with its top-left corner at `(x, y)`; what falls outside is cut off.
    pub fn paste(&mut self, tile: &Image, x: u32, y: u32) {
        for ty in 0..tile.height {
            let dy = y + ty;
            if dy >= self.height || x >= self.width {
                break;
            }
            let w = tile.width.min(self.width - x) as usize;
            let src = ty as usize * tile.width as usize * 4;
            let dst = (dy as usize * self.width as usize + x as usize) * 4;
            self.rgba[dst..dst + w * 4].copy_from_slice(&tile.rgba[src..src + w * 4]);
        }
    }

    /// Fills a disc of `radius` pixels around `(cx, cy)` (pixel coordinates, y down).
    pub fn dot(&mut self, cx: f32, cy: f32, radius: f32, rgba: [u8; 4]) {
        let r = radius.max(0.5);
        let (x0, x1) = ((cx - r).floor().max(0.0), (cx + r).ceil());
        let (y0, y1) = ((cy - r).floor().max(0.0), (cy + r).ceil());
        if !(x0.is_finite() && x1.is_finite() && y0.is_finite() && y1.is_finite()) {
            return;
        }
        let (w, h) = (self.width as f32, self.height as f32);
        let mut y = y0;
        while y <= y1 && y < h {
            let mut x = x0;
            while x <= x1 && x < w {
                let (dx, dy) = (x + 0.5 - cx, y + 0.5 - cy);
                if dx * dx + dy * dy <= r * r {
                    let at = (y as usize * self.width as usize + x as usize) * 4;
                    self.rgba[at..at + 4].copy_from_slice(&rgba);
                }
                x += 1.0;
            }
            y += 1.0;
        }
    }

    /// Plots points `(x, y)` (y up) as dots (non-finite ones skipped), scaled uniformly so the
    /// bounding box of `extent` (e.g. all points of the frame, of which `points` may be a subset)
    /// fits the image with a `margin` fraction left free on each side, centred.
    pub fn plot_points(
        &mut self,
        points: &[[f32; 2]],
        extent: &[[f32; 2]],
        margin: f32,
        radius: f32,
        rgba: [u8; 4],
    ) {
        let finite = |p: &&[f32; 2]| p[0].is_finite() && p[1].is_finite();
        let mut it = extent.iter().filter(finite);
        let Some(first) = it.next() else {
            return;
        };
        let (mut lo, mut hi) = (*first, *first);
        for p in it {
            lo = [lo[0].min(p[0]), lo[1].min(p[1])];
            hi = [hi[0].max(p[0]), hi[1].max(p[1])];
        }
        let (w, h) = (self.width as f32, self.height as f32);
        let span = ((hi[0] - lo[0]) / w).max((hi[1] - lo[1]) / h).max(1e-12);
        let scale = (1.0 - 2.0 * margin) / span;
        let (mx, my) = ((lo[0] + hi[0]) * 0.5, (lo[1] + hi[1]) * 0.5);
        for p in points.iter().filter(finite) {
            let x = w * 0.5 + (p[0] - mx) * scale;
            let y = h * 0.5 - (p[1] - my) * scale;
            self.dot(x, y, radius, rgba);
        }
    }

    /// Mean absolute difference per channel value (0..=255) over all RGBA bytes; `None` if the sizes differ.
    pub fn mean_abs_error(&self, other: &Image) -> Option<f64> {
        if (self.width, self.height) != (other.width, other.height) || self.rgba.is_empty() {
            return None;
        }
        let sum: u64 = self
            .rgba
            .iter()
            .zip(&other.rgba)
            .map(|(a, b)| u64::from(a.abs_diff(*b)))
            .sum();
        Some(sum as f64 / self.rgba.len() as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn png_round_trip_is_lossless() {
        let mut img = Image::filled(7, 5, [10, 20, 30, 255]);
        img.dot(3.0, 2.0, 1.5, [200, 100, 0, 255]);
        let dir = std::env::temp_dir().join(format!("mimic_render_png_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("a.png");
        img.save_png(&path).unwrap();
        let back = Image::load_png(&path).unwrap();
        assert_eq!(back, img);
        assert_eq!(back.mean_abs_error(&img), Some(0.0));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn paste_clips_and_dots_land_where_asked() {
        let mut img = Image::filled(4, 3, [0, 0, 0, 255]);
        img.paste(&Image::filled(3, 3, [9, 9, 9, 255]), 2, 1);
        // Columns 2..4 of rows 1..3 are pasted; the rest of the tile is cut off.
        for y in 0..3u32 {
            for x in 0..4u32 {
                let v = img.rgba[((y * 4 + x) * 4) as usize];
                assert_eq!(v, if x >= 2 && y >= 1 { 9 } else { 0 }, "({x}, {y})");
            }
        }
        let mut img = Image::filled(10, 10, [0, 0, 0, 255]);
        // Two points span the image: the y-up point lands at the top.
        let pts = [[0.0, 0.0], [1.0, 1.0]];
        img.plot_points(&pts, &pts, 0.1, 1.0, [255, 0, 0, 255]);
        // Scale (1 - 2 * 0.1) * 10 = 8 px per unit, centred: (0, 0) -> (1, 9) and (1, 1) -> (9, 1) in
        // pixel-corner coordinates; a radius-1 disc covers the 4 pixels whose centres are 0.707 away.
        let red = |x: usize, y: usize| img.rgba[(y * 10 + x) * 4] == 255;
        for (x, y) in [
            (0, 8),
            (1, 8),
            (0, 9),
            (1, 9),
            (8, 0),
            (9, 0),
            (8, 1),
            (9, 1),
        ] {
            assert!(red(x, y), "({x}, {y})");
        }
        let reds = img.rgba.chunks(4).filter(|p| p[0] == 255).count();
        assert_eq!(reds, 8);
    }
}
