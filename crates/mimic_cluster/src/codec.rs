//! Subjects and the bytes on them (docs/protocol.md, "Cluster"): frames in, answers and notices
//! out, the placement request and reply, lease and checkpoint values.

use mimic_retarget::Checkpoint;
use mimic_stream::placement::StepResult;
use mimic_types::LandmarkFrame;
use serde::{Deserialize, Serialize};

/// Subject of placement requests (a queue group of workers answers).
pub(crate) const OPEN: &str = "mimic.ctl.open";
/// Queue group of the workers.
pub(crate) const WORKERS: &str = "mimic-workers";

/// A session name as a subject token and key: itself when it has no `.` (a subject separator),
/// else `x` and its bytes in hex.
pub fn token(session: &str) -> String {
    if session
        .bytes()
        .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'_' | b'-'))
    {
        return session.to_string();
    }
    let mut t = String::from("x");
    for b in session.bytes() {
        t.push_str(&format!("{b:02x}"));
    }
    t
}

/// Frames in.
pub(crate) fn in_subject(tok: &str) -> String {
    format!("mimic.in.{tok}")
}
/// Answers and notices out.
pub(crate) fn out_subject(tok: &str) -> String {
    format!("mimic.out.{tok}")
}
/// Session description requests.
pub(crate) fn info_subject(tok: &str) -> String {
    format!("mimic.info.{tok}")
}

/// Tag of a frame (in) or an answer (out).
const FRAME: u8 = b'F';
/// Tag of the end of a session's frames (in, front door to worker) or of the session (out,
/// front door to followers).
const END: u8 = b'E';
/// Tag of the live notice (out): the session description.
const LIVE: u8 = b'L';
/// Tag of a worker's last word on a session (out): it answered every frame it got.
const DONE: u8 = b'D';

/// Frame `n` as it goes to the worker: tag, number, then the UDP frame packet of docs/protocol.md.
pub(crate) fn encode_in_frame(n: u64, frame: &LandmarkFrame) -> Vec<u8> {
    let packet = mimic_wire::encode_udp_frame(0, 0, frame);
    let mut b = Vec::with_capacity(9 + packet.len());
    b.push(FRAME);
    b.extend_from_slice(&n.to_le_bytes());
    b.extend_from_slice(&packet);
    b
}

/// The end of a session's frames (`sent` frames were handed over).
pub(crate) fn encode_in_end(sent: u64) -> Vec<u8> {
    let mut b = vec![END];
    b.extend_from_slice(&sent.to_le_bytes());
    b
}

/// What a worker gets on a session's input subject.
#[derive(Debug)]
pub(crate) enum In {
    /// Frame `n`.
    Frame(u64, LandmarkFrame),
    /// No more frames.
    End,
}

/// Reads a message of a session's input subject.
pub(crate) fn decode_in(b: &[u8]) -> Option<In> {
    match *b.first()? {
        FRAME => {
            let n = u64::from_le_bytes(b.get(1..9)?.try_into().ok()?);
            let f = mimic_wire::decode_udp_frame(b.get(9..)?).ok()?;
            Some(In::Frame(n, f.frame))
        }
        END => Some(In::End),
        _ => None,
    }
}

/// An answer: tag, gated, jump, then the FRAME viewer message (its sequence number is `n`).
pub(crate) fn encode_answer(gated: bool, jump: bool, message: &[u8]) -> Vec<u8> {
    let mut b = Vec::with_capacity(3 + message.len());
    b.extend_from_slice(&[FRAME, u8::from(gated), u8::from(jump)]);
    b.extend_from_slice(message);
    b
}

/// The live notice / info reply: the session's description and rig.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub(crate) struct LiveNotice {
    /// SESSION message JSON.
    pub(crate) description: serde_json::Value,
    /// Rig name.
    pub(crate) rig: String,
}

/// The live notice as it goes out.
pub(crate) fn encode_live(n: &LiveNotice) -> Vec<u8> {
    let mut b = vec![LIVE];
    b.extend_from_slice(&serde_json::to_vec(n).unwrap_or_default());
    b
}

/// The session's end (out).
pub(crate) fn encode_out_end() -> Vec<u8> {
    vec![END]
}

/// A worker's last word on a session: it answered every frame it got.
pub(crate) fn encode_done() -> Vec<u8> {
    vec![DONE]
}

/// What a front door gets on a session's output subject.
#[derive(Debug)]
pub(crate) enum Out {
    /// An answer.
    Answer(StepResult),
    /// The session is live (description).
    Live(LiveNotice),
    /// The session ended.
    End,
    /// The worker is done with the session.
    Done,
}

/// Reads a message of a session's output subject.
pub(crate) fn decode_out(b: &[u8]) -> Option<Out> {
    match *b.first()? {
        FRAME => {
            let gated = *b.get(1)? != 0;
            let jump = *b.get(2)? != 0;
            let message = b.get(3..)?.to_vec();
            // The FRAME message's sequence number: after its length (4) and kind (1) bytes.
            let n = u64::from_le_bytes(message.get(5..13)?.try_into().ok()?);
            Some(Out::Answer(StepResult {
                n,
                gated,
                jump,
                message,
            }))
        }
        LIVE => serde_json::from_slice(b.get(1..)?).ok().map(Out::Live),
        END => Some(Out::End),
        DONE => Some(Out::Done),
        _ => None,
    }
}

/// A front door's placement request.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub(crate) struct OpenRequest {
    /// Session name.
    pub(crate) session: String,
    /// Rig name.
    pub(crate) rig: String,
    /// Layout name.
    pub(crate) layout: String,
    /// The front door asking.
    pub(crate) host: String,
    /// The front door's id of the session (with `host`, names this session instance).
    #[serde(default)]
    pub(crate) id: Option<u32>,
    /// A failover: continue from the session's checkpoint.
    pub(crate) resume: bool,
}

/// A worker's reply.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub(crate) struct OpenReply {
    /// The worker took the session.
    pub(crate) ok: bool,
    /// The worker's name.
    pub(crate) worker: String,
    /// Why not, when it did not.
    pub(crate) why: String,
    /// With `ok` on a resume: the checkpoint was restored (else the session starts afresh).
    pub(crate) restored: bool,
}

/// A lease's value.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub(crate) struct Lease {
    /// The worker holding it.
    pub(crate) worker: String,
    /// The session's front door.
    pub(crate) host: String,
    /// The front door's id of the session, from the placement request.
    #[serde(default)]
    pub(crate) id: Option<u32>,
}

impl Lease {
    /// Whether this lease was taken for session instance `id` of front door `host`: a front
    /// door whose placement reply was lost (timed out) finds its worker this way.
    pub(crate) fn taken_for(&self, host: &str, id: u32) -> bool {
        self.host == host && self.id == Some(id)
    }
}

/// A checkpoint's value.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub(crate) struct Saved {
    /// The number of the last frame stepped into it.
    pub(crate) n: u64,
    /// The retargeter's state after it.
    pub(crate) checkpoint: Checkpoint,
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "tests")]
    use super::*;
    use glam::Vec3;

    #[test]
    fn tokens_are_subject_safe_and_distinct() {
        assert_eq!(token("cam-1_a"), "cam-1_a");
        assert_eq!(token("a.b"), "x612e62");
        assert_ne!(token("a.b"), token("a_b"));
    }

    #[test]
    fn frames_in_round_trip() {
        let f = LandmarkFrame::new(123_456, vec![Vec3::new(0.1, -0.2, 0.7); 5]);
        let b = encode_in_frame(42, &f);
        let Some(In::Frame(n, g)) = decode_in(&b) else {
            panic!("not a frame")
        };
        assert_eq!(
            (n, g.timestamp_us, g.points),
            (42, f.timestamp_us, f.points)
        );
        assert!(matches!(decode_in(&encode_in_end(3)), Some(In::End)));
        assert!(decode_in(&b[..5]).is_none());
    }

    #[test]
    fn a_lease_names_the_session_instance_it_was_taken_for() {
        // What a worker stores for request `id` 7 of front door `front-a`, read back as bytes.
        let req: OpenRequest = serde_json::from_str(
            r#"{"session":"s","rig":"r","layout":"l","host":"front-a","id":7,"resume":false}"#,
        )
        .unwrap();
        let stored = serde_json::to_vec(&Lease {
            worker: "w2".into(),
            host: req.host.clone(),
            id: req.id,
        })
        .unwrap();
        let lease: Lease = serde_json::from_slice(&stored).unwrap();
        assert!(lease.taken_for("front-a", 7));
        // Another session instance of the same door (a tracker back under the same name), or
        // another door: not this placement.
        assert!(!lease.taken_for("front-a", 8));
        assert!(!lease.taken_for("front-b", 7));
        // A lease from a worker that wrote no id, or a request without one, never matches.
        let old: Lease = serde_json::from_str(r#"{"worker":"w1","host":"front-a"}"#).unwrap();
        assert!(!old.taken_for("front-a", 0));
        let req: OpenRequest = serde_json::from_str(
            r#"{"session":"s","rig":"r","layout":"l","host":"front-a","resume":true}"#,
        )
        .unwrap();
        assert_eq!(req.id, None);
    }
}
