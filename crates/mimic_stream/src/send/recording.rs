//! A recording replayed into a server as a landmark session (`mimic send REC.jsonl`).

use super::connection::{TcpSent, connect};
use super::error::SendError;
use super::options::SendOptions;
use mimic_capture::{
    FileSource, Pace, RecordedFrame, RecordingReader, RecordingWriter, Replay, ReplayOptions,
};
use serde_json::Value;
use std::path::Path;

/// Sends `path`'s frames as a landmark session (its header as the hello, with the options'
/// session, rig, forward and token), at the recorded pace.
pub fn send_recording(path: &Path, o: &SendOptions) -> Result<TcpSent, SendError> {
    let recording_reader = RecordingReader::open(path, None)?;
    let mut header = recording_reader.header().clone();
    let extra = [
        ("session", o.session.clone()),
        ("rig", o.rig.clone()),
        ("forward", o.forward.map(|f| f.to_string())),
        ("token", o.token.clone()),
    ];
    for (key, value) in extra {
        if let Some(v) = value {
            header.extra.insert(key.into(), Value::from(v));
        }
    }
    let conn = connect(&o.to, o.on_reply, None)?;
    let mut writer = RecordingWriter::new(&conn.stream, &header)?.flush_each_frame(true);
    let options = ReplayOptions {
        pace: if o.fast {
            Pace::AsFastAsPossible
        } else {
            Pace::Recorded { speed: o.speed }
        },
        looping: o.looping,
        ..ReplayOptions::default()
    };
    let mut replay = Replay::new(FileSource::from_reader(recording_reader), options)?;
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_time()
        .build()?;
    let mut sent = 0usize;
    let mut write_failed = None;
    let result = runtime.block_on(async {
        while let Some(item) = replay.next().await {
            let f = item?;
            if let Err(e) = writer.write(&RecordedFrame {
                frame: f.frame,
                label: f.label,
            }) {
                write_failed = Some(SendError::Frame(e));
                break;
            }
            sent += 1;
            if o.max_frames.is_some_and(|m| sent >= m) {
                break;
            }
        }
        Ok::<(), SendError>(())
    });
    drop(writer);
    let bye = conn.close()?;
    result?;
    Ok(TcpSent {
        sent,
        bye,
        write_failed,
    })
}
