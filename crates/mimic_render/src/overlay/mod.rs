//! The overlay drawn over a rendered image: text, panels, the heat map's colour legend and bars,
//! as a list of screen-space quads ([`Quad`]) composited after the mesh by one instanced draw
//! ([`crate::Renderer::render_with`], [`crate::Renderer::draw_to_with`]). Building one allocates
//! nothing once its list has grown; [`Overlay::paint`] is the same compositing on the CPU.
//!
//! Coordinates are screen pixels, x right and y down from the top-left corner; a quad covers the
//! pixels whose centres lie inside it, so integer rectangles cover exactly their pixels and the
//! rest of the image is left as the mesh pass drew it.

mod legend;
mod pass;
pub mod text;

pub use legend::{LegendLayout, LegendTick, RAMP_STOPS, heat_color, legend_ticks};
pub(crate) use pass::OverlayPass;

use crate::Image;
use text::{GLYPH, LINE, block_height, glyph_bits, glyph_pixel, text_width};

/// Most quads an overlay holds (what the GPU buffer is sized for); more are counted as dropped.
pub const MAX_QUADS: usize = 8192;

/// Text colour (linear RGBA): near white.
pub const TEXT: [f32; 4] = [0.92, 0.92, 0.90, 1.0];
/// Dimmer text (labels, hints).
pub const DIM: [f32; 4] = [0.55, 0.57, 0.60, 1.0];
/// Panel background behind text: black at 60%.
pub const PANEL: [f32; 4] = [0.0, 0.0, 0.0, 0.6];
/// A bar's filled part.
pub const BAR: [f32; 4] = [0.95, 0.55, 0.12, 1.0];
/// A bar's empty part.
pub const BAR_BACK: [f32; 4] = [0.12, 0.12, 0.14, 1.0];
/// Padding of a panel around its content, in pixels at scale 1.
pub const PAD: i32 = 4;

/// What a quad draws.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum QuadKind {
    /// Its colour, alpha-blended.
    Solid = 0,
    /// Its colour where its glyph has a pixel, nothing elsewhere.
    Glyph = 1,
    /// The heat map's ramp, hot at the top, cold at the bottom (its colour's alpha).
    Ramp = 2,
}

/// One quad as the overlay shader reads it (`Quad` in `shaders/overlay.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Quad {
    /// Left, top, right, bottom, pixels.
    pub rect: [f32; 4],
    /// Linear RGBA.
    pub color: [f32; 4],
    /// [`QuadKind`], the glyph's two words ([`text::glyph_bits`]), the glyph's scale.
    pub info: [u32; 4],
}

impl Quad {
    /// The kind of quad.
    pub fn kind(&self) -> QuadKind {
        match self.info[0] {
            1 => QuadKind::Glyph,
            2 => QuadKind::Ramp,
            _ => QuadKind::Solid,
        }
    }
}

/// A corner or the middle of the screen, where a panel is placed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Anchor {
    /// Top-left corner.
    TopLeft,
    /// Top-right corner.
    TopRight,
    /// Bottom-left corner.
    BottomLeft,
    /// Bottom-right corner.
    BottomRight,
    /// Centred.
    Centre,
}

/// An integer rectangle: left, top, width, height (pixels).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Rect {
    /// Left edge.
    pub x: i32,
    /// Top edge.
    pub y: i32,
    /// Width.
    pub w: i32,
    /// Height.
    pub h: i32,
}

impl Rect {
    /// Whether pixel (`px`, `py`) lies inside.
    pub fn contains(&self, px: i32, py: i32) -> bool {
        px >= self.x && py >= self.y && px < self.x + self.w && py < self.y + self.h
    }

    /// A `w x h` rectangle at `anchor` of a `screen` (width, height), `margin` pixels from its edges.
    pub fn anchored(anchor: Anchor, w: i32, h: i32, screen: (u32, u32), margin: i32) -> Self {
        let (sw, sh) = (screen.0 as i32, screen.1 as i32);
        let (x, y) = match anchor {
            Anchor::TopLeft => (margin, margin),
            Anchor::TopRight => (sw - margin - w, margin),
            Anchor::BottomLeft => (margin, sh - margin - h),
            Anchor::BottomRight => (sw - margin - w, sh - margin - h),
            Anchor::Centre => ((sw - w) / 2, (sh - h) / 2),
        };
        Self { x, y, w, h }
    }
}

/// The quads of one overlay, rebuilt each frame (cleared, not freed).
#[derive(Clone, Debug, Default)]
pub struct Overlay {
    quads: Vec<Quad>,
    dropped: usize,
}

impl Overlay {
    /// An empty overlay.
    pub fn new() -> Self {
        Self::default()
    }

    /// Removes every quad (keeps the memory).
    pub fn clear(&mut self) {
        self.quads.clear();
        self.dropped = 0;
    }

    /// The quads, in drawing order.
    pub fn quads(&self) -> &[Quad] {
        &self.quads
    }

    /// True when there is nothing to draw.
    pub fn is_empty(&self) -> bool {
        self.quads.is_empty()
    }

    /// Quads left out because the overlay was full ([`MAX_QUADS`]).
    pub fn dropped(&self) -> usize {
        self.dropped
    }

    fn push(&mut self, quad: Quad) {
        if self.quads.len() < MAX_QUADS {
            self.quads.push(quad);
        } else {
            self.dropped += 1;
        }
    }

    /// A filled rectangle in `color` (linear RGBA, alpha-blended).
    pub fn rect(&mut self, r: Rect, color: [f32; 4]) {
        if r.w <= 0 || r.h <= 0 {
            return;
        }
        self.push(Quad {
            rect: edges(r),
            color,
            info: [QuadKind::Solid as u32, 0, 0, 0],
        });
    }

    /// The heat map's colour ramp over `r`, its hottest colour on the top row.
    pub fn ramp(&mut self, r: Rect) {
        if r.w <= 0 || r.h <= 0 {
            return;
        }
        self.push(Quad {
            rect: edges(r),
            color: [0.0, 0.0, 0.0, 1.0],
            info: [QuadKind::Ramp as u32, 0, 0, 0],
        });
    }

    /// One line of text with its top-left corner at (`x`, `y`), each font pixel `scale x scale`
    /// screen pixels; returns its width. Blank characters advance without a quad.
    pub fn text(&mut self, x: i32, y: i32, scale: u32, color: [f32; 4], s: &str) -> i32 {
        let scale = scale.max(1);
        let cell = GLYPH * scale as i32;
        let mut at = x;
        for c in s.chars() {
            let bits = glyph_bits(c);
            if bits != [0, 0] {
                self.push(Quad {
                    rect: edges(Rect {
                        x: at,
                        y,
                        w: cell,
                        h: cell,
                    }),
                    color,
                    info: [QuadKind::Glyph as u32, bits[0], bits[1], scale],
                });
            }
            at += cell;
        }
        at - x
    }

    /// Lines of text on a panel at `anchor` of `screen`, `margin` pixels from its edges; returns
    /// the panel's rectangle (nothing is drawn, and an empty one returned, for no lines).
    pub fn text_panel<'a>(
        &mut self,
        anchor: Anchor,
        screen: (u32, u32),
        margin: i32,
        scale: u32,
        lines: impl Iterator<Item = (&'a str, [f32; 4])> + Clone,
    ) -> Rect {
        let count = lines.clone().count();
        if count == 0 {
            return Rect::default();
        }
        let scale = scale.max(1);
        let pad = PAD * scale as i32;
        let w = lines
            .clone()
            .map(|(s, _)| text_width(s, scale))
            .max()
            .unwrap_or(0);
        let panel = Rect::anchored(
            anchor,
            w + 2 * pad,
            block_height(count, scale) + 2 * pad,
            screen,
            margin,
        );
        self.rect(panel, PANEL);
        for (k, (s, color)) in lines.enumerate() {
            let y = panel.y + pad + k as i32 * LINE * scale as i32;
            self.text(panel.x + pad, y, scale, color, s);
        }
        panel
    }

    /// Width and height of a [`Overlay::text_panel`] of `lines` at `scale` (to pick a scale that fits).
    pub fn panel_size<'a>(lines: impl Iterator<Item = &'a str> + Clone, scale: u32) -> (i32, i32) {
        let scale = scale.max(1);
        let pad = PAD * scale as i32;
        let w = lines
            .clone()
            .map(|s| text_width(s, scale))
            .max()
            .unwrap_or(0);
        (w + 2 * pad, block_height(lines.count(), scale) + 2 * pad)
    }

    /// Bars of `weights` (0 empty, 1 full; clamped) named by `names`, one row each, on a panel at
    /// `anchor`; rows past the screen's height are left out. Returns the panel's rectangle.
    pub fn bars<'a>(
        &mut self,
        anchor: Anchor,
        screen: (u32, u32),
        margin: i32,
        scale: u32,
        rows: impl Iterator<Item = (&'a str, f32)> + Clone,
    ) -> Rect {
        let scale = scale.max(1);
        let s = scale as i32;
        let (pad, pitch) = (PAD * s, LINE * s);
        let fit = ((screen.1 as i32 - 2 * margin - 2 * pad + (LINE - GLYPH) * s) / pitch).max(0);
        let count = rows.clone().take(fit as usize).count();
        if count == 0 {
            return Rect::default();
        }
        let name_w = rows
            .clone()
            .take(count)
            .map(|(n, _)| text_width(n, scale))
            .max()
            .unwrap_or(0);
        let bar_w = 12 * GLYPH * s;
        let gap = GLYPH * s;
        let panel = Rect::anchored(
            anchor,
            name_w + gap + bar_w + 2 * pad,
            block_height(count, scale) + 2 * pad,
            screen,
            margin,
        );
        self.rect(panel, PANEL);
        for (k, (name, w)) in rows.take(count).enumerate() {
            let y = panel.y + pad + k as i32 * pitch;
            self.text(panel.x + pad, y, scale, TEXT, name);
            let back = Rect {
                x: panel.x + pad + name_w + gap,
                y,
                w: bar_w,
                h: GLYPH * s,
            };
            self.rect(back, BAR_BACK);
            let fill = if w.is_finite() {
                w.clamp(0.0, 1.0)
            } else {
                0.0
            };
            self.rect(
                Rect {
                    w: (fill * bar_w as f32).round() as i32,
                    ..back
                },
                BAR,
            );
        }
        panel
    }

    /// The screen rectangles the overlay touches (its quads' rectangles); pixels outside all of
    /// them are the image as drawn without the overlay.
    pub fn rects(&self) -> impl Iterator<Item = Rect> + '_ {
        self.quads.iter().map(rect_of)
    }

    /// Composites the overlay onto `image` (sRGB RGBA8) on the CPU, as the GPU pass does: in
    /// linear light, `src * a + dst * (1 - a)`, alpha `a + dst_a * (1 - a)`.
    pub fn paint(&self, image: &mut Image) {
        let (w, h) = (image.width as i32, image.height as i32);
        for q in &self.quads {
            let r = rect_of(q);
            for py in r.y.max(0)..(r.y + r.h).min(h) {
                for px in r.x.max(0)..(r.x + r.w).min(w) {
                    let color = match q.kind() {
                        QuadKind::Solid => q.color,
                        QuadKind::Glyph => {
                            let s = q.info[3].max(1) as i32;
                            let (col, row) = ((px - r.x) / s, (py - r.y) / s);
                            if !glyph_pixel([q.info[1], q.info[2]], col as u32, row as u32) {
                                continue;
                            }
                            q.color
                        }
                        QuadKind::Ramp => {
                            let t = ((r.y + r.h) as f32 - (py as f32 + 0.5)) / r.h.max(1) as f32;
                            let [cr, cg, cb] = heat_color(t);
                            [cr, cg, cb, q.color[3]]
                        }
                    };
                    let at = (py as usize * image.width as usize + px as usize) * 4;
                    blend(&mut image.rgba[at..at + 4], color);
                }
            }
        }
    }
}

fn rect_of(q: &Quad) -> Rect {
    Rect {
        x: q.rect[0] as i32,
        y: q.rect[1] as i32,
        w: (q.rect[2] - q.rect[0]) as i32,
        h: (q.rect[3] - q.rect[1]) as i32,
    }
}

fn edges(r: Rect) -> [f32; 4] {
    [
        r.x as f32,
        r.y as f32,
        (r.x + r.w) as f32,
        (r.y + r.h) as f32,
    ]
}

/// sRGB-encoded byte to linear light.
pub fn srgb_to_linear(b: u8) -> f32 {
    let c = f32::from(b) / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Linear light (0..=1) to an sRGB-encoded byte, rounded.
pub fn linear_to_srgb(c: f32) -> u8 {
    let c = c.clamp(0.0, 1.0);
    let s = if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round() as u8
}

fn blend(px: &mut [u8], src: [f32; 4]) {
    let a = src[3].clamp(0.0, 1.0);
    for c in 0..3 {
        let dst = srgb_to_linear(px[c]);
        px[c] = linear_to_srgb(src[c] * a + dst * (1.0 - a));
    }
    let dst_a = f32::from(px[3]) / 255.0;
    px[3] = ((a + dst_a * (1.0 - a)) * 255.0).round() as u8;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_places_one_cell_per_character_and_skips_blanks() {
        let mut o = Overlay::new();
        let w = o.text(10, 20, 2, TEXT, "Hi x");
        // Four characters of 16 pixels; the blank gets no quad.
        assert_eq!(w, 64);
        let rects: Vec<Rect> = o.rects().collect();
        let at = |x| Rect {
            x,
            y: 20,
            w: 16,
            h: 16,
        };
        assert_eq!(rects, vec![at(10), at(26), at(58)]);
        assert!(o.quads().iter().all(|q| q.kind() == QuadKind::Glyph));
        assert_eq!(o.quads()[0].info[1..3], glyph_bits('H'));
        assert_eq!(o.quads()[0].info[3], 2);
    }

    #[test]
    fn panels_sit_in_their_corner_sized_to_their_text() {
        let mut o = Overlay::new();
        let screen = (200, 100);
        // Longest line 5 characters at scale 1: 40 + 2 * 4 pixels wide; two lines 18 + 8 high.
        let r = o.text_panel(
            Anchor::BottomRight,
            screen,
            6,
            1,
            [("abc", TEXT), ("defgh", DIM)].into_iter(),
        );
        assert_eq!(
            r,
            Rect {
                x: 200 - 6 - 48,
                y: 100 - 6 - 26,
                w: 48,
                h: 26
            }
        );
        assert_eq!(
            Overlay::panel_size(["abc", "defgh"].into_iter(), 1),
            (48, 26)
        );
        // The panel first, then the glyphs: the second line starts one pitch (10) lower.
        assert_eq!(o.quads()[0].kind(), QuadKind::Solid);
        let first = o.rects().nth(1).unwrap();
        let second_line = o.rects().nth(4).unwrap();
        assert_eq!((first.x, first.y), (r.x + 4, r.y + 4));
        assert_eq!((second_line.x, second_line.y), (r.x + 4, r.y + 14));
        let c = Rect::anchored(Anchor::Centre, 20, 10, screen, 6);
        assert_eq!((c.x, c.y), (90, 45));
        assert!(c.contains(90, 45) && c.contains(109, 54) && !c.contains(110, 54));
    }

    #[test]
    fn bars_fill_in_proportion_and_stop_at_the_screen() {
        let mut o = Overlay::new();
        let rows = [("a", 0.5f32), ("bb", 2.0), ("c", -1.0), ("d", f32::NAN)];
        let r = o.bars(Anchor::TopLeft, (400, 400), 0, 1, rows.iter().copied());
        // Name column 16 wide, a gap of 8, the bar 96: a half weight fills 48, 2 fills 96, the
        // negative and NaN weights nothing (no quad).
        assert_eq!(r.w, 16 + 8 + 96 + 8);
        let fills: Vec<i32> = o
            .quads()
            .iter()
            .filter(|q| q.color == BAR)
            .map(|q| (q.rect[2] - q.rect[0]) as i32)
            .collect();
        assert_eq!(fills, vec![48, 96]);
        // A screen of 30 pixels holds two rows of 10 at scale 1 with its padding.
        let mut small = Overlay::new();
        let r = small.bars(Anchor::TopLeft, (400, 30), 0, 1, rows.iter().copied());
        assert_eq!(r.h, block_height(2, 1) + 8);
    }

    #[test]
    fn a_full_overlay_counts_what_it_drops() {
        let mut o = Overlay::new();
        for k in 0..MAX_QUADS + 3 {
            o.rect(
                Rect {
                    x: k as i32,
                    y: 0,
                    w: 1,
                    h: 1,
                },
                TEXT,
            );
        }
        assert_eq!((o.quads().len(), o.dropped()), (MAX_QUADS, 3));
        o.clear();
        assert!(o.is_empty() && o.dropped() == 0);
    }

    #[test]
    fn paint_blends_in_linear_light() {
        let mut img = Image::filled(4, 1, [0, 0, 0, 255]);
        let mut o = Overlay::new();
        o.rect(
            Rect {
                x: 1,
                y: 0,
                w: 2,
                h: 1,
            },
            [1.0, 1.0, 1.0, 0.5],
        );
        o.paint(&mut img);
        // Half white over black is linear 0.5: sRGB 188.
        assert_eq!(
            &img.rgba[..12],
            &[0, 0, 0, 255, 188, 188, 188, 255, 188, 188, 188, 255]
        );
        assert_eq!(&img.rgba[12..], &[0, 0, 0, 255]);
        assert_eq!(linear_to_srgb(srgb_to_linear(77)), 77);
    }
}
