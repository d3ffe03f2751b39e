//! `mimic import audio` end to end: espeak-ng speaks a sentence, the binary turns it into a
//! weights CSV of ARKit mouth curves, and `mimic replay` plays that onto the ict-face rig, its
//! jawOpen target following the speech (open in the words, shut in the silences). Skips, saying
//! so, without espeak-ng or the recogniser, except under CI (tools/test-deps.sh installs both).
//! A file that is no WAV fails with one line naming it.

use crate::{mimic, text};
use std::process::Command;

/// Whether espeak-ng and the recogniser are here; says so and returns false when not (a
/// failure under CI, where tools/test-deps.sh installs both).
pub(crate) fn speech_tools() -> bool {
    let espeak = Command::new("espeak-ng").arg("--version").output().is_ok();
    let py = mimic_audio::recognise::python();
    let sphinx = Command::new(&py)
        .args(["-c", "import pocketsphinx"])
        .status()
        .is_ok_and(|s| s.success());
    if !(espeak && sphinx) {
        let msg = format!(
            "espeak-ng: {espeak}, pocketsphinx in {}: {sphinx}",
            py.display()
        );
        assert!(std::env::var_os("CI").is_none(), "{msg}");
        eprintln!("SKIPPED: {msg}");
        return false;
    }
    true
}

#[test]
fn speech_imports_as_arkit_weights_that_replay_onto_ict_face() {
    if !speech_tools() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let wav = tmp.path().join("speech.wav");
    // -g 40: 400 ms between words.
    let said = "open your mouth and say papa";
    let ok = Command::new("espeak-ng")
        .args(["-s", "150", "-g", "40", "-w"])
        .arg(&wav)
        .arg(said)
        .status()
        .unwrap();
    assert!(ok.success());
    let take = tmp.path().join("take.weights.csv");
    let o = mimic(&[
        "import",
        "audio",
        wav.to_str().unwrap(),
        "--transcript",
        said,
        "-o",
        take.to_str().unwrap(),
    ]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{out}{err}");
    assert!(
        out.contains("frames at 60 fps") && out.contains("from the transcript"),
        "{out}"
    );

    let glb = tmp.path().join("take.glb");
    let rig_weights = tmp.path().join("rig.weights.csv");
    let o = mimic(&[
        "replay",
        take.to_str().unwrap(),
        "--rig",
        "ict-face",
        "--format",
        "glb",
        "--out",
        glb.to_str().unwrap(),
        "--weights",
        rig_weights.to_str().unwrap(),
    ]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{out}{err}");
    assert!(out.contains("onto rig ict-face") && glb.is_file(), "{out}");
    // The rig's jawOpen weight, frame by frame, is the take's jawOpen.
    let col = |csv: &str, name: &str| -> Vec<f32> {
        let mut lines = csv.lines();
        let header: Vec<&str> = lines.next().unwrap().split(',').collect();
        let c = header.iter().position(|h| *h == name).unwrap();
        lines
            .map(|l| l.split(',').nth(c).unwrap().parse().unwrap())
            .collect()
    };
    let took = col(&std::fs::read_to_string(&take).unwrap(), "jawOpen");
    let drove = col(&std::fs::read_to_string(&rig_weights).unwrap(), "jawOpen");
    assert_eq!(took.len(), drove.len());
    for (a, b) in took.iter().zip(&drove) {
        assert!((a - b).abs() < 1e-3, "{a} vs {b}");
    }
    let peak = drove.iter().fold(0.0f32, |a, b| a.max(*b));
    assert!(peak > 0.3, "jaw opens: {peak}");
    // Shut in the 400 ms pauses between the words (at least 15 frames between open ones).
    let first = drove.iter().position(|w| *w > 0.3).unwrap();
    let last = drove.iter().rposition(|w| *w > 0.3).unwrap();
    let shut = drove[first..last].iter().filter(|w| **w <= 0.05).count();
    assert!(shut >= 15, "{shut} shut frames between the words");

    std::fs::write(tmp.path().join("notes.wav"), "not audio").unwrap();
    let o = mimic(&[
        "import",
        "audio",
        tmp.path().join("notes.wav").to_str().unwrap(),
        "-o",
        "x.csv",
    ]);
    let (_, err) = text(&o);
    assert!(!o.status.success());
    assert!(err.contains("notes.wav: not a WAV file"), "{err}");
}
