//! A tracker's own UDP datagrams, each sent when it is due: a recording's frames as OpenSeeFace
//! datagrams ([`send_openseeface`]) and a Live Link Face take's tracked rows as the app's
//! packets ([`send_take_udp`]). Nothing comes back over these protocols.

use super::error::SendError;
use super::options::SendOptions;
use super::pace::Pacer;
use std::net::{SocketAddr, UdpSocket};
use std::path::Path;

/// The Live Link subject name when the options name no session.
pub const DEFAULT_SUBJECT: &str = "mimic-send";

/// What a UDP send did.
#[derive(Clone, Debug)]
pub struct UdpSent {
    /// Datagrams sent.
    pub sent: usize,
    /// Seconds the sending took.
    pub elapsed_s: f64,
    /// Seconds the recording (or take) spans.
    pub span_s: f64,
}

/// A UDP socket to send to `addr` from (loopback for a loopback address).
fn socket_for(addr: SocketAddr) -> Result<UdpSocket, SendError> {
    let bind = if addr.ip().is_loopback() {
        "127.0.0.1:0"
    } else {
        "0.0.0.0:0"
    };
    UdpSocket::bind(bind).map_err(SendError::Bind)
}

/// Sends datagram `n` to `addr`.
fn send_one(
    socket: &UdpSocket,
    packet: &[u8],
    addr: SocketAddr,
    what: &'static str,
    n: usize,
) -> Result<(), SendError> {
    socket
        .send_to(packet, addr)
        .map(|_| ())
        .map_err(|source| SendError::Datagram {
            what,
            n,
            to: addr,
            source,
        })
}

/// The recording's frames (an `openseeface68` one) as OpenSeeFace datagrams (face 0 of a
/// 640 x 480 image), each sent when its time comes.
pub fn send_openseeface(
    recording: &Path,
    addr: SocketAddr,
    o: &SendOptions,
) -> Result<UdpSent, SendError> {
    use mimic_trackers::openseeface::encode_packet;
    use mimic_trackers::osf_frames::{LAYOUT, to_face};
    let rec = mimic_capture::read_recording(recording, None)?;
    if rec.header.layout != LAYOUT {
        return Err(SendError::Layout {
            path: recording.to_path_buf(),
            layout: rec.header.layout,
            want: LAYOUT,
        });
    }
    let socket = socket_for(addr)?;
    let first_t = rec.frames.first().map_or(0, |f| f.frame.timestamp_us);
    let pace = Pacer::new(o.speed, o.fast);
    let mut sent = 0usize;
    for f in &rec.frames {
        pace.wait(f.frame.timestamp_us - first_t);
        let packet = encode_packet(&[to_face(&f.frame, 0, 640.0, 480.0)]);
        send_one(&socket, &packet, addr, "datagram", sent)?;
        sent += 1;
        if o.max_frames.is_some_and(|m| sent >= m) {
            break;
        }
    }
    let span = rec
        .frames
        .last()
        .map_or(0, |f| f.frame.timestamp_us - first_t);
    Ok(UdpSent {
        sent,
        elapsed_s: pace.elapsed_s(),
        span_s: span as f64 * 1e-6,
    })
}

/// A Live Link Face take's tracked rows as the app's packets (all 61 curves, 60 fps frame times
/// from the take's start, subject: the options' session or [`DEFAULT_SUBJECT`]), each sent when
/// it is due.
pub fn send_take_udp(csv: &Path, addr: SocketAddr, o: &SendOptions) -> Result<UdpSent, SendError> {
    use mimic_trackers::livelink::{LiveLinkPacket, encode_packet};
    let take = mimic_trackers::take::read_take(csv)?;
    let socket = socket_for(addr)?;
    let subject = o.session.clone().unwrap_or_else(|| DEFAULT_SUBJECT.into());
    let pace = Pacer::new(o.speed, o.fast);
    let mut sent = 0usize;
    for row in take.rows.iter().filter(|r| r.tracked) {
        pace.wait(row.t_us);
        let frames = row.t_us as f64 * 60.0 / 1e6;
        let packet = encode_packet(&LiveLinkPacket {
            device_id: "00000000-0000-4000-8000-6d696d696373".into(),
            subject: subject.clone(),
            frame: frames.floor() as i32,
            subframe: frames.fract() as f32,
            rate_numerator: 60,
            rate_denominator: 1,
            curves: row.curves,
        });
        send_one(&socket, &packet, addr, "packet", sent)?;
        sent += 1;
        if o.max_frames.is_some_and(|m| sent >= m) {
            break;
        }
    }
    Ok(UdpSent {
        sent,
        elapsed_s: pace.elapsed_s(),
        span_s: take.duration_s(),
    })
}
