//! Blendshape name maps (`configs/namemaps/*.toml`): the spellings trackers use (ARKit,
//! Live Link Face, MediaPipe) to a rig's morph-target names, with a gain, an offset and a clamp
//! per entry: `w_target = clamp(gain * w + offset, lo, hi)`. Names match without ASCII case. An
//! entry may drive several targets (ARKit's one `browInnerUp` drives ICT's two halves) or none
//! (`targets = []`: a name the map knows and drops, e.g. MediaPipe's `_neutral`).

use crate::error::TrackerError;
use mimic_types::limits::{FileKind, read_capped};
use serde::Deserialize;
use std::collections::HashMap;
use std::path::Path;

/// Name map files (the shipped `arkit.toml` is 10 KB).
pub const NAMEMAP_FILE: FileKind = FileKind {
    what: "name map files",
    max_bytes: 1 << 20,
};

/// One entry of a name map file.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Entry {
    /// The canonical (ARKit) spelling.
    pub source: String,
    /// Other spellings of the same curve (Live Link, MediaPipe, a rig's `_L`/`_R` names).
    #[serde(default)]
    pub aliases: Vec<String>,
    /// Morph-target names it drives.
    pub targets: Vec<String>,
    /// Gain (default 1).
    #[serde(default = "one")]
    pub gain: f32,
    /// Offset added after the gain (default 0).
    #[serde(default)]
    pub offset: f32,
    /// Clamp `[lo, hi]` of the result (default `[0, 1]`).
    #[serde(default = "unit")]
    pub clamp: [f32; 2],
}

fn one() -> f32 {
    1.0
}

fn unit() -> [f32; 2] {
    [0.0, 1.0]
}

impl Entry {
    /// The target weight of tracker weight `w` (a NaN gives the clamp's low end).
    pub fn weight(&self, w: f32) -> f32 {
        let v = self.gain * w + self.offset;
        if v.is_nan() {
            return self.clamp[0];
        }
        v.clamp(self.clamp[0], self.clamp[1])
    }
}

impl Entry {
    /// The tracker weight that gives target weight `w` (the inverse of [`Self::weight`] inside
    /// the clamp), clamped to [0, 1]; 0 for an entry with gain 0.
    pub fn unweight(&self, w: f32) -> f32 {
        if self.gain == 0.0 || !w.is_finite() {
            return 0.0;
        }
        ((w - self.offset) / self.gain).clamp(0.0, 1.0)
    }
}

/// A rig's weights read back as tracker names ([`NameMap::inverse`]): for each output name, the
/// rig weight it comes from and the entry to invert.
#[derive(Clone, Debug, PartialEq)]
pub struct Inverse {
    /// Per output name: `(rig weight index, entry index or usize::MAX for a name the map lacks)`.
    routes: Vec<Option<(usize, usize)>>,
}

impl Inverse {
    /// Whether output `i` has a rig weight to come from.
    pub fn found(&self, i: usize) -> bool {
        self.routes.get(i).is_some_and(Option::is_some)
    }

    /// Writes `out[i]` (one per output name) from the rig's weights `rig`: the entry's inverse
    /// of its rig weight, clamped to [0, 1], or 0 where no rig weight is found. Allocates nothing.
    pub fn apply(&self, map: &NameMap, rig: &[f32], out: &mut [f32]) {
        for (o, r) in out.iter_mut().zip(&self.routes) {
            *o = match *r {
                Some((k, e)) => {
                    let w = rig.get(k).copied().unwrap_or(0.0);
                    match map.entries.get(e) {
                        Some(entry) => entry.unweight(w),
                        None if w.is_finite() => w.clamp(0.0, 1.0),
                        None => 0.0,
                    }
                }
                None => 0.0,
            };
        }
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    name: String,
    #[serde(default)]
    description: String,
    #[serde(rename = "entry", default)]
    entries: Vec<Entry>,
}

/// A name map: entries found by any of their spellings (the default one is empty: every name
/// passes through unchanged).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NameMap {
    /// The map's name.
    pub name: String,
    /// What it is for.
    pub description: String,
    /// Entries in file order.
    pub entries: Vec<Entry>,
    index: HashMap<String, usize>,
}

/// Inputs resolved against a map: where each tracker column goes, and which it does not know.
#[derive(Clone, Debug, PartialEq)]
pub struct Mapping {
    /// Distinct target names, in first-use order.
    pub targets: Vec<String>,
    /// `(input column, target, entry)` triples.
    routes: Vec<(usize, usize, usize)>,
    /// Input names the map does not list (sent on unchanged, clamped to [0, 1]).
    pub unmapped: Vec<String>,
}

impl NameMap {
    /// Parses a name map file's text; errors name `path` and the line.
    pub fn parse(text: &str, path: &Path) -> Result<Self, TrackerError> {
        let line_of = |e: &toml::de::Error| {
            e.span().map_or(1, |s| {
                text[..s.start.min(text.len())].lines().count().max(1)
            })
        };
        let f: File = toml::from_str(text).map_err(|e| TrackerError::Line {
            path: path.to_path_buf(),
            line: line_of(&e),
            reason: e.message().to_string(),
        })?;
        let mut index = HashMap::new();
        for (k, e) in f.entries.iter().enumerate() {
            let bad = |reason: String| TrackerError::Line {
                path: path.to_path_buf(),
                line: 1,
                reason: format!("entry `{}`: {reason}", e.source),
            };
            let finite = e.gain.is_finite() && e.offset.is_finite();
            let [lo, hi] = e.clamp;
            if !(finite && lo.is_finite() && hi.is_finite() && lo <= hi) {
                return Err(bad(
                    "gain and offset must be finite and clamp [lo, hi] with lo <= hi".into(),
                ));
            }
            for name in std::iter::once(&e.source).chain(&e.aliases) {
                if index
                    .insert(name.to_ascii_lowercase(), k)
                    .is_some_and(|j| j != k)
                {
                    return Err(bad(format!("spelling `{name}` is in two entries")));
                }
            }
        }
        Ok(Self {
            name: f.name,
            description: f.description,
            entries: f.entries,
            index,
        })
    }

    /// Reads a name map file (capped at [`NAMEMAP_FILE`]).
    pub fn load(path: &Path) -> Result<Self, TrackerError> {
        let text = read_capped(path, &NAMEMAP_FILE).map_err(|source| TrackerError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&text, path)
    }

    /// The entry spelled `name` (ASCII case ignored).
    pub fn entry(&self, name: &str) -> Option<&Entry> {
        self.index
            .get(&name.to_ascii_lowercase())
            .and_then(|&k| self.entries.get(k))
    }

    /// The inverse for tracker names `outputs` (setup; [`Inverse::apply`] per frame): each name's
    /// entry reads the first of its targets that `find` (a target name to a rig weight index)
    /// knows; a name the map lacks is looked up by `find` itself.
    pub fn inverse(
        &self,
        outputs: &[&str],
        mut find: impl FnMut(&str) -> Option<usize>,
    ) -> Inverse {
        let routes = outputs
            .iter()
            .map(|name| match self.index.get(&name.to_ascii_lowercase()) {
                Some(&e) => self.entries[e]
                    .targets
                    .iter()
                    .find_map(|t| find(t))
                    .map(|k| (k, e)),
                None => find(name).map(|k| (k, usize::MAX)),
            })
            .collect();
        Inverse { routes }
    }

    /// Resolves tracker column names once (setup); [`Mapping::apply`] then maps each frame.
    pub fn resolve(&self, inputs: &[&str]) -> Mapping {
        let mut targets: Vec<String> = Vec::new();
        let mut routes = Vec::new();
        let mut unmapped = Vec::new();
        let target_of = |name: &str, targets: &mut Vec<String>| match targets
            .iter()
            .position(|t| t.eq_ignore_ascii_case(name))
        {
            Some(t) => t,
            None => {
                targets.push(name.to_string());
                targets.len() - 1
            }
        };
        for (c, name) in inputs.iter().enumerate() {
            match self.index.get(&name.to_ascii_lowercase()) {
                Some(&k) => {
                    for t in &self.entries[k].targets {
                        routes.push((c, target_of(t, &mut targets), k));
                    }
                }
                None => {
                    unmapped.push((*name).to_string());
                    routes.push((c, target_of(name, &mut targets), usize::MAX));
                }
            }
        }
        Mapping {
            targets,
            routes,
            unmapped,
        }
    }
}

impl Mapping {
    /// Maps one frame: `values[c]` is input column `c`'s weight; `out` (one per target) gets each
    /// target's weight (the last route to a target wins; targets no route reaches keep 0).
    pub fn apply(&self, map: &NameMap, values: &[f32], out: &mut [f32]) {
        out.iter_mut().for_each(|w| *w = 0.0);
        for &(c, t, k) in &self.routes {
            let v = values.get(c).copied().unwrap_or(0.0);
            let w = match map.entries.get(k) {
                Some(e) => e.weight(v),
                None if v.is_nan() => 0.0,
                None => v.clamp(0.0, 1.0),
            };
            if let Some(o) = out.get_mut(t) {
                *o = w;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MAP: &str = r#"
name = "test"
[[entry]]
source = "browInnerUp"
targets = ["browInnerUp_L", "browInnerUp_R"]
gain = 2.0
offset = -0.5
[[entry]]
source = "jawOpen"
aliases = ["JAW_OPEN"]
targets = ["jawOpen"]
clamp = [0.0, 0.6]
[[entry]]
source = "_neutral"
targets = []
"#;

    #[test]
    fn gain_offset_clamp_and_spellings() {
        let m = NameMap::parse(MAP, Path::new("m.toml")).unwrap();
        let r = m.resolve(&["BrowInnerUp", "jaw_open_x", "JawOpen", "_neutral"]);
        assert_eq!(
            r.targets,
            vec!["browInnerUp_L", "browInnerUp_R", "jaw_open_x", "jawOpen"]
        );
        assert_eq!(r.unmapped, vec!["jaw_open_x"]);
        let mut out = vec![9.0; 4];
        r.apply(&m, &[0.4, 1.5, 0.9, 0.7], &mut out);
        // 2 * 0.4 - 0.5 = 0.3 for both brow halves; 1.5 clamped to 1; 0.9 clamped to 0.6.
        let want = [2.0 * 0.4 - 0.5, 2.0 * 0.4 - 0.5, 1.0, 0.6];
        for (o, w) in out.iter().zip(want) {
            assert!((o - w).abs() <= 1e-6, "{out:?}");
        }
        assert!(m.entry("jaw_open").is_some());
    }

    #[test]
    fn the_inverse_reads_rig_weights_back_as_tracker_weights() {
        let m = NameMap::parse(MAP, Path::new("m.toml")).unwrap();
        let rig = ["jawOpen", "browInnerUp_R", "smile"];
        let find = |t: &str| rig.iter().position(|r| r.eq_ignore_ascii_case(t));
        let outs = ["browInnerUp", "jawOpen", "smile", "cheekPuff"];
        let inv = m.inverse(&outs, find);
        assert_eq!(
            (0..4).map(|i| inv.found(i)).collect::<Vec<_>>(),
            [true, true, true, false]
        );
        // Forward then back: brow 0.4 -> 2 * 0.4 - 0.5 = 0.3 -> 0.4; jaw 0.5 (under its clamp).
        let brow = m.entry("browInnerUp").unwrap().weight(0.4);
        let jaw = m.entry("jawOpen").unwrap().weight(0.5);
        let mut out = [9.0f32; 4];
        inv.apply(&m, &[jaw, brow, 0.7], &mut out);
        let want = [0.4, 0.5, 0.7, 0.0];
        for (o, w) in out.iter().zip(want) {
            assert!((o - w).abs() <= 4.0 * f32::EPSILON, "{out:?}");
        }
    }

    #[test]
    fn bad_maps_are_refused() {
        let e = NameMap::parse("name = 1\n", Path::new("m.toml")).unwrap_err();
        assert!(e.to_string().starts_with("m.toml:1:"), "{e}");
        let twice = "name = \"x\"\n[[entry]]\nsource = \"a\"\ntargets = []\n[[entry]]\nsource = \"A\"\ntargets = []\n";
        assert!(NameMap::parse(twice, Path::new("m.toml")).is_err());
        let bad_clamp =
            "name = \"x\"\n[[entry]]\nsource = \"a\"\ntargets = []\nclamp = [1.0, 0.0]\n";
        assert!(NameMap::parse(bad_clamp, Path::new("m.toml")).is_err());
    }
}
