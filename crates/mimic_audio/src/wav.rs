//! WAV in ([`read_wav`]): PCM 8, 16, 24 or 32 bit or 32-bit float, any common rate, any channel
//! count (mixed down to mono); [`to_16k`] resamples for the recogniser. Anything else (not a
//! RIFF/WAVE file, a compressed WAV, no samples) is an [`AudioError::Wav`] naming the file.

use crate::error::AudioError;
use std::path::Path;

/// Rates a WAV may have (Hz): the common ones from telephone to studio.
pub const RATES: std::ops::RangeInclusive<u32> = 8_000..=192_000;

/// Mono speech: samples in -1..1 at `rate` Hz.
#[derive(Clone, Debug, PartialEq)]
pub struct Mono {
    /// Samples per second.
    pub rate: u32,
    /// The samples, channels averaged.
    pub samples: Vec<f32>,
}

impl Mono {
    /// Length in seconds.
    pub fn duration_s(&self) -> f64 {
        self.samples.len() as f64 / f64::from(self.rate.max(1))
    }
}

/// Reads the WAV at `path` as mono (module docs).
pub fn read_wav(path: &Path) -> Result<Mono, AudioError> {
    let bad = |reason: String| AudioError::Wav {
        path: path.to_path_buf(),
        reason,
    };
    if let Some(tag) = format_tag(path).filter(|t| ![1, 3, 0xFFFE].contains(t)) {
        return Err(bad(format!(
            "a compressed WAV (format tag {tag:#06x}); only PCM and 32-bit float WAV are read"
        )));
    }
    let reader = hound::WavReader::open(path).map_err(|e| {
        bad(match e {
            hound::Error::IoError(io) => io.to_string(),
            hound::Error::FormatError(m) => format!("not a WAV file mimic can read ({m})"),
            hound::Error::Unsupported => {
                "a compressed or unusual WAV (only PCM and 32-bit float WAV are read)".into()
            }
            other => format!("not a WAV file mimic can read ({other})"),
        })
    })?;
    let spec = reader.spec();
    if !RATES.contains(&spec.sample_rate) {
        return Err(bad(format!(
            "sample rate {} Hz is outside {}-{} Hz",
            spec.sample_rate,
            RATES.start(),
            RATES.end()
        )));
    }
    let channels = usize::from(spec.channels.max(1));
    let samples: Vec<f32> = match (spec.sample_format, spec.bits_per_sample) {
        (hound::SampleFormat::Float, 32) => reader
            .into_samples::<f32>()
            .collect::<Result<_, _>>()
            .map_err(|e| bad(e.to_string()))?,
        (hound::SampleFormat::Int, bits @ 1..=32) => {
            let scale = 1.0 / (1u64 << (bits - 1)) as f32;
            reader
                .into_samples::<i32>()
                .map(|s| s.map(|s| s as f32 * scale))
                .collect::<Result<_, _>>()
                .map_err(|e| bad(e.to_string()))?
        }
        (format, bits) => {
            return Err(bad(format!(
                "{bits}-bit {format:?} samples (only PCM and 32-bit float WAV are read)"
            )));
        }
    };
    let mono: Vec<f32> = samples
        .chunks_exact(channels)
        .map(|c| c.iter().sum::<f32>() / channels as f32)
        .collect();
    if mono.is_empty() {
        return Err(bad("the WAV holds no samples".into()));
    }
    Ok(Mono {
        rate: spec.sample_rate,
        samples: mono,
    })
}

/// The format tag of a RIFF/WAVE file's `fmt ` chunk (1 PCM, 3 float, 0xFFFE extensible, others
/// compressed), if the file is one and has it in its first 64 KiB.
fn format_tag(path: &Path) -> Option<u16> {
    use std::io::Read;
    let mut head = Vec::new();
    std::fs::File::open(path)
        .ok()?
        .take(64 * 1024)
        .read_to_end(&mut head)
        .ok()?;
    if head.get(..4)? != b"RIFF" || head.get(8..12)? != b"WAVE" {
        return None;
    }
    let mut at = 12;
    while let Some(id) = head.get(at..at + 4) {
        let len = u32::from_le_bytes(head.get(at + 4..at + 8)?.try_into().ok()?) as usize;
        if id == b"fmt " {
            return Some(u16::from_le_bytes(
                head.get(at + 8..at + 10)?.try_into().ok()?,
            ));
        }
        at = at.checked_add(8 + len + len % 2)?;
    }
    None
}

/// `m` at 16 kHz, the recogniser's rate: each output sample the mean of the input over its
/// 1/16000 s (a box filter against aliasing when downsampling), linear interpolation when
/// upsampling.
pub fn to_16k(m: &Mono) -> Vec<f32> {
    const OUT: f64 = 16_000.0;
    if m.rate == 16_000 {
        return m.samples.clone();
    }
    let ratio = f64::from(m.rate) / OUT;
    let n = (m.samples.len() as f64 / ratio).floor() as usize;
    let at = |i: usize| m.samples.get(i).copied().unwrap_or(0.0);
    (0..n)
        .map(|k| {
            let a = k as f64 * ratio;
            if ratio > 1.0 {
                let (lo, hi) = (a.floor() as usize, ((a + ratio).ceil() as usize).max(1));
                let hi = hi.min(m.samples.len()).max(lo + 1);
                (lo..hi).map(at).sum::<f32>() / (hi - lo) as f32
            } else {
                let i = a.floor() as usize;
                let f = (a - i as f64) as f32;
                at(i) * (1.0 - f) + at(i + 1) * f
            }
        })
        .collect()
}

/// `samples` (-1..1) as 16-bit little-endian PCM bytes.
pub fn pcm16(samples: &[f32]) -> Vec<u8> {
    samples
        .iter()
        .flat_map(|s| ((s.clamp(-1.0, 1.0) * 32767.0).round() as i16).to_le_bytes())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(path: &Path, spec: hound::WavSpec, n: usize) {
        let mut w = hound::WavWriter::create(path, spec).unwrap();
        for i in 0..n * usize::from(spec.channels) {
            w.write_sample((i % 100) as i16 * 100).unwrap();
        }
        w.finalize().unwrap();
    }

    fn spec(channels: u16, rate: u32) -> hound::WavSpec {
        hound::WavSpec {
            channels,
            sample_rate: rate,
            bits_per_sample: 16,
            sample_format: hound::SampleFormat::Int,
        }
    }

    #[test]
    fn stereo_is_mixed_down_and_rates_are_kept() {
        let tmp = tempfile::tempdir().unwrap();
        let p = tmp.path().join("s.wav");
        write(&p, spec(2, 44_100), 4410);
        let m = read_wav(&p).unwrap();
        assert_eq!(m.rate, 44_100);
        assert_eq!(m.samples.len(), 4410);
        // Frame 0 holds samples 0 and 1 (0 and 100): their mean.
        assert!((m.samples[0] - 50.0 / 32768.0).abs() < 1e-6);
        assert!((m.duration_s() - 0.1).abs() < 1e-9);
        assert_eq!(to_16k(&m).len(), 1600);
    }

    #[test]
    fn not_a_wav_empty_and_compressed_are_one_line_errors_naming_the_file() {
        let tmp = tempfile::tempdir().unwrap();
        let text = tmp.path().join("speech.wav");
        std::fs::write(&text, "hello, not audio").unwrap();
        let e = read_wav(&text).unwrap_err().to_string();
        assert!(e.contains("speech.wav") && e.contains("not a WAV"), "{e}");
        assert!(!e.contains('\n'), "{e}");

        let empty = tmp.path().join("empty.wav");
        write(&empty, spec(1, 16_000), 0);
        let e = read_wav(&empty).unwrap_err().to_string();
        assert!(e.contains("empty.wav") && e.contains("no samples"), "{e}");

        // A WAVE header whose format tag is 0x0055 (MPEG Layer 3).
        let mp3 = tmp.path().join("mp3.wav");
        let mut b = Vec::new();
        b.extend_from_slice(b"RIFF");
        b.extend_from_slice(&(4u32 + 8 + 16 + 8 + 4).to_le_bytes());
        b.extend_from_slice(b"WAVEfmt ");
        b.extend_from_slice(&16u32.to_le_bytes());
        b.extend_from_slice(&0x0055u16.to_le_bytes());
        b.extend_from_slice(&1u16.to_le_bytes());
        b.extend_from_slice(&16_000u32.to_le_bytes());
        b.extend_from_slice(&2_000u32.to_le_bytes());
        b.extend_from_slice(&1u16.to_le_bytes());
        b.extend_from_slice(&0u16.to_le_bytes());
        b.extend_from_slice(b"data");
        b.extend_from_slice(&4u32.to_le_bytes());
        b.extend_from_slice(&[0, 0, 0, 0]);
        std::fs::write(&mp3, b).unwrap();
        let e = read_wav(&mp3).unwrap_err().to_string();
        assert!(e.contains("mp3.wav") && e.contains("compressed"), "{e}");

        let missing = tmp.path().join("missing.wav");
        let e = read_wav(&missing).unwrap_err().to_string();
        assert!(e.contains("missing.wav"), "{e}");
    }

    #[test]
    fn downsampling_keeps_a_low_tone_and_upsampling_interpolates() {
        let rate = 48_000;
        let tone: Vec<f32> = (0..rate)
            .map(|i| (i as f32 / rate as f32 * 200.0 * std::f32::consts::TAU).sin())
            .collect();
        let out = to_16k(&Mono {
            rate,
            samples: tone,
        });
        assert_eq!(out.len(), 16_000);
        let peak = out.iter().fold(0.0f32, |a, b| a.max(b.abs()));
        assert!(peak > 0.95 && peak <= 1.0, "{peak}");
        let up = to_16k(&Mono {
            rate: 8_000,
            samples: vec![0.0, 1.0, 0.0],
        });
        assert_eq!(up[..4], [0.0, 0.5, 1.0, 0.5]);
    }
}
