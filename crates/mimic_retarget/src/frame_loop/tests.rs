//! The frame loop against the retargeter stepped by hand (the same frames, no loop), and its
//! outputs' turns, mesh requests and errors, on the synthetic grid face of `crate::tests`.

use crate::tests::{neutral_points, plain, rig_and_layout};
use crate::*;
use glam::{Quat, Vec3};
use mimic_types::{
    FrameSink, LandmarkFrame, MorphTarget, SinkError, SinkFrame, SinkReport, WeightMap,
};
use std::sync::{Arc, Mutex};

/// What a [`Recorder`] saw of one frame.
#[derive(Clone, Debug, PartialEq)]
struct Seen {
    index: usize,
    status: FrameStatus,
    d: Vec<Vec3>,
    first_position: Vec3,
    head: Option<Vec3>,
    weights: Option<Vec<f32>>,
}

/// An output that keeps what it was handed (shared with the test) and can fail at the end.
struct Recorder {
    seen: Arc<Mutex<Vec<Seen>>>,
    mesh: bool,
    fail_at_finish: bool,
}

impl Recorder {
    fn new(mesh: bool, fail_at_finish: bool) -> (Self, Arc<Mutex<Vec<Seen>>>) {
        let seen = Arc::new(Mutex::new(Vec::new()));
        let r = Self {
            seen: seen.clone(),
            mesh,
            fail_at_finish,
        };
        (r, seen)
    }
}

impl FrameSink for Recorder {
    fn wants_mesh(&self) -> bool {
        self.mesh
    }

    fn frame(&mut self, f: &SinkFrame<'_>) -> Result<(), SinkError> {
        self.seen.lock().unwrap().push(Seen {
            index: f.index,
            status: f.view.status,
            d: f.view.displacements.to_vec(),
            first_position: f.positions.first().copied().unwrap_or(Vec3::NAN),
            head: f.head_translation,
            weights: f.weights.map(<[f32]>::to_vec),
        });
        Ok(())
    }

    fn finish(self: Box<Self>) -> Result<SinkReport, SinkError> {
        if self.fail_at_finish {
            return Err(SinkError::new("recorder", "asked to fail"));
        }
        Ok(SinkReport {
            kind: "recorder",
            path: "recorder".into(),
            frames: self.seen.lock().unwrap().len(),
            bytes: 0,
            detail: serde_json::json!(null),
        })
    }
}

/// A neutral frame, then frames whose first control rises by `k` mm and whose whole face moves
/// by `shift` (metres, source space).
fn frames(neutral: &[Vec3], shift: Vec3) -> Vec<LandmarkFrame> {
    (0..6)
        .map(|k| {
            let mut p: Vec<Vec3> = neutral
                .iter()
                .map(|q| *q + shift * (k > 0) as u8 as f32)
                .collect();
            p[0].y += 0.001 * k as f32;
            LandmarkFrame::new(k as i64 * 33_000, p)
        })
        .collect()
}

fn retargeter() -> (Retargeter, Vec<Vec3>) {
    let (rig, layout) = rig_and_layout();
    let basis = mimic_solve::build_basis(&rig, &rig.solver).unwrap();
    let neutral = neutral_points(&rig, &layout);
    (
        Retargeter::new(&rig, &layout, basis, plain()).unwrap(),
        neutral,
    )
}

#[test]
fn outputs_get_the_retargeters_frames_on_their_turns() {
    let (r, neutral) = retargeter();
    let (mut by_hand, _) = retargeter();
    let mut out = by_hand.new_output();
    let shift = Vec3::new(0.002, -0.001, 0.0005);
    let frames = frames(&neutral, shift);
    let mut fl = FrameLoop::landmarks(r, None);
    let (every, every_seen) = Recorder::new(false, false);
    let (odd, odd_seen) = Recorder::new(false, false);
    fl.add_output(Box::new(every), 1);
    fl.add_output(Box::new(odd), 2);
    for f in &frames {
        let status = fl.step(f, Some(7)).unwrap();
        assert_eq!(status, by_hand.step(f, &mut out));
        let seen = every_seen.lock().unwrap();
        let last = seen.last().unwrap();
        // The loop hands over exactly what the retargeter computed.
        assert_eq!(last.d, out.displacements);
        assert_eq!(last.status, out.status);
        assert_eq!(last.weights, None);
    }
    let every = every_seen.lock().unwrap().clone();
    assert_eq!(every.len(), frames.len());
    let odd: Vec<usize> = odd_seen.lock().unwrap().iter().map(|s| s.index).collect();
    assert_eq!(odd, [0, 2, 4]);
    // The first frame calibrates (no head translation); the others moved the whole face by
    // `shift` with no turn: the head's translation is `shift` in target axes and units (the
    // rig is in cm, the performer in m: scale 100, no mirror), up to the fit's rounding.
    assert_eq!(every[0].status, FrameStatus::Calibrating);
    assert_eq!(every[0].head, None);
    let want = shift * 100.0;
    for s in &every[1..] {
        let head = s.head.unwrap();
        assert!(
            (head - want).length() <= 1e-3 * want.length().max(1.0),
            "frame {}: head {head} want {want}",
            s.index
        );
    }
    let report = fl.finish().unwrap();
    assert_eq!(report.frames, frames.len());
    assert_eq!(
        report.outputs.iter().map(|r| r.frames).collect::<Vec<_>>(),
        [6, 3]
    );
    assert_eq!(report.samples.steps(), frames.len() - 1);
    assert_eq!(report.non_finite_frames, 0);
}

#[test]
fn a_weights_loop_blends_the_mesh_only_for_outputs_that_want_it() {
    let (rig, _) = rig_and_layout();
    let n = rig.mesh.vertex_count();
    let delta = Vec3::new(0.5, -0.25, 1.0);
    let target = MorphTarget {
        name: "raise".into(),
        position_deltas: vec![delta; n],
        normal_deltas: vec![Vec3::ZERO; n],
    };
    let fitter =
        || BlendshapeFitter::new(&rig, std::slice::from_ref(&target), &Default::default()).unwrap();
    let rest0 = rig.mesh.positions[0];
    let rotation = Quat::from_rotation_y(0.2);
    for mesh in [false, true] {
        let mut fl = FrameLoop::weights(&rig.mesh.positions, fitter());
        let (rec, seen) = Recorder::new(mesh, false);
        fl.add_output(Box::new(rec), 1);
        fl.push_weights(1_000, &[0.5], rotation).unwrap();
        let seen = seen.lock().unwrap();
        let s = &seen[0];
        assert_eq!(s.weights.as_deref(), Some(&[0.5f32][..]));
        assert_eq!(s.status, FrameStatus::Tracked);
        // Blended by hand: rest + w dP; untouched rest when no output asked for the mesh.
        let want = if mesh { rest0 + 0.5 * delta } else { rest0 };
        assert!((s.first_position - want).length() <= 1e-6, "{mesh}");
    }
    // The map the take replay uses names the target either way.
    let mut w = [0.0];
    assert_eq!(
        WeightMap::new(&["raise".into()]).apply([("Raise", 0.7)], &mut w),
        0
    );
    assert_eq!(w, [0.7]);
}

#[test]
fn finish_finishes_every_output_and_returns_the_first_error() {
    let (r, neutral) = retargeter();
    let mut fl = FrameLoop::landmarks(r, None);
    let (failing, _) = Recorder::new(false, true);
    let (fine, fine_seen) = Recorder::new(false, false);
    fl.add_output(Box::new(failing), 1);
    fl.add_output(Box::new(fine), 1);
    fl.step(&LandmarkFrame::new(0, neutral), None).unwrap();
    let e = fl.finish().unwrap_err();
    assert_eq!(e.to_string(), "recorder: asked to fail");
    assert_eq!(fine_seen.lock().unwrap().len(), 1);
}
