//! The one frame loop: a landmark frame through the [`Retargeter`] (and, in blend-shape mode,
//! the [`BlendshapeFitter`]), or a take's weights straight onto the morph targets; then every
//! output ([`FrameSink`]) in turn. A source (a recording's paced replay, a Live Link take, a
//! socket) drives it one frame at a time; it times the steps, counts frames whose mesh is not
//! finite, and keeps the weights' statistics. Outputs are the only formats it knows of, through
//! the trait: OBJ and `frames.bin` live in mimic_assets, the GLB in mimic_gltf, the CSVs beside
//! their formats.

use crate::{
    BlendshapeFitter, FrameOutput, FrameStatus, Retargeter, StageSamples, StageTimes, WeightStats,
    WeightSummary, elapsed_ns,
};
use glam::{Quat, Vec3};
use mimic_types::pose::head_translation;
use mimic_types::{FrameSink, HeadPose, LandmarkFrame, SinkError, SinkFrame, SinkReport};
use std::time::Instant;

/// One output and which frames it takes.
struct Output {
    sink: Box<dyn FrameSink + Send>,
    /// It takes every `every`-th frame (1: all).
    every: usize,
}

/// The blend-shape stage of a landmark loop: the fit and its running statistics.
struct Blend {
    fitter: BlendshapeFitter,
    stats: WeightStats,
}

/// Frames in, outputs out (module docs).
pub struct FrameLoop {
    retargeter: Option<Retargeter>,
    blend: Option<Blend>,
    /// A weights loop's morph targets (its mesh is their blend).
    morph: Option<BlendshapeFitter>,
    out: FrameOutput,
    outputs: Vec<Output>,
    samples: StageSamples,
    /// Whether tracked steps' times are kept (a replay's summary) or not (a long-lived viewer or
    /// session, whose samples would grow without bound).
    timing: bool,
    non_finite_frames: usize,
    index: usize,
}

/// What a finished loop did.
#[derive(Debug)]
pub struct LoopReport {
    /// Each output's report, in the order they were added.
    pub outputs: Vec<SinkReport>,
    /// Step times of the tracked frames (landmark loops).
    pub samples: StageSamples,
    /// Frames stepped.
    pub frames: usize,
    /// Frames whose deformed mesh had a non-finite vertex.
    pub non_finite_frames: usize,
    /// Per target: mean and max weight over tracked frames (landmark loops in blend-shape mode).
    pub weights: Option<WeightSummary>,
}

impl LoopReport {
    /// The output of the deformed frames (OBJ, `frames.bin` or GLB), if the loop had one.
    pub fn frames_output(&self) -> Option<&SinkReport> {
        SinkReport::frames_output(&self.outputs)
    }
}

impl FrameLoop {
    /// A loop of landmark frames through `retargeter`; with `fitter`, blend-shape mode (the
    /// mesh is the fitted blend of the rig's morph targets).
    pub fn landmarks(retargeter: Retargeter, fitter: Option<BlendshapeFitter>) -> Self {
        let out = retargeter.new_output();
        Self {
            blend: fitter.map(|fitter| Blend {
                stats: WeightStats::new(fitter.target_count()),
                fitter,
            }),
            retargeter: Some(retargeter),
            morph: None,
            out,
            outputs: Vec::new(),
            samples: StageSamples::default(),
            timing: true,
            non_finite_frames: 0,
            index: 0,
        }
    }

    /// A loop of named weights (a Live Link take) onto `fitter`'s morph targets, whose blend
    /// of `rest` is computed only when an output wants the mesh.
    pub fn weights(rest: &[Vec3], fitter: BlendshapeFitter) -> Self {
        let out = FrameOutput {
            timestamp_us: 0,
            status: FrameStatus::Tracked,
            positions: rest.to_vec(),
            normals: vec![Vec3::ZERO; rest.len()],
            displacements: Vec::new(),
            pose: HeadPose::default(),
            target_rotation: Quat::IDENTITY,
            filled: 0,
            times: StageTimes::default(),
        };
        Self {
            retargeter: None,
            blend: None,
            morph: Some(fitter),
            out,
            outputs: Vec::new(),
            samples: StageSamples::default(),
            timing: true,
            non_finite_frames: 0,
            index: 0,
        }
    }

    /// The same loop keeping no step times (for viewers and sessions that run without end).
    pub fn untimed(mut self) -> Self {
        self.timing = false;
        self
    }

    /// Adds an output that takes every `every`-th frame (1 or 0: every frame).
    pub fn add_output(&mut self, sink: Box<dyn FrameSink + Send>, every: usize) {
        self.outputs.push(Output {
            sink,
            every: every.max(1),
        });
    }

    /// The retargeter of a landmark loop.
    pub fn retargeter(&self) -> Option<&Retargeter> {
        self.retargeter.as_ref()
    }

    /// The morph targets' fit (landmark loops in blend-shape mode) or blend (weights loops).
    pub fn fitter(&self) -> Option<&BlendshapeFitter> {
        self.blend
            .as_ref()
            .map(|b| &b.fitter)
            .or(self.morph.as_ref())
    }

    /// The last frame's output.
    pub fn output(&self) -> &FrameOutput {
        &self.out
    }

    /// Frames stepped so far.
    pub fn frames(&self) -> usize {
        self.index
    }

    /// Steps a landmark frame (with the recording's `label`) and hands it to every output.
    /// A weights loop takes no landmark frames: the frame is counted rejected.
    pub fn step(
        &mut self,
        frame: &LandmarkFrame,
        label: Option<i64>,
    ) -> Result<FrameStatus, SinkError> {
        let Some(r) = self.retargeter.as_mut() else {
            return Ok(FrameStatus::Rejected);
        };
        let started = Instant::now();
        let status = r.step(frame, &mut self.out);
        let elapsed = elapsed_ns(started);
        let weights = match self.blend.as_mut() {
            Some(b) => {
                let fitted = Instant::now();
                b.fitter.set_eye_look(r.gaze().map(|g| {
                    let mut w = [0.0; 8];
                    crate::gaze::eye_look_weights(g, &mut w);
                    w
                }));
                b.fitter.set_mouth(r.mouth().and_then(|m| m.weights()));
                let w = b.fitter.apply(&mut self.out);
                if self.out.status == FrameStatus::Tracked {
                    b.stats.push(w, elapsed_ns(fitted));
                }
                Some(w)
            }
            None => None,
        };
        if self.timing && status == FrameStatus::Tracked {
            self.samples.push(elapsed, &self.out.times);
        }
        // A retargeter that computes no positions (a server session's) leaves the rest mesh:
        // nothing to check, and no pass over every vertex a frame.
        if r.moving_vertex_count() > 0 && !self.out.positions.iter().all(|p| p.is_finite()) {
            self.non_finite_frames += 1;
        }
        // The head's translation is for the outputs: none is computed on a frame no output takes
        // (a viewer's loop has none).
        let due = self
            .outputs
            .iter()
            .any(|o| self.index.is_multiple_of(o.every));
        let head = match r.source_to_target() {
            Some(map) if due && status == FrameStatus::Tracked => {
                let points = (0..frame.points.len())
                    .filter(|i| frame.is_valid(*i))
                    .map(|i| frame.points[i]);
                head_translation(points, &self.out.pose, map.linear)
            }
            _ => None,
        };
        let sink_frame = SinkFrame {
            index: self.index,
            label,
            view: self.out.view(),
            positions: &self.out.positions,
            normals: &self.out.normals,
            weights,
            head_translation: head,
        };
        send(&mut self.outputs, &sink_frame)?;
        self.index += 1;
        Ok(status)
    }

    /// Puts one frame of `weights` (in the fitter's target order) with the head `rotation` at
    /// `t_us` through a weights loop; a landmark loop ignores it.
    pub fn push_weights(
        &mut self,
        t_us: i64,
        weights: &[f32],
        rotation: Quat,
    ) -> Result<(), SinkError> {
        let Some(fitter) = self.morph.as_ref() else {
            return Ok(());
        };
        let index = self.index;
        let mesh_due = self
            .outputs
            .iter()
            .any(|o| index.is_multiple_of(o.every) && o.sink.wants_mesh());
        if mesh_due {
            fitter.evaluate(weights, &mut self.out.positions, &mut self.out.normals);
        }
        self.out.timestamp_us = t_us;
        self.out.pose = HeadPose {
            rotation,
            ..HeadPose::default()
        };
        self.out.target_rotation = rotation;
        let sink_frame = SinkFrame {
            index,
            label: None,
            view: self.out.view(),
            positions: &self.out.positions,
            normals: &self.out.normals,
            weights: Some(weights),
            head_translation: None,
        };
        send(&mut self.outputs, &sink_frame)?;
        self.index += 1;
        Ok(())
    }

    /// Finishes every output (all of them, even after one fails; the first error is returned)
    /// and reports.
    pub fn finish(self) -> Result<LoopReport, SinkError> {
        let mut reports = Vec::with_capacity(self.outputs.len());
        let mut first_error = None;
        for o in self.outputs {
            match o.sink.finish() {
                Ok(r) => reports.push(r),
                Err(e) => {
                    first_error.get_or_insert(e);
                }
            }
        }
        if let Some(e) = first_error {
            return Err(e);
        }
        let weights = self
            .blend
            .map(|mut b| b.stats.summary(b.fitter.names(), b.fitter.ridges()));
        Ok(LoopReport {
            outputs: reports,
            samples: self.samples,
            frames: self.index,
            non_finite_frames: self.non_finite_frames,
            weights,
        })
    }
}

/// Hands `frame` to every output whose turn it is.
fn send(outputs: &mut [Output], frame: &SinkFrame<'_>) -> Result<(), SinkError> {
    for o in outputs {
        if frame.index.is_multiple_of(o.every) {
            o.sink.frame(frame)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests;
