//! Running statistics of morph-target weights over a replay, for its summary.

use crate::stage_stats::Percentiles;
use serde::Serialize;

/// Mean and largest weight of each morph target over tracked frames, and the time each fit and
/// blend took.
#[derive(Clone, Debug, Default)]
pub struct WeightStats {
    sum: Vec<f64>,
    max: Vec<f32>,
    frames: usize,
    ns: Vec<u32>,
}

/// One target's line of a [`WeightSummary`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TargetWeight {
    /// Target name.
    pub target: String,
    /// Mean weight over tracked frames.
    pub mean_weight: f64,
    /// Largest weight over tracked frames.
    pub max_weight: f32,
}

/// What [`WeightStats::summary`] reports.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct WeightSummary {
    /// Time of fit + blend per tracked frame.
    pub fit_and_blend: Percentiles,
    /// The ridge weight of each target (rig units squared).
    pub ridge_per_target: Vec<f64>,
    /// Per target, in weight order.
    pub targets: Vec<TargetWeight>,
}

impl WeightStats {
    /// Statistics of `targets` weights.
    pub fn new(targets: usize) -> Self {
        Self {
            sum: vec![0.0; targets],
            max: vec![0.0; targets],
            frames: 0,
            ns: Vec::new(),
        }
    }

    /// Records a tracked frame's weights and the nanoseconds its fit and blend took.
    pub fn push(&mut self, weights: &[f32], ns: u32) {
        self.ns.push(ns);
        self.frames += 1;
        for ((s, m), x) in self.sum.iter_mut().zip(&mut self.max).zip(weights) {
            *s += f64::from(*x);
            *m = m.max(*x);
        }
    }

    /// The summary, naming the targets `names` with their `ridges` (sorts the timings).
    pub fn summary(&mut self, names: &[String], ridges: &[f64]) -> WeightSummary {
        let n = self.frames.max(1) as f64;
        WeightSummary {
            fit_and_blend: Percentiles::of(&mut self.ns),
            ridge_per_target: ridges.to_vec(),
            targets: names
                .iter()
                .zip(&self.sum)
                .zip(&self.max)
                .map(|((name, s), m)| TargetWeight {
                    target: name.clone(),
                    mean_weight: s / n,
                    max_weight: *m,
                })
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mean_and_max_per_target() {
        let mut s = WeightStats::new(2);
        s.push(&[0.5, 0.0], 2000);
        s.push(&[1.0, 0.25], 4000);
        s.push(&[0.0, 0.5], 3000);
        let names = ["a".to_string(), "b".to_string()];
        let r = s.summary(&names, &[0.1, 0.2]);
        assert_eq!(r.targets[0].mean_weight, 0.5);
        assert_eq!(r.targets[0].max_weight, 1.0);
        assert_eq!(r.targets[1].mean_weight, 0.25);
        assert_eq!(r.targets[1].max_weight, 0.5);
        assert_eq!(r.fit_and_blend.median_us, 3.0);
        assert_eq!(r.ridge_per_target, vec![0.1, 0.2]);
        // No frames: zero means, not NaN.
        let empty = WeightStats::new(1).summary(&names[..1], &[0.0]);
        assert_eq!(empty.targets[0].mean_weight, 0.0);
    }
}
