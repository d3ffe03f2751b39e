//! The fps and latency readout (in the window title, a few times a second).

use std::fmt::Write as _;
use std::time::{Duration, Instant};

/// How often the readout is refreshed.
pub const REFRESH: Duration = Duration::from_millis(500);

/// Frames presented and latencies over the current refresh interval.
#[derive(Clone, Debug)]
pub struct Readout {
    since: Option<Instant>,
    frames: u32,
    latency_sum: Duration,
    latency_max: Duration,
    latency_count: u32,
    /// Last figures: fps, mean and max latency over the last interval.
    pub shown: Figures,
}

/// The figures of one refresh interval.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Figures {
    /// Frames presented per second.
    pub fps: f64,
    /// Mean latency, ms (`None`: no frame measured).
    pub latency_ms: Option<f64>,
    /// Worst latency, ms.
    pub latency_max_ms: Option<f64>,
}

impl Default for Readout {
    fn default() -> Self {
        Self::new()
    }
}

impl Readout {
    /// Nothing counted yet.
    pub fn new() -> Self {
        Self {
            since: None,
            frames: 0,
            latency_sum: Duration::ZERO,
            latency_max: Duration::ZERO,
            latency_count: 0,
            shown: Figures::default(),
        }
    }

    /// A frame was presented at `now`, `latency` after its data arrived (or was stepped), if it
    /// showed new data. Returns true when the figures were refreshed (time to update the title).
    pub fn presented(&mut self, now: Instant, latency: Option<Duration>) -> bool {
        let since = *self.since.get_or_insert(now);
        self.frames += 1;
        if let Some(l) = latency {
            self.latency_sum += l;
            self.latency_max = self.latency_max.max(l);
            self.latency_count += 1;
        }
        let elapsed = now.saturating_duration_since(since);
        if elapsed < REFRESH {
            return false;
        }
        let ms = |d: Duration| d.as_secs_f64() * 1e3;
        self.shown = Figures {
            fps: f64::from(self.frames) / elapsed.as_secs_f64(),
            latency_ms: (self.latency_count > 0)
                .then(|| ms(self.latency_sum) / f64::from(self.latency_count)),
            latency_max_ms: (self.latency_count > 0).then(|| ms(self.latency_max)),
        };
        *self = Self {
            since: Some(now),
            shown: self.shown,
            ..Self::new()
        };
        true
    }
}

/// What the title shows besides the figures.
#[derive(Clone, Copy, Debug)]
pub struct Status<'a> {
    /// Rig name.
    pub rig: &'a str,
    /// Solver (or where the basis comes from, e.g. `live`).
    pub solver: &'a str,
    /// Current frame and frame count (`None` for a live feed's count).
    pub frame: (u64, Option<usize>),
    /// Playing (false: paused).
    pub playing: bool,
    /// Heat map on.
    pub heat: bool,
    /// A note, e.g. `waiting for session a` (empty for none).
    pub note: &'a str,
}

/// Writes the window title into `out` (cleared first; reused so refreshing allocates nothing
/// once it has grown).
pub fn write_title(out: &mut String, status: &Status<'_>, figures: &Figures) {
    out.clear();
    let _ = write!(out, "mimic view: {} ({})", status.rig, status.solver);
    let _ = match status.frame.1 {
        Some(n) => write!(out, " | frame {}/{n}", status.frame.0),
        None => write!(out, " | frame {}", status.frame.0),
    };
    if !status.playing {
        out.push_str(" paused");
    }
    if status.heat {
        out.push_str(" | heat");
    }
    let _ = write!(out, " | {:.1} fps", figures.fps);
    if let (Some(mean), Some(max)) = (figures.latency_ms, figures.latency_max_ms) {
        let _ = write!(out, " | latency {mean:.1} ms (max {max:.1})");
    }
    if !status.note.is_empty() {
        let _ = write!(out, " | {}", status.note);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn figures_over_an_interval() {
        let t0 = Instant::now();
        let mut r = Readout::new();
        // 31 frames 1/60 s apart: the 31st lands at 500 ms and refreshes.
        let mut refreshed = false;
        for k in 0..=30u32 {
            let at = t0 + Duration::from_micros(u64::from(k) * 16_667);
            let latency = (k % 2 == 0).then(|| Duration::from_millis(u64::from(1 + k % 4)));
            refreshed = r.presented(at, latency);
            if k < 30 {
                assert!(!refreshed);
            }
        }
        assert!(refreshed);
        assert!(
            (r.shown.fps - 31.0 / 0.50001).abs() < 0.01,
            "{}",
            r.shown.fps
        );
        // Latencies 1, 3, 1, 3, ... ms on the 16 even frames: mean 2.
        let mean = r.shown.latency_ms.unwrap();
        assert!((mean - 2.0).abs() < 1e-9, "{mean}");
        assert_eq!(r.shown.latency_max_ms, Some(3.0));
        // A new interval starts empty.
        assert!(!r.presented(t0 + Duration::from_millis(600), None));
    }

    #[test]
    fn title_shows_status_and_figures() {
        let mut s = String::new();
        let status = Status {
            rig: "ict-face",
            solver: "rbf",
            frame: (12, Some(1062)),
            playing: false,
            heat: true,
            note: "",
        };
        let f = Figures {
            fps: 59.94,
            latency_ms: Some(2.34),
            latency_max_ms: Some(4.0),
        };
        write_title(&mut s, &status, &f);
        assert_eq!(
            s,
            "mimic view: ict-face (rbf) | frame 12/1062 paused | heat | 59.9 fps | latency 2.3 ms (max 4.0)"
        );
        let live = Status {
            frame: (7, None),
            playing: true,
            heat: false,
            note: "waiting for session a",
            solver: "live",
            ..status
        };
        write_title(&mut s, &live, &Figures::default());
        assert_eq!(
            s,
            "mimic view: ict-face (live) | frame 7 | 0.0 fps | waiting for session a"
        );
    }
}
