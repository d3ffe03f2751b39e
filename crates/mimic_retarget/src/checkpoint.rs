//! A retargeter's calibration and filter state as a value ([`Checkpoint`]) that serialises, so that
//! another process can take a session over and continue it (`mimic worker` failover,
//! docs/cluster.md): the neutral (or the neutral still being averaged), the source-to-target map,
//! the One Euro filters, the lost/gated hold clocks, the speed clamp's history and the counters.
//! What comes from the rig, layout, basis and settings is not in it: the restoring retargeter is
//! built from those as the first one was. Taken and restored outside the per-frame step (both
//! allocate).

use crate::pipeline::{Accumulator, INTERVALS};
use crate::{OneEuro, Retargeter, SourceToTarget, Stats};
use glam::{Quat, Vec3};
use mimic_types::HeadPose;
use serde::{Deserialize, Serialize};

/// The neutral being averaged from the first frames.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct NeutralSoFar {
    wanted: usize,
    frames: usize,
    #[serde(deserialize_with = "vec3s")]
    first: Vec<Vec3>,
    first_valid: Vec<bool>,
    #[serde(deserialize_with = "vec3s")]
    sum: Vec<Vec3>,
    count: Vec<u32>,
}

/// One filtered scalar's state: (value, derivative, primed).
type FilterState = (f32, f32, bool);

/// Everything a [`Retargeter`] learned from the frames it has seen.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Checkpoint {
    /// Layout points (checked on restore).
    points: usize,
    /// Rig controls (checked on restore).
    controls: usize,
    #[serde(deserialize_with = "vec3s")]
    neutral_points: Vec<Vec3>,
    neutral_valid: Vec<bool>,
    #[serde(deserialize_with = "vec3s")]
    neutral_controls: Vec<Vec3>,
    /// `None`: no limit yet (infinite).
    outlier_limit: Option<f32>,
    to_target: Option<SourceToTarget>,
    accumulator: Option<NeutralSoFar>,
    #[serde(deserialize_with = "filter_states")]
    filters: Vec<[FilterState; 3]>,
    #[serde(deserialize_with = "vec3s")]
    last_e: Vec<Vec3>,
    #[serde(deserialize_with = "vec3s")]
    frame_delta: Vec<Vec3>,
    #[serde(deserialize_with = "vec3s")]
    last_d: Vec<Vec3>,
    last_pose: HeadPose,
    last_time_us: Option<i64>,
    lost_since_us: Option<i64>,
    accepted_rotation: Quat,
    accepted_time_us: Option<i64>,
    gated_since_us: Option<i64>,
    #[serde(deserialize_with = "vec3s")]
    previous_out: Vec<Vec3>,
    previous_time_us: Option<i64>,
    intervals: Vec<f32>,
    next_interval: usize,
    #[serde(deserialize_with = "vec3s")]
    raw_d: Vec<Vec3>,
    #[serde(deserialize_with = "vec3s")]
    raw_e: Vec<Vec3>,
    stats: Stats,
}

/// Why a checkpoint does not fit a retargeter.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum CheckpointError {
    /// Taken from a retargeter with another layout or rig.
    #[error(
        "checkpoint of {points} points and {controls} controls; this retargeter has {want_points} and {want_controls}"
    )]
    Shape {
        /// Points in the checkpoint.
        points: usize,
        /// Controls in the checkpoint.
        controls: usize,
        /// Points of the layout.
        want_points: usize,
        /// Controls of the rig.
        want_controls: usize,
    },
    /// Its vectors do not have the lengths its own counts say.
    #[error("checkpoint field `{0}` has the wrong length")]
    Length(&'static str),
}

/// Reads a vector of points whose unset ones (NaN) JSON wrote as null.
fn vec3s<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Vec<Vec3>, D::Error> {
    let v: Vec<[Option<f32>; 3]> = Deserialize::deserialize(d)?;
    Ok(v.into_iter()
        .map(|p| Vec3::from_array(p.map(|c| c.unwrap_or(f32::NAN))))
        .collect())
}

/// Reads filter states whose NaN values JSON wrote as null.
fn filter_states<'de, D: serde::Deserializer<'de>>(
    d: D,
) -> Result<Vec<[FilterState; 3]>, D::Error> {
    type Raw = (Option<f32>, Option<f32>, bool);
    let v: Vec<[Raw; 3]> = Deserialize::deserialize(d)?;
    let nan = |x: Option<f32>| x.unwrap_or(f32::NAN);
    Ok(v.into_iter()
        .map(|f| f.map(|(a, b, p)| (nan(a), nan(b), p)))
        .collect())
}

fn same_len<T>(v: &[T], n: usize, field: &'static str) -> Result<(), CheckpointError> {
    if v.len() == n {
        Ok(())
    } else {
        Err(CheckpointError::Length(field))
    }
}

impl Checkpoint {
    /// Frames the retargeter had stepped when the checkpoint was taken.
    pub fn frames(&self) -> u64 {
        self.stats.frames
    }

    /// Whether the neutral was known (calibration done).
    pub fn calibrated(&self) -> bool {
        self.to_target.is_some() && self.accumulator.is_none()
    }

    /// Checks every length against the layout's `p` points and the rig's `m` controls.
    fn check(&self, p: usize, m: usize) -> Result<(), CheckpointError> {
        if self.points != p || self.controls != m {
            return Err(CheckpointError::Shape {
                points: self.points,
                controls: self.controls,
                want_points: p,
                want_controls: m,
            });
        }
        same_len(&self.neutral_points, p, "neutral_points")?;
        same_len(&self.neutral_valid, p, "neutral_valid")?;
        same_len(&self.neutral_controls, m, "neutral_controls")?;
        same_len(&self.filters, m, "filters")?;
        for (v, f) in [
            (&self.last_e, "last_e"),
            (&self.frame_delta, "frame_delta"),
            (&self.last_d, "last_d"),
            (&self.previous_out, "previous_out"),
            (&self.raw_d, "raw_d"),
            (&self.raw_e, "raw_e"),
        ] {
            same_len(v, m, f)?;
        }
        same_len(&self.intervals, INTERVALS, "intervals")?;
        if self.next_interval >= INTERVALS {
            return Err(CheckpointError::Length("next_interval"));
        }
        if let Some(a) = &self.accumulator {
            same_len(&a.first, p, "accumulator.first")?;
            same_len(&a.first_valid, p, "accumulator.first_valid")?;
            same_len(&a.sum, p, "accumulator.sum")?;
            same_len(&a.count, p, "accumulator.count")?;
        }
        Ok(())
    }
}

impl Retargeter {
    /// The state learned so far, to continue elsewhere with [`Retargeter::restore`].
    pub fn checkpoint(&self) -> Checkpoint {
        Checkpoint {
            points: self.neutral_points.len(),
            controls: self.target_controls.len(),
            neutral_points: self.neutral_points.clone(),
            neutral_valid: self.neutral_valid.clone(),
            neutral_controls: self.neutral_controls.clone(),
            outlier_limit: self.outlier_limit.is_finite().then_some(self.outlier_limit),
            to_target: self.to_target,
            accumulator: self.accumulator.as_ref().map(|a| NeutralSoFar {
                wanted: a.wanted,
                frames: a.frames,
                first: a.first.clone(),
                first_valid: a.first_valid.clone(),
                sum: a.sum.clone(),
                count: a.count.clone(),
            }),
            filters: self
                .filters
                .iter()
                .map(|f| f.map(|e| (e.value, e.derivative, e.primed)))
                .collect(),
            last_e: self.last_e.clone(),
            frame_delta: self.frame_delta.clone(),
            last_d: self.last_d.clone(),
            last_pose: self.last_pose,
            last_time_us: self.last_time_us,
            lost_since_us: self.lost_since_us,
            accepted_rotation: self.accepted_rotation,
            accepted_time_us: self.accepted_time_us,
            gated_since_us: self.gated_since_us,
            previous_out: self.previous_out.clone(),
            previous_time_us: self.previous_time_us,
            intervals: self.intervals.to_vec(),
            next_interval: self.next_interval,
            raw_d: self.raw_d.clone(),
            raw_e: self.raw_e.clone(),
            stats: self.stats,
        }
    }

    /// Continues from `c` (taken by a retargeter built from the same rig, layout, basis and
    /// settings): the next [`Retargeter::step`] gives what the first retargeter's would have.
    /// Refused, changing nothing, when its shape does not fit.
    pub fn restore(&mut self, c: &Checkpoint) -> Result<(), CheckpointError> {
        c.check(self.neutral_points.len(), self.target_controls.len())?;
        self.neutral_points.clone_from(&c.neutral_points);
        self.neutral_valid.clone_from(&c.neutral_valid);
        self.neutral_controls.clone_from(&c.neutral_controls);
        self.outlier_limit = c.outlier_limit.unwrap_or(f32::INFINITY);
        self.to_target = c.to_target;
        self.accumulator = c.accumulator.as_ref().map(|a| Accumulator {
            wanted: a.wanted,
            frames: a.frames,
            first: a.first.clone(),
            first_valid: a.first_valid.clone(),
            sum: a.sum.clone(),
            count: a.count.clone(),
        });
        for (f, s) in self.filters.iter_mut().zip(&c.filters) {
            for (e, &(value, derivative, primed)) in f.iter_mut().zip(s) {
                *e = OneEuro {
                    value,
                    derivative,
                    primed,
                };
            }
        }
        self.last_e.clone_from(&c.last_e);
        self.frame_delta.clone_from(&c.frame_delta);
        self.last_d.clone_from(&c.last_d);
        self.last_pose = c.last_pose;
        self.last_time_us = c.last_time_us;
        self.lost_since_us = c.lost_since_us;
        self.accepted_rotation = c.accepted_rotation;
        self.accepted_time_us = c.accepted_time_us;
        self.gated_since_us = c.gated_since_us;
        self.previous_out.clone_from(&c.previous_out);
        self.previous_time_us = c.previous_time_us;
        self.intervals.copy_from_slice(&c.intervals);
        self.next_interval = c.next_interval;
        self.raw_d.clone_from(&c.raw_d);
        self.raw_e.clone_from(&c.raw_e);
        self.stats = c.stats;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use crate::{RetargetSettings, Retargeter};
    use mimic_assets::{load_layout, load_rig};
    use mimic_capture::read_recording;
    use mimic_solve::build_basis;
    use std::path::PathBuf;

    fn repo() -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
    }

    /// A retargeter checkpointed mid-take (through JSON, as a worker stores it) and restored into
    /// a fresh one gives, frame for frame, bit for bit, what the uninterrupted one gives.
    #[test]
    fn restored_retargeter_continues_exactly() {
        let root = repo();
        let rig = load_rig(&root.join("configs/rigs/candide3.toml")).unwrap();
        let layout = load_layout(&root.join("configs/layouts/kinect121.toml")).unwrap();
        let path = root.join("recordings/a_yn_question.kinect121.jsonl");
        let rec = read_recording(&path, Some(layout.point_count)).unwrap();
        let basis = std::sync::Arc::new(build_basis(&rig, &rig.solver).unwrap());
        let settings = RetargetSettings::default();
        let frames = &rec.frames;
        assert!(frames.len() > 60, "{} frames", frames.len());
        for cut in [2, frames.len() / 2] {
            let mut a = Retargeter::new(&rig, &layout, basis.clone(), settings.clone()).unwrap();
            let mut out_a = a.new_output();
            for f in &frames[..cut] {
                a.step(&f.frame, &mut out_a);
            }
            let json = serde_json::to_string(&a.checkpoint()).unwrap();
            let c: super::Checkpoint = serde_json::from_str(&json).unwrap();
            // NaN (the unset points of a neutral still being averaged) is written as null and
            // read back as NaN, so the round trip is checked on the text.
            assert_eq!(
                serde_json::to_string(&c).unwrap(),
                json,
                "JSON round trip at {cut}"
            );
            let mut b = Retargeter::new(&rig, &layout, basis.clone(), settings.clone()).unwrap();
            b.restore(&c).unwrap();
            let mut out_b = b.new_output();
            for (k, f) in frames[cut..].iter().enumerate() {
                let sa = a.step(&f.frame, &mut out_a);
                let sb = b.step(&f.frame, &mut out_b);
                assert_eq!(sa, sb, "status of frame {}", cut + k);
                assert_eq!(
                    out_a.displacements,
                    out_b.displacements,
                    "d of frame {}",
                    cut + k
                );
                assert_eq!(
                    out_a.positions,
                    out_b.positions,
                    "positions of frame {}",
                    cut + k
                );
                assert_eq!(out_a.pose, out_b.pose, "pose of frame {}", cut + k);
            }
            assert_eq!(a.stats(), b.stats());
        }
    }

    /// A checkpoint of another rig's retargeter is refused and leaves the retargeter as it was.
    #[test]
    fn checkpoint_of_another_shape_is_refused() {
        let root = repo();
        let rig = load_rig(&root.join("configs/rigs/candide3.toml")).unwrap();
        let layout = load_layout(&root.join("configs/layouts/kinect121.toml")).unwrap();
        let basis = std::sync::Arc::new(build_basis(&rig, &rig.solver).unwrap());
        let mut r = Retargeter::new(&rig, &layout, basis, RetargetSettings::default()).unwrap();
        let mut c = r.checkpoint();
        c.controls += 1;
        let before = r.checkpoint();
        assert!(matches!(
            r.restore(&c),
            Err(super::CheckpointError::Shape { .. })
        ));
        assert_eq!(r.checkpoint(), before);
    }
}
