//! The trackers' importers on real data and at their file limits (moved here from mimic_capture
//! with the importers).

#![allow(
    clippy::unwrap_used,
    reason = "a test: a failed unwrap is the failure report"
)]

mod limits;
mod real_data;
