//! Issue 42's figures on speech of known timing: sentences spoken word by word by `espeak-ng`
//! (each word's WAV trimmed and joined with known silences, so the word spans are exact), turned
//! into mouth weights with and without the transcript. Skips, saying so, where espeak-ng or the
//! recogniser is missing, except under CI (`CI` set), where tools/test-deps.sh installs both.
//! `MIMIC_AUDIO_SENTENCES=FILE` (one sentence a line) checks sentences the project does not ship.

#![allow(clippy::unwrap_used, reason = "tests")]

use mimic_audio::visemes::VisemeTable;
use mimic_audio::{LipSync, lip_sync, transcript_words};
use std::path::Path;
use std::process::Command;

/// Sentences of our own, rich in p, b and m.
const SENTENCES: [&str; 4] = [
    "the big brown bear made a map of the pond",
    "please bring my purple umbrella home before lunch",
    "a happy puppy jumped over the bumpy bridge",
    "maybe the baker will bake more bread tomorrow morning",
];
/// Silence before, between and after the words (s).
const GAP_S: f64 = 0.4;
const RATE: u32 = 22_050;

/// A word's span in the joined WAV (s) and whether it has a p, b or m.
struct Word {
    text: String,
    start: f64,
    end: f64,
    bilabial: bool,
}

fn available() -> bool {
    let espeak = Command::new("espeak-ng").arg("--version").output().is_ok();
    let py = mimic_audio::recognise::python();
    let sphinx = Command::new(&py)
        .args(["-c", "import pocketsphinx"])
        .status()
        .is_ok_and(|s| s.success());
    if espeak && sphinx {
        return true;
    }
    let msg = format!(
        "espeak-ng found: {espeak}; pocketsphinx importable by {}: {sphinx} (tools/test-deps.sh installs both)",
        py.display()
    );
    assert!(std::env::var_os("CI").is_none(), "{msg}");
    eprintln!("SKIPPED: {msg}");
    false
}

/// `word` spoken by espeak-ng, trimmed of its leading and trailing silence.
fn speak(word: &str, dir: &Path) -> Vec<i16> {
    let p = dir.join("w.wav");
    let ok = Command::new("espeak-ng")
        .args(["-s", "150", "-w"])
        .arg(&p)
        .arg(word)
        .status()
        .unwrap();
    assert!(ok.success());
    let mut r = hound::WavReader::open(&p).unwrap();
    assert_eq!(r.spec().sample_rate, RATE);
    let s: Vec<i16> = r.samples::<i16>().map(Result::unwrap).collect();
    let loud = |x: &i16| x.unsigned_abs() > 300;
    let a = s.iter().position(loud).unwrap_or(0);
    let b = s.iter().rposition(loud).map_or(s.len(), |b| b + 1);
    s[a..b].to_vec()
}

/// The sentence spoken word by word into `out` (stereo when `stereo`, to check the mix-down).
fn sentence_wav(sentence: &str, dir: &Path, out: &Path, stereo: bool) -> Vec<Word> {
    let gap = vec![0i16; (GAP_S * f64::from(RATE)) as usize];
    let mut all = gap.clone();
    let mut words = Vec::new();
    for w in sentence.split_whitespace() {
        let s = speak(w, dir);
        let start = all.len() as f64 / f64::from(RATE);
        all.extend(&s);
        words.push(Word {
            text: w.to_string(),
            start,
            end: all.len() as f64 / f64::from(RATE),
            bilabial: w.contains(['p', 'b', 'm']),
        });
        all.extend(&gap);
    }
    let spec = hound::WavSpec {
        channels: if stereo { 2 } else { 1 },
        sample_rate: RATE,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut wr = hound::WavWriter::create(out, spec).unwrap();
    for s in all {
        for _ in 0..spec.channels {
            wr.write_sample(s).unwrap();
        }
    }
    wr.finalize().unwrap();
    words
}

/// Counts toward the three figures.
#[derive(Default, Debug)]
struct Figures {
    words: usize,
    open: usize,
    silence_frames: usize,
    closed: usize,
    bilabial_words: usize,
    lips_closed: usize,
    /// Words with p/b/m whose lips press or close (>= 0.3), the jaw clause left out.
    pressed: usize,
    /// Words without p/b/m whose lips press or close (>= 0.3): closures where none is said.
    other_words: usize,
    other_pressed: usize,
}

impl Figures {
    fn add(&mut self, s: &LipSync, words: &[Word], missed: &mut Vec<String>) {
        let col = |n: &str| s.names.iter().position(|x| *x == n).unwrap();
        let (jaw, close) = (col("jawOpen"), col("mouthClose"));
        let press = [col("mouthPressLeft"), col("mouthPressRight")];
        let t = |k: usize| k as f64 / mimic_audio::coart::FPS;
        for w in words {
            let inside: Vec<&Vec<f32>> = (0..s.frames.len())
                .filter(|&k| t(k) >= w.start && t(k) < w.end)
                .map(|k| &s.frames[k])
                .collect();
            let peak = inside.iter().map(|f| f[jaw]).fold(0.0f32, f32::max);
            self.words += 1;
            if peak >= 0.15 {
                self.open += 1;
            } else {
                missed.push(format!("{} (jaw {peak:.2})", w.text));
            }
            let pressed = inside
                .iter()
                .any(|f| f[close] >= 0.3 || press.iter().any(|&p| f[p] >= 0.3));
            if !w.bilabial {
                self.other_words += 1;
                self.other_pressed += usize::from(pressed);
            }
            if w.bilabial {
                self.bilabial_words += 1;
                self.pressed += usize::from(pressed);
                let shut = inside.iter().any(|f| {
                    f[close] >= 0.3 || press.iter().any(|&p| f[p] >= 0.3) || f[jaw] <= 0.4 * peak
                });
                if shut {
                    self.lips_closed += 1;
                } else {
                    missed.push(format!("{} (lips open)", w.text));
                }
            }
        }
        // Silence: every frame outside the words (and the file's ends).
        for (k, f) in s.frames.iter().enumerate() {
            if words.iter().all(|w| t(k) < w.start || t(k) >= w.end) {
                self.silence_frames += 1;
                if f[jaw] <= 0.05 {
                    self.closed += 1;
                }
            }
        }
    }

    fn ratios(&self) -> (f64, f64, f64) {
        let r = |a: usize, b: usize| a as f64 / b.max(1) as f64;
        (
            r(self.open, self.words),
            r(self.closed, self.silence_frames),
            r(self.lips_closed, self.bilabial_words),
        )
    }
}

fn measure(sentences: &[String], transcript: bool) -> Figures {
    let tmp = tempfile::tempdir().unwrap();
    let table = VisemeTable::shipped().unwrap();
    let mut f = Figures::default();
    let mut missed = Vec::new();
    for (i, s) in sentences.iter().enumerate() {
        let wav = tmp.path().join(format!("s{i}.wav"));
        let words = sentence_wav(s, tmp.path(), &wav, i % 2 == 1);
        let tw = transcript_words(s).unwrap();
        let sync = lip_sync(&wav, transcript.then_some(&tw[..]), &table).unwrap();
        f.add(&sync, &words, &mut missed);
    }
    let (open, closed, lips) = f.ratios();
    eprintln!(
        "transcript {transcript}: jaw open in {:.0}% of {} words, {:.0}% of {} silence frames closed, \
         lips closed in {:.0}% of {} words with p/b/m \
         (pressed >= 0.3: {} of them; words without p/b/m pressed: {} of {}); missed: {}",
        open * 100.0,
        f.words,
        closed * 100.0,
        f.silence_frames,
        lips * 100.0,
        f.bilabial_words,
        f.pressed,
        f.other_pressed,
        f.other_words,
        missed.join(", ")
    );
    f
}

/// The shipped sentences, or those of `MIMIC_AUDIO_SENTENCES` (a file, one a line).
fn sentences() -> Vec<String> {
    match std::env::var_os("MIMIC_AUDIO_SENTENCES") {
        Some(extra) => std::fs::read_to_string(extra)
            .unwrap()
            .lines()
            .filter(|l| !l.trim().is_empty())
            .map(str::to_string)
            .collect(),
        None => SENTENCES.iter().map(|s| s.to_string()).collect(),
    }
}

#[test]
fn espeak_sentences_open_the_jaw_in_words_close_it_in_silence_and_close_the_lips_on_p_b_m() {
    if !available() {
        return;
    }
    let sentences = sentences();
    for transcript in [true, false] {
        let f = measure(&sentences, transcript);
        let (open, closed, lips) = f.ratios();
        assert!(
            open >= 0.9,
            "transcript {transcript}: jaw open in {open:.2} of words"
        );
        assert!(
            closed >= 0.9,
            "transcript {transcript}: {closed:.2} of silence closed"
        );
        assert!(
            lips >= 0.7,
            "transcript {transcript}: lips closed in {lips:.2} of p/b/m words"
        );
        if transcript {
            // The lips themselves (the jaw clause left out): every p, b, m is laid in its word.
            assert!(f.pressed as f64 >= 0.7 * f.bilabial_words as f64, "{f:?}");
        }
    }
}

/// The live path (`mimic_audio::live`, what `mimic serve` runs on an audio session's chunks):
/// the same sentences fed in 20 ms chunks, as they would arrive, and the same three figures;
/// also the delay in the stream from each word's first sample to its first frame with jawOpen
/// >= 0.15 (the word's opening consonant included). Needs espeak-ng only.
#[test]
fn live_lip_sync_opens_in_words_closes_in_silence_and_follows_the_onsets_within_150_ms() {
    let espeak = Command::new("espeak-ng").arg("--version").output().is_ok();
    if !espeak {
        assert!(std::env::var_os("CI").is_none(), "espeak-ng missing");
        eprintln!("SKIPPED: espeak-ng missing (tools/test-deps.sh installs it)");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let table = VisemeTable::shipped().unwrap();
    let (mut f, mut missed, mut delays) = (Figures::default(), Vec::new(), Vec::new());
    for (i, s) in sentences().iter().enumerate() {
        let wav = tmp.path().join(format!("s{i}.wav"));
        let words = sentence_wav(s, tmp.path(), &wav, i % 2 == 1);
        let mono = mimic_audio::wav::read_wav(&wav).unwrap();
        let mut live = mimic_audio::live::LiveLipSync::new(mono.rate, &table).unwrap();
        // Frame 0 (time 0, before any audio) is the closed mouth; frame k follows sample k/60 s.
        let mut frames = vec![vec![0.0f32; table.names.len()]];
        for chunk in mono.samples.chunks(mono.rate as usize / 50) {
            live.push(chunk, |k, w| {
                assert_eq!(k as usize, frames.len());
                frames.push(w.to_vec());
            });
        }
        let jaw = table.column("jawOpen").unwrap();
        for w in &words {
            let k0 = (w.start * mimic_audio::coart::FPS).ceil() as usize;
            let t = |k: usize| k as f64 / mimic_audio::coart::FPS;
            if let Some(k) = (k0..frames.len())
                .take_while(|&k| t(k) < w.end)
                .find(|&k| frames[k][jaw] >= 0.15)
            {
                delays.push(t(k) - w.start);
            }
        }
        let sync = LipSync {
            names: table.names.clone(),
            frames,
            phones: Vec::new(),
            duration_s: mono.duration_s(),
            speech_s: 0.0,
            transcript: false,
            oov: Vec::new(),
        };
        f.add(&sync, &words, &mut missed);
    }
    delays.sort_by(f64::total_cmp);
    let q = |p: f64| delays[((delays.len() - 1) as f64 * p).round() as usize] * 1e3;
    let (open, closed, lips) = f.ratios();
    eprintln!(
        "live: jaw open in {:.0}% of {} words, {:.0}% of {} silence frames closed, lips closed in \
         {:.0}% of {} p/b/m words (pressed >= 0.3: {}; other words pressed: {} of {}); onset to \
         jawOpen >= 0.15: median {:.0} ms, p90 {:.0} ms, max {:.0} ms; missed: {}",
        open * 100.0,
        f.words,
        closed * 100.0,
        f.silence_frames,
        lips * 100.0,
        f.bilabial_words,
        f.pressed,
        f.other_pressed,
        f.other_words,
        q(0.5),
        q(0.9),
        q(1.0),
        missed.join(", ")
    );
    assert!(open >= 0.9, "jaw open in {open:.2} of words");
    assert!(closed >= 0.9, "{closed:.2} of silence closed");
    assert!(lips >= 0.7, "lips closed in {lips:.2} of p/b/m words");
    // Stream time, not wall clock: the causal front end's own delay.
    assert!(q(0.9) <= 150.0, "p90 onset delay {} ms", q(0.9));
}
