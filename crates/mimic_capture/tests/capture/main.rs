//! Integration tests of mimic_capture: recording format and replay (the importers' tests live in mimic_trackers).

#![allow(
    clippy::unwrap_used,
    reason = "a test: a failed unwrap is the failure report"
)]

mod format;
mod replay;
