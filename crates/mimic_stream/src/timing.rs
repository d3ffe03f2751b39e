//! The timestamp rule of a session: frames must come after the last accepted one, and not run
//! ahead of it by more than the wall-clock time between their arrivals plus a tolerance.
//!
//! Before a session's first accepted frame the clock stands at 0 with a range of
//! ±[`MAX_ABS_TIMESTAMP_US`]: a first frame outside it (`i64::MAX`, `1e18`, `i64::MIN`) is refused
//! and counted like any other and the clock stays unanchored, so the next sane frame anchors it.
//!
//! A restarted tracker starts its clock again: a frame more than [`RESTART_BACK`] behind the last
//! accepted one that arrives after at least [`RESTART_PAUSE`] without an accepted frame is the
//! first of a new run, so it re-anchors the clock (counted in [`FrameClock::restarts`]). The
//! same frame within a running stream (a repeat, a flood of a recording sent twice) is late.

use std::time::{Duration, Instant};

/// The largest `t_us` magnitude taken: 2^53 µs (about 285 years), the largest integer a JSON
/// double holds exactly. Unix time in µs (about 1.8e15 in 2026) is well inside.
pub const MAX_ABS_TIMESTAMP_US: i64 = 1 << 53;

/// How far behind the last accepted frame a new run of the tracker starts (more than a few
/// frames at any tracker rate).
pub const RESTART_BACK: Duration = Duration::from_millis(500);

/// How long a tracker is silent, at least, before a frame far behind is a new run rather than a
/// late frame (a tracker's restart takes longer; a stream's frames come tens of ms apart).
pub const RESTART_PAUSE: Duration = Duration::from_millis(500);

/// Why a frame's timestamp was not taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TimeProblem {
    /// Not after the last accepted frame's timestamp (late, repeated or out of order).
    Late,
    /// Ahead of the last accepted frame by more than the wall-clock time since it arrived plus
    /// the allowed jump: a clock from the future.
    Future {
        /// How far the frame's timestamp is past the last accepted one (µs).
        jump_us: u64,
        /// The most it could have been (µs).
        allowed_us: u64,
    },
}

/// The last accepted timestamp of a session and when it arrived.
#[derive(Clone, Copy, Debug)]
pub struct FrameClock {
    last: Option<(i64, Instant)>,
    max_jump: Duration,
    restarts: u64,
}

impl FrameClock {
    /// A clock that takes any first timestamp and then allows jumps of the arrival gap plus
    /// `max_jump`.
    pub fn new(max_jump: Duration) -> Self {
        Self {
            last: None,
            max_jump,
            restarts: 0,
        }
    }

    /// New runs of the tracker seen so far (each re-anchored the clock).
    pub fn restarts(&self) -> u64 {
        self.restarts
    }

    /// Takes `t_us` (arrived at `arrival`) as the new last timestamp, or says why not.
    ///
    /// A timestamp beyond ±[`MAX_ABS_TIMESTAMP_US`] is never taken: below it is `Late`, above it
    /// `Future` (judged against 0 with the range as the allowed jump while nothing was accepted).
    pub fn advance(&mut self, t_us: i64, arrival: Instant) -> Result<(), TimeProblem> {
        if t_us < -MAX_ABS_TIMESTAMP_US {
            return Err(TimeProblem::Late);
        }
        if self.last.is_none() && t_us > MAX_ABS_TIMESTAMP_US {
            return Err(TimeProblem::Future {
                jump_us: t_us.unsigned_abs(),
                allowed_us: MAX_ABS_TIMESTAMP_US.unsigned_abs(),
            });
        }
        if let Some((last, at)) = self.last {
            if t_us <= last {
                let back = i128::from(last) - i128::from(t_us);
                let pause = arrival.saturating_duration_since(at);
                if back > RESTART_BACK.as_micros() as i128 && pause >= RESTART_PAUSE {
                    self.restarts += 1;
                    self.last = Some((t_us, arrival));
                    return Ok(());
                }
                return Err(TimeProblem::Late);
            }
            // Both in i128: no overflow for any pair of i64 timestamps.
            let jump = i128::from(t_us) - i128::from(last);
            let allowed = arrival.saturating_duration_since(at) + self.max_jump;
            let allowed_us = i128::try_from(allowed.as_micros()).unwrap_or(i128::MAX);
            if jump > allowed_us || t_us > MAX_ABS_TIMESTAMP_US {
                return Err(TimeProblem::Future {
                    jump_us: u64::try_from(jump).unwrap_or(u64::MAX),
                    allowed_us: u64::try_from(allowed_us).unwrap_or(u64::MAX),
                });
            }
        }
        self.last = Some((t_us, arrival));
        Ok(())
    }
}

/// `t + d`, or about a century after `t` where that sum does not fit an `Instant` (a duration
/// setting of a library caller can be as large as `Duration::MAX`; the CLI bounds its own).
pub(crate) fn instant_after(
    t: tokio::time::Instant,
    d: std::time::Duration,
) -> tokio::time::Instant {
    const CENTURY: std::time::Duration = std::time::Duration::from_secs(100 * 365 * 24 * 3600);
    t.checked_add(d)
        .or_else(|| t.checked_add(CENTURY))
        .unwrap_or(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn late_and_future_frames_leave_the_clock_where_it_was() {
        let t0 = Instant::now();
        let mut c = FrameClock::new(Duration::from_secs(10));
        assert_eq!(c.advance(-MAX_ABS_TIMESTAMP_US, t0), Ok(()));
        // From the far past to the far future in one step: refused, no overflow.
        assert!(matches!(
            c.advance(i64::MAX, t0),
            Err(TimeProblem::Future { .. })
        ));
        let mut c = FrameClock::new(Duration::from_secs(10));
        assert_eq!(c.advance(1_000, t0), Ok(()));
        assert_eq!(c.advance(1_000, t0), Err(TimeProblem::Late));
        assert_eq!(c.advance(999, t0), Err(TimeProblem::Late));
        // 10 s after the last frame is allowed at once; a microsecond more is not ...
        assert_eq!(
            c.advance(1_000 + 10_000_001, t0),
            Err(TimeProblem::Future {
                jump_us: 10_000_001,
                allowed_us: 10_000_000
            })
        );
        assert_eq!(c.advance(1_000 + 10_000_000, t0), Ok(()));
        // ... unless that much wall-clock time went by between the arrivals (a tracker pause).
        let later = t0 + Duration::from_secs(60);
        assert_eq!(c.advance(1_000 + 10_000_000 + 65_000_000, later), Ok(()));
        assert_eq!(c.advance(1_000 + 75_000_001, later), Ok(()));
    }

    #[test]
    fn a_wild_first_timestamp_is_refused_and_the_next_sane_one_anchors_the_clock() {
        let t0 = Instant::now();
        for (wild, late) in [
            (i64::MAX, false),
            (1_000_000_000_000_000_000, false),
            (MAX_ABS_TIMESTAMP_US + 1, false),
            (i64::MIN, true),
            (-MAX_ABS_TIMESTAMP_US - 1, true),
        ] {
            let mut c = FrameClock::new(Duration::from_secs(10));
            let got = c.advance(wild, t0);
            assert_eq!(
                matches!(got, Err(TimeProblem::Late)),
                late,
                "{wild}: {got:?}"
            );
            assert_eq!(
                matches!(got, Err(TimeProblem::Future { .. })),
                !late,
                "{wild}: {got:?}"
            );
            // The session goes on: sane frames from any origin are taken, in order.
            assert_eq!(c.advance(1_000, t0), Ok(()), "after {wild}");
            assert_eq!(c.advance(34_333, t0), Ok(()), "after {wild}");
            // A wild frame in the middle is refused too, and leaves the clock where it was.
            assert!(c.advance(wild, t0).is_err(), "{wild} in the middle");
            assert_eq!(c.advance(67_666, t0), Ok(()), "after {wild} in the middle");
        }
        // Unix time in µs (2026) is a sane first timestamp; so are 0 and the range's ends.
        for first in [
            1_764_000_000_000_000,
            0,
            MAX_ABS_TIMESTAMP_US,
            -MAX_ABS_TIMESTAMP_US,
        ] {
            assert_eq!(FrameClock::new(Duration::ZERO).advance(first, t0), Ok(()));
        }
    }

    #[test]
    fn a_clock_far_behind_after_a_pause_is_a_new_run_and_re_anchors() {
        let t0 = Instant::now();
        let mut c = FrameClock::new(Duration::from_secs(10));
        assert_eq!(c.advance(5_000_000, t0), Ok(()));
        // Far behind within the stream: late, the clock stays.
        assert_eq!(c.advance(1_000_000, t0), Err(TimeProblem::Late));
        // A little behind after a pause: late too (a frame, not a new run).
        let paused = t0 + RESTART_PAUSE;
        assert_eq!(c.advance(4_900_000, paused), Err(TimeProblem::Late));
        assert_eq!(c.restarts(), 0);
        // Far behind after the pause: a new run, the clock starts from it.
        assert_eq!(c.advance(0, paused), Ok(()));
        assert_eq!(c.restarts(), 1);
        assert_eq!(c.advance(33_333, paused), Ok(()));
        assert_eq!(c.advance(10_000, paused), Err(TimeProblem::Late));
        // Wild timestamps never start a run.
        let later = paused + Duration::from_secs(5);
        assert_eq!(c.advance(i64::MIN, later), Err(TimeProblem::Late));
        assert_eq!(c.restarts(), 1);
    }

    #[test]
    fn instant_after_never_overflows() {
        let t = tokio::time::Instant::now();
        let d = std::time::Duration::from_millis(1500);
        assert_eq!(instant_after(t, d), t + d);
        // Duration::MAX does not fit: a century later instead of a panic.
        let far = instant_after(t, std::time::Duration::MAX);
        assert!(far > t + std::time::Duration::from_secs(50 * 365 * 24 * 3600));
    }
}
