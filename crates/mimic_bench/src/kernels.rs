//! The step with each kernel variant against the default, in one run: one retargeter per
//! variant, taking turns on the same frames ([`crate::sessions::step_alternately`]), so that
//! every variant sees the same machine speed states. A variant is kept in `mimic_solve` only
//! where this shows it buys at least 10 % of the step (docs/performance.md).

use crate::{BenchError, Recorded, Subject};
use mimic_retarget::{RetargetSettings, Retargeter, Stage};
use mimic_solve::VectorKernel;
use serde::Serialize;
use std::collections::BTreeMap;
use std::sync::Arc;

/// One variant of the step: its name and how its settings differ from the default's.
struct Variant {
    name: &'static str,
    what: &'static str,
    set: fn(&mut RetargetSettings),
}

/// The variants, the default first: each vector kernel replaced by the portable one.
const VARIANTS: [Variant; 3] = [
    Variant {
        name: "Default",
        what: "the kernels the step picks on this CPU",
        set: |_| {},
    },
    Variant {
        name: "PortableDeform",
        what: "the deform by the portable kernel",
        set: |s| s.deform_kernel = Some(VectorKernel::Portable),
    },
    Variant {
        name: "PortableNormals",
        what: "the normals by the portable kernel",
        set: |s| s.normals_kernel = Some(VectorKernel::Portable),
    },
];

/// Medians of one variant's tracked steps, microseconds.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct VariantFigures {
    /// What differs from the default.
    pub what: &'static str,
    /// The deform stage.
    pub deform_median_us: f64,
    /// The normals stage.
    pub normals_median_us: f64,
    /// The whole step.
    pub step_median_us: f64,
    /// This variant's step over the default's (above 1: the default is faster).
    pub step_ratio: f64,
}

/// One way of taking turns: its turn length and each variant's figures, by name.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Turns {
    /// Frames each retargeter steps before the next takes its turn.
    pub turn_frames: usize,
    /// Each variant's figures (`Default` among them).
    #[serde(flatten)]
    pub variants: BTreeMap<String, VariantFigures>,
}

/// The variants in turns of 200 frames (`warm`: each runs as one session does, its data in
/// cache) and of 1 frame (`cold`: each step finds the others' data in cache, as with many
/// sessions on a core).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct KernelsInStep {
    /// Turns of 200 frames.
    pub warm: Turns,
    /// Turns of 1 frame.
    pub cold: Turns,
}

/// Runs every variant for `steps` steps (at least 100), in both turn lengths.
pub fn run(
    subject: &Subject<'_>,
    recorded: &Recorded,
    steps: usize,
) -> Result<KernelsInStep, BenchError> {
    let basis = Arc::new(subject.retargeter.basis().clone());
    let turns = |turn: usize| -> Result<Turns, BenchError> {
        let mut retargeters = VARIANTS
            .iter()
            .map(|v| {
                let mut settings = subject.settings.clone();
                (v.set)(&mut settings);
                Retargeter::new(subject.rig, subject.layout, basis.clone(), settings)
            })
            .collect::<Result<Vec<_>, _>>()?;
        let span = recorded.span_us();
        let steps = steps.max(100);
        let samples = crate::sessions::step_alternately(
            &mut retargeters,
            &recorded.frames,
            span,
            steps,
            turn,
        )?;
        let mut medians = Vec::new();
        for mut s in samples {
            let (stages, step) = s.summary();
            let stage = |k| stages.get(k).median_us;
            medians.push((stage(Stage::Deform), stage(Stage::Normals), step.median_us));
        }
        let default_step = medians.first().map_or(0.0, |m| m.2);
        let variants = VARIANTS
            .iter()
            .zip(medians)
            .map(|(v, (deform, normals, step))| {
                let figures = VariantFigures {
                    what: v.what,
                    deform_median_us: deform,
                    normals_median_us: normals,
                    step_median_us: step,
                    step_ratio: crate::baseline::ratio(step, default_step),
                };
                (v.name.to_string(), figures)
            })
            .collect();
        Ok(Turns {
            turn_frames: turn,
            variants,
        })
    };
    Ok(KernelsInStep {
        warm: turns(200)?,
        cold: turns(1)?,
    })
}
