//! Gaze on real takes: the MediaPipe Megamind recording and the OpenSeeFace Megamind capture,
//! each against its first usable frame as the neutral with the head motion removed by a Kabsch
//! fit of the layout's stable points. `cargo test -p mimic_retarget --test gaze -- --nocapture`
//! prints each take's gaze range.
#![allow(
    clippy::unwrap_used,
    reason = "a test: a failed unwrap is the failure report"
)]

use std::path::PathBuf;

use glam::Vec3;
use mimic_retarget::gaze::{EyeGaze, GazePoints, GazeSettings, GazeTracker, LEFT, RIGHT};
use mimic_solve::kabsch::fit_similarity;
use mimic_types::{LandmarkFrame, Layout};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn layout(name: &str) -> Layout {
    mimic_assets::load_layout(&repo().join(format!("configs/layouts/{name}.toml"))).unwrap()
}

/// What a take's gaze did.
#[derive(Debug, Default)]
struct Range {
    frames: usize,
    /// Frames where each eye was read.
    trusted: [usize; 2],
    /// Frames where neither eye was read (held).
    held: usize,
    /// Per eye: (min yaw, max yaw, min pitch, max pitch), degrees.
    extent: [[f32; 4]; 2],
    /// Largest angle of either eye from the first frame's gaze, degrees.
    moved: f32,
    /// Lowest openness relative to the neutral, per eye.
    min_openness: [f32; 2],
    /// RMS of left minus right yaw over the frames where both eyes were read, degrees.
    left_right_yaw_rms: f32,
}

/// Runs a tracker over `frames` (`layout`'s) with the first frame whose gaze points are all
/// valid as the neutral.
fn run(layout: &Layout, frames: &[LandmarkFrame]) -> Range {
    let points = GazePoints::of(layout).unwrap();
    let all_valid = |f: &LandmarkFrame| {
        f.tracked
            && [LEFT, RIGHT]
                .iter()
                .all(|&e| points.eye(e).unwrap().all().all(|p| f.is_valid(p)))
    };
    let neutral = frames.iter().find(|f| all_valid(f)).unwrap();
    let mut t = GazeTracker::new(points, GazeSettings::default());
    t.set_neutral(&neutral.points, &neutral.valid);
    assert!(t.has_neutral());
    let stable_n: Vec<Vec3> = layout.stable.iter().map(|&i| neutral.points[i]).collect();
    let deg = 180.0 / std::f32::consts::PI;
    let mut r = Range {
        extent: [[
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::INFINITY,
            f32::NEG_INFINITY,
        ]; 2],
        min_openness: [f32::INFINITY; 2],
        ..Range::default()
    };
    let mut first: Option<[EyeGaze; 2]> = None;
    let mut prev_t = neutral.timestamp_us;
    let (mut both, mut lr) = (0usize, 0.0f32);
    for f in frames.iter().filter(|f| f.tracked) {
        if !layout.stable.iter().all(|&i| f.is_valid(i)) {
            continue;
        }
        let stable_f: Vec<Vec3> = layout.stable.iter().map(|&i| f.points[i]).collect();
        let pose = fit_similarity(&stable_n, &stable_f, false).unwrap();
        let dt = (f.timestamp_us - prev_t) as f32 * 1e-6;
        prev_t = f.timestamp_us;
        let g = t.step(f, &pose.inverse_affine(), dt);
        r.frames += 1;
        for e in [LEFT, RIGHT] {
            r.trusted[e] += usize::from(t.trusted()[e]);
            let o = t.openness()[e];
            if o.is_finite() {
                r.min_openness[e] = r.min_openness[e].min(o);
            }
            let (y, p) = (g[e].yaw * deg, g[e].pitch * deg);
            assert!(y.is_finite() && p.is_finite(), "frame {}: {g:?}", r.frames);
            let x = &mut r.extent[e];
            *x = [x[0].min(y), x[1].max(y), x[2].min(p), x[3].max(p)];
        }
        r.held += usize::from(t.trusted() == [false, false]);
        if t.trusted() == [true, true] {
            both += 1;
            lr += ((g[LEFT].yaw - g[RIGHT].yaw) * deg).powi(2);
        }
        let first = *first.get_or_insert(g);
        for e in [LEFT, RIGHT] {
            let d = (g[e].yaw - first[e].yaw)
                .abs()
                .max((g[e].pitch - first[e].pitch).abs());
            r.moved = r.moved.max(d * deg);
        }
    }
    r.left_right_yaw_rms = (lr / both.max(1) as f32).sqrt();
    r
}

/// The settings' limits hold on every frame of `r`, and the gaze moved at least 2 degrees.
fn check(name: &str, r: &Range) {
    println!("{name}: {r:?}");
    let s = GazeSettings::default();
    let deg = 180.0 / std::f32::consts::PI;
    let slack = 1e-3;
    for x in r.extent {
        assert!(x[0] >= -s.yaw_limit * deg - slack && x[1] <= s.yaw_limit * deg + slack);
        assert!(x[2] >= -s.pitch_down_limit * deg - slack);
        assert!(x[3] <= s.pitch_up_limit * deg + slack);
    }
    assert!(r.moved >= 2.0, "{name}: the gaze never moves 2 degrees");
    assert!(r.trusted.iter().all(|&n| n > r.frames / 2), "{name}: {r:?}");
}

#[test]
fn megamind_mediapipe_gaze_moves_within_its_limits() {
    let layout = layout("mediapipe478");
    let path = repo().join("recordings/megamind_mediapipe.jsonl");
    let reader = mimic_capture::RecordingReader::open(&path, Some(layout.point_count)).unwrap();
    assert_eq!(reader.header().layout, "mediapipe478");
    let frames: Vec<LandmarkFrame> = reader
        .read_all()
        .frames
        .into_iter()
        .map(|f| f.frame)
        .collect();
    let r = run(&layout, &frames);
    assert!(r.frames > 100, "{r:?}");
    check("megamind_mediapipe", &r);
}

#[test]
fn megamind_openseeface_gaze_moves_within_its_limits() {
    use mimic_trackers::openseeface::{decode_packet, read_capture};
    let layout = layout("openseeface68");
    let records = read_capture(&repo().join("tests/data/openseeface/megamind.osf")).unwrap();
    let frames: Vec<LandmarkFrame> = records
        .iter()
        .flat_map(|r| decode_packet(&r.datagram).unwrap())
        .map(|f| mimic_trackers::osf_frames::to_frame(&f, (f.timestamp * 1e6) as i64))
        .collect();
    let r = run(&layout, &frames);
    assert!(r.frames > 100, "{r:?}");
    check("megamind_openseeface", &r);
}
