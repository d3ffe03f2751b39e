//! The recording half of `mimic info`: strict validation of a v1 recording against its layout.

use mimic_assets::ConfigDirs;
use serde_json::Value;
use std::path::Path;

/// Validates a recording strictly (the first rejected frame is the error) and returns its summary.
///
/// The layout named in the header is loaded from the config directory when it exists there, so
/// frames are checked against the layout's point count; otherwise against the header's.
pub fn summary(path: &Path, configs: &ConfigDirs) -> anyhow::Result<Value> {
    let header = mimic_capture::RecordingReader::open(path, None)?
        .header()
        .clone();
    let layout = configs.load_layout_named(&header.layout).ok();
    let summary = mimic_capture::summarize(path, layout.as_ref().map(|l| l.point_count))?;
    let mut v = serde_json::to_value(&summary)?;
    if let Value::Object(map) = &mut v {
        map.insert("kind".into(), "recording".into());
        map.insert("layout_found".into(), Value::Bool(layout.is_some()));
    }
    Ok(v)
}
