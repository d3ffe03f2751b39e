//! The recording half of `mimic info` (strict validation of a v1 recording).

use mimic_assets::ConfigDirs;
use serde_json::Value;
use std::path::Path;

/// Validates a recording strictly against its layout and returns its summary.
pub fn summary(path: &Path, _configs: &ConfigDirs) -> anyhow::Result<Value> {
    anyhow::bail!("{}: recordings are not supported yet", path.display())
}
