//! Integration tests of mimic_capture: recording format, importers on real data, replay.

#![allow(
    clippy::unwrap_used,
    reason = "a test: a failed unwrap is the failure report"
)]

mod format;
mod limits;
mod real_data;
mod replay;
