//! The bytes an avatar names: buffers and images from the GLB chunk, a file beside a `.gltf`
//! (a plain relative name, `%XX` decoded, no `..`) or a base64 data URI.

use super::read::AVATAR_FILE;
use super::{AvatarError, Image};
use mimic_types::FileKind;
use std::path::Path;

/// A relative file name from a URI (percent-decoded), refusing absolute paths and `..`.
fn relative_file(uri: &str) -> Option<String> {
    let mut out = Vec::with_capacity(uri.len());
    let b = uri.as_bytes();
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            let hex = std::str::from_utf8(b.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    let name = String::from_utf8(out).ok()?;
    let p = Path::new(&name);
    let plain = p
        .components()
        .all(|c| matches!(c, std::path::Component::Normal(_)));
    (plain && !name.contains(':') && !name.is_empty()).then_some(name)
}

/// The bytes a URI names: a base64 data URI, or a file in `files`.
fn uri_bytes(
    path: &Path,
    pointer: &str,
    uri: &str,
    files: Option<&Path>,
    kind: &FileKind,
) -> Result<Vec<u8>, AvatarError> {
    let at = |m: String| AvatarError::at(path, pointer, m);
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, data) = rest
            .split_once(";base64,")
            .ok_or_else(|| at("a data URI that is not base64".into()))?;
        return base64(data).ok_or_else(|| at("a data URI with invalid base64".into()));
    }
    let name = relative_file(uri).ok_or_else(|| {
        at(format!(
            "`{uri}` is not a relative file name beside the avatar"
        ))
    })?;
    let dir = files.ok_or_else(|| at(format!("`{uri}` is a separate file, not read here")))?;
    mimic_types::limits::read_bytes_capped(&dir.join(&name), kind)
        .map_err(|e| at(format!("`{name}`: {e}")))
}

/// Standard base64 (padding optional), None on any other character.
fn base64(text: &str) -> Option<Vec<u8>> {
    let mut out = Vec::with_capacity(text.len() / 4 * 3);
    let (mut acc, mut bits) = (0u32, 0u32);
    for c in text.bytes().filter(|&c| c != b'=') {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            _ => return None,
        };
        acc = (acc << 6) | u32::from(v);
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    Some(out)
}

pub(crate) fn read_buffers(
    path: &Path,
    doc: &gltf::Document,
    bin: Option<&[u8]>,
    files: Option<&Path>,
) -> Result<Vec<Vec<u8>>, AvatarError> {
    let mut buffers = Vec::new();
    for buffer in doc.buffers() {
        let pointer = format!("/buffers/{}", buffer.index());
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => bin
                .ok_or_else(|| {
                    AvatarError::at(
                        path,
                        &pointer,
                        "names the GLB binary chunk, which is missing",
                    )
                })?
                .to_vec(),
            gltf::buffer::Source::Uri(uri) => {
                uri_bytes(path, &format!("{pointer}/uri"), uri, files, &AVATAR_FILE)?
            }
        };
        if data.len() < buffer.length() {
            return Err(AvatarError::at(
                path,
                format!("{pointer}/byteLength"),
                format!("says {} bytes, there are {}", buffer.length(), data.len()),
            ));
        }
        buffers.push(data);
    }
    Ok(buffers)
}

pub(crate) fn read_images(
    path: &Path,
    doc: &gltf::Document,
    buffers: &[Vec<u8>],
    files: Option<&Path>,
) -> Result<Vec<Image>, AvatarError> {
    let mut images = Vec::new();
    for image in doc.images() {
        let pointer = format!("/images/{}", image.index());
        let (bytes, mime, uri) = match image.source() {
            gltf::image::Source::View { view, mime_type } => {
                let bytes = buffers
                    .get(view.buffer().index())
                    .and_then(|b| b.get(view.offset()..view.offset().checked_add(view.length())?))
                    .ok_or_else(|| {
                        AvatarError::at(path, format!("{pointer}/bufferView"), "out of range")
                    })?;
                (bytes.to_vec(), Some(mime_type.to_string()), None)
            }
            gltf::image::Source::Uri { uri, mime_type } => {
                let bytes = uri_bytes(
                    path,
                    &format!("{pointer}/uri"),
                    uri,
                    files,
                    &mimic_types::TEXTURE_FILE,
                )?;
                let file = (!uri.starts_with("data:")).then(|| uri.to_string());
                (bytes, mime_type.map(str::to_string), file)
            }
        };
        let mime_type = mime.or_else(|| {
            if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
                Some("image/png".into())
            } else if bytes.starts_with(&[0xFF, 0xD8]) {
                Some("image/jpeg".into())
            } else {
                None
            }
        });
        images.push(Image {
            name: image.name().map(str::to_string),
            mime_type,
            uri,
            bytes,
        });
    }
    Ok(images)
}
