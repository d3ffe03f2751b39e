//! Where there is speech: the loudness of each 10 ms frame at 16 kHz and the runs of frames
//! loud enough to be speech ([`speech_frames`]), short gaps inside a word (stop closures)
//! bridged and short blips dropped.

/// Samples per analysis frame at 16 kHz (10 ms: pocketsphinx's frame).
pub const FRAME: usize = 160;
/// A frame is speech when its RMS is within this many dB of the loud frames' (95th percentile).
pub const SPEECH_DB: f32 = 30.0;
/// Below this RMS a frame is never speech (-70 dBFS: digital silence and dither).
pub const FLOOR_RMS: f32 = 3.2e-4;
/// Quiet gaps of at most this many frames between speech are speech (a stop's closure).
pub const BRIDGE_FRAMES: usize = 10;
/// Speech runs shorter than this many frames are dropped (clicks).
pub const MIN_RUN_FRAMES: usize = 4;

/// RMS of each 10 ms frame of `pcm` (16 kHz); a partial last frame counts.
pub fn frame_rms(pcm: &[f32]) -> Vec<f32> {
    pcm.chunks(FRAME)
        .map(|c| (c.iter().map(|s| s * s).sum::<f32>() / c.len() as f32).sqrt())
        .collect()
}

/// Whether each 10 ms frame of `pcm` (16 kHz) is speech (module docs).
pub fn speech_frames(pcm: &[f32]) -> Vec<bool> {
    let rms = frame_rms(pcm);
    let mut sorted = rms.clone();
    sorted.sort_by(f32::total_cmp);
    let loud = sorted
        .get(sorted.len() * 95 / 100)
        .copied()
        .unwrap_or_default();
    let threshold = (loud * 10f32.powf(-SPEECH_DB / 20.0)).max(FLOOR_RMS);
    let mut speech: Vec<bool> = rms.iter().map(|r| *r > threshold).collect();
    // Bridge short gaps between speech.
    let runs = runs(&speech);
    for w in runs.windows(2) {
        let gap = w[1].0 - w[0].1;
        if gap <= BRIDGE_FRAMES {
            speech[w[0].1..w[1].0].fill(true);
        }
    }
    for (a, b) in runs_of(&speech) {
        if b - a < MIN_RUN_FRAMES {
            speech[a..b].fill(false);
        }
    }
    speech
}

/// The `[start, end)` frame ranges where `speech` is true.
pub fn runs_of(speech: &[bool]) -> Vec<(usize, usize)> {
    runs(speech)
}

fn runs(speech: &[bool]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut start = None;
    for (i, s) in speech.iter().enumerate() {
        match (s, start) {
            (true, None) => start = Some(i),
            (false, Some(a)) => {
                out.push((a, i));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(a) = start {
        out.push((a, speech.len()));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tone(frames: usize, amp: f32) -> Vec<f32> {
        (0..frames * FRAME)
            .map(|i| amp * (i as f32 * 0.2).sin())
            .collect()
    }

    #[test]
    fn words_and_silences_are_told_apart_and_a_closure_is_bridged() {
        let mut pcm = vec![0.0; 30 * FRAME];
        pcm.extend(tone(20, 0.3));
        pcm.extend(vec![0.0; 6 * FRAME]); // a stop's closure: bridged
        pcm.extend(tone(20, 0.3));
        pcm.extend(vec![0.0; 40 * FRAME]);
        pcm.extend(tone(2, 0.3)); // a click: dropped
        pcm.extend(vec![0.0; 20 * FRAME]);
        let s = speech_frames(&pcm);
        assert_eq!(runs_of(&s), vec![(30, 76)]);
    }
}
