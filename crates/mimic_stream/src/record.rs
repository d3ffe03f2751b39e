//! Session recordings (`mimic serve --record DIR`): every accepted frame of a session, one file
//! per session, written and flushed frame by frame on a blocking thread behind a bounded
//! channel: a landmark session's frames as a v1 recording (`.jsonl`), a weights or Live Link
//! session's morph-target weights as a weights CSV (`.weights.csv`, [`weights`]). A full channel
//! makes the session wait (the tracker's TCP reads pause, its UDP queue fills) rather than lose an
//! accepted frame.

mod weights;

use weights::WeightsCsv;

use crate::counter::Counter;
use mimic_capture::{RecordedFrame, RecordingHeader, RecordingWriter, WriteError};
use serde_json::Value;
use std::fs::{File, OpenOptions};
use std::io::BufWriter;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{SystemTime, UNIX_EPOCH};
use tokio::sync::mpsc::{self, error::TrySendError};
use tokio::sync::oneshot;
use tokio::task::JoinHandle;

/// Counters of one session's recording.
#[derive(Debug, Default)]
pub struct RecordCounters {
    /// Frames written and flushed to the file.
    pub recorded: Counter,
    /// Accepted frames that could not be written (the file could not be created or a write
    /// failed); 0 unless the disk failed.
    pub lost: Counter,
    /// Frames that found the recording queue full, so the session waited for the disk.
    pub waits: Counter,
}

/// Why a session's recording could not be started.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// The file could not be created.
    #[error("creating {path}: {source}")]
    Create {
        /// The file.
        path: PathBuf,
        /// What the OS said.
        source: std::io::Error,
    },
    /// The header could not be written.
    #[error("writing the header of {path}: {source}")]
    Header {
        /// The file.
        path: PathBuf,
        /// What the writer said.
        source: WriteError,
    },
    /// The blocking task that creates the file failed.
    #[error("recording task: {0}")]
    Task(String),
}

/// Who a session is, for its recording's name and header.
#[derive(Debug)]
pub struct SessionLabel<'a> {
    /// Session name.
    pub name: &'a str,
    /// Session id.
    pub id: u32,
    /// Rig driven.
    pub rig: &'a str,
    /// The tracker's address.
    pub peer: Option<SocketAddr>,
}

/// Decrements the count of open recordings when the writer thread ends, however it ends.
struct OpenGuard(Arc<AtomicUsize>);

impl Drop for OpenGuard {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::AcqRel);
    }
}

/// What a session's recording holds.
#[derive(Clone, Copy, Debug)]
pub enum RecordKind<'a> {
    /// Landmark frames: a v1 recording with this header (`.jsonl`).
    Landmarks(&'a RecordingHeader),
    /// Morph-target weights, one column per name in this order (`.weights.csv`).
    Weights(&'a [String]),
}

/// One accepted frame, as its recording keeps it.
#[derive(Clone, Debug, PartialEq)]
pub enum Entry {
    /// A landmark frame.
    Landmarks(RecordedFrame),
    /// A frame's weights at `t_us`, in the recording's column order.
    Weights {
        /// Frame time (µs, the session's clock).
        t_us: i64,
        /// One weight per column.
        weights: Vec<f32>,
    },
}

impl From<RecordedFrame> for Entry {
    fn from(f: RecordedFrame) -> Self {
        Entry::Landmarks(f)
    }
}

/// The file a recording writes, by kind.
enum FileWriter {
    Landmarks(RecordingWriter<BufWriter<File>>),
    Weights(WeightsCsv),
}

impl FileWriter {
    /// Writes and flushes one entry (an entry of the other kind is an error).
    fn write(&mut self, e: &Entry) -> Result<(), WriteError> {
        match (self, e) {
            (FileWriter::Landmarks(w), Entry::Landmarks(f)) => w.write(f),
            (FileWriter::Weights(w), Entry::Weights { t_us, weights }) => {
                w.write(*t_us, weights).map_err(WriteError::from)
            }
            _ => Err(WriteError::Header(
                "a frame of another kind than the recording's".into(),
            )),
        }
    }

    /// The file under the buffer (for `fdatasync`).
    fn file(&self) -> &File {
        match self {
            FileWriter::Landmarks(w) => w.get_ref().get_ref(),
            FileWriter::Weights(w) => w.file(),
        }
    }

    /// Flushes what is buffered and hands back the file.
    fn finish(self) -> Result<File, WriteError> {
        match self {
            FileWriter::Landmarks(w) => w
                .finish()?
                .into_inner()
                .map_err(|e| WriteError::from(e.into_error())),
            FileWriter::Weights(w) => w.finish().map_err(WriteError::from),
        }
    }
}

/// A frame for the writer, and where to say when it is on disk (`--record-sync`).
/// A frame to write, and for a frame its sender waits on, the answer (true once written) and
/// whether to sync it to the disk too.
type Item = (Entry, Option<(oneshot::Sender<bool>, bool)>);

/// The session's end of its recording.
#[derive(Debug)]
pub struct Recorder {
    tx: mpsc::Sender<Item>,
    task: JoinHandle<()>,
    counters: Arc<RecordCounters>,
    path: PathBuf,
}

impl Recorder {
    /// Creates `DIR/<session>-<id>-<peer>-<UTC time>.jsonl` (`.weights.csv` for weights; never
    /// overwriting a file), writes the header and starts the writer thread; `open` counts
    /// recordings not yet closed.
    pub async fn start(
        dir: &Path,
        kind: RecordKind<'_>,
        who: &SessionLabel<'_>,
        queue_frames: usize,
        counters: Arc<RecordCounters>,
        open: Arc<AtomicUsize>,
    ) -> Result<Self, RecordError> {
        let now = SystemTime::now();
        let stamp = utc_stamp(now);
        let peer = who.peer.map_or("unknown".to_string(), |p| p.to_string());
        let safe_peer: String = peer
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '.' {
                    c
                } else {
                    '_'
                }
            })
            .collect();
        let stem = format!("{}-{}-{safe_peer}-{stamp}", who.name, who.id);
        let what = match kind {
            RecordKind::Landmarks(header) => {
                let mut h = header.clone();
                for (k, v) in [
                    ("session", Value::from(who.name)),
                    ("session_id", Value::from(who.id)),
                    ("rig", Value::from(who.rig)),
                    ("peer", Value::from(peer)),
                    ("recorded_by", Value::from("mimic serve")),
                    ("started_utc", Value::from(stamp)),
                ] {
                    h.extra.insert(k.to_string(), v);
                }
                Owned::Landmarks(h)
            }
            RecordKind::Weights(names) => Owned::Weights(names.to_vec()),
        };
        let dir = dir.to_path_buf();
        let (path, writer) = tokio::task::spawn_blocking(move || create(&dir, &stem, &what))
            .await
            .map_err(|e| RecordError::Task(e.to_string()))??;
        let (tx, mut rx) = mpsc::channel::<Item>(queue_frames.max(1));
        open.fetch_add(1, Ordering::AcqRel);
        let guard = OpenGuard(open);
        let c = counters.clone();
        let shown = path.clone();
        let task = tokio::task::spawn_blocking(move || {
            let _guard = guard;
            let mut writer = Some(writer);
            while let Some((f, ack)) = rx.blocking_recv() {
                let written = writer.as_mut().map(|w| {
                    w.write(&f)?;
                    if ack.as_ref().is_some_and(|(_, sync)| *sync) {
                        // Written and flushed to the OS per frame; now to the disk too.
                        w.file().sync_data().map_err(WriteError::from)?;
                    }
                    Ok::<(), WriteError>(())
                });
                let ok = match written {
                    Some(Ok(())) => {
                        c.recorded.bump();
                        true
                    }
                    Some(Err(e)) => {
                        tracing::error!(path = %shown.display(), "recording failed; the session's further frames are counted as record_lost: {e}");
                        c.lost.bump();
                        writer = None;
                        false
                    }
                    None => {
                        c.lost.bump();
                        false
                    }
                };
                if let Some((done, _)) = ack {
                    let _ = done.send(ok);
                }
            }
            if let Some(w) = writer {
                match w.finish() {
                    Ok(out) => {
                        if let Err(e) = out.sync_data() {
                            tracing::warn!(path = %shown.display(), "syncing the recording: {e}");
                        }
                    }
                    Err(e) => {
                        tracing::error!(path = %shown.display(), "closing the recording: {e}")
                    }
                }
            }
        });
        Ok(Self {
            tx,
            task,
            counters,
            path,
        })
    }

    /// The file being written.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Queues an accepted frame, waiting for room when the disk is behind (counted in `waits`).
    pub async fn record(&self, f: impl Into<Entry>) {
        let f = match self.tx.try_send((f.into(), None)) {
            Ok(()) => return,
            Err(TrySendError::Full(f)) => {
                self.counters.waits.bump();
                f
            }
            Err(TrySendError::Closed(_)) => {
                self.counters.lost.bump();
                return;
            }
        };
        if self.tx.send(f).await.is_err() {
            self.counters.lost.bump();
        }
    }

    /// Writes an accepted frame and flushes it to the OS (it then survives a kill of the
    /// process), with `sync` also to the disk (`fdatasync`: it survives a power loss), returning
    /// once that is done: true when it is written, false when it could not be (counted in `lost`).
    pub async fn record_acked(&self, f: impl Into<Entry>, sync: bool) -> bool {
        let (done, on_disk) = oneshot::channel();
        if self.tx.send((f.into(), Some((done, sync)))).await.is_err() {
            self.counters.lost.bump();
            return false;
        }
        on_disk.await.unwrap_or(false)
    }

    /// Closes the recording and waits until every queued frame is written, flushed and synced.
    pub async fn finish(self) {
        drop(self.tx);
        if let Err(e) = self.task.await {
            tracing::error!(path = %self.path.display(), "recording task: {e}");
        }
    }
}

/// A recording's kind with what its header needs, owned (for the blocking task).
enum Owned {
    Landmarks(RecordingHeader),
    Weights(Vec<String>),
}

/// Creates the file (first free name of `stem.jsonl`, `stem-2.jsonl`, ...; `.weights.csv` for
/// weights) and writes the header.
fn create(dir: &Path, stem: &str, what: &Owned) -> Result<(PathBuf, FileWriter), RecordError> {
    let ext = match what {
        Owned::Landmarks(_) => "jsonl",
        Owned::Weights(_) => "weights.csv",
    };
    let mut k = 1;
    let (path, file) = loop {
        let name = if k == 1 {
            format!("{stem}.{ext}")
        } else {
            format!("{stem}-{k}.{ext}")
        };
        let path = dir.join(name);
        match OpenOptions::new().write(true).create_new(true).open(&path) {
            Ok(f) => break (path, f),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && k < 1000 => k += 1,
            Err(source) => return Err(RecordError::Create { path, source }),
        }
    };
    let header_error = |source| RecordError::Header {
        path: path.clone(),
        source,
    };
    let writer = match what {
        Owned::Landmarks(header) => FileWriter::Landmarks(
            RecordingWriter::new(BufWriter::new(file), header)
                .map_err(header_error)?
                .flush_each_frame(true)
                .exact_coordinates(true),
        ),
        Owned::Weights(names) => {
            FileWriter::Weights(WeightsCsv::new(file, names).map_err(header_error)?)
        }
    };
    Ok((path, writer))
}

/// `YYYYMMDDTHHMMSSZ` of a time (UTC).
pub fn utc_stamp(t: SystemTime) -> String {
    let secs = t
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs() as i64);
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    // Civil date from days since 1970-01-01 (H. Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}{month:02}{day:02}T{:02}{:02}{:02}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use mimic_capture::RecordingReader;
    use mimic_types::LandmarkFrame;
    use std::time::Duration;

    #[test]
    fn utc_stamps() {
        let at = |s: u64| utc_stamp(UNIX_EPOCH + Duration::from_secs(s));
        assert_eq!(at(0), "19700101T000000Z");
        assert_eq!(at(951_782_400), "20000229T000000Z");
        assert_eq!(at(1_795_436_607), "20261123T122327Z");
    }

    #[tokio::test]
    async fn frames_land_in_order_and_a_second_session_gets_its_own_file() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().to_path_buf();
        let header = RecordingHeader::new("t", "test", 30.0, Some(1));
        let open = Arc::new(AtomicUsize::new(0));
        let who = SessionLabel {
            name: "a",
            id: 7,
            rig: "r",
            peer: "127.0.0.1:5000".parse().ok(),
        };
        let counters = Arc::new(RecordCounters::default());
        // A one-frame queue: most frames wait for the writer, none is lost.
        let kind = RecordKind::Landmarks(&header);
        let r = Recorder::start(&dir, kind, &who, 1, counters.clone(), open.clone())
            .await
            .unwrap();
        let again = Recorder::start(&dir, kind, &who, 1, Arc::default(), open.clone())
            .await
            .unwrap();
        assert_ne!(r.path(), again.path());
        assert_eq!(open.load(Ordering::Acquire), 2);
        let name = r.path().file_name().unwrap().to_string_lossy().into_owned();
        assert!(name.starts_with("a-7-127.0.0.1_5000-"), "{name}");
        let path = r.path().to_path_buf();
        let frames: Vec<_> = (0..200)
            .map(|k| LandmarkFrame::new(k, vec![glam::Vec3::new(k as f32 / 3.0, 1.0, -1.0)]))
            .collect();
        for f in &frames {
            r.record(RecordedFrame::unlabelled(f.clone())).await;
        }
        r.finish().await;
        again.finish().await;
        assert_eq!(open.load(Ordering::Acquire), 0);
        assert_eq!(counters.recorded.get(), 200);
        assert_eq!(counters.lost.get(), 0);
        let reader = RecordingReader::open(&path, None).unwrap();
        assert_eq!(reader.header().extra["session"], "a");
        assert_eq!(reader.header().extra["peer"], "127.0.0.1:5000");
        let got: Vec<_> = reader.map(|f| f.unwrap().frame).collect();
        assert_eq!(got, frames);
    }
}
