//! `mimic view --connect`: a viewer of a live `mimic serve` session on a background thread.
//!
//! The thread sends the viewer hello, reads length-prefixed messages (`docs/protocol.md`,
//! decoded by `mimic_wire`), passes SESSION, RIG, END and ERROR through an unbounded
//! channel (rare, never dropped) and frames through a [`Latest`] queue (newest wins), each
//! stamped with its arrival time.

use crate::latest::Latest;
use mimic_wire::{FrameMessage, RigMessage, ViewerMessage, decode_viewer_message};
use std::io::{BufReader, Read, Write};
use std::net::TcpStream;
use std::sync::Arc;
use std::sync::mpsc;
use std::time::Instant;

/// Frames waiting for the window at most (older ones are dropped).
pub const FRAME_QUEUE: usize = 4;
/// Largest message accepted (the ICT RIG message is about 5 MB).
pub const MAX_MESSAGE_BYTES: usize = 512 << 20;

/// A frame and when its last byte was read.
#[derive(Debug)]
pub struct Arrived {
    /// The frame.
    pub frame: FrameMessage,
    /// When it was read off the socket.
    pub at: Instant,
}

/// What the reader thread reports besides frames.
#[derive(Debug)]
pub enum Event {
    /// A tracker started the session (SESSION's JSON).
    Session(serde_json::Value),
    /// The session's rig.
    Rig(Box<RigMessage>),
    /// The tracker left (END's JSON).
    End(serde_json::Value),
    /// The server refused or closed with an error (ERROR's JSON).
    ServerError(serde_json::Value),
    /// The connection ended (EOF or an I/O or protocol error), with why.
    Closed(String),
}

/// Session events the socket thread may queue before it waits for the window.
pub const EVENT_QUEUE: usize = 16;

/// The consumer side of a live connection.
#[derive(Debug)]
pub struct Live {
    /// SESSION, RIG, END, ERROR and the end of the connection.
    pub events: mpsc::Receiver<Event>,
    /// Frames, newest wins.
    pub frames: Arc<Latest<Arrived>>,
}

/// Connects to `addr` as a viewer of `session` (presenting `token` when the server has one)
/// and starts the reader thread.
pub fn connect(addr: &str, session: &str, token: Option<&str>) -> std::io::Result<Live> {
    let mut stream = TcpStream::connect(addr)?;
    stream.set_nodelay(true)?;
    let mut hello = serde_json::json!({"type": "viewer", "session": session, "positions": false});
    if let Some(t) = token {
        hello["token"] = serde_json::Value::from(t);
    }
    stream.write_all(format!("{hello}\n").as_bytes())?;
    // Session events are few (SESSION, RIG, END, ERROR, the close): a small bound, which makes
    // the socket thread wait for the window rather than queue without limit.
    let (tx, events) = mpsc::sync_channel(EVENT_QUEUE);
    let frames = Arc::new(Latest::new(FRAME_QUEUE));
    let queue = frames.clone();
    std::thread::Builder::new()
        .name("mimic-view-socket".into())
        .spawn(move || {
            let why = read_messages(BufReader::new(stream), &tx, &queue);
            // The window may be gone already: nothing to tell then.
            let _ = tx.send(Event::Closed(why));
        })?;
    Ok(Live { events, frames })
}

/// Reads messages until the connection ends; returns why it ended.
pub fn read_messages<R: Read>(
    mut r: R,
    tx: &mpsc::SyncSender<Event>,
    frames: &Latest<Arrived>,
) -> String {
    let mut payload = Vec::new();
    loop {
        let mut len = [0u8; 4];
        match r.read_exact(&mut len) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => {
                return "the server closed the connection".into();
            }
            Err(e) => return format!("read error: {e}"),
        }
        let len = u32::from_le_bytes(len) as usize;
        if len == 0 || len > MAX_MESSAGE_BYTES {
            return format!("bad message length {len}");
        }
        payload.resize(len, 0);
        if let Err(e) = r.read_exact(&mut payload) {
            return format!("read error in a message: {e}");
        }
        let at = Instant::now();
        let event = match decode_viewer_message(payload[0], &payload[1..]) {
            Ok(ViewerMessage::Frame(frame)) => {
                frames.push(Arrived { frame, at });
                continue;
            }
            Ok(ViewerMessage::Session(v)) => Event::Session(v),
            Ok(ViewerMessage::Rig(rig)) => Event::Rig(Box::new(rig)),
            Ok(ViewerMessage::End(v)) => Event::End(v),
            Ok(ViewerMessage::Error(v)) => Event::ServerError(v),
            Err(e) => return format!("bad message: {e}"),
        };
        if tx.send(event).is_err() {
            return "the window closed".into();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mimic_wire::{KIND_END, KIND_SESSION, encode_json};

    #[test]
    fn messages_are_sorted_into_events_and_frames() {
        let mut bytes = encode_json(KIND_SESSION, &serde_json::json!({"session": "a"}));
        // A FRAME: seq 7, t 1000, tracked, no positions, m = 1.
        let mut frame = vec![3u8];
        frame.extend(7u64.to_le_bytes());
        frame.extend(1000i64.to_le_bytes());
        frame.extend([1, 0, 0, 0]);
        frame.extend(1u32.to_le_bytes());
        for f in [
            0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.5, 0.0, 0.0,
        ] {
            frame.extend(f.to_le_bytes());
        }
        bytes.extend((frame.len() as u32).to_le_bytes());
        bytes.extend(&frame);
        bytes.extend(encode_json(
            KIND_END,
            &serde_json::json!({"reason": "closed"}),
        ));
        let (tx, rx) = mpsc::sync_channel(EVENT_QUEUE);
        let q = Latest::new(2);
        let why = read_messages(bytes.as_slice(), &tx, &q);
        assert_eq!(why, "the server closed the connection");
        assert!(matches!(rx.try_recv(), Ok(Event::Session(v)) if v["session"] == "a"));
        assert!(matches!(rx.try_recv(), Ok(Event::End(v)) if v["reason"] == "closed"));
        let f = q.take_latest().unwrap().frame;
        assert_eq!((f.seq, f.timestamp_us, f.status), (7, 1000, 1));
        assert_eq!(f.displacements, vec![glam::Vec3::new(0.5, 0.0, 0.0)]);
    }

    #[test]
    fn a_bad_length_or_kind_ends_the_connection() {
        let (tx, _rx) = mpsc::sync_channel(EVENT_QUEUE);
        let q = Latest::new(2);
        assert_eq!(
            read_messages(&0u32.to_le_bytes()[..], &tx, &q),
            "bad message length 0"
        );
        let mut b = 1u32.to_le_bytes().to_vec();
        b.push(99);
        assert!(read_messages(b.as_slice(), &tx, &q).starts_with("bad message"));
        let mut b = 10u32.to_le_bytes().to_vec();
        b.push(3);
        assert!(read_messages(b.as_slice(), &tx, &q).starts_with("read error in a message"));
    }
}
