//! What the window draws over the head ([`mimic_render::Overlay`]): the readout (rig, frame,
//! fps, latency, the last frame's state) top-left, the heat map's colour legend bottom-right,
//! the morph-target weights as bars top-right (key `w`), the waiting message in the middle, and
//! the key help (`?` or F1) centred over everything. Rebuilt every frame into reused strings and
//! quads: nothing allocates once they have grown.

use crate::keys::BINDINGS;
use crate::readout::Figures;
use mimic_render::overlay::{DIM, LegendTick, TEXT, legend_ticks};
use mimic_render::{Anchor, Overlay};
use std::fmt::Write as _;

/// Pixels between a panel and the window's edge.
pub const MARGIN: i32 = 8;

/// What the overlay shows this frame.
#[derive(Clone, Copy, Debug)]
pub struct HudState<'a> {
    /// Rig name (`-` before a live rig came).
    pub rig: &'a str,
    /// Solver, or `live`.
    pub solver: &'a str,
    /// The live session followed (`None`: a local replay).
    pub session: Option<&'a str>,
    /// Frame shown and frame count (`None` for a live feed).
    pub frame: (u64, Option<usize>),
    /// Playing (false: paused).
    pub playing: bool,
    /// fps and latency.
    pub figures: Figures,
    /// The shown frame's state (`tracked`, `lost (held)`, ...), if known.
    pub state: Option<&'a str>,
    /// The viewer's note (waiting, errors, basis builds); empty for none.
    pub note: &'a str,
    /// Nothing to draw yet (waiting for a live rig): the note goes in the middle.
    pub idle: bool,
    /// The heat map's full scale (rig units) when it is on.
    pub heat: Option<f32>,
    /// The rig's length unit (`cm`, `m`, `model`, ...).
    pub units: &'a str,
    /// Names of the morph targets whose weights are known (empty: none).
    pub weight_names: &'a [String],
    /// Their weights, parallel to `weight_names`.
    pub weights: &'a [f32],
}

/// The overlay, its toggles and the strings it draws from.
#[derive(Debug)]
pub struct Hud {
    overlay: Overlay,
    lines: [String; 4],
    help_text: Vec<String>,
    ticks: Vec<LegendTick>,
    ticks_for: Option<(f32, String)>,
    /// Key help shown (`?`, F1).
    pub show_help: bool,
    /// Weights shown as bars (`w`).
    pub show_weights: bool,
    /// The heat map's legend shown (`l`; on by default).
    pub show_legend: bool,
}

impl Default for Hud {
    fn default() -> Self {
        Self::new()
    }
}

/// Text scale for a window: 2 (16-pixel glyphs) from 640 pixels on each side, else 1.
pub fn text_scale(screen: (u32, u32)) -> u32 {
    if screen.0.min(screen.1) >= 640 { 2 } else { 1 }
}

/// The key help as lines: the mouse, then each key of [`BINDINGS`] with what it does.
pub fn help_lines() -> Vec<String> {
    let mut lines = vec![
        "keys (? or F1 closes this)".to_string(),
        "left drag: orbit, wheel: zoom, right drag: scrub".to_string(),
    ];
    for (key, _, what) in BINDINGS {
        if !what.is_empty() {
            lines.push(format!("{key:<9} {what}"));
        }
    }
    lines
}

/// The state label of a FRAME status byte (`docs/protocol.md`).
pub fn status_label(status: u8) -> &'static str {
    match status {
        0 => "calibrating",
        1 => "tracked",
        2 => "lost (held)",
        3 => "rejected (held)",
        _ => "gated (held)",
    }
}

impl Hud {
    /// Legend on, help and weights off.
    pub fn new() -> Self {
        Self {
            overlay: Overlay::new(),
            lines: Default::default(),
            help_text: help_lines(),
            ticks: Vec::new(),
            ticks_for: None,
            show_help: false,
            show_weights: false,
            show_legend: true,
        }
    }

    /// The overlay last built.
    pub fn overlay(&self) -> &Overlay {
        &self.overlay
    }

    /// Rebuilds the overlay for a `screen` (width, height) window showing `s`.
    pub fn build(&mut self, s: &HudState<'_>, screen: (u32, u32)) -> &Overlay {
        self.overlay.clear();
        let scale = text_scale(screen);
        let [l0, l1, l2, l3] = &mut self.lines;
        for l in [&mut *l0, &mut *l1, &mut *l2, &mut *l3] {
            l.clear();
        }
        if s.idle {
            // Only the message, in the middle.
            let msg = if s.note.is_empty() { "waiting" } else { s.note };
            let fits = Overlay::panel_size([msg].into_iter(), scale).0 <= screen.0 as i32;
            let scale = if fits { scale } else { 1 };
            self.overlay.text_panel(
                Anchor::Centre,
                screen,
                MARGIN,
                scale,
                [(msg, TEXT), ("? or F1: keys", DIM)].into_iter(),
            );
        } else {
            let _ = match s.session {
                Some(name) => write!(l0, "session {name}: {} ({})", s.rig, s.solver),
                None => write!(l0, "{} ({})", s.rig, s.solver),
            };
            let _ = match s.frame.1 {
                Some(n) => write!(l1, "frame {}/{n}", s.frame.0),
                None => write!(l1, "frame {}", s.frame.0),
            };
            if !s.playing {
                l1.push_str(" paused");
            }
            if let Some(state) = s.state {
                let _ = write!(l1, " {state}");
            }
            let _ = write!(l2, "{:.1} fps", s.figures.fps);
            if let (Some(mean), Some(max)) = (s.figures.latency_ms, s.figures.latency_max_ms) {
                let _ = write!(l2, " latency {mean:.1} ms (max {max:.1})");
            }
            l3.push_str(s.note);
            let rows = [
                (l0.as_str(), TEXT),
                (l1.as_str(), TEXT),
                (l2.as_str(), TEXT),
            ];
            let note = (!l3.is_empty()).then_some((l3.as_str(), DIM));
            self.overlay.text_panel(
                Anchor::TopLeft,
                screen,
                MARGIN,
                scale,
                rows.into_iter().chain(note),
            );
        }
        if let (Some(full), true, false) = (s.heat, self.show_legend, s.idle) {
            let stale = self
                .ticks_for
                .as_ref()
                .is_none_or(|(f, u)| *f != full || u != s.units);
            if stale {
                self.ticks = legend_ticks(Some(full), s.units);
                self.ticks_for = Some((full, s.units.to_string()));
            }
            self.overlay
                .legend(screen, MARGIN, scale, "|P - P0|", &self.ticks);
        }
        if self.show_weights && !s.idle {
            if s.weight_names.is_empty() {
                self.overlay.text_panel(
                    Anchor::TopRight,
                    screen,
                    MARGIN,
                    scale,
                    [("no weights known (w)", DIM)].into_iter(),
                );
            } else {
                let rows = s
                    .weight_names
                    .iter()
                    .map(String::as_str)
                    .zip(s.weights.iter().copied());
                self.overlay
                    .bars(Anchor::TopRight, screen, MARGIN, scale, rows);
            }
        }
        if self.show_help {
            let lines = self.help_text.iter().map(String::as_str);
            let fits = |k: u32| {
                let (w, h) = Overlay::panel_size(lines.clone(), k);
                w + 2 * MARGIN <= screen.0 as i32 && h + 2 * MARGIN <= screen.1 as i32
            };
            let scale = if fits(scale) { scale } else { 1 };
            let first = self.help_text.first().map(String::as_str);
            self.overlay.text_panel(
                Anchor::Centre,
                screen,
                MARGIN,
                scale,
                lines.map(|l| (l, if Some(l) == first { DIM } else { TEXT })),
            );
        }
        &self.overlay
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mimic_render::Rect;
    use mimic_render::overlay::{BAR, QuadKind};

    fn state<'a>(names: &'a [String], weights: &'a [f32]) -> HudState<'a> {
        HudState {
            rig: "ict-face",
            solver: "rbf",
            session: None,
            frame: (12, Some(1062)),
            playing: false,
            figures: Figures {
                fps: 59.94,
                latency_ms: Some(2.34),
                latency_max_ms: Some(4.0),
            },
            state: Some("tracked"),
            note: "",
            idle: false,
            heat: None,
            units: "cm",
            weight_names: names,
            weights,
        }
    }

    /// The union of the rectangles of all quads.
    fn union(o: &Overlay) -> Rect {
        let rs: Vec<Rect> = o.rects().collect();
        let x0 = rs.iter().map(|r| r.x).min().unwrap_or(0);
        let y0 = rs.iter().map(|r| r.y).min().unwrap_or(0);
        let x1 = rs.iter().map(|r| r.x + r.w).max().unwrap_or(0);
        let y1 = rs.iter().map(|r| r.y + r.h).max().unwrap_or(0);
        Rect {
            x: x0,
            y: y0,
            w: x1 - x0,
            h: y1 - y0,
        }
    }

    fn glyphs(o: &Overlay) -> usize {
        o.quads()
            .iter()
            .filter(|q| q.kind() == QuadKind::Glyph)
            .count()
    }

    fn ink(s: &str) -> usize {
        s.chars().filter(|c| !c.is_whitespace()).count()
    }

    #[test]
    fn the_readout_sits_top_left_with_every_character_drawn() {
        let mut hud = Hud::new();
        let o = hud.build(&state(&[], &[]), (400, 300));
        let lines = [
            "ict-face (rbf)",
            "frame 12/1062 paused tracked",
            "59.9 fps latency 2.3 ms (max 4.0)",
        ];
        assert_eq!(glyphs(o), lines.iter().map(|l| ink(l)).sum::<usize>());
        let r = union(o);
        // Scale 1 under 640 pixels: the longest line is 33 cells of 8 plus 4 of padding a side.
        assert_eq!(
            r,
            Rect {
                x: MARGIN,
                y: MARGIN,
                w: 33 * 8 + 8,
                h: 28 + 8
            }
        );
        // No legend without the heat map, no bars until `w`.
        assert!(o.quads().iter().all(|q| q.kind() != QuadKind::Ramp));
    }

    #[test]
    fn the_waiting_message_is_centred_and_alone() {
        let mut hud = Hud::new();
        let s = HudState {
            idle: true,
            note: "waiting for session a on 127.0.0.1:7878",
            heat: Some(1.0),
            ..state(&[], &[])
        };
        let o = hud.build(&s, (800, 800));
        assert_eq!(glyphs(o), ink(s.note) + ink("? or F1: keys"));
        let r = union(o);
        // Scale 2: 39 cells of 16 plus 8 of padding a side, centred.
        assert_eq!((r.w, r.h), (39 * 16 + 16, 36 + 16));
        assert_eq!((r.x, r.y), ((800 - r.w) / 2, (800 - r.h) / 2));
    }

    #[test]
    fn heat_draws_the_legend_bottom_right_and_keys_toggle_the_rest() {
        let names = ["jawOpen".to_string(), "eyeBlink_L".to_string()];
        let weights = [0.5, 1.0];
        let mut hud = Hud::new();
        let s = HudState {
            heat: Some(1.5),
            ..state(&names, &weights)
        };
        let screen = (500, 400);
        let o = hud.build(&s, screen);
        let ramp = o
            .quads()
            .iter()
            .find(|q| q.kind() == QuadKind::Ramp)
            .unwrap();
        assert!(ramp.rect[2] <= 500.0 - MARGIN as f32 && ramp.rect[3] <= 400.0 - MARGIN as f32);
        assert!(
            ramp.rect[0] > 250.0 && ramp.rect[1] > 200.0,
            "{:?}",
            ramp.rect
        );
        assert_eq!(
            hud.ticks
                .iter()
                .map(|t| t.label.as_str())
                .collect::<Vec<_>>(),
            ["0", "0.75 cm", "1.5 cm"]
        );
        // `l` off: no legend.
        hud.show_legend = false;
        let o = hud.build(&s, screen);
        assert!(o.quads().iter().all(|q| q.kind() != QuadKind::Ramp));
        // `w`: bars top-right, the first half full.
        hud.show_weights = true;
        let o = hud.build(&s, screen);
        let fills: Vec<f32> = o
            .quads()
            .iter()
            .filter(|q| q.color == BAR)
            .map(|q| q.rect[2] - q.rect[0])
            .collect();
        assert_eq!(fills, [48.0, 96.0]);
        let right = o.quads().iter().map(|q| q.rect[2]).fold(0.0, f32::max);
        assert_eq!(right, (500 - MARGIN) as f32);
        // No weights known: a hint instead of bars.
        let o = hud.build(&state(&[], &[]), screen);
        assert!(o.quads().iter().all(|q| q.color != BAR));
        let readout: usize = [
            "ict-face (rbf)",
            "frame 12/1062 paused tracked",
            "59.9 fps latency 2.3 ms (max 4.0)",
        ]
        .iter()
        .map(|l| ink(l))
        .sum();
        assert_eq!(glyphs(o), readout + ink("no weights known (w)"));
    }

    #[test]
    fn the_help_lists_every_key_and_fits_the_window() {
        let lines = help_lines();
        for (key, _, what) in BINDINGS {
            if !what.is_empty() {
                assert!(
                    lines.iter().any(|l| l.starts_with(key) && l.contains(what)),
                    "{key}"
                );
            }
        }
        let mut hud = Hud::new();
        hud.show_help = true;
        for screen in [(800, 800), (480, 400)] {
            let o = hud.build(&state(&[], &[]), screen);
            let help = o.rects().last().unwrap();
            let r = union(o);
            assert!(
                r.x >= 0 && r.x + r.w <= screen.0 as i32,
                "{screen:?}: {r:?}"
            );
            assert!(help.y + help.h <= screen.1 as i32);
        }
    }
}
