//! Integration tests of mimic_capture: recording format, importers on real data, replay.

mod format;
mod limits;
mod real_data;
mod replay;
