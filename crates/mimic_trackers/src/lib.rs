//! Outside trackers' formats, as pure parsers and encoders over bytes and text (no I/O but the
//! capped file reads, no tokio); one module (or folder) per tracker, every landmark tracker's file
//! behind one [`importer::Importer`] in the [`importer::IMPORTERS`] table:
//!
//! - [`gfe`]: the UCI GFE Kinect files (`kinect-gfe100`), with the depth repair (`gfe/depth.rs`);
//! - [`openface`]: OpenFace 2.x CSVs (`ibug68`);
//! - [`mediapipe`]: MediaPipe Face Mesh dumps (`mediapipe478`, camera-space metres);
//! - [`openseeface`]: OpenSeeFace's UDP datagram (one 1785-byte block per face), decoded and
//!   encoded, and the `.osf` capture container (receive time, length, datagram);
//! - [`livelink`]: Live Link Face's UDP packet (61 curves in ARKit enum order, head and eye
//!   rotation), decoded and encoded;
//! - [`take`]: Live Link Face CSV takes, columns by name, `Timecode` parsed to microseconds;
//! - [`namemap`]: blendshape spellings (ARKit, Live Link, MediaPipe) to a rig's morph-target
//!   names with per-target gain, offset and clamp, kept as data (`configs/namemaps/*.toml`);
//! - [`osf_frames`]: an OpenSeeFace face as an `openseeface68` landmark frame;
//! - [`osf_pose`]: its head pose in the recording convention (the quaternion corrected, refined
//!   on the 2D landmarks);
//! - `import_write`: an import written as its recording, or fitted with CANDIDE-3 first
//!   ([`importer::Import::write_fitted`]);
//! - [`import`]: a `.osf` capture as a v1 recording (`mimic import openseeface`);
//! - [`weights_csv`]: per-frame morph weights written as mimic's CSV or a Live Link take (a
//!   frame loop output);
//! - [`weights_take`]: a weights CSV of ARKit curves (`mimic import audio`) read as a take.
//!
//! Errors name the packet (by number or byte offset) or the file and line.
//! Depends on mimic_types, mimic_capture (recordings, without its tokio replay), mimic_fit (the
//! CANDIDE-3 fit of an import), glam, serde and toml.

mod error;
pub mod gfe;
pub mod import;
mod import_write;
pub mod importer;
pub mod livelink;
pub mod mediapipe;
pub mod namemap;
pub mod openface;
pub mod openseeface;
pub mod osf_frames;
pub mod osf_pose;
pub mod take;
pub mod take_rig;
pub mod take_summary;
pub mod weights_csv;
pub mod weights_take;

pub use error::{PacketError, TrackerError};
pub use import_write::ImportWriteError;
