//! Throughput of many independent sessions: one [`Retargeter`] per session, each stepped on its
//! own named thread over the same looped frames, one basis shared by all (`Arc<Basis>`).

use crate::{FrameStatus, Retargeter};
use mimic_types::LandmarkFrame;
use std::time::{Duration, Instant};

/// What [`step_sessions`] measured.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SessionsReport {
    /// Sessions (threads) run at once.
    pub sessions: usize,
    /// Steps each session took (every frame counted, whatever its status).
    pub steps_per_session: usize,
    /// Tracked frames over all sessions.
    pub tracked: u64,
    /// Wall time from the common start until the last session finished, seconds.
    pub wall_s: f64,
    /// Frames per second over all sessions (`sessions * steps / wall`).
    pub frames_per_second: f64,
    /// Each session's own frames per second.
    pub per_session_frames_per_second: Vec<f64>,
}

/// Why [`step_sessions`] could not run.
#[derive(Debug, thiserror::Error)]
pub enum SessionsError {
    /// No frames to step.
    #[error("no frames to step")]
    NoFrames,
    /// A session thread could not be started or panicked.
    #[error("session thread {0}: {1}")]
    Thread(usize, String),
}

/// Steps every retargeter `steps` times over `frames` (looped, each loop shifted by `span_us`
/// so time runs forward) on its own thread (`mimic-session-K`), all released together after an
/// untimed warm-up loop over `frames` (the neutral and the source-to-target fit); the threads
/// share `frames` and nothing else but what the retargeters share (their basis).
pub fn step_sessions(
    retargeters: Vec<Retargeter>,
    frames: &[LandmarkFrame],
    span_us: i64,
    steps: usize,
) -> Result<SessionsReport, SessionsError> {
    if frames.is_empty() {
        return Err(SessionsError::NoFrames);
    }
    let sessions = retargeters.len();
    let barrier = std::sync::Barrier::new(sessions + 1);
    let results: Vec<Result<(Duration, u64), SessionsError>> = std::thread::scope(|scope| {
        let mut handles = Vec::with_capacity(sessions);
        for (k, mut r) in retargeters.into_iter().enumerate() {
            let barrier = &barrier;
            let spawned = std::thread::Builder::new()
                .name(format!("mimic-session-{k}"))
                .spawn_scoped(scope, move || {
                    let mut out = r.new_output();
                    let mut frame = frames[0].clone();
                    // Untimed warm-up: the neutral and the source-to-target fit (once per
                    // session, up to a few hundred milliseconds) and one loop of the frames.
                    for src in frames {
                        frame.clone_from(src);
                        frame.timestamp_us = src.timestamp_us - span_us;
                        r.step(&frame, &mut out);
                    }
                    barrier.wait();
                    let t = Instant::now();
                    let mut tracked = 0u64;
                    for s in 0..steps {
                        let src = &frames[s % frames.len()];
                        frame.points.clone_from(&src.points);
                        frame.valid.clone_from(&src.valid);
                        frame.tracked = src.tracked;
                        frame.timestamp_us = src.timestamp_us + (s / frames.len()) as i64 * span_us;
                        if r.step(&frame, &mut out) == FrameStatus::Tracked {
                            tracked += 1;
                        }
                    }
                    (t.elapsed(), tracked)
                });
            handles.push((k, spawned));
        }
        let started = handles.iter().filter(|(_, h)| h.is_ok()).count();
        // Threads that failed to start never reach the barrier: release the others anyway.
        if started == sessions {
            barrier.wait();
        }
        handles
            .into_iter()
            .map(|(k, h)| match h {
                Ok(h) => h
                    .join()
                    .map_err(|_| SessionsError::Thread(k, "panicked".into())),
                Err(e) => Err(SessionsError::Thread(k, e.to_string())),
            })
            .collect()
    });
    let mut per_session = Vec::with_capacity(sessions);
    let (mut wall, mut tracked) = (0f64, 0u64);
    for r in results {
        let (t, n) = r?;
        let secs = t.as_secs_f64();
        wall = wall.max(secs);
        tracked += n;
        per_session.push(if secs > 0.0 { steps as f64 / secs } else { 0.0 });
    }
    let total = (sessions * steps) as f64;
    Ok(SessionsReport {
        sessions,
        steps_per_session: steps,
        tracked,
        wall_s: wall,
        frames_per_second: if wall > 0.0 { total / wall } else { 0.0 },
        per_session_frames_per_second: per_session,
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "tests")]

    use super::*;
    use crate::RetargetSettings;
    use glam::Vec3;
    use std::sync::Arc;

    #[test]
    fn sessions_step_every_frame_and_share_one_basis() {
        let (rig, layout) = crate::tests::rig_and_layout();
        let basis = Arc::new(mimic_solve::build_basis(&rig, &rig.solver).unwrap());
        let retargeters: Vec<Retargeter> = (0..3)
            .map(|_| {
                Retargeter::new(&rig, &layout, basis.clone(), RetargetSettings::default()).unwrap()
            })
            .collect();
        assert_eq!(Arc::strong_count(&basis), 4, "one basis for three sessions");
        let neutral = crate::tests::neutral_points(&rig, &layout);
        let frames: Vec<LandmarkFrame> = (0..20)
            .map(|k| {
                let mut points = neutral.clone();
                // The first control moves up and down a little; the rest hold still.
                points[0] += Vec3::new(0.0, 0.0005 * (k % 4) as f32, 0.0);
                LandmarkFrame::new(k * 33_333, points)
            })
            .collect();
        // The same frames through one retargeter on this thread: the count each session sees.
        let mut one =
            Retargeter::new(&rig, &layout, basis.clone(), RetargetSettings::default()).unwrap();
        let mut out = one.new_output();
        let mut expect = 0u64;
        for f in &frames {
            let mut f = f.clone();
            f.timestamp_us -= 20 * 33_333;
            one.step(&f, &mut out);
        }
        for s in 0..50 {
            let mut f = frames[s % 20].clone();
            f.timestamp_us += (s / 20) as i64 * 20 * 33_333;
            if one.step(&f, &mut out) == FrameStatus::Tracked {
                expect += 1;
            }
        }
        assert_eq!(expect, 50, "after the warm-up every frame is tracked");
        let report = step_sessions(retargeters, &frames, 20 * 33_333, 50).unwrap();
        assert_eq!(report.sessions, 3);
        assert_eq!(report.steps_per_session, 50);
        assert_eq!(report.per_session_frames_per_second.len(), 3);
        assert_eq!(report.tracked, 3 * expect);
        assert!(report.frames_per_second > 0.0 && report.wall_s > 0.0);
        assert!(matches!(
            step_sessions(Vec::new(), &[], 0, 1),
            Err(SessionsError::NoFrames)
        ));
    }
}
