//! `mimic replay REC --audio SPEECH.wav`: the mouth from speech, the rest of the face from the
//! tracker. espeak-ng speaks a sentence word by word (400 ms silences); the shipped MediaPipe
//! recording replays onto ict-face with and without it. In the audio's silences the lips are
//! closed (the controls' opening, and the rig's jawOpen weight in blend-shape mode); the brows'
//! controls are the tracker's, to the digit. Skips like `audio.rs` without the speech tools.

use crate::audio::speech_tools;
use crate::{mimic, repo, text};
use std::collections::HashMap;
use std::path::Path;
use std::process::Command;

/// A CSV as its header and rows of cells.
fn table(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let t = std::fs::read_to_string(path).unwrap();
    let mut lines = t.lines();
    let header = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect();
    (header, rows)
}

/// Column `name`'s values as numbers.
fn column(t: &(Vec<String>, Vec<Vec<String>>), name: &str) -> Vec<f64> {
    let c =
        t.0.iter()
            .position(|h| h == name)
            .unwrap_or_else(|| panic!("{name}"));
    t.1.iter().map(|r| r[c].parse().unwrap()).collect()
}

fn replay(rec: &str, extra: &[&str]) {
    let mut args = vec!["replay", rec, "--rig", "ict-face"];
    args.extend_from_slice(extra);
    let o = mimic(&args);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{out}{err}");
}

#[test]
fn speech_drives_the_mouth_of_a_mediapipe_replay_and_the_tracker_the_brows() {
    if !speech_tools() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let p = |n: &str| tmp.path().join(n).to_str().unwrap().to_string();
    let said = "we met the bad man by the old mill";
    let ok = Command::new("espeak-ng")
        .args(["-s", "150", "-g", "40", "-w", &p("speech.wav"), said])
        .status()
        .unwrap();
    assert!(ok.success());
    // The speech's own timeline: its phone labels and jawOpen at 60 frames a second.
    let o = mimic(&[
        "import",
        "audio",
        &p("speech.wav"),
        "--transcript",
        said,
        "-o",
        &p("take.csv"),
    ]);
    assert!(o.status.success(), "{}", text(&o).1);
    let take = table(Path::new(&p("take.csv")));
    let labels: Vec<&str> = take.1.iter().map(|r| r[3].as_str()).collect();
    let said_jaw = column(&take, "jawOpen");

    let rec = repo().join("recordings/megamind_mediapipe.jsonl");
    let rec = rec.to_str().unwrap();
    let speech = ["--audio", &p("speech.wav"), "--transcript", said];
    replay(
        rec,
        &[&["--controls", &p("audio.csv")][..], &speech].concat(),
    );
    replay(rec, &["--controls", &p("plain.csv")]);
    let blend = ["--mode", "blendshapes", "--weights", &p("w.csv")];
    replay(rec, &[&blend[..], &speech].concat());
    let (audio, plain, weights) = (
        table(Path::new(&p("audio.csv"))),
        table(Path::new(&p("plain.csv"))),
        table(Path::new(&p("w.csv"))),
    );

    // Each replayed frame's place in the speech (the audio starts at the first frame).
    let t = column(&audio, "t_us");
    let at: Vec<Option<usize>> = t
        .iter()
        .map(|t_us| {
            let k = ((t_us - t[0]) * 60e-6).round() as usize;
            (k < labels.len()).then_some(k)
        })
        .collect();
    let silent: Vec<usize> = (0..t.len())
        .filter(|&i| at[i].is_some_and(|k| labels[k].eq_ignore_ascii_case("sil")))
        .collect();
    let spoken = at.iter().flatten().count() - silent.len();
    assert!(
        silent.len() >= 20 && spoken >= 20,
        "{} silent, {spoken} spoken frames",
        silent.len()
    );

    // The lips' opening at the controls: the upper inner lip's rise over the lower's.
    let opening = |t: &(Vec<String>, Vec<Vec<String>>)| -> Vec<f64> {
        let (up, low) = (column(t, "2.2_y"), column(t, "2.3_y"));
        up.iter().zip(&low).map(|(u, l)| u - l).collect()
    };
    let (open_a, open_p) = (opening(&audio), opening(&plain));
    let widest = open_a.iter().fold(0.0f64, |a, b| a.max(*b));
    let closed = |o: &[f64]| silent.iter().filter(|&&i| o[i] <= 0.05 * widest).count();
    let (closed_a, closed_p) = (closed(&open_a), closed(&open_p));
    eprintln!(
        "silences: {} frames, closed {closed_a} with the audio, {closed_p} on the tracker alone; widest opening {widest:.3} cm",
        silent.len()
    );
    assert!(widest > 0.5, "the speech opens the mouth: {widest} cm");
    assert!(
        closed_a * 10 >= silent.len() * 8,
        "{closed_a} of {}",
        silent.len()
    );
    // Where the speech opens the jaw wide, the lips open with it (the tracker's do not follow it).
    let wide: Vec<usize> = (0..t.len())
        .filter(|&i| at[i].is_some_and(|k| said_jaw[k] >= 0.3))
        .collect();
    let opened = |o: &[f64]| wide.iter().filter(|&&i| o[i] >= 0.25 * widest).count();
    let (opened_a, opened_p) = (opened(&open_a), opened(&open_p));
    eprintln!(
        "wide-open speech: {} frames, lips open >= 0.25 of the widest in {opened_a} with the audio, {opened_p} on the tracker alone",
        wide.len()
    );
    assert!(
        wide.len() >= 10 && opened_a * 10 >= wide.len() * 8,
        "{opened_a} of {}",
        wide.len()
    );

    // Blend-shape mode: the rig's jawOpen is shut in the silences.
    let jaw = column(&weights, "jawOpen");
    let shut = silent.iter().filter(|&&i| jaw[i] <= 0.05).count();
    let peak = jaw.iter().fold(0.0f64, |a, b| a.max(*b));
    eprintln!(
        "blend shapes: jawOpen <= 0.05 in {shut} of {} silent frames, peak {peak:.2}",
        silent.len()
    );
    assert!(shut * 10 >= silent.len() * 8, "{shut} of {}", silent.len());
    assert!(peak >= 0.3, "jawOpen peaks at {peak}");
    // In blend-shape mode the rig's jawOpen is the speech's (interpolated between its frames).
    let step = said_jaw
        .windows(2)
        .fold(0.0f64, |a, w| a.max((w[1] - w[0]).abs()));
    for (i, k) in at.iter().enumerate() {
        if let Some(k) = k {
            assert!(
                (jaw[i] - said_jaw[*k]).abs() <= step / 2.0 + 1e-3,
                "frame {i}: {} vs {}",
                jaw[i],
                said_jaw[*k]
            );
        }
    }

    // The brows are the tracker's, and they move.
    let mut moved: HashMap<&str, f64> = HashMap::new();
    for fdp in ["4.1", "4.2", "4.3", "4.4", "4.5", "4.6"] {
        for axis in ["x", "y", "z"] {
            let name = format!("{fdp}_{axis}");
            let (a, b) = (column(&audio, &name), column(&plain, &name));
            assert_eq!(a, b, "{name}");
            let reach = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let e = moved.entry(fdp).or_default();
            *e = e.max(reach);
        }
    }
    let most = moved.values().fold(0.0f64, |a, b| a.max(*b));
    eprintln!("brows: reach {moved:?}");
    assert!(most > 0.1, "the tracker's brows move: {most} cm");
}
