//! Paced replay: frames at their recorded pace on `tokio::time`, with speed, seek and looping.
//!
//! Frame `k` is due at `start + (t_k − t_first) / speed`, where `start` is the instant the first
//! frame was handed out: every deadline is computed from that one instant, so timer lateness
//! never accumulates. Looping restarts at the beginning of the recording (not at the seek
//! point) and shifts timestamps so they keep increasing: the first frame of a pass comes one
//! nominal frame interval (`1 / rate_hz`) after the last frame of the previous pass.
//! Lost-tracking frames are handed on like any other frame. A consumer slower than the recording
//! gets the late frames back to back; replay never drops frames to catch up.

use crate::recording::{FrameError, RecordedFrame, RecordingError, RecordingReader};
use mimic_types::LandmarkFrame;
use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};
use std::time::Duration;
use tokio::time::{Instant, sleep_until};

/// How fast frames are handed out.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Pace {
    /// At the recorded pace times `speed` (2.0 is twice as fast).
    Recorded {
        /// Speed factor, positive and finite.
        speed: f64,
    },
    /// Without waiting.
    AsFastAsPossible,
}

/// Where replay starts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ReplayStart {
    /// At the first frame.
    Beginning,
    /// At the first frame whose timestamp is at or after this one (µs, the recording's clock).
    Timestamp(i64),
    /// At the first frame at least this long after the recording's first frame.
    Offset(Duration),
}

/// Replay settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReplayOptions {
    /// Pacing.
    pub pace: Pace,
    /// Seek position for the first pass.
    pub start: ReplayStart,
    /// Start again from the beginning after the last frame.
    pub looping: bool,
}

impl Default for ReplayOptions {
    fn default() -> Self {
        Self {
            pace: Pace::Recorded { speed: 1.0 },
            start: ReplayStart::Beginning,
            looping: false,
        }
    }
}

/// Why replay cannot go on.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// The speed factor is not a positive number.
    #[error("replay speed {0} is not a positive number")]
    Speed(f64),
    /// Reopening the recording for the next loop failed.
    #[error(transparent)]
    Source(#[from] RecordingError),
}

/// A sequence of frames that can be restarted.
pub trait FrameSource {
    /// The next frame, a rejected line (skipped by [`Replay`] with a warning), or `None` at the end.
    fn next_frame(&mut self) -> Option<Result<RecordedFrame, FrameError>>;
    /// Goes back to the first frame.
    fn rewind(&mut self) -> Result<(), RecordingError>;
    /// Nominal gap between frames, in µs (used between loop passes).
    fn nominal_interval_us(&self) -> i64;
}

/// Frames held in memory.
pub struct MemorySource {
    frames: Vec<RecordedFrame>,
    next: usize,
    interval_us: i64,
}

impl MemorySource {
    /// Frames in time order and the nominal rate (Hz) that sets the gap between loop passes.
    pub fn new(frames: Vec<RecordedFrame>, rate_hz: f64) -> Self {
        Self {
            frames,
            next: 0,
            interval_us: interval_us(rate_hz),
        }
    }
}

impl FrameSource for MemorySource {
    fn next_frame(&mut self) -> Option<Result<RecordedFrame, FrameError>> {
        let f = self.frames.get(self.next)?.clone();
        self.next += 1;
        Some(Ok(f))
    }
    fn rewind(&mut self) -> Result<(), RecordingError> {
        self.next = 0;
        Ok(())
    }
    fn nominal_interval_us(&self) -> i64 {
        self.interval_us
    }
}

/// A recording file read line by line; rewinding reopens it.
pub struct FileSource {
    path: PathBuf,
    expected_points: Option<usize>,
    reader: RecordingReader<BufReader<File>>,
}

impl FileSource {
    /// Opens a recording (see [`RecordingReader::open`]).
    pub fn open(path: &Path, expected_points: Option<usize>) -> Result<Self, RecordingError> {
        let reader = RecordingReader::open(path, expected_points)?;
        Ok(Self {
            path: path.to_path_buf(),
            expected_points,
            reader,
        })
    }

    /// A source continuing from an open reader (e.g. one whose header was already looked at).
    pub fn from_reader(reader: RecordingReader<BufReader<File>>) -> Self {
        Self {
            path: reader.path().to_path_buf(),
            expected_points: reader.expected_points(),
            reader,
        }
    }

    /// The current pass's reader (header and counts).
    pub fn reader(&self) -> &RecordingReader<BufReader<File>> {
        &self.reader
    }
}

impl FrameSource for FileSource {
    fn next_frame(&mut self) -> Option<Result<RecordedFrame, FrameError>> {
        self.reader.next_frame()
    }
    fn rewind(&mut self) -> Result<(), RecordingError> {
        let points = self.expected_points.or(self.reader.expected_points());
        self.reader = RecordingReader::open(&self.path, points)?;
        Ok(())
    }
    fn nominal_interval_us(&self) -> i64 {
        interval_us(self.reader.header().rate_hz)
    }
}

fn interval_us(rate_hz: f64) -> i64 {
    if rate_hz.is_finite() && rate_hz > 0.0 {
        (1e6 / rate_hz).round().max(1.0) as i64
    } else {
        33_333
    }
}

/// One replayed frame.
#[derive(Clone, Debug, PartialEq)]
pub struct ReplayFrame {
    /// The frame, its timestamp shifted so it keeps increasing across loop passes.
    pub frame: LandmarkFrame,
    /// The frame's label, if the recording has one.
    pub label: Option<i64>,
    /// Timestamp as recorded (µs).
    pub recorded_us: i64,
    /// Loop pass, from 0.
    pub pass: u32,
}

/// Hands out a source's frames at their recorded pace.
pub struct Replay<S> {
    source: S,
    options: ReplayOptions,
    /// Instant the first frame was handed out, and its (shifted) timestamp.
    clock: Option<(Instant, i64)>,
    first_recorded_us: Option<i64>,
    seek_us: Option<i64>,
    pass: u32,
    pass_offset_us: i64,
    last_shifted_us: Option<i64>,
    frames_this_pass: usize,
    pending: Option<(ReplayFrame, Option<Instant>)>,
    skipped: usize,
    finished: bool,
}

impl Replay<MemorySource> {
    /// Replays frames held in memory; `rate_hz` sets the gap between loop passes.
    pub fn from_frames(
        frames: Vec<RecordedFrame>,
        rate_hz: f64,
        options: ReplayOptions,
    ) -> Result<Self, ReplayError> {
        Self::new(MemorySource::new(frames, rate_hz), options)
    }
}

impl Replay<FileSource> {
    /// Replays a recording file, reading it line by line.
    pub fn open(
        path: &Path,
        expected_points: Option<usize>,
        options: ReplayOptions,
    ) -> Result<Self, ReplayError> {
        Self::new(FileSource::open(path, expected_points)?, options)
    }
}

impl<S: FrameSource> Replay<S> {
    /// Replays `source` with `options`; fails on a speed that is not positive.
    pub fn new(source: S, options: ReplayOptions) -> Result<Self, ReplayError> {
        if let Pace::Recorded { speed } = options.pace
            && !(speed.is_finite() && speed > 0.0)
        {
            return Err(ReplayError::Speed(speed));
        }
        let seek_us = match options.start {
            ReplayStart::Timestamp(t) => Some(t),
            _ => None,
        };
        Ok(Self {
            source,
            options,
            clock: None,
            first_recorded_us: None,
            seek_us,
            pass: 0,
            pass_offset_us: 0,
            last_shifted_us: None,
            frames_this_pass: 0,
            pending: None,
            skipped: 0,
            finished: false,
        })
    }

    /// Rejected lines skipped so far.
    pub fn skipped(&self) -> usize {
        self.skipped
    }

    /// The source.
    pub fn source(&self) -> &S {
        &self.source
    }

    /// The next frame when it is due; `None` after the last one (never, when looping).
    ///
    /// Cancel-safe: a frame taken from the source but not yet due is kept for the next call.
    pub async fn next(&mut self) -> Option<Result<ReplayFrame, ReplayError>> {
        if self.pending.is_none() {
            match self.take() {
                Ok(Some(f)) => {
                    let due = self.due(f.frame.timestamp_us);
                    self.pending = Some((f, due));
                }
                Ok(None) => return None,
                Err(e) => return Some(Err(e)),
            }
        }
        if let Some((_, Some(due))) = &self.pending {
            sleep_until(*due).await;
        }
        self.pending.take().map(|(f, _)| Ok(f))
    }

    /// When a frame with this (shifted) timestamp is due; `None` when unpaced.
    fn due(&mut self, t_us: i64) -> Option<Instant> {
        let Pace::Recorded { speed } = self.options.pace else {
            return None;
        };
        let (start, origin) = *self.clock.get_or_insert_with(|| (Instant::now(), t_us));
        let micros = ((t_us - origin).max(0) as f64 / speed).round() as u64;
        Some(start + Duration::from_micros(micros))
    }

    /// The next frame to hand out, seek and loops applied.
    fn take(&mut self) -> Result<Option<ReplayFrame>, ReplayError> {
        loop {
            if self.finished {
                return Ok(None);
            }
            let Some(item) = self.source.next_frame() else {
                if !self.options.looping || self.frames_this_pass == 0 && self.pass > 0 {
                    self.finished = true;
                    return Ok(None);
                }
                self.source.rewind()?;
                self.seek_us = None;
                let gap = self.source.nominal_interval_us();
                if let (Some(last), Some(first)) = (self.last_shifted_us, self.first_recorded_us) {
                    self.pass_offset_us = last + gap - first;
                }
                self.pass += 1;
                self.frames_this_pass = 0;
                continue;
            };
            let rec = match item {
                Ok(r) => r,
                Err(e) => {
                    tracing::warn!("replay skips a frame: {e}");
                    self.skipped += 1;
                    continue;
                }
            };
            let recorded_us = rec.frame.timestamp_us;
            let first = *self.first_recorded_us.get_or_insert(recorded_us);
            if self.pass == 0 {
                if let ReplayStart::Offset(d) = self.options.start {
                    self.seek_us.get_or_insert(
                        first.saturating_add(d.as_micros().min(i64::MAX as u128) as i64),
                    );
                }
                if self.seek_us.is_some_and(|s| recorded_us < s) {
                    continue;
                }
            }
            let shifted = recorded_us + self.pass_offset_us;
            if self.last_shifted_us.is_some_and(|l| shifted <= l) {
                tracing::warn!(
                    "replay skips a frame at {recorded_us} us: not after the previous one"
                );
                self.skipped += 1;
                continue;
            }
            self.last_shifted_us = Some(shifted);
            self.frames_this_pass += 1;
            let mut frame = rec.frame;
            frame.timestamp_us = shifted;
            return Ok(Some(ReplayFrame {
                frame,
                label: rec.label,
                recorded_us,
                pass: self.pass,
            }));
        }
    }
}
