//! `cargo test -p mimic_retarget --test shipped -- --nocapture` prints the per-recording figures
//! that `docs/gate.md` quotes.
#![allow(
    clippy::unwrap_used,
    reason = "a test: a failed unwrap is the failure report"
)]

use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

use glam::Vec3;
use mimic_retarget::{FrameStatus, GateReason, RetargetSettings, Retargeter, face_size};
use mimic_solve::{Basis, build_basis};
use mimic_types::{LandmarkFrame, Layout, Rig, SolverKind};

/// A frame-to-frame control jump larger than this (cm on the ICT head) counts as a jump.
const JUMP_CM: f32 = 1.0;
/// On frames 99-109 of the fit failure, every vertex stays this close (cm on the ICT head) to rest.
const FAILURE_CM: f32 = 2.0;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Shipped recordings, sorted.
fn recordings() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(root().join("recordings"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "jsonl"))
        .collect();
    v.sort();
    assert!(v.len() >= 7, "{v:?}");
    v
}

fn layout(name: &str) -> Layout {
    mimic_assets::load_layout(&root().join(format!("configs/layouts/{name}.toml"))).unwrap()
}

/// A shipped recording, opened once: the layout its header names and every frame (none may be
/// rejected).
fn recording(path: &Path) -> (Layout, Vec<LandmarkFrame>) {
    let mut reader = mimic_capture::RecordingReader::open(path, None).unwrap();
    let layout = layout(&reader.header().layout);
    reader.expect_points(layout.point_count).unwrap();
    let read = reader.read_all();
    assert_eq!(read.stats.rejected.total(), 0, "{}", path.display());
    (layout, read.frames.into_iter().map(|f| f.frame).collect())
}

/// A rig with its bases for both solvers, built once.
struct RigBases {
    rig: Rig,
    rbf: Arc<Basis>,
    laplacian: Arc<Basis>,
}

fn rig(name: &str) -> &'static RigBases {
    static ICT: OnceLock<RigBases> = OnceLock::new();
    static CANDIDE: OnceLock<RigBases> = OnceLock::new();
    let cell = if name == "ict-face" { &ICT } else { &CANDIDE };
    cell.get_or_init(|| {
        let rig =
            mimic_assets::load_rig(&root().join(format!("configs/rigs/{name}.toml"))).unwrap();
        let mut s = rig.solver;
        s.kind = SolverKind::Rbf;
        let rbf = Arc::new(build_basis(&rig, &s).unwrap());
        s.kind = SolverKind::Laplacian;
        let laplacian = Arc::new(build_basis(&rig, &s).unwrap());
        RigBases {
            rig,
            rbf,
            laplacian,
        }
    })
}

/// What one replay did, measured on the output.
#[derive(Debug, Default)]
struct Replayed {
    tracked: u64,
    gated: u64,
    clamped: u64,
    /// Indices of the frames the gate held, and why.
    gated_frames: Vec<(usize, GateReason)>,
    jumps_counted: u64,
    /// Tracked frames whose largest control jump exceeds the 1 cm-equivalent.
    jump_frames: u64,
    /// Largest control jump, in ICT cm.
    max_jump_cm: f32,
    /// Largest vertex distance from rest on frames 99-109, in ICT cm.
    max_vertex_99_109_cm: f32,
}

/// Replays `frames` onto `rig` with `settings`; lengths converted to ICT cm by the rig's face size.
fn replay(
    frames: &[LandmarkFrame],
    layout: &Layout,
    rb: &RigBases,
    laplacian: bool,
    settings: RetargetSettings,
) -> Replayed {
    let basis = if laplacian { &rb.laplacian } else { &rb.rbf };
    let mut rt = Retargeter::new(&rb.rig, layout, basis.clone(), settings).unwrap();
    let mut out = rt.new_output();
    let to_cm = ict_face_size() / rig_face_size(&rb.rig);
    let rest = rb.rig.mesh.positions.clone();
    let mut prev: Option<Vec<Vec3>> = None;
    let mut r = Replayed::default();
    for (k, f) in frames.iter().enumerate() {
        let status = rt.step(f, &mut out);
        let held = rt.stats().gated > r.gated_frames.len() as u64;
        if let (true, Some(why)) = (held, rt.gate_reading().reason) {
            r.gated_frames.push((k, why));
        }
        if let (FrameStatus::Tracked, Some(p)) = (status, &prev) {
            let jump = p
                .iter()
                .zip(&out.displacements)
                .map(|(a, b)| a.distance(*b))
                .fold(0.0, f32::max)
                * to_cm;
            r.max_jump_cm = r.max_jump_cm.max(jump);
            if jump > JUMP_CM {
                r.jump_frames += 1;
            }
        }
        if (99..=109).contains(&k) {
            let v = out
                .positions
                .iter()
                .zip(&rest)
                .map(|(p, q)| p.distance(*q))
                .fold(0.0, f32::max)
                * to_cm;
            r.max_vertex_99_109_cm = r.max_vertex_99_109_cm.max(v);
        }
        prev = Some(out.displacements.clone());
    }
    let s = rt.stats();
    r.tracked = s.tracked;
    r.gated = s.gated;
    r.clamped = s.clamped;
    r.jumps_counted = s.jumps;
    r
}

fn rig_face_size(rig: &Rig) -> f32 {
    let fdps: Vec<_> = rig.controls.iter().map(|c| c.fdp).collect();
    face_size(&fdps, &rig.control_positions()).unwrap()
}

fn ict_face_size() -> f32 {
    rig_face_size(&rig("ict-face").rig)
}

fn ungated() -> RetargetSettings {
    let mut s = RetargetSettings::default();
    s.gate.enabled = false;
    s
}

#[test]
fn gate_keeps_jumps_and_fit_failures_out_on_every_shipped_recording() {
    let mut failures = Vec::new();
    println!(
        "recording rig solver: tracked gated clamped | jump frames, max jump cm | max vertex 99-109 cm (ungated -> gated)"
    );
    for path in recordings() {
        let (layout, frames) = recording(&path);
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let failure = name == "a_yn_question.kinect121.jsonl";
        for rig_name in ["ict-face", "candide3"] {
            let rb = rig(rig_name);
            for laplacian in [false, true] {
                let solver = if laplacian { "laplacian" } else { "rbf" };
                let before = replay(&frames, &layout, rb, laplacian, ungated());
                let after = replay(&frames, &layout, rb, laplacian, RetargetSettings::default());
                println!(
                    "{name} {rig_name} {solver}: {} {} {} | {} -> {}, {:.2} -> {:.2} | {:.2} -> {:.2}",
                    after.tracked,
                    after.gated,
                    after.clamped,
                    before.jump_frames,
                    after.jump_frames,
                    before.max_jump_cm,
                    after.max_jump_cm,
                    before.max_vertex_99_109_cm,
                    after.max_vertex_99_109_cm,
                );
                if !after.gated_frames.is_empty() {
                    println!("  held: {:?}", after.gated_frames);
                }
                let what = format!("{name} on {rig_name} ({solver})");
                // The library's own count of jumps is the one measured here.
                for r in [&before, &after] {
                    if r.jumps_counted != r.jump_frames {
                        failures.push(format!(
                            "{what}: Stats::jumps {} but {} frames jump",
                            r.jumps_counted, r.jump_frames
                        ));
                    }
                }
                if after.jump_frames * 100 > after.tracked {
                    failures.push(format!(
                        "{what}: {} of {} tracked frames jump more than {JUMP_CM} cm",
                        after.jump_frames, after.tracked
                    ));
                }
                if failure && after.max_vertex_99_109_cm > FAILURE_CM {
                    failures.push(format!(
                        "{what}: a vertex moves {:.2} cm on frames 99-109",
                        after.max_vertex_99_109_cm
                    ));
                }
                if after.tracked * 10 < (frames.len() as u64) * 9 {
                    failures.push(format!("{what}: only {} tracked", after.tracked));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Per-frame readings for choosing the gate's bounds (`-- --ignored --nocapture`): with the gate
/// off, each tracked frame's largest |d| per FDP group (IOD), head rotation from the neutral and
/// its speed, and the fastest output control (IOD/s).
#[test]
#[ignore]
fn dump_gate_readings() {
    let rb = rig("ict-face");
    let face = ict_face_size();
    for path in recordings() {
        let (layout, frames) = recording(&path);
        let s = ungated();
        let mut rt = Retargeter::new(&rb.rig, &layout, rb.rbf.clone(), s).unwrap();
        let mut out = rt.new_output();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let mut previous: Option<(i64, Vec<Vec3>)> = None;
        for (k, f) in frames.iter().enumerate() {
            if rt.step(f, &mut out) != FrameStatus::Tracked {
                continue;
            }
            let g = rt.gate_reading();
            let speed = previous.as_ref().map_or(0.0, |(t, d)| {
                let step = d
                    .iter()
                    .zip(&out.displacements)
                    .map(|(a, b)| a.distance(*b))
                    .fold(0.0, f32::max);
                step / face / ((f.timestamp_us - t) as f32 * 1e-6)
            });
            previous = Some((f.timestamp_us, out.displacements.clone()));
            let mut by_group = [0f32; 12];
            for (c, d) in rb.rig.controls.iter().zip(&out.displacements) {
                let slot = &mut by_group[c.fdp.as_fdp().map_or(0, |f| f.group) as usize];
                *slot = slot.max(d.length() / face);
            }
            println!(
                "R {name} {k} jaw {:.3} eye {:.3} brow {:.3} cheek {:.3} lip {:.3} nose {:.3} rot {:.1} rotv {:.0} ctlv {:.2} gated {:?}",
                by_group[2],
                by_group[3],
                by_group[4],
                by_group[5],
                by_group[8],
                by_group[9],
                g.rotation_deg,
                g.turn_deg / g.since_accepted_s,
                speed,
                g.reason
            );
        }
    }
}

/// A real recording with 30 frames in a row lost, in each documented form (`"points":[]` as
/// `mimic import openface` writes failed frames, and a full point list with `"tracked":false`):
/// the reader accepts them, the retargeter counts 30 lost, holds the last expression for
/// `lost_hold_secs`, eases it to neutral over `lost_ease_secs`, and tracks again after.
#[test]
fn thirty_lost_frames_are_held_then_eased_in_every_documented_form() {
    let path = root().join("recordings/a_affirmative.kinect121.jsonl");
    let text = std::fs::read_to_string(&path).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let (first, count) = (300usize, 30usize);
    for empty in [true, false] {
        let mut edited = String::new();
        for (k, line) in lines.iter().enumerate() {
            // Line 0 is the header; frame k is line k + 1.
            let frame = k.wrapping_sub(1);
            if k > 0 && (first..first + count).contains(&frame) {
                let v: serde_json::Value = serde_json::from_str(line).unwrap();
                let lost = if empty {
                    serde_json::json!({"t_us": v["t_us"], "points": [], "tracked": false})
                } else {
                    serde_json::json!({"t_us": v["t_us"], "points": v["points"], "invalid": v["invalid"], "tracked": false})
                };
                edited.push_str(&lost.to_string());
            } else {
                edited.push_str(line);
            }
            edited.push('\n');
        }
        let layout = layout("kinect121");
        let mut reader = mimic_capture::RecordingReader::new(
            std::io::Cursor::new(edited.into_bytes()),
            "edited.jsonl",
            Some(layout.point_count),
        )
        .unwrap();
        let mut frames = Vec::new();
        while let Some(f) = reader.next_frame() {
            frames.push(f.unwrap().frame);
        }
        assert_eq!(reader.stats().lost_tracking, count);
        assert_eq!(reader.stats().rejected.total(), 0);
        assert_eq!(frames.len(), lines.len() - 1);
        assert_eq!(frames[first].points.is_empty(), empty);

        let rb = rig("ict-face");
        let settings = RetargetSettings::default();
        let (hold, ease) = (settings.lost_hold_secs, settings.lost_ease_secs);
        let mut rt = Retargeter::new(&rb.rig, &layout, rb.rbf.clone(), settings).unwrap();
        let mut out = rt.new_output();
        let mut held = Vec::new();
        let mut last_k = 1.0f32;
        for (k, f) in frames.iter().enumerate() {
            let status = rt.step(f, &mut out);
            if k == first - 1 {
                assert_eq!(status, FrameStatus::Tracked);
                assert_eq!(
                    rt.gate_reading().reason,
                    None,
                    "frame before the gap is gated"
                );
                // The controls' entries (the rigid parts' after them follow from these).
                held = out.displacements[..rb.rig.controls.len()].to_vec();
            }
            if (first..first + count).contains(&k) {
                assert_eq!(status, FrameStatus::Lost, "frame {k}");
                // The control that moved most before the gap tells the easing factor.
                let (j, dj) = held
                    .iter()
                    .enumerate()
                    .max_by(|a, b| a.1.length().total_cmp(&b.1.length()))
                    .unwrap();
                assert!(dj.length() > 1e-3, "nothing to hold");
                let factor = out.displacements[j].dot(*dj) / dj.length_squared();
                for (o, h) in out.displacements.iter().zip(&held) {
                    assert!(
                        (*o - *h * factor).length() < 1e-4,
                        "frame {k}: not a scaled hold"
                    );
                }
                let t = (f.timestamp_us - frames[first].timestamp_us) as f32 * 1e-6;
                if t <= hold {
                    assert!(
                        (factor - 1.0).abs() < 1e-5,
                        "frame {k} (t {t}): factor {factor}"
                    );
                } else if t >= hold + ease {
                    assert!(factor.abs() < 1e-5, "frame {k} (t {t}): factor {factor}");
                } else {
                    assert!(factor < 1.0 && factor > 0.0, "frame {k} (t {t}): {factor}");
                }
                assert!(factor <= last_k + 1e-6, "frame {k}: easing went back up");
                last_k = factor;
            }
            if k == first + count {
                assert_eq!(status, FrameStatus::Tracked, "tracking resumes");
            }
        }
        assert!(
            last_k.abs() < 1e-6,
            "30 frames at 15 Hz outlast hold + ease"
        );
        let s = rt.stats();
        assert_eq!(s.lost, count as u64);
        assert_eq!(s.rejected, 0);
        assert_eq!(s.tracked + s.calibrating + s.lost, frames.len() as u64);
    }
}
