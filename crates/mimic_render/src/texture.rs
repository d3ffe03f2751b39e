//! Texture images prepared for the GPU: resampled to one size (a texture array has one size for
//! all its layers) and their mip chains, averaged in linear light (sRGB decoded and re-encoded).

use mimic_types::TextureImage;

/// sRGB-encoded byte to linear light.
pub(crate) fn srgb_to_linear(c: u8) -> f32 {
    let x = f32::from(c) / 255.0;
    if x <= 0.04045 {
        x / 12.92
    } else {
        ((x + 0.055) / 1.055).powf(2.4)
    }
}

/// Linear light (0..=1) to an sRGB-encoded byte, rounded.
pub(crate) fn linear_to_srgb(x: f32) -> u8 {
    let x = x.clamp(0.0, 1.0);
    let s = if x <= 0.003_130_8 {
        x * 12.92
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round() as u8
}

/// One image level: `width * height` RGBA pixels in linear light (alpha as is).
#[derive(Clone, Debug)]
pub(crate) struct Level {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f32; 4]>,
}

impl Level {
    /// The image in linear light.
    pub fn from_image(image: &TextureImage) -> Self {
        let lut: Vec<f32> = (0..=255u8).map(srgb_to_linear).collect();
        let pixels = image
            .rgba
            .chunks_exact(4)
            .map(|p| {
                [
                    lut[p[0] as usize],
                    lut[p[1] as usize],
                    lut[p[2] as usize],
                    f32::from(p[3]) / 255.0,
                ]
            })
            .collect();
        Self {
            width: image.width,
            height: image.height,
            pixels,
        }
    }

    fn at(&self, x: u32, y: u32) -> [f32; 4] {
        self.pixels[(y.min(self.height - 1) * self.width + x.min(self.width - 1)) as usize]
    }

    /// Resampled to `width x height` bilinearly (pixel centres aligned), or itself at that size.
    pub fn resized(self, width: u32, height: u32) -> Self {
        if (width, height) == (self.width, self.height) {
            return self;
        }
        let (sx, sy) = (
            self.width as f32 / width as f32,
            self.height as f32 / height as f32,
        );
        let mut pixels = Vec::with_capacity((width * height) as usize);
        for y in 0..height {
            let fy = ((y as f32 + 0.5) * sy - 0.5).max(0.0);
            let (y0, ty) = (fy.floor() as u32, fy.fract());
            for x in 0..width {
                let fx = ((x as f32 + 0.5) * sx - 0.5).max(0.0);
                let (x0, tx) = (fx.floor() as u32, fx.fract());
                let (a, b, c, d) = (
                    self.at(x0, y0),
                    self.at(x0 + 1, y0),
                    self.at(x0, y0 + 1),
                    self.at(x0 + 1, y0 + 1),
                );
                let mut p = [0f32; 4];
                for k in 0..4 {
                    let top = a[k] + (b[k] - a[k]) * tx;
                    let bottom = c[k] + (d[k] - c[k]) * tx;
                    p[k] = top + (bottom - top) * ty;
                }
                pixels.push(p);
            }
        }
        Self {
            width,
            height,
            pixels,
        }
    }

    /// The next mip level: half the size (at least 1), each pixel the mean of the 2 x 2 (or
    /// fewer, at an odd edge) pixels it covers.
    pub fn half(&self) -> Self {
        let (w, h) = ((self.width / 2).max(1), (self.height / 2).max(1));
        let mut pixels = Vec::with_capacity((w * h) as usize);
        for y in 0..h {
            for x in 0..w {
                let xs = [2 * x, (2 * x + 1).min(self.width - 1)];
                let ys = [2 * y, (2 * y + 1).min(self.height - 1)];
                let mut p = [0f32; 4];
                for &yy in &ys {
                    for &xx in &xs {
                        let q = self.at(xx, yy);
                        for k in 0..4 {
                            p[k] += q[k] * 0.25;
                        }
                    }
                }
                pixels.push(p);
            }
        }
        Self {
            width: w,
            height: h,
            pixels,
        }
    }

    /// sRGB-encoded RGBA8 bytes of the level.
    pub fn to_srgb8(&self) -> Vec<u8> {
        self.pixels
            .iter()
            .flat_map(|p| {
                [
                    linear_to_srgb(p[0]),
                    linear_to_srgb(p[1]),
                    linear_to_srgb(p[2]),
                    (p[3].clamp(0.0, 1.0) * 255.0).round() as u8,
                ]
            })
            .collect()
    }
}

/// Mip levels of a `width x height` image down to 1 x 1.
pub(crate) fn mip_count(width: u32, height: u32) -> u32 {
    32 - width.max(height).max(1).leading_zeros()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trips_every_byte() {
        for c in 0..=255u8 {
            assert_eq!(linear_to_srgb(srgb_to_linear(c)), c);
        }
        // The standard's anchor: 50% linear is sRGB 188.
        assert_eq!(linear_to_srgb(0.5), 188);
    }

    #[test]
    fn mips_average_in_linear_light() {
        // Black and white columns: the half-size level is 50% linear grey, sRGB 188, not 128.
        let image = TextureImage {
            name: "t".into(),
            width: 4,
            height: 2,
            rgba: (0..8)
                .flat_map(|i| if i % 2 == 0 { [0, 0, 0, 255] } else { [255; 4] })
                .collect(),
            encoded: Vec::new(),
            mime: "image/png",
        };
        let l = Level::from_image(&image);
        let h = l.half();
        assert_eq!((h.width, h.height), (2, 1));
        assert_eq!(h.to_srgb8(), vec![188, 188, 188, 255, 188, 188, 188, 255]);
        assert_eq!(mip_count(4, 2), 3);
        assert_eq!(mip_count(1, 1), 1);
        assert_eq!(mip_count(1024, 1024), 11);
        assert_eq!(h.half().width, 1);
        // Resizing to its own size keeps the pixels; up to 8 x 4 keeps the corners.
        let same = l.clone().resized(4, 2);
        assert_eq!(same.to_srgb8(), image.rgba);
        let up = l.resized(8, 4);
        assert_eq!(up.to_srgb8()[..4], [0, 0, 0, 255]);
        assert_eq!(up.to_srgb8()[(8 * 4 - 1) * 4..], [255; 4]);
    }
}
