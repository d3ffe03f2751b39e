//! Pacing for the sender (`mimic send`): frames handed out at their recorded times, `start +
//! offset / speed`, on the calling thread (a blocking sleep), or at once with `fast`.

use std::time::{Duration, Instant};

/// Waits for each frame's time, measured from the pacer's start.
#[derive(Clone, Debug)]
pub struct Pacer {
    start: Instant,
    speed: f64,
    fast: bool,
}

impl Pacer {
    /// A pacer starting now at `speed` (2 is twice as fast; a speed that is not positive and
    /// finite counts as 1), or one that never waits (`fast`).
    pub fn new(speed: f64, fast: bool) -> Self {
        let speed = if speed.is_finite() && speed > 0.0 {
            speed
        } else {
            1.0
        };
        Self {
            start: Instant::now(),
            speed,
            fast,
        }
    }

    /// When a frame `offset_us` after the first is due: seconds after the start (negative
    /// offsets count as 0).
    pub fn due_s(&self, offset_us: i64) -> f64 {
        offset_us.max(0) as f64 / 1e6 / self.speed
    }

    /// Sleeps until the frame `offset_us` after the first is due (not with `fast`); returns when
    /// it was due, in seconds after the start.
    pub fn wait(&self, offset_us: i64) -> f64 {
        let due = self.due_s(offset_us);
        if !self.fast {
            let now = self.start.elapsed().as_secs_f64();
            if due > now
                && let Ok(d) = Duration::try_from_secs_f64(due - now)
            {
                std::thread::sleep(d);
            }
        }
        due
    }

    /// Seconds since the start.
    pub fn elapsed_s(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_due_at_their_offset_over_the_speed() {
        let p = Pacer::new(4.0, true);
        assert_eq!(p.due_s(2_000_000), 0.5);
        assert_eq!(p.due_s(-5), 0.0);
        assert_eq!(Pacer::new(0.0, true).due_s(1_000_000), 1.0);
        // Fast: no wait, whatever the offset.
        assert_eq!(p.wait(3_600_000_000), 900.0);
        // Paced: never before the frame is due (a lower bound only).
        let p = Pacer::new(1.0, false);
        let due = p.wait(20_000);
        assert!(p.elapsed_s() >= due, "{} < {due}", p.elapsed_s());
    }
}
