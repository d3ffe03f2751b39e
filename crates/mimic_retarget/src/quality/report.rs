//! What `mimic eval` prints, built from its measures: the shapes' report ([`ShapesReport`]) and
//! the jitter report ([`JitterReport`]), each as JSON or as plain text for people.

use super::{Jitter, ShapeError, jitter_text, median_and_max, region_table, summary_text};
use crate::Stats;
use mimic_types::{Region, Rig, SolverSettings};
use serde_json::{Map, Value, json};
use std::fmt::Write as _;
use std::path::Path;

/// The file name of `path`, as the reports name shapes and recordings.
pub fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

/// Which rig and controls a report is about.
#[derive(Clone, Copy, Debug)]
pub struct RigUnder<'a> {
    /// The rig as the command line named it.
    pub name: &'a str,
    /// The control set (`mpeg4`, or a layout's).
    pub controls: &'a str,
    /// The rig, its controls set.
    pub rig: &'a Rig,
}

/// The shapes' evaluation of one solver.
#[derive(Clone, Debug)]
pub struct ShapesReport<'a> {
    /// The rig evaluated.
    pub under: RigUnder<'a>,
    /// The solver's settings.
    pub settings: SolverSettings,
    /// The measured vertex ranges, if not every non-frozen vertex.
    pub vertices: Option<&'a [(u32, u32)]>,
    /// Time to build the basis, ms.
    pub setup_ms: f64,
    /// The basis' noise gain.
    pub noise_gain: f64,
    /// Whether the rig's morph targets were the solver.
    pub blend: bool,
    /// Each shape's fitted weights, by path (morph targets as the solver).
    pub weights: &'a Map<String, Value>,
    /// Each shape's path and error.
    pub shapes: &'a [(String, ShapeError)],
}

impl ShapesReport<'_> {
    /// Every figure as JSON.
    pub fn json(&self) -> Result<Value, serde_json::Error> {
        let errors: Vec<ShapeError> = self.shapes.iter().map(|s| s.1).collect();
        let (median, max) = median_and_max(&errors);
        let rig = self.under.rig;
        Ok(json!({
            "rig": self.under.name,
            "controls": self.under.controls,
            "control_count": rig.controls.len(),
            "units": rig.units,
            "settings": serde_json::to_value(self.settings)?,
            "band": rig.regions.band,
            "vertices": self.vertices.map(|r| r.iter().map(|(a, b)| json!([a, b])).collect::<Vec<_>>()),
            "setup_ms": self.setup_ms,
            "noise_gain": self.noise_gain,
            "blendshape_weights": self.blend.then_some(self.weights),
            "median_ratio": median,
            "max_ratio": max,
            "shapes": self.shapes.iter().map(|(p, e)| json!({
                "shape": p,
                "all": e.all,
                "regions": Region::ALL.iter().zip(&e.regions).map(|(r, s)| (r.name().to_string(), json!(s))).collect::<Map<_, _>>(),
            })).collect::<Vec<_>>(),
        }))
    }

    /// The report in words, each line ended by a newline; `detail` adds the solver's settings,
    /// each region's errors and the fitted weights.
    pub fn text(&self, detail: bool) -> Result<String, serde_json::Error> {
        let rig = self.under.rig;
        let solver = if self.blend {
            "the rig's morph targets (weights fitted to the controls)".to_string()
        } else {
            format!(
                "the {} solver (basis built in {:.0} ms)",
                self.settings.kind.name(),
                self.setup_ms
            )
        };
        let named: Vec<(String, ShapeError)> = self
            .shapes
            .iter()
            .map(|(p, e)| (file_name(Path::new(p)), *e))
            .collect();
        let mut out = format!(
            "Evaluated rig {} ({} controls: {}; units {}) with {solver} on {} expression meshes.\n{}",
            self.under.name,
            rig.controls.len(),
            self.under.controls,
            rig.units,
            self.shapes.len(),
            summary_text(&named, &rig.units, self.noise_gain)
        );
        if !detail {
            out.push_str("(--detail adds the solver's settings and each region's errors; --json prints everything)\n");
            return Ok(out);
        }
        out.push_str("\nSolver settings:\n");
        if let Value::Object(map) = serde_json::to_value(self.settings)? {
            for (key, value) in &map {
                let _ = writeln!(out, "  {key}: {value}");
            }
        }
        let _ = write!(
            out,
            "  band: {}\n\n{}",
            rig.regions.band,
            region_table(&named)
        );
        for (shape, w) in self.weights {
            let _ = writeln!(out, "weights for {shape}: {w}");
        }
        Ok(out)
    }
}

/// The jitter of replayed recordings on one rig.
#[derive(Clone, Debug)]
pub struct JitterReport<'a> {
    /// The rig replayed onto.
    pub under: RigUnder<'a>,
    /// Whether the One Euro filter was on.
    pub filter: bool,
    /// The basis' noise gain.
    pub noise_gain: f64,
    /// Each recording's path, jitter and the retargeter's counters.
    pub rows: &'a [(std::path::PathBuf, Jitter, Stats)],
}

impl JitterReport<'_> {
    /// Every figure as JSON.
    pub fn json(&self) -> Value {
        json!({
            "rig": self.under.name,
            "controls": self.under.controls,
            "control_count": self.under.rig.controls.len(),
            "filter": self.filter,
            "noise_gain": self.noise_gain,
            "recordings": self.rows.iter().map(|(p, j, s)| json!({
                "recording": p.display().to_string(), "jitter": j, "stats": s,
            })).collect::<Vec<_>>(),
        })
    }

    /// The report in words, each line ended by a newline.
    pub fn text(&self) -> String {
        let rig = self.under.rig;
        let named: Vec<_> = self
            .rows
            .iter()
            .map(|(p, j, s)| (file_name(p), *j, s.gated))
            .collect();
        format!(
            "Jitter of rig {} ({} controls: {}; units {}) replaying {} recordings, the One Euro filter {}; noise gain {:.2}.\n{}",
            self.under.name,
            rig.controls.len(),
            self.under.controls,
            rig.units,
            self.rows.len(),
            if self.filter { "on" } else { "off" },
            self.noise_gain,
            jitter_text(&named, &rig.units)
        )
    }
}
