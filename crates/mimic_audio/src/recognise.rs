//! The phoneme recogniser: PyPI's pocketsphinx run by a small Python helper (`phonemes.py`,
//! compiled into this crate and run with `python -c`), 16 kHz PCM on its stdin, JSON on its
//! stdout ([`Recognised`]). The interpreter is `MIMIC_AUDIO_PYTHON`, else the project's venv
//! (`target/ci-tools/audio/bin/python` beside the running binary's `target/`, made by
//! tools/test-deps.sh), else `python3` on the PATH ([`python`]).

use crate::error::AudioError;
use serde::Deserialize;
use std::io::Write;
use std::path::PathBuf;
use std::process::{Command, Stdio};

/// The helper's text (module docs).
pub const HELPER: &str = include_str!("phonemes.py");
/// The environment variable naming the Python interpreter that has pocketsphinx.
pub const PYTHON_ENV: &str = "MIMIC_AUDIO_PYTHON";

/// What the recogniser said.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
pub struct Recognised {
    /// Free phone recognition: `(phone, first frame, last frame)`, 10 ms frames, inclusive.
    #[serde(default)]
    pub phones: Vec<(String, usize, usize)>,
    /// With a transcript: each word and its phones (CMU dictionary).
    #[serde(default)]
    pub words: Vec<(String, Vec<String>)>,
    /// Transcript words the dictionary lacks (spelt out letter by letter).
    #[serde(default)]
    pub oov: Vec<String>,
    /// Set when the helper could not run the recogniser.
    #[serde(default)]
    pub error: Option<String>,
}

/// The Python interpreter to run (module docs).
pub fn python() -> PathBuf {
    if let Some(p) = std::env::var_os(PYTHON_ENV) {
        return PathBuf::from(p);
    }
    // target/{debug,release}/mimic (or target/debug/deps/test-...) -> target/ci-tools/audio.
    if let Ok(exe) = std::env::current_exe() {
        for dir in exe.ancestors().skip(1).take(3) {
            let venv = dir.join("ci-tools/audio/bin/python");
            if venv.is_file() {
                return venv;
            }
        }
    }
    PathBuf::from("python3")
}

/// Recognises the phones of `pcm` (16 kHz mono, -1..1); with `words`, looks up their phones too.
pub fn recognise(pcm: &[f32], words: Option<&[String]>) -> Result<Recognised, AudioError> {
    let py = python();
    let fail = |reason: String| AudioError::Recogniser {
        python: py.display().to_string(),
        reason,
    };
    let mut cmd = Command::new(&py);
    cmd.arg("-c").arg(HELPER);
    if let Some(w) = words {
        cmd.arg("--words").args(w);
    }
    let mut child = cmd
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| {
            fail(format!(
                "cannot run it ({e}); install pocketsphinx==5.1.1 with pip (tools/test-deps.sh) \
                 and name its python in {PYTHON_ENV}"
            ))
        })?;
    let bytes = crate::wav::pcm16(pcm);
    let mut stdin = child.stdin.take().ok_or_else(|| fail("no stdin".into()))?;
    // A writer thread, so that a helper that fails early cannot block on a full stdout pipe.
    let writer = std::thread::Builder::new()
        .name("mimic-audio-pcm".into())
        .spawn(move || stdin.write_all(&bytes))
        .map_err(|e| fail(e.to_string()))?;
    let out = child.wait_with_output().map_err(|e| fail(e.to_string()))?;
    let written = writer.join().map_err(|_| fail("writer panicked".into()))?;
    let stdout = String::from_utf8_lossy(&out.stdout);
    let Some(line) = stdout.lines().rev().find(|l| l.starts_with('{')) else {
        let err = String::from_utf8_lossy(&out.stderr);
        let last = err.lines().last().unwrap_or("no output");
        return Err(fail(format!("{} ({last})", out.status)));
    };
    written.map_err(|e| fail(format!("writing the audio: {e}")))?;
    let r: Recognised =
        serde_json::from_str(line).map_err(|e| fail(format!("unreadable output: {e}")))?;
    match &r.error {
        Some(e) => Err(fail(format!(
            "{e}; or name a python that has it in {PYTHON_ENV}"
        ))),
        None => Ok(r),
    }
}
