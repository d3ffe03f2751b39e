//! Lip sync from speech (`mimic import audio`, docs/audio.md): a WAV ([`wav`]) at 16 kHz, where
//! the speech is ([`speech`]), its phones from pocketsphinx ([`recognise`]: a Python helper) or
//! a transcript's phones laid along the speech ([`timeline`]), each phone's viseme from the table
//! in `configs/visemes.toml` ([`visemes`]) and coarticulated ARKit mouth weights at 60 frames a
//! second ([`coart`]), written as mimic's weights CSV ([`LipSync::write_csv`]); live, causal
//! speech-to-mouth for the server's audio sessions ([`live`]). No tokio.

pub mod coart;
pub mod error;
pub mod live;
pub mod recognise;
pub mod speech;
pub mod timeline;
pub mod visemes;
pub mod wav;

pub use error::AudioError;

use std::io::Write;
use std::path::Path;
use timeline::Phone;
use visemes::VisemeTable;

/// Speech turned into mouth weights.
#[derive(Clone, Debug, PartialEq)]
pub struct LipSync {
    /// The ARKit names of the weight columns.
    pub names: Vec<&'static str>,
    /// Per frame ([`coart::FPS`] a second from 0) the weights, columns as `names`.
    pub frames: Vec<Vec<f32>>,
    /// The phones in time, silence included.
    pub phones: Vec<Phone>,
    /// Seconds of audio.
    pub duration_s: f64,
    /// Seconds of it that are speech.
    pub speech_s: f64,
    /// Whether the phones came from a transcript (else free recognition).
    pub transcript: bool,
    /// Transcript words the dictionary lacked (spelt letter by letter).
    pub oov: Vec<String>,
}

impl LipSync {
    /// The frame's time in microseconds.
    pub fn t_us(k: usize) -> i64 {
        (k as f64 * 1e6 / coart::FPS).round() as i64
    }

    /// The phone at `t` seconds (silence past the end).
    pub fn phone_at(&self, t: f64) -> &str {
        self.phones
            .iter()
            .find(|p| p.start_s <= t && t < p.end_s)
            .map_or(timeline::SIL, |p| p.name.as_str())
    }

    /// Writes mimic's weights CSV: `frame,t_us,status,label` and the ARKit names; status 1
    /// (tracked), label the phone at the frame's time.
    pub fn write_csv(&self, path: &Path) -> Result<(), AudioError> {
        let io = |source| AudioError::Io {
            path: path.to_path_buf(),
            source,
        };
        let mut w = std::io::BufWriter::new(std::fs::File::create(path).map_err(io)?);
        let mut line = String::from("frame,t_us,status,label");
        for n in &self.names {
            line.push(',');
            line.push_str(n);
        }
        writeln!(w, "{line}").map_err(io)?;
        for (k, f) in self.frames.iter().enumerate() {
            line.clear();
            let t = Self::t_us(k);
            line.push_str(&format!("{k},{t},1,{}", self.phone_at(t as f64 * 1e-6)));
            for x in f {
                line.push_str(&format!(",{x:.4}"));
            }
            writeln!(w, "{line}").map_err(io)?;
        }
        w.flush().map_err(io)
    }

    /// One line saying what was made.
    pub fn said(&self, out: &Path) -> String {
        let spoken = self
            .phones
            .iter()
            .filter(|p| p.name != timeline::SIL && p.name != timeline::REST)
            .count();
        let mut s = format!(
            "{}: {} frames at {} fps ({:.2} s, {:.2} s of speech), {spoken} phones {}, {} ARKit mouth curves",
            out.display(),
            self.frames.len(),
            coart::FPS,
            self.duration_s,
            self.speech_s,
            if self.transcript {
                "from the transcript"
            } else {
                "recognised"
            },
            self.names.len()
        );
        if !self.oov.is_empty() {
            s.push_str(&format!(
                "; not in the dictionary (spelt out): {}",
                self.oov.join(" ")
            ));
        }
        s
    }
}

/// The transcript's words: `arg` is a file's path when such a file exists, else the text.
pub fn transcript_words(arg: &str) -> Result<Vec<String>, AudioError> {
    let path = Path::new(arg);
    let text = if path.is_file() {
        std::fs::read_to_string(path).map_err(|source| AudioError::Io {
            path: path.to_path_buf(),
            source,
        })?
    } else {
        arg.to_string()
    };
    Ok(text
        .split(|c: char| c.is_whitespace() || (c.is_ascii_punctuation() && c != '\''))
        .filter(|w| w.chars().any(char::is_alphabetic))
        .map(str::to_string)
        .collect())
}

/// Speech at `wav` to mouth weights: phones recognised, or laid along `words` when given.
pub fn lip_sync(
    wav: &Path,
    words: Option<&[String]>,
    table: &VisemeTable,
) -> Result<LipSync, AudioError> {
    let mono = wav::read_wav(wav)?;
    let pcm = wav::to_16k(&mono);
    let speech = speech::speech_frames(&pcm);
    let r = recognise::recognise(&pcm, words)?;
    let labels = match words {
        Some(_) => timeline::from_transcript(&speech, &r.words),
        None => timeline::from_recognised(&speech, &r.phones),
    };
    let phones = timeline::phones(&labels);
    let duration_s = mono.duration_s();
    let frames = (duration_s * coart::FPS).floor() as usize + 1;
    Ok(LipSync {
        names: table.names.clone(),
        frames: coart::curves(&phones, table, frames),
        phones,
        duration_s,
        speech_s: speech.iter().filter(|s| **s).count() as f64 * timeline::FRAME_S,
        transcript: words.is_some(),
        oov: r.oov,
    })
}

/// `mimic import audio`: `wav` to the weights CSV `out` with the shipped viseme table; the
/// transcript (text or a file) is optional. Returns the line to print.
pub fn import_audio(
    wav: &Path,
    transcript: Option<&str>,
    out: &Path,
) -> Result<String, AudioError> {
    let table = VisemeTable::shipped()?;
    let words = transcript.map(transcript_words).transpose()?;
    let sync = lip_sync(wav, words.as_deref(), &table)?;
    sync.write_csv(out)?;
    Ok(sync.said(out))
}
