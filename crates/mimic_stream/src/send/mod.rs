//! The tracker simulator behind `mimic send`: a recording (or a CSV of named blendshape weights,
//! as a weights session; a WAV of speech, as an audio session) replayed into a server over TCP
//! at its pace ([`send_recording`], [`send_weights`], [`send_audio`], a Live Link Face take
//! through [`TakeSender`]), or sent as a tracker's own UDP datagrams ([`send_openseeface`], [`send_take_udp`]). The server's replies are read on
//! their own thread (`connection`); what each send did comes back as a report for the caller to
//! print.

mod audio;
mod connection;
mod error;
mod options;
mod pace;
mod recording;
mod said;
mod take;
mod udp;
mod weights;

pub use audio::{CHUNK_MS, send_audio};
pub use connection::TcpSent;
pub use error::SendError;
pub use options::SendOptions;
pub use recording::send_recording;
pub use said::{recording_bye, weights_bye};
pub use take::{TakeSender, TakeSent};
pub use udp::{DEFAULT_SUBJECT, UdpSent, send_openseeface, send_take_udp};
pub use weights::send_weights;

/// Makes socket writes after the server closed come back as errors (to report its `bye`)
/// instead of killing the process; call before starting any thread (`mimic send` does first;
/// the binary's main restores SIGPIPE's default for stdout pipes).
pub fn ignore_sigpipe() {
    #[cfg(unix)]
    // SAFETY: setting a signal disposition; the caller has started no thread yet.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_IGN);
    }
}
