//! Every file this crate reads goes through here: regular files only, each kind within its
//! size cap ([`mimic_types::limits`]); errors name the file (and the cap).

use crate::AssetError;
use mimic_types::FileKind;
use mimic_types::limits::{check_file, open_regular, read_capped};
use std::io::Read;
use std::path::Path;

/// The whole text of `path`, a file of `kind`.
pub(crate) fn read_text(path: &Path, kind: &FileKind) -> Result<String, AssetError> {
    read_capped(path, kind).map_err(|e| AssetError::read(path, e))
}

/// `path`, a file of `kind`, opened for a streaming reader that stops at the kind's cap.
pub(crate) fn open_capped(path: &Path, kind: &FileKind) -> Result<impl Read, AssetError> {
    check_file(path, kind).map_err(|e| AssetError::read(path, e))?;
    let file = open_regular(path, kind.what).map_err(|e| AssetError::read(path, e))?;
    Ok(file.take(kind.max_bytes))
}
