//! The phones in time ([`Phone`]): per 10 ms frame a label, from the recogniser's phones
//! ([`from_recognised`]) or from a transcript's phones laid along the speech ([`from_transcript`]),
//! with every quiet frame silence (`SIL`) and speech the recogniser left unnamed `REST`; then
//! runs of one label become one phone ([`phones`]).

use crate::speech::runs_of;

/// Seconds per label frame (pocketsphinx's 10 ms).
pub const FRAME_S: f64 = 0.01;
/// The label of a quiet frame.
pub const SIL: &str = "SIL";
/// The label of speech without a phone.
pub const REST: &str = "REST";

/// One phone in time.
#[derive(Clone, Debug, PartialEq)]
pub struct Phone {
    /// CMU phone (no stress digit), [`SIL`] or [`REST`].
    pub name: String,
    /// Start (s).
    pub start_s: f64,
    /// End (s).
    pub end_s: f64,
}

/// A phone's name without its stress digit (`AH0` -> `AH`), upper case.
pub fn bare(phone: &str) -> String {
    phone
        .trim_end_matches(|c: char| c.is_ascii_digit())
        .to_ascii_uppercase()
}

/// Frame labels from free recognition: `phones` (first and last frame, inclusive) inside the
/// speech frames, [`SIL`] outside them, [`REST`] where the recogniser heard silence or noise.
pub fn from_recognised(speech: &[bool], phones: &[(String, usize, usize)]) -> Vec<String> {
    let mut labels: Vec<String> = speech
        .iter()
        .map(|s| if *s { REST } else { SIL }.to_string())
        .collect();
    for (name, a, b) in phones {
        let name = bare(name);
        if name == SIL || name.starts_with('+') {
            continue;
        }
        for f in *a..=(*b).min(labels.len().saturating_sub(1)) {
            if speech[f] {
                labels[f].clone_from(&name);
            }
        }
    }
    labels
}

/// How long a phone is relative to others when laid along the speech: vowels twice a consonant.
fn weight(phone: &str) -> f64 {
    let vowel = matches!(
        phone,
        "AA" | "AE"
            | "AH"
            | "AO"
            | "AW"
            | "AY"
            | "EH"
            | "ER"
            | "EY"
            | "IH"
            | "IY"
            | "OW"
            | "OY"
            | "UH"
            | "UW"
    );
    if vowel { 2.0 } else { 1.0 }
}

/// Lays `phones` along the frames `frames` of `labels`, each a share by its [`weight`].
fn lay(labels: &mut [String], frames: &[usize], phones: &[String]) {
    let total: f64 = phones.iter().map(|p| weight(p)).sum();
    if total <= 0.0 || frames.is_empty() {
        return;
    }
    let n = frames.len() as f64;
    let mut at = 0.0;
    for p in phones {
        let next = at + weight(p) / total * n;
        let (a, b) = (
            at.round() as usize,
            (next.round() as usize).min(frames.len()),
        );
        for &f in &frames[a..b] {
            labels[f].clone_from(p);
        }
        at = next;
    }
}

/// Frame labels from a transcript: each word's `phones` laid along the speech. When the speech
/// falls into as many runs as there are words, word k takes run k; otherwise all the phones are
/// laid along all the speech frames in order.
pub fn from_transcript(speech: &[bool], words: &[(String, Vec<String>)]) -> Vec<String> {
    let mut labels: Vec<String> = speech
        .iter()
        .map(|s| if *s { REST } else { SIL }.to_string())
        .collect();
    let words: Vec<Vec<String>> = words
        .iter()
        .map(|(_, p)| p.iter().map(|p| bare(p)).collect::<Vec<_>>())
        .filter(|p| !p.is_empty())
        .collect();
    let runs = runs_of(speech);
    if runs.len() == words.len() {
        for ((a, b), phones) in runs.iter().zip(&words) {
            let frames: Vec<usize> = (*a..*b).collect();
            lay(&mut labels, &frames, phones);
        }
    } else {
        let frames: Vec<usize> = (0..speech.len()).filter(|&f| speech[f]).collect();
        let all: Vec<String> = words.into_iter().flatten().collect();
        lay(&mut labels, &frames, &all);
    }
    labels
}

/// Runs of one label as phones.
pub fn phones(labels: &[String]) -> Vec<Phone> {
    let mut out: Vec<Phone> = Vec::new();
    for (f, l) in labels.iter().enumerate() {
        let t = f as f64 * FRAME_S;
        match out.last_mut() {
            Some(p) if p.name == *l => p.end_s = t + FRAME_S,
            _ => out.push(Phone {
                name: l.clone(),
                start_s: t,
                end_s: t + FRAME_S,
            }),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(v: &[&str]) -> Vec<String> {
        v.iter().map(|x| x.to_string()).collect()
    }

    #[test]
    fn a_transcript_word_per_speech_run_and_silence_elsewhere() {
        let speech: Vec<bool> = (0..30).map(|f| (5..13).contains(&f) || f >= 20).collect();
        let words = vec![
            ("map".to_string(), s(&["M", "AE1", "P"])),
            ("ma".to_string(), s(&["M", "AA0"])),
        ];
        let labels = from_transcript(&speech, &words);
        let p = phones(&labels);
        let names: Vec<&str> = p.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(names, ["SIL", "M", "AE", "P", "SIL", "M", "AA"]);
        // "map": 8 frames, shares 1:2:1 -> 2, 4, 2 frames.
        assert!((p[1].start_s - 0.05).abs() < 1e-9 && (p[1].end_s - 0.07).abs() < 1e-9);
        assert!((p[3].end_s - 0.13).abs() < 1e-9);
    }

    #[test]
    fn recognised_silence_inside_speech_is_rest_and_quiet_frames_are_silence() {
        let speech = [false, true, true, true, false];
        let ph = vec![
            ("SIL".to_string(), 0, 1),
            ("B".to_string(), 2, 2),
            ("AA".to_string(), 3, 4),
        ];
        assert_eq!(
            from_recognised(&speech, &ph),
            s(&["SIL", "REST", "B", "AA", "SIL"])
        );
    }
}
