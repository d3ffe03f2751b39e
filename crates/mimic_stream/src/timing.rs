//! The timestamp rule of a session: frames must come after the last accepted one, and not run
//! ahead of it by more than the wall-clock time between their arrivals plus a tolerance.

use std::time::{Duration, Instant};

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
}

impl FrameClock {
    /// A clock that takes any first timestamp and then allows jumps of the arrival gap plus
    /// `max_jump`.
    pub fn new(max_jump: Duration) -> Self {
        Self {
            last: None,
            max_jump,
        }
    }

    /// Takes `t_us` (arrived at `arrival`) as the new last timestamp, or says why not.
    pub fn advance(&mut self, t_us: i64, arrival: Instant) -> Result<(), TimeProblem> {
        if let Some((last, at)) = self.last {
            if t_us <= last {
                return Err(TimeProblem::Late);
            }
            // Both in i128: no overflow for any pair of i64 timestamps.
            let jump = i128::from(t_us) - i128::from(last);
            let allowed = arrival.saturating_duration_since(at) + self.max_jump;
            let allowed_us = i128::try_from(allowed.as_micros()).unwrap_or(i128::MAX);
            if jump > allowed_us {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn late_and_future_frames_leave_the_clock_where_it_was() {
        let t0 = Instant::now();
        let mut c = FrameClock::new(Duration::from_secs(10));
        assert_eq!(c.advance(i64::MIN + 1, t0), Ok(()));
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
}
