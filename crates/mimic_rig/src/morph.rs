//! A rig's morph targets against a morph data file ([`MorphCheck`], reported by [`MorphImport`],
//! `mimic morph import`), and
//! the columns of a named-weights table that drive them ([`WeightColumns`]), and a CSV of
//! named weights turned into OBJ meshes ([`apply_csv`], `mimic morph apply`).

use mimic_assets::{AssetError, MORPH_FILE_DECIMALS, compare_deltas, write_obj_frame};
use mimic_capture::named_csv::{CsvError, read_named_csv};
use mimic_retarget::{BlendshapeError, BlendshapeFitter, BlendshapeSettings};
use mimic_types::{MorphTarget, Rig, WeightMap};
use serde::Serialize;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};

/// One target of a morph data file compared with the rig's target of that name.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TargetCheck {
    /// The target's name.
    pub target: String,
    /// Whether the rig has a target of that name (the figures below are `None` when not).
    pub in_rig: bool,
    /// Largest difference of a position delta component.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_position_difference: Option<f32>,
    /// Largest difference of a normal delta component.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_normal_difference: Option<f32>,
    /// Whether both are within the file's printed precision.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub within_printed_precision: Option<bool>,
}

/// A morph data file's targets compared with a rig's own.
#[derive(Clone, Debug, PartialEq)]
pub struct MorphCheck {
    /// One row per target of the file, in its order.
    pub rows: Vec<TargetCheck>,
    /// Whether the file has exactly the rig's targets, each within the printed precision.
    pub round_trip_ok: bool,
}

/// A morph data file checked against a rig, as `mimic morph import` reports it.
#[derive(Clone, Debug, PartialEq)]
pub struct MorphImport<'a> {
    /// The morph data file.
    pub file: &'a Path,
    /// The rig's name.
    pub rig: &'a str,
    /// Targets in the file.
    pub targets_in_file: usize,
    /// Targets of the rig.
    pub targets_in_rig: usize,
    /// Vertices per target.
    pub vertices: usize,
    /// The comparison.
    pub check: MorphCheck,
}

impl MorphImport<'_> {
    /// Every figure as JSON.
    pub fn json(&self) -> Result<Value, serde_json::Error> {
        Ok(json!({
            "file": self.file.display().to_string(),
            "rig": self.rig,
            "targets_in_file": self.targets_in_file,
            "targets_in_rig": self.targets_in_rig,
            "vertices": self.vertices,
            "decimals": MORPH_FILE_DECIMALS,
            "targets": serde_json::to_value(&self.check.rows)?,
            "round_trip_ok": self.check.round_trip_ok,
        }))
    }

    /// A line for the file, then one per target with its largest differences; each line ended
    /// by a newline.
    pub fn text(&self) -> String {
        let mut out = format!(
            "{}: {} targets x {} vertices; rig {} has {} targets\n",
            self.file.display(),
            self.targets_in_file,
            self.vertices,
            self.rig,
            self.targets_in_rig
        );
        for r in &self.check.rows {
            out.push_str(&format!(
                "  {:<16} max |position diff| {:>10.3e}   max |normal diff| {:>10.3e}\n",
                r.target,
                r.max_position_difference.map_or(f64::NAN, f64::from),
                r.max_normal_difference.map_or(f64::NAN, f64::from)
            ));
        }
        out
    }
}

impl MorphCheck {
    /// Compares the targets `read` from a file with the rig's `own`.
    pub fn compare(read: &[MorphTarget], own: &[MorphTarget]) -> Self {
        let mut all_ok = read.len() == own.len();
        let rows = read
            .iter()
            .map(|t| {
                let Some(o) = own.iter().find(|o| o.name == t.name) else {
                    all_ok = false;
                    return TargetCheck {
                        target: t.name.clone(),
                        in_rig: false,
                        max_position_difference: None,
                        max_normal_difference: None,
                        within_printed_precision: None,
                    };
                };
                let (dp, okp) = compare_deltas(&o.position_deltas, &t.position_deltas);
                let (dn, okn) = compare_deltas(&o.normal_deltas, &t.normal_deltas);
                all_ok &= okp && okn;
                TargetCheck {
                    target: t.name.clone(),
                    in_rig: true,
                    max_position_difference: Some(dp),
                    max_normal_difference: Some(dn),
                    within_printed_precision: Some(okp && okn),
                }
            })
            .collect();
        Self {
            rows,
            round_trip_ok: all_ok,
        }
    }
}

/// Which columns of a table of named weights (a header of names) drive a rig's targets.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WeightColumns {
    /// Columns that drive at least one target, in order.
    pub used: Vec<usize>,
    /// The other columns.
    pub ignored: Vec<usize>,
}

impl WeightColumns {
    /// Sorts the `header`'s columns by whether `map` (over `targets` targets) takes their name.
    pub fn new(header: &[String], map: &WeightMap, targets: usize) -> Self {
        let mut probe = vec![0f32; targets];
        let (used, ignored) = (0..header.len())
            .partition(|&c| map.apply([(header[c].as_str(), 1.0)], &mut probe) == 0);
        Self { used, ignored }
    }

    /// The weights of one row (its field per column by `field`) into `out`; the column whose
    /// field is not a number is the error.
    pub fn weights<'a>(
        &self,
        header: &[String],
        map: &WeightMap,
        field: impl Fn(usize) -> &'a str,
        out: &mut [f32],
    ) -> Result<(), usize> {
        let mut pairs: Vec<(&str, f32)> = Vec::with_capacity(self.used.len());
        for &c in &self.used {
            let v: f32 = field(c).parse().map_err(|_| c)?;
            pairs.push((header[c].as_str(), v));
        }
        map.apply(pairs.iter().copied(), out);
        Ok(())
    }
}

/// Why [`apply_csv`] failed.
#[derive(Debug, thiserror::Error)]
pub enum MorphApplyError {
    /// The rig's morph targets cannot be blended.
    #[error("blendshapes of rig `{rig}`")]
    Blend {
        /// The rig's name.
        rig: String,
        /// The cause.
        #[source]
        source: BlendshapeError,
    },
    /// The CSV could not be read.
    #[error(transparent)]
    Csv(#[from] CsvError),
    /// No column of the CSV names a target of the rig.
    #[error("{}: no column names a target of rig `{rig}` ({})", path.display(), targets.join(", "))]
    NoColumn {
        /// The CSV.
        path: PathBuf,
        /// The rig's name.
        rig: String,
        /// The rig's target names.
        targets: Vec<String>,
    },
    /// A field is not a number.
    #[error("{}:{line}: column `{column}`: `{value}` is not a number", path.display())]
    NotANumber {
        /// The CSV.
        path: PathBuf,
        /// Its line (1-based).
        line: usize,
        /// The column's name.
        column: String,
        /// The field.
        value: String,
    },
    /// The output folder could not be created.
    #[error("{}", path.display())]
    Folder {
        /// The folder.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// An OBJ could not be written.
    #[error(transparent)]
    Write(#[from] AssetError),
}

/// What [`apply_csv`] did, as `mimic morph apply` says it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MorphApplied {
    /// Rows (frames) read.
    pub frames: usize,
    /// OBJ files written.
    pub written: usize,
    /// Names of the columns that drive targets.
    pub used: Vec<String>,
    /// Names of the other columns.
    pub ignored: Vec<String>,
}

impl MorphApplied {
    /// The summary line for the CSV `weights` written to `out`.
    pub fn summary(&self, weights: &Path, out: &Path) -> String {
        format!(
            "{}: {} frames, {} written to {}; columns used: {}; ignored: {}",
            weights.display(),
            self.frames,
            self.written,
            out.display(),
            self.used.join(" "),
            if self.ignored.is_empty() {
                "none".to_string()
            } else {
                self.ignored.join(" ")
            }
        )
    }
}

/// Turns the CSV `weights` (a header row of names, one row of weights per frame) into meshes of
/// `rig` through its morph `targets`: every `every`-th frame as an OBJ in `out` (created if
/// missing; `frame_000000.obj` ...).
pub fn apply_csv(
    rig: &Rig,
    targets: &[MorphTarget],
    weights: &Path,
    out: &Path,
    every: usize,
) -> Result<MorphApplied, MorphApplyError> {
    let fitter =
        BlendshapeFitter::new(rig, targets, &BlendshapeSettings::default()).map_err(|source| {
            MorphApplyError::Blend {
                rig: rig.name.clone(),
                source,
            }
        })?;
    let map = WeightMap::new(fitter.names());
    let csv = read_named_csv(weights)?;
    let columns = WeightColumns::new(&csv.header, &map, fitter.target_count());
    if columns.used.is_empty() {
        return Err(MorphApplyError::NoColumn {
            path: weights.to_path_buf(),
            rig: rig.name.clone(),
            targets: fitter.names().to_vec(),
        });
    }
    std::fs::create_dir_all(out).map_err(|source| MorphApplyError::Folder {
        path: out.to_path_buf(),
        source,
    })?;
    let mut w = vec![0f32; fitter.target_count()];
    let mut positions = rig.mesh.positions.clone();
    let (mut frames, mut written) = (0usize, 0usize);
    for row in &csv.rows {
        columns
            .weights(&csv.header, &map, |c| row.field(c), &mut w)
            .map_err(|c| MorphApplyError::NotANumber {
                path: weights.to_path_buf(),
                line: row.line,
                column: csv.header[c].clone(),
                value: row.field(c).to_string(),
            })?;
        if frames.is_multiple_of(every.max(1)) {
            fitter.evaluate(&w, &mut positions, &mut []);
            let header = format!("mimic morph apply onto rig {}: frame {frames}", rig.name);
            write_obj_frame(out, frames, &header, &positions, &rig.mesh.triangles)?;
            written += 1;
        }
        frames += 1;
    }
    let names = |cols: &[usize]| cols.iter().map(|&c| csv.header[c].clone()).collect();
    Ok(MorphApplied {
        frames,
        written,
        used: names(&columns.used),
        ignored: names(&columns.ignored),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn target(name: &str, d: f32) -> MorphTarget {
        MorphTarget {
            name: name.into(),
            position_deltas: vec![Vec3::splat(d); 2],
            normal_deltas: vec![Vec3::ZERO; 2],
        }
    }

    #[test]
    fn a_file_with_the_rigs_targets_round_trips_and_one_without_does_not() {
        let own = [target("a", 1.0), target("b", 2.0)];
        assert!(MorphCheck::compare(&own, &own).round_trip_ok);
        let other = [target("a", 1.0), target("c", 2.0)];
        let check = MorphCheck::compare(&other, &own);
        assert!(!check.round_trip_ok);
        assert!(!check.rows[1].in_rig);
    }

    #[test]
    fn columns_that_name_no_target_are_ignored() {
        let map = WeightMap::new(&["jawOpen".to_string()]);
        let header = vec!["time".to_string(), "JawOpen".to_string()];
        let cols = WeightColumns::new(&header, &map, 1);
        assert_eq!(
            (cols.used.clone(), cols.ignored.clone()),
            (vec![1], vec![0])
        );
        let mut w = [0f32];
        let fields = ["0.1", "0.5"];
        assert_eq!(cols.weights(&header, &map, |c| fields[c], &mut w), Ok(()));
        assert_eq!(w, [0.5]);
        assert_eq!(cols.weights(&header, &map, |_| "x", &mut w), Err(1));
    }
}
