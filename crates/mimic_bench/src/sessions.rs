//! Throughput of many independent sessions: one [`Retargeter`] per session, each stepped on its
//! own named thread over the same looped frames, one basis shared by all (`Arc<Basis>`); and
//! several retargeters stepped alternately on one thread, so that an A/B of their settings sees
//! the same machine speed states.

use crate::record_cost::RecordWrite;
use mimic_retarget::{FrameStatus, RetargetError, Retargeter, StageSamples, elapsed_ns};
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
    /// A session's retargeter could not be made.
    #[error("session retargeter: {0}")]
    Retargeter(#[from] RetargetError),
    /// A session's recording file or writer thread could not be made.
    #[error("session {0}'s recording: {1}")]
    Record(usize, std::io::Error),
}

/// What [`compare_sessions`] measured: one session against `sessions` at once.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SessionsComparison {
    /// Sessions run at once in the "many" runs.
    pub sessions: usize,
    /// Cores this process may use.
    pub cores: usize,
    /// Steps each session took in every run.
    pub steps_per_session: usize,
    /// The best of the one-session runs, frames per second.
    pub one_frames_per_second: f64,
    /// The best of the many-session runs, frames per second over all sessions.
    pub many_frames_per_second: f64,
    /// `many / one` (0 where one is 0).
    pub speedup: f64,
    /// The many-session figure per core in use (`sessions` or the cores, whichever is fewer).
    pub per_core_frames_per_second: f64,
    /// Every run, in the order run.
    pub runs: ComparisonRuns,
}

/// The runs behind a [`SessionsComparison`].
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ComparisonRuns {
    /// One session at a time.
    pub one: Vec<SessionsReport>,
    /// `sessions` at once.
    pub many: Vec<SessionsReport>,
}

/// Steps 1 session, then `sessions` at once, then 1 and `sessions` again (A/B pairs, so both see
/// the machine's speed states), each run `steps` steps a session ([`step_sessions`]) with fresh
/// retargeters from `make`; reports the best run of each.
pub fn compare_sessions(
    make: impl Fn() -> Result<Retargeter, RetargetError>,
    frames: &[LandmarkFrame],
    span_us: i64,
    steps: usize,
    sessions: usize,
) -> Result<SessionsComparison, SessionsError> {
    let fresh = |count: usize| (0..count).map(|_| make()).collect::<Result<Vec<_>, _>>();
    let mut runs = ComparisonRuns {
        one: Vec::new(),
        many: Vec::new(),
    };
    for _ in 0..2 {
        runs.one
            .push(step_sessions(fresh(1)?, frames, span_us, steps)?);
        runs.many
            .push(step_sessions(fresh(sessions)?, frames, span_us, steps)?);
    }
    let best = |v: &[SessionsReport]| v.iter().map(|r| r.frames_per_second).fold(0f64, f64::max);
    let (one, many) = (best(&runs.one), best(&runs.many));
    let cores = std::thread::available_parallelism().map_or(1, |c| c.get());
    Ok(SessionsComparison {
        sessions,
        cores,
        steps_per_session: steps,
        one_frames_per_second: one,
        many_frames_per_second: many,
        speedup: if one > 0.0 { many / one } else { 0.0 },
        per_core_frames_per_second: many / sessions.clamp(1, cores) as f64,
        runs,
    })
}

/// Steps every retargeter over the same `steps` frames of `frames` (looped, each loop shifted by
/// `span_us` so time runs forward), in turns of `block` frames each (at least 1), on this thread;
/// returns each one's timings of its tracked frames (whole step and stages), in the order given.
/// Taking turns puts every retargeter in the same machine speed states: an A/B of settings in
/// one run. With `block` 1 each step finds the caches holding the other retargeters' data; with
/// a block of many frames (a few ms) each runs warm, as one session does.
pub fn step_alternately(
    retargeters: &mut [Retargeter],
    frames: &[LandmarkFrame],
    span_us: i64,
    steps: usize,
    block: usize,
) -> Result<Vec<StageSamples>, SessionsError> {
    if frames.is_empty() {
        return Err(SessionsError::NoFrames);
    }
    let block = block.max(1);
    let mut outs: Vec<_> = retargeters.iter().map(Retargeter::new_output).collect();
    let mut samples: Vec<_> = retargeters
        .iter()
        .map(|_| StageSamples::with_capacity(steps))
        .collect();
    let mut frame = frames[0].clone();
    for start in (0..steps).step_by(block) {
        for ((r, out), samples) in retargeters.iter_mut().zip(&mut outs).zip(&mut samples) {
            for s in start..steps.min(start + block) {
                let src = &frames[s % frames.len()];
                frame.clone_from(src);
                frame.timestamp_us = src.timestamp_us + (s / frames.len()) as i64 * span_us;
                let t = Instant::now();
                let status = r.step(&frame, out);
                let ns = elapsed_ns(t);
                if status == FrameStatus::Tracked {
                    samples.push(ns, &out.times);
                }
            }
        }
    }
    Ok(samples)
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
    step_sessions_with(retargeters, frames, span_us, steps, None)
}

/// [`step_sessions`], with `record` each session also writing every timed frame as a recording
/// line into the folder in that mode ([`crate::record_cost`]).
pub fn step_sessions_with(
    retargeters: Vec<Retargeter>,
    frames: &[LandmarkFrame],
    span_us: i64,
    steps: usize,
    record: Option<(&std::path::Path, RecordWrite)>,
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
                    std::thread::scope(|writers| {
                        let mut rec = record
                            .map(|(dir, mode)| crate::record_cost::start(writers, dir, k, mode))
                            .transpose();
                        let mut out = r.new_output();
                        let mut frame = frames[0].clone();
                        // Untimed warm-up: the neutral and the source-to-target fit (once per
                        // session, up to a few hundred milliseconds) and one loop of the frames.
                        for src in frames {
                            frame.clone_from(src);
                            frame.timestamp_us = src.timestamp_us - span_us;
                            r.step(&frame, &mut out);
                        }
                        // Every started thread reaches the barrier, even one whose file failed.
                        barrier.wait();
                        let rec = match &mut rec {
                            Ok(rec) => rec,
                            Err(e) => {
                                let e = std::io::Error::new(e.kind(), e.to_string());
                                return Err(SessionsError::Record(k, e));
                            }
                        };
                        let t = Instant::now();
                        let mut tracked = 0u64;
                        for s in 0..steps {
                            let src = &frames[s % frames.len()];
                            frame.points.clone_from(&src.points);
                            frame.valid.clone_from(&src.valid);
                            frame.tracked = src.tracked;
                            frame.timestamp_us =
                                src.timestamp_us + (s / frames.len()) as i64 * span_us;
                            if r.step(&frame, &mut out) == FrameStatus::Tracked {
                                tracked += 1;
                            }
                            if let Some(rec) = rec.as_mut() {
                                rec.frame(&frame);
                            }
                        }
                        Ok((t.elapsed(), tracked))
                    })
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
                    .map_err(|_| SessionsError::Thread(k, "panicked".into()))
                    .and_then(|r| r),
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
mod tests;
