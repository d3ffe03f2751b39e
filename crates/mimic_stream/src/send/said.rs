//! What `mimic send` prints after a send: a server's `bye` in words ([`recording_bye`],
//! [`weights_bye`]) and each report's line ([`TcpSent::said`], [`UdpSent::said`],
//! [`TakeSender::lacking_line`], [`TakeSent::said`]).

use super::connection::TcpSent;
use super::take::{TakeSender, TakeSent};
use super::udp::UdpSent;
use serde_json::Value;
use std::net::SocketAddr;
use std::path::Path;

/// A landmark session's `bye` as printed.
pub fn recording_bye(b: &Value) -> String {
    let (f, l, m, why) = (&b["frames"], &b["late"], &b["malformed"], &b["reason"]);
    format!("{f} frames retargeted, {l} late, {m} malformed ({why})")
}

/// A weights session's `bye` as printed.
pub fn weights_bye(b: &Value) -> String {
    let (f, l, m, u, why) = (
        &b["frames"],
        &b["late"],
        &b["malformed"],
        &b["unknown_weights"],
        &b["reason"],
    );
    format!("{f} frames, {l} late, {m} malformed, {u} unknown weight names ({why})")
}

impl TcpSent {
    /// What the send of `frames` (e.g. `weight frames`) to `to` did, the `bye` worded by
    /// `server`; nothing when a write failed before any `bye` (that error is the news).
    pub fn said(&self, frames: &str, to: &str, server: fn(&Value) -> String) -> Option<String> {
        let sent = self.sent;
        match &self.bye {
            Some(b) => Some(format!(
                "sent {sent} {frames} to {to}; server: {}",
                server(b)
            )),
            None if self.write_failed.is_none() => Some(format!(
                "sent {sent} {frames} to {to}; no reply from the server"
            )),
            None => None,
        }
    }
}

impl UdpSent {
    /// What the send of `what` (e.g. `OpenSeeFace datagrams`) to `addr` at `speed` did; `of`
    /// names the source (`recording`, `take`).
    pub fn said(&self, what: &str, addr: SocketAddr, of: &str, speed: f64) -> String {
        let (n, t, span) = (self.sent, self.elapsed_s, self.span_s);
        format!("sent {n} {what} to {addr} in {t:.3} s ({of} {span:.3} s, speed {speed})")
    }
}

impl TakeSender {
    /// The line naming the take's names the rig lacks, if any.
    pub fn lacking_line(&self) -> Option<String> {
        if self.lacking.is_empty() {
            return None;
        }
        let (rig, k, all) = (&self.rig, self.lacking.len(), self.names());
        let names = self.lacking.join(", ");
        Some(format!(
            "rig `{rig}` has no morph target for {k} of the take's {all} names (not sent): {names}"
        ))
    }
}

impl TakeSent {
    /// What the send of the take `csv` did.
    pub fn said(&self, csv: &Path) -> String {
        let (sent, paced, due) = (self.tcp.sent, self.paced_s, self.last_due_s);
        let (rows, none, secs, fps) = (
            self.rows,
            self.untracked,
            self.duration_s,
            self.timecode_rate,
        );
        format!(
            "take {}: {rows} rows ({none} with no face, not sent), {secs:.3} s at {fps} fps timecode; sent {sent} weight frames in {paced:.3} s (due {due:.3} s)",
            csv.display()
        )
    }
}
