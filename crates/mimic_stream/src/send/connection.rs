//! A tracker's TCP connection to a server: the stream, and the thread reading the server's
//! replies (the welcome, errors and warnings, the `bye`); what a send over it did ([`TcpSent`]).

use super::error::SendError;
use serde_json::Value;
use std::io::{BufRead, BufReader, Read};
use std::net::{Shutdown, TcpStream};
use std::time::Duration;

/// Longest reply line read from the server (its replies are short JSON lines); a longer one is
/// reported and the replies are no longer read.
const MAX_REPLY_BYTES: usize = 64 * 1024;

/// What a TCP session's send did.
#[derive(Debug)]
pub struct TcpSent {
    /// Frames sent.
    pub sent: usize,
    /// The server's `bye` line, if one came.
    pub bye: Option<Value>,
    /// The write error that stopped the sending, if one did.
    pub write_failed: Option<SendError>,
}

/// A server's tracker connection: the stream, and the thread reading its replies.
pub(super) struct Connection {
    /// The stream frames go out on.
    pub(super) stream: TcpStream,
    replies: std::thread::JoinHandle<Option<Value>>,
}

impl Connection {
    /// Ends the sending and waits (up to 10 s) for the server's `bye`.
    pub(super) fn close(self) -> Result<Option<Value>, SendError> {
        let _ = self.stream.shutdown(Shutdown::Write);
        self.stream
            .set_read_timeout(Some(Duration::from_secs(10)))?;
        Ok(self.replies.join().ok().flatten())
    }
}

/// Connects to a server as a tracker; its replies (welcome, errors, bye) are read on their own
/// thread, errors told to `on_reply`, the welcome handed to `welcome` (if given), and the
/// thread returns the `bye` message, if one came.
pub(super) fn connect(
    to: &str,
    on_reply: fn(&str),
    welcome: Option<std::sync::mpsc::SyncSender<Value>>,
) -> Result<Connection, SendError> {
    let stream = TcpStream::connect(to).map_err(|source| SendError::Connect {
        to: to.to_string(),
        source,
    })?;
    stream.set_nodelay(true)?;
    let replies = stream.try_clone()?;
    let reader = std::thread::Builder::new()
        .name("mimic-send-replies".into())
        .spawn(move || {
            let mut bye = None;
            let mut replies = BufReader::new(replies);
            let mut buf = Vec::new();
            loop {
                buf.clear();
                // At most one byte over the cap is read: a line that long is not a reply.
                let cap = u64::try_from(MAX_REPLY_BYTES + 1).unwrap_or(u64::MAX);
                match (&mut replies).take(cap).read_until(b'\n', &mut buf) {
                    Ok(0) | Err(_) => break,
                    Ok(_) => {}
                }
                if buf.len() > MAX_REPLY_BYTES {
                    on_reply(&format!(
                        "a reply line over {MAX_REPLY_BYTES} bytes; no longer reading replies"
                    ));
                    break;
                }
                let line = String::from_utf8_lossy(&buf);
                let line = line.trim_end_matches(['\n', '\r']);
                let v: Value = serde_json::from_str(line).unwrap_or(Value::Null);
                match v["type"].as_str() {
                    Some("welcome") => {
                        tracing::info!("{line}");
                        if let Some(w) = &welcome {
                            let _ = w.try_send(v.clone());
                        }
                    }
                    Some("bye") => bye = Some(v),
                    _ => on_reply(line),
                }
            }
            bye
        })?;
    Ok(Connection {
        stream,
        replies: reader,
    })
}
