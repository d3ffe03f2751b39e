//! The bodies of mimic's fuzz targets, one function per target, each taking the raw input bytes.
//!
//! `fuzz/fuzz_targets/<name>.rs` hands libFuzzer's input to [`TARGETS`]' function of the same name
//! (`fuzz/run_all.sh`, docs/reliability.md); this crate's test replays every seed of
//! `fuzz/corpus/<name>/` through the same function in the ordinary test run, so the seeds stay
//! parsed by the code that ships without a fuzzing toolchain. A function panics (an assertion)
//! only when a parser breaks a promise; bad input is an `Err`, never a panic.

mod assets;
mod capture;
mod trackers;
mod wire;

pub use assets::{avatar, layout, morph, obj, rig};
pub use capture::{gfe, mediapipe, openface, recording};
pub use trackers::{livelink, openseeface};
pub use wire::stream;

/// A fuzz target's body: the raw input bytes, a panic only for a broken promise.
pub type Body = fn(&[u8]);

/// Every fuzz target: its name (the `[[bin]]` of `fuzz/Cargo.toml`, the folder of its corpus) and
/// its body.
pub const TARGETS: &[(&str, Body)] = &[
    ("recording", recording),
    ("gfe", gfe),
    ("openface", openface),
    ("obj", obj),
    ("layout", layout),
    ("rig", rig),
    ("morph", morph),
    ("mediapipe", mediapipe),
    ("stream", stream),
    ("openseeface", openseeface),
    ("livelink", livelink),
    ("avatar", avatar),
];
