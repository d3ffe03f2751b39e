//! Audio sessions (`{"mode":"audio"}`, docs/protocol.md): the hello's stream format and the PCM
//! chunk lines (`{"t_us":0,"pcm":"<base64 of 16-bit little-endian samples>"}`).

use crate::code::ErrorCode;
use base64::Engine;
use serde::Deserialize;
use std::borrow::Cow;

/// Sample rates an audio session may have (Hz).
pub const AUDIO_RATES: std::ops::RangeInclusive<u32> = 8_000..=48_000;
/// Most channels an audio session may have (interleaved; mixed down by the server).
pub const MAX_AUDIO_CHANNELS: u16 = 2;
/// Longest chunk (ms of audio); the sender's are 20 ms.
pub const MAX_CHUNK_MS: u32 = 100;

/// The stream an audio session's hello announces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AudioFormat {
    /// Samples a second per channel.
    pub sample_rate: u32,
    /// Interleaved channels (1 or 2).
    pub channels: u16,
}

impl AudioFormat {
    /// The format of a hello's fields (`sample_rate` required, `channels` 1 by default,
    /// `format` `s16le` if given), or why it is refused.
    pub fn read(obj: &serde_json::Map<String, serde_json::Value>) -> Result<Self, String> {
        let sample_rate = obj
            .get("sample_rate")
            .and_then(serde_json::Value::as_u64)
            .and_then(|r| u32::try_from(r).ok())
            .filter(|r| AUDIO_RATES.contains(r))
            .ok_or_else(|| {
                format!(
                    "`sample_rate` must be an integer from {} to {} Hz",
                    AUDIO_RATES.start(),
                    AUDIO_RATES.end()
                )
            })?;
        let channels = match obj.get("channels") {
            None => 1,
            Some(c) => c
                .as_u64()
                .and_then(|c| u16::try_from(c).ok())
                .filter(|c| (1..=MAX_AUDIO_CHANNELS).contains(c))
                .ok_or_else(|| format!("`channels` must be 1 to {MAX_AUDIO_CHANNELS}"))?,
        };
        match obj.get("format").map(|f| f.as_str()) {
            None | Some(Some("s16le")) => {}
            Some(_) => return Err("`format` must be `s16le` (16-bit little-endian PCM)".into()),
        }
        Ok(Self {
            sample_rate,
            channels,
        })
    }

    /// Most samples (per channel) one chunk may carry: [`MAX_CHUNK_MS`] of audio.
    pub fn max_chunk_samples(&self) -> usize {
        (self.sample_rate * MAX_CHUNK_MS / 1000) as usize
    }
}

/// Why a chunk line is rejected.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum AudioChunkError {
    /// Not JSON, not an object, or no integer `t_us` / string `pcm`.
    #[error("{0}")]
    Json(String),
    /// `pcm` is not base64, not whole samples of every channel, empty or too long.
    #[error("{0}")]
    Pcm(String),
}

impl AudioChunkError {
    /// The error code the session answers with.
    pub fn code(&self) -> ErrorCode {
        match self {
            AudioChunkError::Json(_) => ErrorCode::BadJson,
            AudioChunkError::Pcm(_) => ErrorCode::BadAudio,
        }
    }
}

#[derive(Deserialize)]
struct RawChunk<'a> {
    t_us: i64,
    #[serde(borrow)]
    pcm: Cow<'a, str>,
}

/// Parses a chunk line (without its newline) of a `format` stream: its `t_us` (the time of its
/// first sample), and its samples mixed down to mono (-1..1) into `mono` (cleared first);
/// `scratch` holds the decoded bytes. Reuses both buffers: nothing is allocated once they
/// have grown to a chunk's size.
pub fn parse_audio_chunk(
    line: &[u8],
    format: AudioFormat,
    scratch: &mut Vec<u8>,
    mono: &mut Vec<f32>,
) -> Result<i64, AudioChunkError> {
    let raw: RawChunk<'_> = serde_json::from_slice(crate::hello::trim_end(line)).map_err(|e| {
        AudioChunkError::Json(format!(
            "an audio chunk is {{\"t_us\": integer, \"pcm\": base64 string}}: {e}"
        ))
    })?;
    scratch.clear();
    base64::engine::general_purpose::STANDARD
        .decode_vec(raw.pcm.as_bytes(), scratch)
        .map_err(|e| AudioChunkError::Pcm(format!("`pcm` is not base64: {e}")))?;
    let ch = usize::from(format.channels.max(1));
    let frame = 2 * ch;
    if scratch.is_empty() || !scratch.len().is_multiple_of(frame) {
        return Err(AudioChunkError::Pcm(format!(
            "`pcm` has {} bytes: not a positive whole number of {ch}-channel 16-bit samples",
            scratch.len()
        )));
    }
    let n = scratch.len() / frame;
    if n > format.max_chunk_samples() {
        return Err(AudioChunkError::Pcm(format!(
            "`pcm` has {n} samples a channel; at most {} ({MAX_CHUNK_MS} ms at {} Hz)",
            format.max_chunk_samples(),
            format.sample_rate
        )));
    }
    mono.clear();
    mono.extend(scratch.chunks_exact(frame).map(|f| {
        let sum: f32 = f
            .chunks_exact(2)
            .map(|b| f32::from(i16::from_le_bytes([b[0], b[1]])))
            .sum();
        sum / (32768.0 * ch as f32)
    }));
    Ok(raw.t_us)
}

/// A chunk line for `samples` (mono, -1..1, 16-bit) starting at `t_us`, with its newline.
pub fn encode_audio_chunk(t_us: i64, samples: &[f32]) -> String {
    let bytes: Vec<u8> = samples
        .iter()
        .flat_map(|s| ((s.clamp(-1.0, 1.0) * 32767.0).round() as i16).to_le_bytes())
        .collect();
    let pcm = base64::engine::general_purpose::STANDARD.encode(bytes);
    format!("{{\"t_us\":{t_us},\"pcm\":\"{pcm}\"}}\n")
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn fmt(v: serde_json::Value) -> Result<AudioFormat, String> {
        AudioFormat::read(v.as_object().unwrap())
    }

    #[test]
    fn the_format_is_checked() {
        let f = fmt(json!({"sample_rate": 16000})).unwrap();
        assert_eq!((f.sample_rate, f.channels), (16000, 1));
        assert_eq!(f.max_chunk_samples(), 1600);
        assert!(fmt(json!({})).unwrap_err().contains("sample_rate"));
        assert!(fmt(json!({"sample_rate": 96000})).is_err());
        assert!(fmt(json!({"sample_rate": 16000.5})).is_err());
        assert!(fmt(json!({"sample_rate": 16000, "channels": 3})).is_err());
        assert!(fmt(json!({"sample_rate": 16000, "format": "f32le"})).is_err());
    }

    #[test]
    fn a_chunk_round_trips_and_stereo_is_mixed_down() {
        let f = AudioFormat {
            sample_rate: 16000,
            channels: 1,
        };
        let samples = [0.0f32, 0.5, -0.5, 1.0, -1.0];
        let line = encode_audio_chunk(20_000, &samples);
        let (mut scratch, mut mono) = (Vec::new(), Vec::new());
        let t = parse_audio_chunk(line.as_bytes(), f, &mut scratch, &mut mono).unwrap();
        assert_eq!(t, 20_000);
        for (a, b) in mono.iter().zip(samples) {
            assert!((a - b).abs() <= 1.0 / 32767.0, "{a} {b}");
        }
        // The same bytes as stereo: pairs averaged.
        let st = AudioFormat {
            sample_rate: 16000,
            channels: 2,
        };
        let line = encode_audio_chunk(0, &[0.5, -0.5, 0.25, 0.75]);
        parse_audio_chunk(line.as_bytes(), st, &mut scratch, &mut mono).unwrap();
        assert_eq!(mono.len(), 2);
        assert!(mono[0].abs() < 1e-4 && (mono[1] - 0.5).abs() < 1e-4);
    }

    #[test]
    fn bad_chunks_say_what_is_wrong() {
        let f = AudioFormat {
            sample_rate: 8000,
            channels: 2,
        };
        let (mut s, mut m) = (Vec::new(), Vec::new());
        let mut err = |line: &str| parse_audio_chunk(line.as_bytes(), f, &mut s, &mut m);
        assert_eq!(err("nope").unwrap_err().code(), ErrorCode::BadJson);
        assert_eq!(
            err(r#"{"pcm":"AAAA"}"#).unwrap_err().code(),
            ErrorCode::BadJson
        );
        let e = err(r#"{"t_us":0,"pcm":"!!"}"#).unwrap_err();
        assert!(e.to_string().contains("base64") && e.code() == ErrorCode::BadAudio);
        // 2 bytes: half a stereo sample.
        assert!(
            err(r#"{"t_us":0,"pcm":"AAA="}"#)
                .unwrap_err()
                .to_string()
                .contains("2 bytes")
        );
        assert!(err(r#"{"t_us":0,"pcm":""}"#).is_err());
        // 101 ms at 8 kHz stereo: 808 samples a channel.
        let long = encode_audio_chunk(0, &vec![0.1; 808 * 2]);
        assert!(
            err(long.trim_end())
                .unwrap_err()
                .to_string()
                .contains("at most 800")
        );
    }
}
