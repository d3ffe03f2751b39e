//! mimic's wire protocol (`docs/protocol.md`): the first line of a TCP connection (hellos), a
//! tracker's frame and reply lines, the length-prefixed binary messages viewers get, and UDP frame
//! packets.
//!
//! Pure functions over bytes: encoders return `Vec<u8>` (or a reply `String`), decoders take
//! `&[u8]` and return a value or an error naming the packet and field. No sockets and no tokio, so
//! a viewer ([`decode_viewer_message`]) or a fuzz target decodes frames without the server.
//! Depends on no workspace crate but mimic_types (`RecordingHeader`, `FrameStatus`, `FrameView`).

mod audio;
mod bytes;
mod code;
mod hello;
mod text;
mod udp;
mod viewer;

pub use audio::{
    AUDIO_RATES, AudioChunkError, AudioFormat, MAX_AUDIO_CHANNELS, MAX_CHUNK_MS,
    encode_audio_chunk, parse_audio_chunk,
};
pub use bytes::DecodeError;
pub use code::{ErrorCode, error_line, warning_line};
pub use hello::{
    AudioHello, Hello, HelloError, MAX_TOKEN_BYTES, SessionRequest, WeightFrame, WeightFrameError,
    WeightsHello, parse_hello, parse_hello_with_token, parse_weight_frame, valid_session_name,
};
pub use text::{escape_untrusted, plain_lines};
pub use udp::{UDP_HEADER_BYTES, UDP_MAGIC, UdpFrame, decode_udp_frame, encode_udp_frame};
pub use viewer::{
    BasisRows, FRAME_FIXED_BYTES, FrameMessage, KIND_END, KIND_ERROR, KIND_FRAME, KIND_RIG,
    KIND_SESSION, RigMessage, ViewerMessage, decode_viewer_message, encode_frame, encode_json,
    encode_morph_rig, encode_rig, status_byte,
};
