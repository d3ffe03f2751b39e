//! Timing statistics over many steps: median and 99th percentile per [`Stage`] and of the whole
//! step, as `mimic replay` and `mimic bench` report them.

use crate::{Stage, StageTimes};
use serde::ser::{Serialize, SerializeMap, Serializer};
use std::fmt;
use std::time::Instant;

/// Nanoseconds since `since`, saturating at `u32::MAX` (about 4.3 s).
pub fn elapsed_ns(since: Instant) -> u32 {
    u32::try_from(since.elapsed().as_nanos()).unwrap_or(u32::MAX)
}

/// Median and 99th percentile of nanosecond samples, in microseconds; sorts `samples`.
///
/// Nearest rank at `round((n - 1) q)`; `(0, 0)` for no samples.
pub fn median_p99_us(samples: &mut [u32]) -> (f64, f64) {
    if samples.is_empty() {
        return (0.0, 0.0);
    }
    samples.sort_unstable();
    let at = |q: f64| samples[((samples.len() - 1) as f64 * q).round() as usize] as f64 / 1000.0;
    (at(0.5), at(0.99))
}

/// Median and 99th percentile of one timed quantity.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Percentiles {
    /// Median, microseconds.
    pub median_us: f64,
    /// 99th percentile, microseconds.
    pub p99_us: f64,
}

impl Percentiles {
    /// The percentiles of nanosecond samples (sorts them; see [`median_p99_us`]).
    pub fn of(samples: &mut [u32]) -> Self {
        let (median_us, p99_us) = median_p99_us(samples);
        Self { median_us, p99_us }
    }

    /// Steps per second at the median time (0 when nothing was timed).
    pub fn per_second(&self) -> f64 {
        if self.median_us > 0.0 {
            1e6 / self.median_us
        } else {
            0.0
        }
    }
}

/// Percentiles of each stage, in [`Stage::ALL`] order; serializes as `{stage name: {median_us,
/// p99_us}}` and displays as one `name median .. us   p99 .. us` line per stage.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StagePercentiles(pub [Percentiles; 5]);

impl StagePercentiles {
    /// The percentiles of one stage.
    pub fn get(&self, s: Stage) -> Percentiles {
        self.0[s as usize]
    }
}

impl Serialize for StagePercentiles {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut map = serializer.serialize_map(Some(Stage::ALL.len()))?;
        for s in Stage::ALL {
            map.serialize_entry(s.name(), &self.get(s))?;
        }
        map.end()
    }
}

impl fmt::Display for StagePercentiles {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for s in Stage::ALL {
            let p = self.get(s);
            writeln!(
                f,
                "  {:<10} median {:>8.1} us   p99 {:>8.1} us",
                s.name(),
                p.median_us,
                p.p99_us
            )?;
        }
        Ok(())
    }
}

/// Step and stage times collected over tracked frames.
#[derive(Clone, Debug, Default)]
pub struct StageSamples {
    stages: [Vec<u32>; 5],
    step: Vec<u32>,
}

impl StageSamples {
    /// Room for `steps` frames without reallocating.
    pub fn with_capacity(steps: usize) -> Self {
        Self {
            stages: std::array::from_fn(|_| Vec::with_capacity(steps)),
            step: Vec::with_capacity(steps),
        }
    }

    /// Records one frame: the whole step's nanoseconds and its stage times.
    pub fn push(&mut self, step_ns: u32, times: &StageTimes) {
        self.step.push(step_ns);
        for s in Stage::ALL {
            self.stages[s as usize].push(times.get(s));
        }
    }

    /// Frames recorded.
    pub fn steps(&self) -> usize {
        self.step.len()
    }

    /// Percentiles per stage and of the step (sorts the samples).
    pub fn summary(&mut self) -> (StagePercentiles, Percentiles) {
        let stages = StagePercentiles(std::array::from_fn(|k| {
            Percentiles::of(&mut self.stages[k])
        }));
        (stages, Percentiles::of(&mut self.step))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_and_p99_of_a_known_sample() {
        // 0, 1, ..., 100 us in shuffled order: the median is 50 us and the 99th percentile 99 us.
        let mut ns: Vec<u32> = (0..=100u32).map(|k| (k * 37 % 101) * 1000).collect();
        assert_eq!(median_p99_us(&mut ns), (50.0, 99.0));
        assert_eq!(median_p99_us(&mut []), (0.0, 0.0));
        assert_eq!(median_p99_us(&mut [2500]), (2.5, 2.5));
    }

    #[test]
    fn samples_summarise_per_stage_and_serialize_in_pipeline_order() {
        let mut s = StageSamples::with_capacity(3);
        for k in 1..=3u32 {
            s.push(k * 10_000, &StageTimes([k * 1000, 0, 0, k * 2000, 0]));
        }
        assert_eq!(s.steps(), 3);
        let (stages, step) = s.summary();
        assert_eq!(step.median_us, 20.0);
        assert_eq!(step.per_second(), 50_000.0);
        assert_eq!(stages.get(Stage::Select).median_us, 2.0);
        assert_eq!(stages.get(Stage::Deform).p99_us, 6.0);
        let mut json = Vec::new();
        stages
            .serialize(&mut serde_json::Serializer::new(&mut json))
            .unwrap();
        let text = String::from_utf8(json).unwrap();
        assert!(
            text.starts_with(r#"{"select":{"median_us":2.0,"p99_us":3.0},"stabilise":"#),
            "{text}"
        );
        let shown = stages.to_string();
        assert_eq!(shown.lines().count(), 5);
        assert_eq!(
            shown.lines().next(),
            Some("  select     median      2.0 us   p99      3.0 us")
        );
    }
}
