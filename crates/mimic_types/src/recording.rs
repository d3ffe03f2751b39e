//! The header line of a v1 recording (docs/recording-format.md): here, below every crate that
//! reads one (the recording reader in mimic_capture, a tracker's hello in mimic_wire).

use serde::{Deserialize, Serialize};

/// Value of the header's `format` field.
pub const FORMAT_NAME: &str = "mimic-recording";
/// The format version this crate reads and writes.
pub const FORMAT_VERSION: u64 = 1;
/// The only length unit v1 allows.
pub const UNITS_METRES: &str = "m";

/// First line of a recording: what the frames are and where they came from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RecordingHeader {
    /// Always [`FORMAT_NAME`].
    pub format: String,
    /// Format version, [`FORMAT_VERSION`].
    pub version: u64,
    /// Name of the landmark layout, e.g. `kinect-gfe100` or `ibug68`.
    pub layout: String,
    /// Length unit of every coordinate; v1 allows only `m`.
    pub units: String,
    /// Free text: which tracker and which capture the frames come from.
    pub source: String,
    /// Nominal frame rate in Hz (replay paces by timestamps, not by this).
    pub rate_hz: f64,
    /// Number of points in every tracked frame, when the writer knew it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub point_count: Option<usize>,
    /// Optional human description.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    /// Any further fields, kept as they are.
    #[serde(flatten)]
    pub extra: serde_json::Map<String, serde_json::Value>,
}

impl RecordingHeader {
    /// A v1 header in metres with no description or extra fields.
    pub fn new(layout: &str, source: &str, rate_hz: f64, point_count: Option<usize>) -> Self {
        Self {
            format: FORMAT_NAME.to_string(),
            version: FORMAT_VERSION,
            layout: layout.to_string(),
            units: UNITS_METRES.to_string(),
            source: source.to_string(),
            rate_hz,
            point_count,
            description: None,
            extra: serde_json::Map::new(),
        }
    }

    /// Checks the fields a reader relies on; the error is the reason, in words.
    pub fn check(&self) -> Result<(), String> {
        if self.format != FORMAT_NAME {
            return Err(format!(
                "format is `{}`, expected `{FORMAT_NAME}`",
                self.format
            ));
        }
        if self.version != FORMAT_VERSION {
            return Err(format!(
                "format version {} is not supported (this reader knows version {FORMAT_VERSION})",
                self.version
            ));
        }
        if self.units != UNITS_METRES {
            return Err(format!(
                "units are `{}`; version 1 recordings are in metres (`m`)",
                self.units
            ));
        }
        if self.layout.trim().is_empty() {
            return Err("layout name is empty".to_string());
        }
        if !(self.rate_hz.is_finite() && self.rate_hz > 0.0) {
            return Err(format!(
                "rate_hz is {}; it must be a positive number",
                self.rate_hz
            ));
        }
        if self.point_count == Some(0) {
            return Err("point_count is 0".to_string());
        }
        Ok(())
    }
}
