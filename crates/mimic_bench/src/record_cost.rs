//! What `mimic serve --record` costs many sessions: the sessions of [`crate::sessions`] stepped
//! with each frame also written as a recording line, the way the server writes it (a writer
//! thread per session behind a bounded queue of 128 frames, one `write` per frame), in each of
//! the server's modes, against no recording, alternating so every mode sees the same machine
//! speed states (docs/reliability.md, "Crash loss").
//!
//! - `queued` (`--record-queued`): the session hands the line over and goes on.
//! - `written` (the default): the session waits until the writer has written it to the OS.
//! - `synced` (`--record-sync`): as `written`, after an `fdatasync` too.

use crate::sessions::{SessionsError, step_sessions_with};
use mimic_retarget::{RetargetError, Retargeter};
use mimic_types::LandmarkFrame;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::mpsc;

/// The recording queue's length per session (the server's `--record-queue` default).
pub const QUEUE_FRAMES: usize = 128;

/// When a recorded frame is written, relative to the session going on (the server's modes).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RecordWrite {
    /// Handed to the writer; the session goes on at once.
    Queued,
    /// The session waits until the line is written to the OS.
    Written,
    /// The session waits until the line is written and synced to the disk.
    Synced,
}

/// One session's recording while it is stepped: the file's writer thread and its queue.
pub(crate) struct SessionRecording {
    tx: mpsc::SyncSender<(Vec<u8>, bool)>,
    acks: mpsc::Receiver<bool>,
    mode: RecordWrite,
    line: Vec<u8>,
}

impl SessionRecording {
    /// Writes `frame` as a recording line in this mode (waiting where the mode waits); false
    /// once the writer has stopped.
    pub(crate) fn frame(&mut self, frame: &LandmarkFrame) -> bool {
        self.line.clear();
        let _ = write!(self.line, "{{\"t_us\":{},\"points\":[", frame.timestamp_us);
        for (k, p) in frame.points.iter().enumerate() {
            let sep = if k == 0 { "" } else { "," };
            let _ = write!(self.line, "{sep}[{},{},{}]", p.x, p.y, p.z);
        }
        self.line.extend_from_slice(b"]}\n");
        let wait = self.mode != RecordWrite::Queued;
        if self.tx.send((self.line.clone(), wait)).is_err() {
            return false;
        }
        !wait || self.acks.recv().unwrap_or(false)
    }
}

/// Starts session `k`'s recording in `dir` (`session-K-MODE.jsonl`) with its writer thread in
/// `scope`.
pub(crate) fn start<'scope>(
    scope: &'scope std::thread::Scope<'scope, '_>,
    dir: &Path,
    k: usize,
    mode: RecordWrite,
) -> std::io::Result<SessionRecording> {
    let path: PathBuf = dir.join(format!("session-{k}-{mode:?}.jsonl").to_lowercase());
    let mut file = std::io::BufWriter::new(std::fs::File::create(path)?);
    let (tx, rx) = mpsc::sync_channel::<(Vec<u8>, bool)>(QUEUE_FRAMES);
    let (ack_tx, acks) = mpsc::sync_channel::<bool>(1);
    std::thread::Builder::new()
        .name(format!("mimic-record-{k}"))
        .spawn_scoped(scope, move || {
            for (line, ack) in rx {
                let mut ok = file.write_all(&line).and_then(|()| file.flush()).is_ok();
                if ack && mode == RecordWrite::Synced {
                    ok &= file.get_ref().sync_data().is_ok();
                }
                if ack && ack_tx.send(ok).is_err() {
                    return;
                }
            }
        })?;
    Ok(SessionRecording {
        tx,
        acks,
        mode,
        line: Vec::new(),
    })
}

/// One mode's frames per second over all sessions, per round.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ModeRuns {
    /// The mode (`None`: no recording).
    pub mode: Option<RecordWrite>,
    /// Frames per second over all sessions, each round.
    pub frames_per_second: Vec<f64>,
    /// The median over rounds.
    pub median_frames_per_second: f64,
    /// The median against no recording's median (1.0: free).
    pub ratio_to_none: f64,
}

/// What [`compare_recording`] measured.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RecordCost {
    /// Sessions at once.
    pub sessions: usize,
    /// Steps each session took in every run.
    pub steps_per_session: usize,
    /// No recording, then each mode.
    pub modes: Vec<ModeRuns>,
}

/// Steps `sessions` sessions at once `steps` steps each ([`step_sessions_with`]) with no
/// recording and with each mode's recording into `dir`, `rounds` rounds in turn; reports each
/// mode's median and its ratio to no recording.
pub fn compare_recording(
    make: impl Fn() -> Result<Retargeter, RetargetError>,
    frames: &[LandmarkFrame],
    span_us: i64,
    steps: usize,
    sessions: usize,
    dir: &Path,
    rounds: usize,
) -> Result<RecordCost, SessionsError> {
    let modes = [
        None,
        Some(RecordWrite::Queued),
        Some(RecordWrite::Written),
        Some(RecordWrite::Synced),
    ];
    let mut fps = vec![Vec::new(); modes.len()];
    for _ in 0..rounds.max(1) {
        for (m, mode) in modes.iter().enumerate() {
            let retargeters = (0..sessions)
                .map(|_| make())
                .collect::<Result<Vec<_>, _>>()?;
            let record = mode.map(|w| (dir, w));
            let report = step_sessions_with(retargeters, frames, span_us, steps, record)?;
            fps[m].push(report.frames_per_second);
        }
    }
    let median = |v: &[f64]| {
        let mut s = v.to_vec();
        s.sort_by(f64::total_cmp);
        s.get(s.len() / 2).copied().unwrap_or(0.0)
    };
    let none = median(&fps[0]);
    let modes = modes
        .iter()
        .zip(fps)
        .map(|(mode, runs)| {
            let m = median(&runs);
            ModeRuns {
                mode: *mode,
                median_frames_per_second: m,
                ratio_to_none: if none > 0.0 { m / none } else { 0.0 },
                frames_per_second: runs,
            }
        })
        .collect();
    Ok(RecordCost {
        sessions,
        steps_per_session: steps,
        modes,
    })
}
