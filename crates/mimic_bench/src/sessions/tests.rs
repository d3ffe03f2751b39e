//! Tests of the sessions runs on a synthetic face (mimic_retarget's grid rig, `fixtures`).

#![allow(clippy::unwrap_used, reason = "tests")]

use mimic_retarget::fixtures as grid;

use super::*;
use glam::Vec3;
use mimic_retarget::RetargetSettings;
use std::sync::Arc;

#[test]
fn sessions_step_every_frame_and_share_one_basis() {
    let (rig, layout) = grid::rig_and_layout();
    let basis = Arc::new(mimic_solve::build_basis(&rig, &rig.solver).unwrap());
    let retargeters: Vec<Retargeter> = (0..3)
        .map(|_| {
            Retargeter::new(&rig, &layout, basis.clone(), RetargetSettings::default()).unwrap()
        })
        .collect();
    assert_eq!(Arc::strong_count(&basis), 4, "one basis for three sessions");
    let neutral = grid::neutral_points(&rig, &layout);
    let frames: Vec<LandmarkFrame> = (0..20)
        .map(|k| {
            let mut points = neutral.clone();
            // The first control moves up and down a little; the rest hold still.
            points[0] += Vec3::new(0.0, 0.0005 * (k % 4) as f32, 0.0);
            LandmarkFrame::new(k * 33_333, points)
        })
        .collect();
    // The same frames through one retargeter on this thread: the count each session sees.
    let mut one =
        Retargeter::new(&rig, &layout, basis.clone(), RetargetSettings::default()).unwrap();
    let mut out = one.new_output();
    let mut expect = 0u64;
    for f in &frames {
        let mut f = f.clone();
        f.timestamp_us -= 20 * 33_333;
        one.step(&f, &mut out);
    }
    for s in 0..50 {
        let mut f = frames[s % 20].clone();
        f.timestamp_us += (s / 20) as i64 * 20 * 33_333;
        if one.step(&f, &mut out) == FrameStatus::Tracked {
            expect += 1;
        }
    }
    assert_eq!(expect, 50, "after the warm-up every frame is tracked");
    let report = step_sessions(retargeters, &frames, 20 * 33_333, 50).unwrap();
    assert_eq!(report.sessions, 3);
    assert_eq!(report.steps_per_session, 50);
    assert_eq!(report.per_session_frames_per_second.len(), 3);
    assert_eq!(report.tracked, 3 * expect);
    assert!(report.frames_per_second > 0.0 && report.wall_s > 0.0);
    assert!(matches!(
        step_sessions(Vec::new(), &[], 0, 1),
        Err(SessionsError::NoFrames)
    ));
}

/// The frames of the tests above: the neutral, the first control moving a little.
fn frames_and_parts() -> (mimic_types::Rig, mimic_types::Layout, Vec<LandmarkFrame>) {
    let (rig, layout) = grid::rig_and_layout();
    let neutral = grid::neutral_points(&rig, &layout);
    let frames = (0..20)
        .map(|k| {
            let mut points = neutral.clone();
            points[0] += Vec3::new(0.0, 0.0005 * (k % 4) as f32, 0.0);
            LandmarkFrame::new(k * 33_333, points)
        })
        .collect();
    (rig, layout, frames)
}

#[test]
fn compare_sessions_runs_two_ab_pairs_and_reports_the_best_of_each() {
    let (rig, layout, frames) = frames_and_parts();
    let basis = Arc::new(mimic_solve::build_basis(&rig, &rig.solver).unwrap());
    let make = || Retargeter::new(&rig, &layout, basis.clone(), RetargetSettings::default());
    let c = compare_sessions(make, &frames, 20 * 33_333, 40, 2).unwrap();
    assert_eq!((c.runs.one.len(), c.runs.many.len()), (2, 2));
    assert!(
        c.runs
            .one
            .iter()
            .all(|r| r.sessions == 1 && r.steps_per_session == 40)
    );
    assert!(
        c.runs
            .many
            .iter()
            .all(|r| r.sessions == 2 && r.tracked == 80)
    );
    let best = |v: &[SessionsReport]| v.iter().map(|r| r.frames_per_second).fold(0f64, f64::max);
    assert_eq!(c.one_frames_per_second, best(&c.runs.one));
    assert_eq!(c.many_frames_per_second, best(&c.runs.many));
    assert_eq!(
        c.speedup,
        c.many_frames_per_second / c.one_frames_per_second
    );
    assert_eq!(
        c.per_core_frames_per_second,
        c.many_frames_per_second / 2usize.min(c.cores) as f64
    );
    // Every session's retargeter is made fresh, and they all share the one basis.
    assert_eq!(Arc::strong_count(&basis), 1);
}

#[test]
fn step_alternately_times_every_tracked_step_of_each_retargeter() {
    let (rig, layout, frames) = frames_and_parts();
    let basis = Arc::new(mimic_solve::build_basis(&rig, &rig.solver).unwrap());
    let make =
        || Retargeter::new(&rig, &layout, basis.clone(), RetargetSettings::default()).unwrap();
    // The same frames through one retargeter here: how many steps are tracked.
    let mut one = make();
    let mut out = one.new_output();
    let tracked = (0..50)
        .filter(|&s| {
            let mut f = frames[s % 20].clone();
            f.timestamp_us += (s / 20) as i64 * 20 * 33_333;
            one.step(&f, &mut out) == FrameStatus::Tracked
        })
        .count();
    assert!(
        tracked > 0 && tracked < 50,
        "{tracked}: calibration, then tracked"
    );
    // Turns of one frame, of 7 (50 is no multiple of 7) and of more than every frame.
    for block in [1, 7, 64] {
        let mut both = [make(), make()];
        let samples = step_alternately(&mut both, &frames, 20 * 33_333, 50, block).unwrap();
        assert_eq!(samples.len(), 2);
        for s in &samples {
            assert_eq!(s.steps(), tracked, "block {block}");
        }
    }
    let mut both = [make(), make()];
    assert!(matches!(
        step_alternately(&mut both, &[], 0, 1, 1),
        Err(SessionsError::NoFrames)
    ));
}
