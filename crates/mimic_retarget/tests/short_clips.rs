//! Short clips and single frames (issue 45 item 5): until the performer's neutral is calibrated,
//! frames are retargeted against the layout's canonical neutral, so a single MediaPipe frame or a
//! clip shorter than the calibration gives the expression the full take gives those frames, within
//! the figures below (`cargo test -p mimic_retarget --test short_clips -- --nocapture` prints
//! them; docs/replay.md, "Short clips").
//!
//! The figures are relative errors: the RMS over the rig's controls of the clip's output `d` minus
//! the full take's for the same frame, over the RMS of the full take's `d` (the rest face scores
//! 1). "raw": against the full take replayed with no filter and no gate, which a single frame also
//! has none of, so that only the neutral differs; "output": against the full take's own (filtered,
//! speed-clamped) output.
#![allow(
    clippy::unwrap_used,
    reason = "a test: a failed unwrap is the failure report"
)]

mod common;

use common::{ict, layout, root};
use std::sync::OnceLock;

use glam::Vec3;
use mimic_retarget::{FrameStatus, Neutral, Provisional, RetargetSettings, Retargeter};
use mimic_types::{LandmarkFrame, Layout};
fn frames(name: &str, layout: &Layout) -> Vec<LandmarkFrame> {
    let path = root().join("recordings").join(name);
    let reader = mimic_capture::RecordingReader::open(&path, Some(layout.point_count)).unwrap();
    reader
        .read_all()
        .frames
        .into_iter()
        .map(|f| f.frame)
        .collect()
}

/// The controls' output `d` (rig units) and the status of each of `frames`, retargeted from the
/// first with `settings`, and the retargeter after them.
fn replay(
    layout: &Layout,
    frames: &[LandmarkFrame],
    settings: &RetargetSettings,
) -> (Vec<Vec<Vec3>>, Vec<FrameStatus>, Retargeter) {
    let (rig, basis) = ict();
    let mut r = Retargeter::new(rig, layout, basis.clone(), settings.clone()).unwrap();
    let mut out = r.new_output();
    let m = rig.controls.len();
    let mut ds = Vec::new();
    let mut st = Vec::new();
    for f in frames {
        st.push(r.step(f, &mut out));
        ds.push(out.displacements[..m].to_vec());
    }
    (ds, st, r)
}

fn rms(v: impl Iterator<Item = f32>) -> f32 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
    (s / n.max(1) as f32).sqrt()
}

/// RMS over controls of `a - b` relative to the RMS of `b`.
fn relative_error(a: &[Vec3], b: &[Vec3]) -> f32 {
    rms(a.iter().zip(b).map(|(x, y)| x.distance(*y))) / rms(b.iter().map(|y| y.length()))
}

/// The MediaPipe take replayed whole.
struct Take {
    layout: Layout,
    frames: Vec<LandmarkFrame>,
    /// The full take's output `d`.
    output: Vec<Vec<Vec3>>,
    /// The same with no filter and no gate.
    raw: Vec<Vec<Vec3>>,
    /// The rig's inter-ocular distance (cm).
    iod: f32,
    /// Frames 20 frames or more from either end, most expressive first (RMS of `d` in `output`).
    expressive: Vec<usize>,
}

fn settings() -> RetargetSettings {
    RetargetSettings::default().displacements_only()
}

fn take() -> &'static Take {
    static TAKE: OnceLock<Take> = OnceLock::new();
    TAKE.get_or_init(|| {
        let layout = layout("mediapipe478");
        let frames = frames("megamind_mediapipe.jsonl", &layout);
        let (output, _, r) = replay(&layout, &frames, &settings());
        let mut bare = settings();
        bare.filter = None;
        bare.gate.enabled = false;
        let (raw, _, _) = replay(&layout, &frames, &bare);
        let iod = r.face_size();
        let size = |t: usize| rms(output[t].iter().map(|d| d.length()));
        let mut expressive: Vec<usize> = (20..frames.len() - 20).collect();
        expressive.sort_by(|a, b| size(*b).total_cmp(&size(*a)));
        Take {
            layout,
            frames,
            output,
            raw,
            iod,
            expressive,
        }
    })
}

fn median(mut v: Vec<f32>) -> f32 {
    v.sort_by(f32::total_cmp);
    v[v.len() / 2]
}

fn max(v: &[f32]) -> f32 {
    v.iter().copied().fold(0.0, f32::max)
}

/// Largest control displacement of `d`, in IODs.
fn largest(d: &[Vec3], iod: f32) -> f32 {
    max(&d.iter().map(|x| x.length()).collect::<Vec<_>>()) / iod
}

#[test]
fn a_single_mediapipe_frame_gives_the_full_takes_expression() {
    let take = take();
    let (mut raw, mut output, mut biggest) = (Vec::new(), Vec::new(), Vec::new());
    for &t in &take.expressive[..10] {
        let (one, status, r) = replay(&take.layout, &take.frames[t..=t], &settings());
        assert_eq!(status, [FrameStatus::Tracked], "frame {t}");
        assert_eq!((r.stats().provisional, r.stats().calibrating), (1, 0));
        let d = &one[0];
        biggest.push(largest(d, take.iod));
        raw.push(relative_error(d, &take.raw[t]));
        output.push(relative_error(d, &take.output[t]));
    }
    // Every 5th frame, expressive or not, against the raw take.
    let every: Vec<f32> = (20..take.frames.len() - 20)
        .step_by(5)
        .map(|t| {
            let (one, _, _) = replay(&take.layout, &take.frames[t..=t], &settings());
            relative_error(&one[0], &take.raw[t])
        })
        .collect();
    eprintln!(
        "single frames, the 10 most expressive ({:?}): largest control {:.3}-{:.3} IOD; error raw median {:.2} max {:.2}, output median {:.2} max {:.2}; every 5th frame: raw median {:.2}",
        &take.expressive[..10],
        biggest.iter().copied().fold(f32::INFINITY, f32::min),
        max(&biggest),
        median(raw.clone()),
        max(&raw),
        median(output.clone()),
        max(&output),
        median(every),
    );
    // An expression, not the rest face: some control moves over a tenth of the eye distance.
    assert!(biggest.iter().all(|b| *b > 0.1), "{biggest:?}");
    // Closer to the full take than the rest face (1): the canonical face's identity is the error.
    assert!(median(raw) < 0.75, "raw");
    assert!(median(output) < 0.8, "output");
}

#[test]
fn a_16_frame_clip_gives_the_full_takes_expression_while_shorter_than_the_calibration() {
    let take = take();
    let t = take.expressive[0];
    let clip = &take.frames[t - 8..t + 8];
    for k in [16, 5] {
        let s = RetargetSettings {
            neutral: Neutral::FirstFrames(k),
            ..settings()
        };
        let (d, status, r) = replay(&take.layout, clip, &s);
        assert!(status.iter().all(|s| *s == FrameStatus::Tracked));
        let raw: Vec<f32> = (0..16)
            .map(|i| relative_error(&d[i], &take.raw[t - 8 + i]))
            .collect();
        let output: Vec<f32> = (0..16)
            .map(|i| relative_error(&d[i], &take.output[t - 8 + i]))
            .collect();
        eprintln!(
            "16 frames around {t}, neutral from {k} frames: provisional {}; error raw {:?}, output median {:.2}",
            r.stats().provisional,
            raw.iter()
                .map(|e| (e * 100.0).round() / 100.0)
                .collect::<Vec<_>>(),
            median(output.clone()),
        );
        if k == 16 {
            assert_eq!(r.stats().provisional, 16);
            assert!(median(raw) < 0.75, "raw");
            assert!(median(output) < 0.8, "output");
            assert!(d.iter().all(|d| largest(d, take.iod) > 0.1));
        }
    }
}

#[test]
fn a_long_take_is_unchanged_once_the_ease_into_its_neutral_is_over() {
    let take = take();
    let rest = RetargetSettings {
        provisional: Provisional::Rest,
        ..settings()
    };
    let (old, old_status, r_old) = replay(&take.layout, &take.frames, &rest);
    let (_, new_status, r_new) = replay(&take.layout, &take.frames, &settings());
    let new = &take.output;
    let (so, sn) = (r_old.stats(), r_new.stats());
    // The calibrating frames are tracked against the canonical face instead.
    assert_eq!((so.calibrating, so.provisional), (5, 0));
    assert_eq!((sn.calibrating, sn.provisional), (0, 5));
    assert_eq!(so.tracked + 5, sn.tracked);
    assert_eq!(so.jumps, sn.jumps);
    let first = old_status
        .iter()
        .position(|s| *s == FrameStatus::Tracked)
        .unwrap();
    assert!(
        new_status[..first]
            .iter()
            .all(|s| *s != FrameStatus::Calibrating)
    );
    // Calibrated from `first` on, eased over `lost_ease_secs` (0.5 s at 24 fps: 12 frames).
    let last_different = (0..take.frames.len())
        .rev()
        .find(|t| new[*t] != old[*t])
        .unwrap();
    let ease_end = first + 13;
    assert!(last_different < ease_end, "{last_different} vs {ease_end}");
    // No pop: the switch holds the last provisional output, and no step of the ease is larger
    // than the take's own steps after it (IOD; the speed clamp bounds those).
    let step = |d: &[Vec<Vec3>], t: usize| {
        let s: Vec<f32> = d[t]
            .iter()
            .zip(&d[t - 1])
            .map(|(a, b)| a.distance(*b))
            .collect();
        max(&s) / take.iod
    };
    assert!(step(new, first) < 1e-6, "{}", step(new, first));
    let ease = max(&(first + 1..ease_end)
        .map(|t| step(new, t))
        .collect::<Vec<_>>());
    let after: Vec<f32> = (ease_end..take.frames.len())
        .filter(|t| new_status[*t] == FrameStatus::Tracked)
        .filter(|t| new_status[*t - 1] == FrameStatus::Tracked)
        .map(|t| step(new, t))
        .collect();
    eprintln!(
        "the ease into the calibrated neutral (calibrated from frame {first}; frames up to {last_different} differ from before): largest step {ease:.3} IOD; the take's steps after it: median {:.3}, largest {:.3} IOD",
        median(after.clone()),
        max(&after)
    );
    assert!(ease <= max(&after) + 1e-6, "{ease} > {}", max(&after));
}

#[test]
fn a_layout_without_a_canonical_neutral_calibrates_as_before() {
    let layout = layout("kinect121");
    assert!(layout.canonical_neutral.is_none());
    let frames = frames("a_yn_question.kinect121.jsonl", &layout);
    let rest = RetargetSettings {
        provisional: Provisional::Rest,
        ..settings()
    };
    let (old, old_status, r_old) = replay(&layout, &frames[..60], &rest);
    let (new, new_status, r_new) = replay(&layout, &frames[..60], &settings());
    assert_eq!(old, new);
    assert_eq!(old_status, new_status);
    assert_eq!(r_old.stats(), r_new.stats());
    assert_eq!(
        (r_new.stats().calibrating, r_new.stats().provisional),
        (5, 0)
    );
}
