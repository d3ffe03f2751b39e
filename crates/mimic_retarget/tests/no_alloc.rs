//! "The per-frame step allocates nothing" (docs/ARCHITECTURE.md, "Invariants"), checked: a
//! counting global allocator around the system one, in its own test binary, counts every
//! allocation the current thread makes while `Retargeter::step` (positions and normals on) and
//! `Basis::apply` run on the real ICT-FaceKit rig and a real Kinect recording, and while
//! `GazeTracker::step` runs on the real MediaPipe recording, after a warm-up.

#![allow(
    clippy::unwrap_used,
    reason = "a test: a failed unwrap is the failure report"
)]

use std::alloc::{GlobalAlloc, Layout as AllocLayout, System};
use std::cell::Cell;
use std::path::PathBuf;
use std::sync::Arc;

use glam::Vec3;
use mimic_retarget::{FrameStatus, RetargetSettings, Retargeter};
use mimic_solve::build_basis;
use mimic_types::LandmarkFrame;

/// The system allocator, counting the allocations of threads that asked to be counted (the test
/// harness's own threads allocate at any time and are not counted).
struct Counting;

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    static COUNT: Cell<u64> = const { Cell::new(0) };
}

fn note() {
    // `try_with`: the allocator also runs while thread-locals are torn down.
    let _ = COUNTING.try_with(|on| {
        if on.get() {
            let _ = COUNT.try_with(|c| c.set(c.get() + 1));
        }
    });
}

// SAFETY: every call forwards to `System` with the same arguments; counting touches only
// const-initialised thread-locals, which never allocate.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: AllocLayout) -> *mut u8 {
        note();
        // SAFETY: the caller's contract for `alloc` is passed on unchanged.
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: AllocLayout) -> *mut u8 {
        note();
        // SAFETY: as for `alloc`.
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: AllocLayout, new_size: usize) -> *mut u8 {
        note();
        // SAFETY: `ptr` came from this allocator, that is from `System`, with `layout`.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: AllocLayout) {
        note();
        // SAFETY: as for `realloc`.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Allocations, reallocations and frees made by this thread while `f` runs.
fn allocations_during(f: impl FnOnce()) -> u64 {
    COUNT.with(|c| c.set(0));
    COUNTING.with(|on| on.set(true));
    f();
    COUNTING.with(|on| on.set(false));
    COUNT.with(|c| c.get())
}

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The frames of a real recording: the shipped Kinect 121-point yes/no question.
fn frames(point_count: usize) -> Vec<LandmarkFrame> {
    let path = repo().join("recordings/a_yn_question.kinect121.jsonl");
    let mut reader = mimic_capture::RecordingReader::open(&path, Some(point_count)).unwrap();
    let mut frames = Vec::new();
    while let Some(f) = reader.next_frame() {
        frames.push(f.unwrap().frame);
    }
    frames
}

#[test]
fn counting_allocator_sees_an_allocation() {
    // The check below would pass vacuously if the counter missed allocations.
    let n = allocations_during(|| {
        let v: Vec<u64> = std::hint::black_box(vec![1, 2, 3]);
        drop(std::hint::black_box(v));
    });
    assert_eq!(n, 2, "one allocation and one free");
}

#[test]
fn step_and_apply_allocate_nothing_on_the_ict_rig() {
    let rig = mimic_assets::load_rig(&repo().join("configs/rigs/ict-face.toml")).unwrap();
    let layout = mimic_assets::load_layout(&repo().join("configs/layouts/kinect121.toml")).unwrap();
    let basis = Arc::new(build_basis(&rig, &rig.solver).unwrap());
    let mut settings = RetargetSettings {
        normals: true,
        positions: true,
        ..RetargetSettings::default()
    };
    // The mouth and chin repair on, with bounds low enough that it repairs frames here.
    settings.gate.max_mouth_residual = 0.02;
    settings.gate.max_chin_residual = 0.02;
    let mut rt = Retargeter::new(&rig, &layout, basis.clone(), settings).unwrap();
    let mut out = rt.new_output();
    let frames = frames(layout.point_count);
    assert!(frames.len() > 40, "{} frames", frames.len());
    // Every path of `step`: tracked frames, a lost one, a wrong point count (rejected).
    let mut lost = frames[20].clone();
    lost.tracked = false;
    let mut short = frames[21].clone();
    short.points.pop();
    short.valid.pop();
    let (warm, measured) = frames.split_at(10);
    for f in warm {
        rt.step(f, &mut out);
    }
    let mut tracked = 0;
    let n = allocations_during(|| {
        for f in measured.iter().chain([&lost, &short]).chain(measured) {
            if rt.step(f, &mut out) == FrameStatus::Tracked {
                tracked += 1;
            }
        }
    });
    assert!(tracked > measured.len(), "{tracked} tracked frames");
    assert!(rt.stats().repaired > 10, "{:?}", rt.stats());
    assert!(out.normals.iter().all(|v| v.is_finite()));
    assert_eq!(n, 0, "{n} allocations in {} steps", 2 * measured.len() + 2);

    let d: Vec<Vec3> = (0..basis.control_count())
        .map(|j| Vec3::new(0.01 * j as f32, -0.02, 0.005))
        .collect();
    let mut u = vec![Vec3::ZERO; basis.vertex_count()];
    basis.apply(&d, &mut u);
    let n = allocations_during(|| {
        for _ in 0..20 {
            basis.apply(std::hint::black_box(&d), &mut u);
        }
    });
    assert!(u.iter().any(|v| *v != Vec3::ZERO));
    assert_eq!(n, 0, "{n} allocations in 20 Basis::apply calls");
}

#[test]
fn gaze_step_allocates_nothing_on_a_real_take() {
    use mimic_retarget::gaze::{GazePoints, GazeSettings, GazeTracker};
    let layout =
        mimic_assets::load_layout(&repo().join("configs/layouts/mediapipe478.toml")).unwrap();
    let path = repo().join("recordings/megamind_mediapipe.jsonl");
    let reader = mimic_capture::RecordingReader::open(&path, Some(layout.point_count)).unwrap();
    let frames: Vec<LandmarkFrame> = reader
        .read_all()
        .frames
        .into_iter()
        .map(|f| f.frame)
        .filter(|f| f.tracked)
        .collect();
    assert!(frames.len() > 100, "{} frames", frames.len());
    let mut t = GazeTracker::new(GazePoints::of(&layout).unwrap(), GazeSettings::default());
    t.set_neutral(&frames[0].points, &frames[0].valid);
    // A small head turn for `back` (the step's cost does not depend on it).
    let back = glam::Affine3A::from_rotation_y(0.1);
    let (warm, measured) = frames.split_at(5);
    for f in warm {
        t.step(f, &back, 0.04);
    }
    let mut lost = measured[0].clone();
    lost.tracked = false;
    let mut read = 0;
    let n = allocations_during(|| {
        for f in measured.iter().chain([&lost]) {
            t.step(f, &back, 0.04);
            read += usize::from(t.trusted()[0]);
        }
        t.hold(0.5);
        t.reset();
    });
    assert!(read > measured.len() / 2, "{read} frames read");
    assert_eq!(n, 0, "{n} allocations in {} gaze steps", measured.len() + 1);
}

#[test]
fn provisional_and_easing_steps_allocate_nothing() {
    // MediaPipe frames against the layout's canonical neutral while the neutral is calibrated
    // (30 frames here), then the ease into the calibrated output: only the first frame (which
    // scales the canonical face) and the one that fixes the neutral may allocate.
    let rig = mimic_assets::load_rig(&repo().join("configs/rigs/ict-face.toml")).unwrap();
    let layout =
        mimic_assets::load_layout(&repo().join("configs/layouts/mediapipe478.toml")).unwrap();
    let basis = Arc::new(build_basis(&rig, &rig.solver).unwrap());
    let settings = RetargetSettings {
        neutral: mimic_retarget::Neutral::FirstFrames(30),
        ..RetargetSettings::default()
    };
    let mut rt = Retargeter::new(&rig, &layout, basis, settings).unwrap();
    let mut out = rt.new_output();
    let path = repo().join("recordings/megamind_mediapipe.jsonl");
    let reader = mimic_capture::RecordingReader::open(&path, Some(layout.point_count)).unwrap();
    let frames: Vec<LandmarkFrame> = reader
        .read_all()
        .frames
        .into_iter()
        .map(|f| f.frame)
        .filter(|f| f.tracked)
        .collect();
    rt.step(&frames[0], &mut out);
    let n = allocations_during(|| {
        for f in &frames[1..29] {
            rt.step(f, &mut out);
        }
    });
    assert_eq!(rt.stats().provisional, 29);
    assert_eq!(n, 0, "{n} allocations in 28 provisional steps");
    rt.step(&frames[29], &mut out);
    assert!(rt.source_to_target().is_some(), "the neutral is fixed");
    let n = allocations_during(|| {
        for f in &frames[30..50] {
            rt.step(f, &mut out);
        }
    });
    assert_eq!(rt.stats().provisional, 30);
    assert!(out.normals.iter().all(|v| v.is_finite()));
    assert_eq!(
        n, 0,
        "{n} allocations in 20 steps easing into the calibrated output"
    );
}

#[test]
fn blendshape_fit_with_every_term_allocates_nothing() {
    use mimic_retarget::{BlendshapeFit, BlendshapeFitter, BlendshapeSettings};
    // ICT's whole expression set on the ICT rig (its symmetric pairs give the symmetry term work).
    let rig = mimic_assets::load_rig(&repo().join("configs/rigs/ict-face.toml")).unwrap();
    let pack = mimic_assets::load_shape_pack(
        &repo().join("configs/meshes/ict-facekit/expressions.shapes"),
    )
    .unwrap();
    let n = rig.mesh.vertex_count();
    let targets: Vec<mimic_types::MorphTarget> = pack
        .shapes
        .iter()
        .map(|s| mimic_types::MorphTarget {
            name: s.name.clone(),
            position_deltas: s.deltas.clone(),
            normal_deltas: vec![Vec3::ZERO; n],
        })
        .collect();
    let fit = BlendshapeFit {
        ridge: 0.02,
        l1: 0.01,
        temporal: 0.5,
        symmetry: 0.3,
    };
    let mut f = BlendshapeFitter::new(&rig, &targets, &BlendshapeSettings::with_fit(&fit)).unwrap();
    assert!(f.mirror_pairs().len() >= 10, "{:?}", f.mirror_pairs());
    // Control displacements of a few targets at varying weights.
    let d_of = |i: usize| -> Vec<Vec3> {
        rig.controls
            .iter()
            .map(|c| {
                let v = c.vertex as usize;
                targets[i % 7].position_deltas[v] * 0.7
                    + targets[(i + 3) % 11].position_deltas[v] * 0.3
            })
            .collect()
    };
    let ds: Vec<Vec<Vec3>> = (0..20).map(d_of).collect();
    f.fit(&ds[0], 0);
    let mut moved = 0.0f32;
    let n = allocations_during(|| {
        for (i, d) in ds.iter().enumerate() {
            moved += f.fit(d, 33_333 * (i as i64 + 1)).iter().sum::<f32>();
        }
    });
    assert!(moved > 0.0);
    assert_eq!(n, 0, "{n} allocations in 20 fits");
}
