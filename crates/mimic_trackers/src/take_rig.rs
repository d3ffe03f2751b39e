//! A take's tracked rows onto a rig's morph targets ([`TakeOntoRig`]): per row its time, the
//! weights in the rig's target order and the head rotation; and the take's names the rig lacks.

use crate::livelink::{HEAD_YAW, head_quat};
use crate::take::{Take, TakeRow, TakeWeights};
use mimic_types::WeightMap;

/// A take's weights (through the name map) put onto a rig's targets, row by row.
#[derive(Debug)]
pub struct TakeOntoRig<'a> {
    rows: Vec<&'a TakeRow>,
    weights: &'a TakeWeights,
    rig_map: WeightMap,
    out: Vec<f32>,
}

impl<'a> TakeOntoRig<'a> {
    /// `weights` of `take` onto the rig's targets named `rig_targets`.
    pub fn new(take: &'a Take, weights: &'a TakeWeights, rig_targets: &[String]) -> Self {
        Self {
            rows: take.rows.iter().filter(|r| r.tracked).collect(),
            weights,
            rig_map: WeightMap::new(rig_targets),
            out: vec![0.0; rig_targets.len()],
        }
    }

    /// Tracked rows.
    pub fn len(&self) -> usize {
        self.rows.len().min(self.weights.frames.len())
    }

    /// Whether the take has no tracked row.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The take's target names that the rig has no target for.
    pub fn lacking(&self) -> Vec<&'a str> {
        let mut probe = vec![0.0f32; self.out.len()];
        self.weights
            .targets
            .iter()
            .filter(|t| self.rig_map.apply([(t.as_str(), 1.0)], &mut probe) > 0)
            .map(String::as_str)
            .collect()
    }

    /// The line naming the take's names the rig `rig` lacks (`lacking`, of [`Self::lacking`]),
    /// if any.
    pub fn lacking_line(&self, rig: &str, lacking: &[&str]) -> Option<String> {
        (!lacking.is_empty()).then(|| {
            format!(
                "rig `{rig}` has no morph target for {} of the take's {} names (ignored): {}",
                lacking.len(),
                self.weights.targets.len(),
                lacking.join(", ")
            )
        })
    }

    /// Tracked row `k`: its time (microseconds), the weights in the rig's target order and the
    /// head rotation; `None` past the end.
    pub fn frame(&mut self, k: usize) -> Option<(i64, &[f32], glam::Quat)> {
        let (row, (_, t_us, mapped)) = (self.rows.get(k)?, self.weights.frames.get(k)?);
        let names = self.weights.targets.iter().map(String::as_str);
        self.rig_map
            .apply(names.zip(mapped.iter().copied()), &mut self.out);
        let mut head = [0.0f32; 3];
        head.copy_from_slice(&row.curves[HEAD_YAW..HEAD_YAW + 3]);
        Some((*t_us, &self.out, head_quat(head)))
    }
}
