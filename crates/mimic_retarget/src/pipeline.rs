//! The retargeter: setup once, then one allocation-free `step` per frame.

use crate::gate::{GateReading, face_size};
use crate::patch::MovingPatch;

mod hold;
mod neutral;
mod output;
mod parts;
mod pose;
mod stats;
use crate::gaze::{GazePoints, GazeSettings, GazeTracker};
use crate::{Neutral, OneEuro, OneEuroStep, RetargetSettings, SourceToTarget};
use glam::{Quat, Vec3};
use mimic_solve::VectorKernel;
use mimic_solve::{Basis, vertex_normals};
use mimic_types::layout::mean_of_valid;
use mimic_types::{ControlName, Fdp, HeadPose, LandmarkFrame, Layout, Rig};
pub(crate) use neutral::Accumulator;
use std::sync::Arc;
use std::time::Instant;

/// Why a retargeter cannot be set up.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RetargetError {
    /// The rig drives a control the layout does not define (an FDP it does not map, or a
    /// point control of another layout).
    #[error("rig control {fdp} has no counterpart in layout `{layout}`")]
    MissingControl {
        /// Control of the rig.
        fdp: ControlName,
        /// Layout name.
        layout: String,
    },
    /// The basis was built for another mesh or control set.
    #[error(
        "basis is {rows} x {cols}, but the rig has {vertices} vertices and {controls} columns (controls and rigid parts)"
    )]
    BasisShape {
        /// Basis rows.
        rows: usize,
        /// Basis columns.
        cols: usize,
        /// Rig vertices.
        vertices: usize,
        /// Rig controls plus four per rigid part.
        controls: usize,
    },
    /// A given neutral frame does not fit the layout or lacks controls.
    #[error("neutral frame: {0}")]
    BadNeutral(String),
}

pub use mimic_types::FrameStatus;
pub use output::FrameOutput;
pub use stats::{Stage, StageTimes, Stats};

/// Ties a layout to a rig and turns landmark frames into deformed meshes.
#[derive(Debug)]
pub struct Retargeter {
    pub(crate) layout: Layout,
    pub(crate) settings: RetargetSettings,
    pub(crate) basis: Arc<Basis>,
    pub(crate) patch: MovingPatch,
    pub(crate) rest: Vec<Vec3>,
    pub(crate) triangles: Vec<[u32; 3]>,
    pub(crate) target_controls: Vec<Vec3>,
    /// Layout points of each rig control (its position is their mean): an FDP's points, or a
    /// point control's one point.
    pub(crate) source_points: Vec<Vec<usize>>,
    // Neutral, once known.
    pub(crate) neutral_points: Vec<Vec3>,
    pub(crate) neutral_valid: Vec<bool>,
    pub(crate) neutral_controls: Vec<Vec3>,
    /// Target-space displacements longer than this (target units) are outliers.
    pub(crate) outlier_limit: f32,
    /// Inter-ocular distance of the target's controls (target units): the gate's length unit.
    pub(crate) face_size: f32,
    /// `1 / bound^2` of each control's gate bound on its displacement (bound in target units;
    /// infinite for a zero bound), so the gate compares squared lengths with a multiply.
    pub(crate) gate_inverse_bounds2: Vec<f32>,
    pub(crate) to_target: Option<SourceToTarget>,
    pub(crate) accumulator: Option<Accumulator>,
    /// The layout's canonical neutral, used until the performer's is calibrated.
    pub(crate) canonical: Option<neutral::CanonicalNeutral>,
    // Per-frame state.
    pub(crate) filters: Vec<[OneEuro; 3]>,
    pub(crate) last_e: Vec<Vec3>,
    pub(crate) frame_delta: Vec<Vec3>,
    pub(crate) last_d: Vec<Vec3>,
    pub(crate) last_pose: HeadPose,
    pub(crate) last_time_us: Option<i64>,
    pub(crate) lost_since_us: Option<i64>,
    // Gate state: the last frame it accepted (head rotation, time) and the hold clock.
    pub(crate) accepted_rotation: Quat,
    pub(crate) accepted_time_us: Option<i64>,
    pub(crate) gated_since_us: Option<i64>,
    pub(crate) gate_reading: GateReading,
    /// Output `d` and time of the previous frame, for the speed clamp and [`Stats::jumps`].
    pub(crate) previous_out: Vec<Vec3>,
    pub(crate) previous_time_us: Option<i64>,
    /// The last intervals between frames (seconds, a ring; 0: not yet seen), whose median is the
    /// speed clamp's frame time, so that jittery timestamps (the GFE stamps fall on a 15.6 ms
    /// timer grid) and gaps (dropped frames) do not open it.
    pub(crate) intervals: [f32; INTERVALS],
    pub(crate) next_interval: usize,
    pub(crate) raw_d: Vec<Vec3>,
    pub(crate) raw_e: Vec<Vec3>,
    // Scratch.
    pub(crate) stable_src: Vec<Vec3>,
    pub(crate) stable_dst: Vec<Vec3>,
    pub(crate) stable_residual: Vec<f32>,
    pub(crate) stable_sorted: Vec<f32>,
    pub(crate) controls_now: Vec<Option<Vec3>>,
    pub(crate) stats: Stats,
    /// The rigid parts' columns of `d` (jaw, eyeballs), after the controls'.
    pub(crate) parts: parts::PartMotion,
    /// The gaze the eyeballs are turned by (left, right), once one is read.
    pub(crate) eye_turn: Option<[crate::gaze::EyeGaze; 2]>,
    /// The gaze, for a layout with pupils (`[gaze]`).
    pub(crate) gaze: Option<GazeTracker>,
    /// The mouth from another source (speech), mixed into `d` before the deform.
    pub(crate) mouth: Option<crate::mouth::MouthDrive>,
    /// The mouth and chin repair (`GateSettings::max_mouth_residual`), when on and the rig has
    /// the feature points for it.
    pub(crate) repair: Option<crate::repair::MouthRepair>,
    /// What the repair measured on the last accepted frame.
    pub(crate) repair_reading: crate::RepairReading,
}

impl Retargeter {
    /// Sets up the pipeline for `layout` frames driving `rig` through `basis` (built for `rig`;
    /// pass an `Arc<Basis>` to share one basis between many retargeters).
    pub fn new(
        rig: &Rig,
        layout: &Layout,
        basis: impl Into<Arc<Basis>>,
        settings: RetargetSettings,
    ) -> Result<Self, RetargetError> {
        let basis: Arc<Basis> = basis.into();
        let n = rig.mesh.vertex_count();
        let m = rig.controls.len();
        let fdps: Vec<Option<Fdp>> = rig.controls.iter().map(|c| layout.fdp_of(c.fdp)).collect();
        let part_motion = parts::PartMotion::new(rig, &fdps);
        let columns = m + rig.parts.column_count();
        if basis.vertex_count() != n || basis.control_count() != columns {
            return Err(RetargetError::BasisShape {
                rows: basis.vertex_count(),
                cols: basis.control_count(),
                vertices: n,
                controls: columns,
            });
        }
        let source_points = rig
            .controls
            .iter()
            .map(|c| {
                layout.control_points(c.fdp).map(<[usize]>::to_vec).ok_or(
                    RetargetError::MissingControl {
                        fdp: c.fdp,
                        layout: layout.name.clone(),
                    },
                )
            })
            .collect::<Result<Vec<_>, _>>()?;
        let p = layout.point_count;
        // `fdps`: the FDP each control stands for (a point control: the FDP that is that point
        // alone in the layout, e.g. kinect121:20 is 3.7), for the face size, the gate's bounds
        // and the jaw.
        let target_controls = rig.control_positions();
        // A rig too degenerate to measure has no face size: the gate then never holds a frame.
        let face = face_size(&fdps, &target_controls).unwrap_or(f32::INFINITY);
        let gate_inverse_bounds2 = fdps
            .iter()
            .zip(&rig.controls)
            .map(|(f, c)| (settings.gate.bound_of(*f, c.region) * face).powi(-2))
            .collect();
        let repair = crate::repair::MouthRepair::of_rig(&settings.gate, &fdps, rig, face);
        let mut r = Retargeter {
            layout: layout.clone(),
            patch: if settings.positions {
                MovingPatch::new(&basis, &rig.mesh.triangles, &rig.mesh.positions).with_kernels(
                    settings
                        .deform_kernel
                        .unwrap_or_else(VectorKernel::best_for_deform),
                    settings
                        .normals_kernel
                        .unwrap_or_else(VectorKernel::best_for_normals),
                )
            } else {
                // No positions: an empty patch, so no per-retargeter copy of the moving rows.
                let empty = Basis::from_row_major(0, basis.control_count(), Vec::new())
                    .unwrap_or_else(|| unreachable!("0 x m from no values"));
                MovingPatch::new(&empty, &[], &[])
            },
            basis,
            rest: rig.mesh.positions.clone(),
            triangles: rig.mesh.triangles.clone(),
            target_controls,
            source_points,
            neutral_points: vec![Vec3::ZERO; p],
            neutral_valid: vec![false; p],
            neutral_controls: vec![Vec3::ZERO; m],
            outlier_limit: f32::INFINITY,
            face_size: face,
            gate_inverse_bounds2,
            to_target: None,
            accumulator: None,
            canonical: None,
            filters: vec![[OneEuro::default(); 3]; m],
            last_e: vec![Vec3::ZERO; m],
            frame_delta: vec![Vec3::ZERO; m],
            last_d: vec![Vec3::ZERO; m],
            last_pose: HeadPose::IDENTITY,
            last_time_us: None,
            lost_since_us: None,
            accepted_rotation: Quat::IDENTITY,
            accepted_time_us: None,
            gated_since_us: None,
            gate_reading: GateReading::default(),
            previous_out: vec![Vec3::ZERO; m],
            previous_time_us: None,
            intervals: [0.0; INTERVALS],
            next_interval: 0,
            raw_d: vec![Vec3::ZERO; m],
            raw_e: vec![Vec3::ZERO; m],
            stable_src: Vec::with_capacity(layout.stable.len()),
            stable_dst: Vec::with_capacity(layout.stable.len()),
            stable_residual: Vec::with_capacity(layout.stable.len()),
            stable_sorted: Vec::with_capacity(layout.stable.len()),
            controls_now: vec![None; m],
            stats: Stats::default(),
            // Read whenever the layout has pupils: it turns the rig's eyeballs if it has some,
            // and gives the ARKit `eyeLook*` weights (blend-shape mode, forwarding) either way.
            gaze: GazePoints::of(layout).map(|p| GazeTracker::new(p, GazeSettings::default())),
            parts: part_motion,
            eye_turn: None,
            mouth: None,
            repair,
            repair_reading: crate::RepairReading::default(),
            settings: settings.clone(),
        };
        match settings.neutral {
            Neutral::FirstFrames(k) => {
                r.accumulator = Some(Accumulator {
                    wanted: k.max(1),
                    frames: 0,
                    first: vec![Vec3::ZERO; p],
                    first_valid: vec![false; p],
                    sum: vec![Vec3::ZERO; p],
                    count: vec![0; p],
                });
                if settings.provisional == crate::Provisional::Canonical {
                    r.canonical = neutral::CanonicalNeutral::new(
                        layout,
                        &r.source_points,
                        &r.target_controls,
                        settings.allow_mirror,
                        settings.per_axis_scale,
                    );
                }
            }
            Neutral::Frame(f) => {
                if f.points.len() != p {
                    return Err(RetargetError::BadNeutral(format!(
                        "{} points, layout `{}` has {p}",
                        f.points.len(),
                        layout.name
                    )));
                }
                for i in 0..p {
                    r.neutral_valid[i] = f.is_valid(i);
                    r.neutral_points[i] = if f.is_valid(i) {
                        f.points[i]
                    } else {
                        Vec3::ZERO
                    };
                }
                if !r.finish_neutral() {
                    return Err(RetargetError::BadNeutral(
                        "some control or too many stable points have no valid point".into(),
                    ));
                }
            }
        }
        Ok(r)
    }

    /// An output buffer sized for this rig.
    pub fn new_output(&self) -> FrameOutput {
        let n = self.rest.len();
        FrameOutput {
            timestamp_us: 0,
            status: FrameStatus::Calibrating,
            positions: self.rest.clone(),
            normals: if self.settings.normals {
                let mut normals = vec![Vec3::ZERO; n];
                vertex_normals(&self.rest, &self.triangles, &mut normals);
                normals
            } else {
                Vec::new()
            },
            displacements: vec![Vec3::ZERO; self.basis.control_count()],
            pose: HeadPose::IDENTITY,
            target_rotation: Quat::IDENTITY,
            filled: 0,
            times: StageTimes::default(),
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> Stats {
        self.stats
    }

    /// The fitted source-to-target map, once the neutral is known (not the canonical neutral's).
    pub fn source_to_target(&self) -> Option<&SourceToTarget> {
        self.to_target
            .as_ref()
            .filter(|_| self.accumulator.is_none())
    }

    /// The calibrated neutral's control positions (source space, the performer's units), once
    /// the neutral is known (not the canonical neutral's).
    pub fn neutral_controls(&self) -> Option<&[Vec3]> {
        self.source_to_target().map(|_| &self.neutral_controls[..])
    }

    /// The rig's control positions at rest (target units).
    pub fn target_controls(&self) -> &[Vec3] {
        &self.target_controls
    }

    /// The basis in use.
    pub fn basis(&self) -> &Basis {
        &self.basis
    }

    /// Rest positions of the rig.
    pub fn rest_positions(&self) -> &[Vec3] {
        &self.rest
    }

    /// Triangles of the rig.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// Frame-to-frame displacement of the last tracked frame, stabilised, in source space
    /// (the source method's `stab(s_t) - stab(s_{t-1})`).
    pub fn frame_delta(&self) -> &[Vec3] {
        &self.frame_delta
    }

    /// Neutral-relative displacement of the last tracked frame, stabilised, in source space
    /// (unfiltered, unscaled).
    pub fn source_displacement(&self) -> &[Vec3] {
        &self.last_e
    }

    /// Processes one frame into `out` (from [`Retargeter::new_output`]); allocates nothing.
    ///
    /// A lost frame (`tracked: false`, with any point count, none included) holds the last
    /// expression and eases it to neutral. A tracked frame the plausibility gate refuses is held
    /// the same way and counted in [`Stats::gated`]; control speeds are clamped (`docs/gate.md`).
    pub fn step(&mut self, frame: &LandmarkFrame, out: &mut FrameOutput) -> FrameStatus {
        let status = self.step_frame(frame, out);
        if status != FrameStatus::Rejected {
            // Compared squared: no square root per control.
            let limit2 = (self.settings.gate.jump_report * self.face_size).powi(2);
            let jump = out
                .displacements
                .iter()
                .zip(&self.previous_out)
                .any(|(d, p)| d.distance_squared(*p) > limit2);
            if status == FrameStatus::Tracked && jump {
                self.stats.jumps += 1;
            }
            for (p, d) in self.previous_out.iter_mut().zip(&out.displacements) {
                *p = *d;
            }
            if let Some(t) = self.previous_time_us {
                let dt = frame.timestamp_us.saturating_sub(t) as f32 * 1e-6;
                if dt > 0.0 && dt <= 1.0 {
                    self.intervals[self.next_interval] = dt;
                    self.next_interval = (self.next_interval + 1) % INTERVALS;
                }
            }
            self.previous_time_us = Some(frame.timestamp_us);
        }
        status
    }

    /// What the mouth and chin repair measured on the last accepted frame (docs/gate.md, "Tears").
    pub fn repair_reading(&self) -> crate::RepairReading {
        self.repair_reading
    }

    /// What the plausibility gate measured on the last tracked frame, and whether it held it.
    pub fn gate_reading(&self) -> GateReading {
        self.gate_reading
    }

    /// The target's inter-ocular distance (target units): the gate's unit of length (infinite,
    /// which turns the gate's bounds off, for a rig too degenerate to measure).
    pub fn face_size(&self) -> f32 {
        self.face_size
    }

    fn step_frame(&mut self, frame: &LandmarkFrame, out: &mut FrameOutput) -> FrameStatus {
        self.stats.frames += 1;
        out.timestamp_us = frame.timestamp_us;
        out.filled = 0;
        out.times = StageTimes::default();
        // A lost frame needs no points: the documented forms are `points: []` (OpenFace
        // imports, UDP P = 0) and a full point list with `tracked: false`; both are held.
        if !frame.tracked {
            return self.lost(frame.timestamp_us, out);
        }
        if frame.points.len() != self.layout.point_count {
            self.stats.rejected += 1;
            out.status = FrameStatus::Rejected;
            return out.status;
        }
        if self.accumulator.is_some() {
            return self.calibrate(frame, out);
        }
        self.track(frame, out)
    }

    /// A tracked frame against the neutral in use: pose, displacements, gate, filter, deform.
    fn track(&mut self, frame: &LandmarkFrame, out: &mut FrameOutput) -> FrameStatus {
        let t0 = Instant::now();
        for (j, slot) in self.controls_now.iter_mut().enumerate() {
            *slot = mean_of_valid(&self.source_points[j], frame);
        }
        let t1 = Instant::now();
        pose::gather_stable(
            &self.layout.stable,
            frame,
            (&self.neutral_points, &self.neutral_valid),
            (&mut self.stable_src, &mut self.stable_dst),
        );
        let Some(pose) = self.robust_pose() else {
            return self.lost(frame.timestamp_us, out);
        };
        let t2 = Instant::now();
        let Some(to_target) = self.to_target else {
            return self.lost(frame.timestamp_us, out);
        };
        let dt = self
            .last_time_us
            .map(|t| frame.timestamp_us.saturating_sub(t) as f32 * 1e-6)
            .unwrap_or(0.0);
        let mut filled = 0u32;
        let back = pose.inverse_affine();
        // Lengths compared squared: no square root per control.
        let outlier2 = self.outlier_limit * self.outlier_limit;
        for j in 0..self.controls_now.len() {
            let e = match self.controls_now[j] {
                Some(p) => Some(back.transform_point3(p) - self.neutral_controls[j]),
                None => None,
            };
            // The target-space displacement is computed once: for the outlier check, and kept.
            let (e, d) = match e.map(|e| (e, to_target.apply(e))) {
                Some((e, d)) if d.length_squared() <= outlier2 => (e, d),
                _ => {
                    filled += 1;
                    (self.last_e[j], to_target.apply(self.last_e[j]))
                }
            };
            self.raw_e[j] = e;
            self.raw_d[j] = d;
        }
        if self.gate(&pose, frame.timestamp_us).is_some() {
            return self.hold_gated(frame.timestamp_us, filled, &to_target, out);
        }
        self.gated_since_us = None;
        self.accepted_rotation = pose.rotation;
        self.accepted_time_us = Some(frame.timestamp_us);
        if let Some(repair) = self.repair.as_mut() {
            self.repair_reading = repair.apply(&mut self.raw_d, self.face_size);
            self.stats.repaired += u64::from(self.repair_reading.repaired);
        }
        let filter = self
            .settings
            .filter
            .as_ref()
            .map(|fs| (fs, OneEuroStep::new(fs, dt)));
        for j in 0..self.controls_now.len() {
            let e = self.raw_e[j];
            self.frame_delta[j] = e - self.last_e[j];
            self.last_e[j] = e;
            let mut d = self.raw_d[j];
            if let Some((fs, step)) = &filter {
                let f = &mut self.filters[j];
                d = Vec3::new(
                    f[0].filter_step(fs, step, d.x),
                    f[1].filter_step(fs, step, d.y),
                    f[2].filter_step(fs, step, d.z),
                );
            }
            out.displacements[j] = d;
        }
        self.ease_from_canonical(frame.timestamp_us, out);
        if self.clamp_speed(frame.timestamp_us, out) {
            self.stats.clamped += 1;
        }
        for (l, d) in self.last_d.iter_mut().zip(&out.displacements) {
            *l = *d;
        }
        if let Some(g) = self.gaze.as_mut().filter(|g| g.has_neutral()) {
            self.eye_turn = Some(g.step(frame, &back, dt));
        }
        let t3 = Instant::now();
        self.stats.tracked += 1;
        self.stats.filled_controls += u64::from(filled);
        self.last_pose = pose;
        self.last_time_us = Some(frame.timestamp_us);
        self.lost_since_us = None;
        out.filled = filled;
        out.pose = pose;
        out.target_rotation = to_target.rotation_in_target(pose.rotation);
        out.status = FrameStatus::Tracked;
        let (t4, t5) = self.deform(out);
        out.times = StageTimes([
            nanos(t0, t1),
            nanos(t1, t2),
            nanos(t2, t3),
            nanos(t3, t4),
            nanos(t4, t5),
        ]);
        out.status
    }

    /// `positions = rest + B d` and normals, over the moving part only; returns the instants after each.
    fn deform(&mut self, out: &mut FrameOutput) -> (Instant, Instant) {
        if let Some(mouth) = self.mouth.as_mut() {
            mouth.apply(
                out.timestamp_us,
                &mut out.displacements[..self.target_controls.len()],
            );
        }
        self.parts.fill(&mut out.displacements, self.eye_turn);
        if !self.settings.positions {
            let t = Instant::now();
            return (t, t);
        }
        self.patch.deform(&out.displacements, &mut out.positions);
        let t4 = Instant::now();
        if self.settings.normals {
            self.patch.normals(&mut out.normals);
        }
        (t4, Instant::now())
    }

    /// Lets `mouth` drive the mouth's controls from now on (`None`: the tracker again); the jaw
    /// follows them, as it follows the tracker's.
    pub fn set_mouth(&mut self, mouth: Option<crate::mouth::MouthDrive>) {
        self.mouth = mouth;
    }

    /// The mouth drive, if one is set.
    pub fn mouth(&self) -> Option<&crate::mouth::MouthDrive> {
        self.mouth.as_ref()
    }

    /// The eyes' gaze (left, right) the last frame turned the eyeballs by, once one is read (a
    /// layout with pupils driving a rig with eyeballs).
    pub fn gaze(&self) -> Option<[crate::gaze::EyeGaze; 2]> {
        self.eye_turn
    }

    /// Number of vertices that can move (non-zero rows of `B`); 0 when positions are off.
    pub fn moving_vertex_count(&self) -> usize {
        self.patch.moving_count()
    }
}

/// Frame intervals the speed clamp takes the median of.
pub(crate) const INTERVALS: usize = 15;

fn nanos(a: Instant, b: Instant) -> u32 {
    u32::try_from(b.duration_since(a).as_nanos()).unwrap_or(u32::MAX)
}
