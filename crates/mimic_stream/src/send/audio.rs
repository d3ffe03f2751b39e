//! Audio sessions from a WAV (`mimic send --audio`): the speech mixed down to mono (a rate
//! outside the protocol's 8-48 kHz resampled to 16 kHz) and sent as [`CHUNK_MS`] ms chunks,
//! each when its last sample would exist live (so the server gets the audio as a microphone
//! would give it), `t_us` the time of its first sample.

use super::connection::{TcpSent, connect};
use super::error::SendError;
use super::options::{SendOptions, with_request};
use super::pace::Pacer;
use mimic_wire::{AUDIO_RATES, encode_audio_chunk};
use std::io::Write;
use std::path::Path;

/// Milliseconds of audio per chunk.
pub const CHUNK_MS: u64 = 20;

/// Sends the speech in `wav` as an audio session, paced (or `--fast`), looping with `--loop`
/// (each pass after the last), up to `max_frames` chunks.
pub fn send_audio(wav: &Path, o: &SendOptions) -> Result<TcpSent, SendError> {
    let mut mono = mimic_audio::wav::read_wav(wav)?;
    if !AUDIO_RATES.contains(&mono.rate) {
        mono = mimic_audio::wav::Mono {
            samples: mimic_audio::wav::to_16k(&mono),
            rate: 16_000,
        };
    }
    let rate = u64::from(mono.rate);
    let hello = serde_json::json!({"mode": "audio", "sample_rate": mono.rate, "channels": 1});
    let hello = with_request(o, hello);
    let mut conn = connect(&o.to, o.on_reply, None)?;
    conn.stream.write_all(format!("{hello}\n").as_bytes())?;
    let pace = Pacer::new(o.speed, o.fast);
    let len = mono.samples.len() as u64;
    let chunks = len.div_ceil(rate * CHUNK_MS / 1000).max(1);
    let (mut sent, mut write_failed, mut pass) = (0usize, None, 0u64);
    'passes: loop {
        for c in 0..chunks {
            // Chunk c holds samples [c rate / 50, (c + 1) rate / 50) (whole samples at any rate).
            let a = (c * rate * CHUNK_MS / 1000).min(len);
            let b = ((c + 1) * rate * CHUNK_MS / 1000).min(len);
            let first = pass * len + a;
            let t_us = i64::try_from(first * 1_000_000 / rate).unwrap_or(i64::MAX);
            let end_us = i64::try_from((pass * len + b) * 1_000_000 / rate).unwrap_or(i64::MAX);
            pace.wait(end_us);
            let line = encode_audio_chunk(t_us, &mono.samples[a as usize..b as usize]);
            if let Err(e) = conn.stream.write_all(line.as_bytes()) {
                write_failed = Some(SendError::AudioChunk(e));
                break 'passes;
            }
            sent += 1;
            if o.max_frames.is_some_and(|m| sent >= m) {
                break 'passes;
            }
        }
        if !o.looping {
            break;
        }
        pass += 1;
    }
    let bye = conn.close()?;
    Ok(TcpSent {
        sent,
        bye,
        write_failed,
    })
}
