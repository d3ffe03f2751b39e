//! The GLB container (glTF 2.0 binary): the JSON chunk and the optional binary chunk, every
//! length checked against the bytes there are (the `gltf` crate's reader subtracts without a check).

/// The JSON text and the binary chunk of a GLB, or the bytes as JSON for a `.gltf`.
pub(crate) struct Chunks<'a> {
    /// The JSON text.
    pub json: &'a [u8],
    /// The `BIN` chunk, if any.
    pub bin: Option<&'a [u8]>,
}

fn u32_at(bytes: &[u8], at: usize) -> Option<usize> {
    let b = bytes.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
}

/// Splits `bytes` into chunks: a GLB (magic `glTF`) by its header, anything else as JSON text.
pub(crate) fn split(bytes: &[u8]) -> Result<Chunks<'_>, String> {
    if !bytes.starts_with(b"glTF") {
        return Ok(Chunks {
            json: bytes,
            bin: None,
        });
    }
    let version = u32_at(bytes, 4).ok_or("GLB header cut short")?;
    if version != 2 {
        return Err(format!("GLB version {version}, not 2"));
    }
    let length = u32_at(bytes, 8).ok_or("GLB header cut short")?;
    if length > bytes.len() || length < 12 {
        return Err(format!(
            "GLB header says {length} bytes, the file has {}",
            bytes.len()
        ));
    }
    let bytes = &bytes[..length];
    let mut at = 12;
    let mut json = None;
    let mut bin = None;
    while at < bytes.len() {
        let len = u32_at(bytes, at).ok_or("GLB chunk header cut short")?;
        let kind = u32_at(bytes, at + 4).ok_or("GLB chunk header cut short")?;
        let start = at + 8;
        let data = start
            .checked_add(len)
            .and_then(|end| bytes.get(start..end))
            .ok_or_else(|| format!("GLB chunk at byte {at} ({len} bytes) runs past the file"))?;
        match kind {
            0x4E4F_534A if json.is_none() => json = Some(data),
            0x004E_4942 if json.is_some() && bin.is_none() => bin = Some(data),
            0x4E4F_534A | 0x004E_4942 => {
                return Err(format!("GLB chunk at byte {at} is out of order"));
            }
            _ => {} // Unknown chunks are skipped (glTF 2.0, 4.4.3).
        }
        at = start + len.next_multiple_of(4).min(bytes.len() - start);
    }
    Ok(Chunks {
        json: json.ok_or("GLB has no JSON chunk")?,
        bin,
    })
}
