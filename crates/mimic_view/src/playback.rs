//! The playback clock of a local replay: recorded pace, pause, scrub, loop.

use std::time::Duration;

/// Position in a recording, moved by wall time at the recorded pace while playing.
#[derive(Clone, Debug)]
pub struct Playback {
    /// Frame times relative to the first frame, µs, non-decreasing.
    times_us: Vec<i64>,
    /// Current time relative to the first frame, µs.
    position_us: i64,
    /// Current frame: the last one whose time is at or before `position_us`.
    frame: usize,
    playing: bool,
    /// Times the playback wrapped from the end to the start.
    loops: u64,
}

impl Playback {
    /// A clock over frames with these capture times (µs; sorted, as a recording's accepted frames
    /// are), at the first frame, playing.
    pub fn new(times_us: &[i64]) -> Self {
        let first = times_us.first().copied().unwrap_or(0);
        Self {
            times_us: times_us.iter().map(|t| t.saturating_sub(first)).collect(),
            position_us: 0,
            frame: 0,
            playing: true,
            loops: 0,
        }
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        self.times_us.len()
    }

    /// True when there are no frames.
    pub fn is_empty(&self) -> bool {
        self.times_us.is_empty()
    }

    /// The current frame index.
    pub fn frame(&self) -> usize {
        self.frame
    }

    /// True while playing.
    pub fn playing(&self) -> bool {
        self.playing
    }

    /// Times the playback went round from the end to the start.
    pub fn loops(&self) -> u64 {
        self.loops
    }

    /// Space: pause or resume.
    pub fn toggle(&mut self) {
        self.playing = !self.playing;
    }

    /// Advances by `dt` of wall time while playing (at the end it goes round to the first frame);
    /// returns the current frame.
    pub fn advance(&mut self, dt: Duration) -> usize {
        let Some(&end) = self.times_us.last() else {
            return 0;
        };
        if !self.playing {
            return self.frame;
        }
        let dt = i64::try_from(dt.as_micros()).unwrap_or(i64::MAX);
        self.position_us = self.position_us.saturating_add(dt);
        if self.position_us > end {
            // One frame interval past the last frame, start again (a recording of one frame stays).
            let period = end.saturating_add(self.typical_interval()).max(1);
            self.loops += (self.position_us / period) as u64;
            self.position_us %= period;
        }
        self.frame = self
            .times_us
            .partition_point(|&t| t <= self.position_us)
            .saturating_sub(1);
        self.frame
    }

    /// Arrow keys: moves `by` frames (clamped to the recording) and stays there.
    pub fn step(&mut self, by: isize) -> usize {
        let last = self.len().saturating_sub(1);
        self.seek(self.frame.saturating_add_signed(by).min(last))
    }

    /// Goes to frame `frame` (clamped).
    pub fn seek(&mut self, frame: usize) -> usize {
        if let Some(&t) = self.times_us.get(frame).or_else(|| self.times_us.last()) {
            self.frame = frame.min(self.len() - 1);
            self.position_us = t;
        }
        self.frame
    }

    /// A horizontal drag: the frame at `fraction` (0..=1) of the recording's frames.
    pub fn seek_fraction(&mut self, fraction: f64) -> usize {
        let last = self.len().saturating_sub(1);
        self.seek((fraction.clamp(0.0, 1.0) * last as f64).round() as usize)
    }

    /// Average spacing of the frames (µs), at least 1.
    fn typical_interval(&self) -> i64 {
        let n = self.times_us.len();
        if n < 2 {
            return 1;
        }
        // Average spacing: the recording's span over its gaps (no allocation per frame).
        (self.times_us[n - 1] / (n as i64 - 1)).max(1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(k: u64) -> Duration {
        Duration::from_millis(k)
    }

    #[test]
    fn plays_at_the_recorded_pace_and_loops() {
        // 4 frames 100 ms apart, starting at an arbitrary tracker time.
        let mut p = Playback::new(&[5_000_000, 5_100_000, 5_200_000, 5_300_000]);
        assert_eq!(p.frame(), 0);
        assert_eq!(p.advance(ms(99)), 0);
        assert_eq!(p.advance(ms(1)), 1);
        assert_eq!(p.advance(ms(250)), 3);
        // The last frame is shown for one interval, then playback starts over.
        assert_eq!(p.advance(ms(49)), 3);
        assert_eq!(p.advance(ms(1)), 0);
        assert_eq!(p.loops(), 1);
    }

    #[test]
    fn pause_holds_and_scrub_moves_within_the_recording() {
        let mut p = Playback::new(&[0, 100_000, 200_000, 300_000]);
        p.toggle();
        assert!(!p.playing());
        assert_eq!(p.advance(ms(1000)), 0);
        assert_eq!(p.step(2), 2);
        assert_eq!(p.step(5), 3);
        assert_eq!(p.step(-10), 0);
        assert_eq!(p.seek_fraction(0.7), 2);
        assert_eq!(p.seek_fraction(2.0), 3);
        // Resuming continues from the scrubbed frame.
        p.seek(1);
        p.toggle();
        assert_eq!(p.advance(ms(100)), 2);
    }

    #[test]
    fn empty_and_single_frame_recordings_do_not_panic() {
        let mut p = Playback::new(&[]);
        assert!(p.is_empty());
        assert_eq!(
            (p.advance(ms(10)), p.step(3), p.seek_fraction(0.5)),
            (0, 0, 0)
        );
        let mut one = Playback::new(&[42]);
        assert_eq!((one.advance(ms(10)), one.step(1)), (0, 0));
    }
}
