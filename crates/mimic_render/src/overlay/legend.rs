//! The heat map's colour legend: the ramp as a bar, hot at the top, with ticks at 0, half and
//! full scale labelled in a length unit that suits the scale (`0`, `0.5 cm`, `1 cm`).

use super::text::{GLYPH, LINE, text_width};
use super::{Anchor, DIM, Overlay, PAD, PANEL, Rect, TEXT};
use std::fmt::Write as _;

/// The ramp's stops at 0, 1/4, 1/2, 3/4 and 1 (linear RGB): blue, cyan, green, yellow, red. The
/// same numbers as `ramp` in `shaders/ramp.wgsl`, which the mesh's heat map and the legend use.
pub const RAMP_STOPS: [[f32; 3]; 5] = [
    [0.05, 0.10, 0.60],
    [0.00, 0.65, 0.90],
    [0.15, 0.80, 0.25],
    [0.98, 0.85, 0.10],
    [0.85, 0.08, 0.05],
];

/// The heat map's colour at `t` (clamped to 0..=1), linear RGB: piecewise linear between
/// [`RAMP_STOPS`].
pub fn heat_color(t: f32) -> [f32; 3] {
    let x = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    } * 4.0;
    let k = x.floor().min(3.0);
    let f = x - k;
    let (a, b) = (RAMP_STOPS[k as usize], RAMP_STOPS[k as usize + 1]);
    [0, 1, 2].map(|c| a[c] + (b[c] - a[c]) * f)
}

/// One tick of the legend: where on the bar (0 bottom, 1 top) and its label.
#[derive(Clone, Debug, PartialEq)]
pub struct LegendTick {
    /// Position on the bar, 0 (cold) to 1 (hot).
    pub at: f32,
    /// Label, e.g. `0.5 cm`.
    pub label: String,
}

/// A number with at most three significant digits, trailing zeros dropped (`1.5`, `0.75`, `12`).
fn short_number(out: &mut String, v: f64) {
    if v == 0.0 || !v.is_finite() {
        out.push('0');
        return;
    }
    let digits = (2 - v.abs().log10().floor() as i32).clamp(0, 9) as usize;
    let mut s = format!("{v:.digits$}");
    if s.contains('.') {
        while s.ends_with('0') {
            s.pop();
        }
        if s.ends_with('.') {
            s.pop();
        }
    }
    out.push_str(&s);
}

/// The ticks of a heat map whose hottest colour is `full_scale` rig units, the rig's length unit
/// being `units` (a name of `mimic_types::RIG_UNITS`): 0, half and full scale, in mm below 1 cm,
/// cm below 1 m, else m. `model` (or an unknown unit) labels plain numbers (with the unit's name,
/// when it has one other than `model`); `None` labels weights 0, 0.5, 1 (a control's weight map).
pub fn legend_ticks(full_scale: Option<f32>, units: &str) -> Vec<LegendTick> {
    let fractions = [0.0f64, 0.5, 1.0];
    let Some(full) = full_scale.map(f64::from) else {
        return fractions
            .iter()
            .map(|&f| {
                let mut label = String::new();
                short_number(&mut label, f);
                LegendTick {
                    at: f as f32,
                    label,
                }
            })
            .collect();
    };
    let (factor, unit): (f64, &str) = match mimic_types::rig::unit_in_metres(units) {
        Some(m) => {
            let metres = full * m;
            if metres < 0.01 {
                (m / 0.001, "mm")
            } else if metres < 1.0 {
                (m / 0.01, "cm")
            } else {
                (m, "m")
            }
        }
        None if units == "model" || units.is_empty() => (1.0, ""),
        None => (1.0, units),
    };
    fractions
        .iter()
        .map(|&f| {
            let mut label = String::new();
            short_number(&mut label, f * full * factor);
            if f > 0.0 && !unit.is_empty() {
                let _ = write!(label, " {unit}");
            }
            LegendTick {
                at: f as f32,
                label,
            }
        })
        .collect()
}

/// Where the legend's parts go: the panel, the ramp bar inside it, and the bar's height.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LegendLayout {
    /// The panel behind it all.
    pub panel: Rect,
    /// The ramp.
    pub bar: Rect,
}

impl Overlay {
    /// The colour legend at the bottom-right of `screen`: `title` on top, then the ramp bar
    /// with `ticks` to its left (labels right-aligned, a tick mark at each).
    pub fn legend(
        &mut self,
        screen: (u32, u32),
        margin: i32,
        scale: u32,
        title: &str,
        ticks: &[LegendTick],
    ) -> LegendLayout {
        let scale = scale.max(1);
        let s = scale as i32;
        let (pad, glyph) = (PAD * s, GLYPH * s);
        let label_w = ticks
            .iter()
            .map(|t| text_width(&t.label, scale))
            .max()
            .unwrap_or(0);
        let bar_w = 2 * glyph;
        let mark = glyph / 2;
        let bar_h = ((screen.1 as i32 * 3) / 10).clamp(4 * glyph, 40 * glyph);
        let title_h = LINE * s;
        let inner_w = (label_w + mark + bar_w).max(text_width(title, scale));
        // Half a glyph above and below the bar so its end labels fit.
        let inner_h = title_h + glyph / 2 + bar_h + glyph / 2;
        let panel = Rect::anchored(
            Anchor::BottomRight,
            inner_w + 2 * pad,
            inner_h + 2 * pad,
            screen,
            margin,
        );
        self.rect(panel, PANEL);
        self.text(panel.x + pad, panel.y + pad, scale, TEXT, title);
        let bar = Rect {
            x: panel.x + panel.w - pad - bar_w,
            y: panel.y + pad + title_h + glyph / 2,
            w: bar_w,
            h: bar_h,
        };
        self.ramp(bar);
        for t in ticks {
            let y = bar.y + ((1.0 - t.at.clamp(0.0, 1.0)) * (bar_h - s) as f32).round() as i32;
            self.rect(
                Rect {
                    x: bar.x - mark,
                    y,
                    w: mark,
                    h: s,
                },
                DIM,
            );
            let w = text_width(&t.label, scale);
            self.text(bar.x - mark - w, y - glyph / 2, scale, TEXT, &t.label);
        }
        LegendLayout { panel, bar }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn labels(full: Option<f32>, units: &str) -> Vec<String> {
        legend_ticks(full, units)
            .into_iter()
            .map(|t| t.label)
            .collect()
    }

    #[test]
    fn ticks_are_labelled_in_a_unit_that_suits_the_scale() {
        // 1 cm in a centimetre rig: 0, 0.5 cm, 1 cm.
        assert_eq!(labels(Some(1.0), "cm"), ["0", "0.5 cm", "1 cm"]);
        // 5% of a 30 cm diagonal: 1.5 cm, half 0.75 cm.
        assert_eq!(labels(Some(1.5), "cm"), ["0", "0.75 cm", "1.5 cm"]);
        // 0.012 m = 12 mm < 1 cm? No: 1.2 cm. 0.008 m is 8 mm, half 4 mm.
        assert_eq!(labels(Some(0.012), "m"), ["0", "0.6 cm", "1.2 cm"]);
        assert_eq!(labels(Some(0.008), "m"), ["0", "4 mm", "8 mm"]);
        // 2.5 mm in a millimetre rig stays in mm: 1.25 rounds to three digits.
        assert_eq!(labels(Some(2.5), "mm"), ["0", "1.25 mm", "2.5 mm"]);
        // 150 cm is 1.5 m.
        assert_eq!(labels(Some(150.0), "cm"), ["0", "0.75 m", "1.5 m"]);
        // 0.5 in = 12.7 mm = 1.27 cm.
        assert_eq!(labels(Some(0.5), "in"), ["0", "0.635 cm", "1.27 cm"]);
        // No physical unit: plain numbers.
        assert_eq!(labels(Some(0.04), "model"), ["0", "0.02", "0.04"]);
        // A control's weights.
        assert_eq!(labels(None, "cm"), ["0", "0.5", "1"]);
        let at: Vec<f32> = legend_ticks(Some(1.0), "cm").iter().map(|t| t.at).collect();
        assert_eq!(at, [0.0, 0.5, 1.0]);
    }

    #[test]
    fn the_ramp_runs_through_its_stops() {
        // At a stop, a + (b - a) * f rounds within one unit of the last place of 1.
        let near = |got: [f32; 3], want: [f32; 3]| {
            (0..3).all(|c| (got[c] - want[c]).abs() <= 2.0 * f32::EPSILON)
        };
        for (k, stop) in RAMP_STOPS.iter().enumerate() {
            let got = heat_color(k as f32 / 4.0);
            assert!(near(got, *stop), "stop {k}: {got:?}");
        }
        // Midway between cyan and green.
        let mid = heat_color(0.375);
        for c in 0..3 {
            let want = 0.5 * (RAMP_STOPS[1][c] + RAMP_STOPS[2][c]);
            assert!((mid[c] - want).abs() <= 2.0 * f32::EPSILON, "{mid:?}");
        }
        assert_eq!(heat_color(-1.0), RAMP_STOPS[0]);
        assert!(near(heat_color(7.0), RAMP_STOPS[4]));
        assert_eq!(heat_color(f32::NAN), RAMP_STOPS[0]);
    }

    #[test]
    fn the_legend_bar_sits_right_of_its_labels() {
        let mut o = Overlay::new();
        let ticks = legend_ticks(Some(1.0), "cm");
        let l = o.legend((400, 300), 8, 1, "|P - P0|", &ticks);
        // Bar: 16 wide, 30% of 300 = 90 high, at the panel's right inside its padding.
        assert_eq!((l.bar.w, l.bar.h), (16, 90));
        assert_eq!(l.bar.x + l.bar.w, l.panel.x + l.panel.w - PAD);
        assert_eq!(l.panel.x + l.panel.w, 400 - 8);
        assert_eq!(l.panel.y + l.panel.h, 300 - 8);
        assert!(l.panel.contains(l.bar.x, l.bar.y));
        // Every quad lies inside the panel.
        for r in o.rects() {
            assert!(
                r.x >= l.panel.x
                    && r.y >= l.panel.y
                    && r.x + r.w <= l.panel.x + l.panel.w
                    && r.y + r.h <= l.panel.y + l.panel.h,
                "{r:?} outside {:?}",
                l.panel
            );
        }
    }
}
