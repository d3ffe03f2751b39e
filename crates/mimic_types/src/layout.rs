//! Landmark layouts: what each tracked point is, and which points make the MPEG-4 controls;
//! [`ControlName`], the name of a rig control (an FDP, or a layout's own point `layout:index`);
//! [`GazeLayout`], which points are the eyes' pupils, corners and lids (for gaze).

use crate::{Fdp, LandmarkFrame, ModelCorrespondence, Region};
use glam::Vec3;
use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// Longest layout name a point control may name (bytes).
pub const MAX_SET_NAME: usize = 23;

/// The name of a control: an MPEG-4 FDP (`8.3`), which every layout maps through its
/// `controls`, or one point of one layout (`kinect121:23`, 0-based), which only that layout
/// drives, with that point directly (a dense control set, docs/layouts.md).
#[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum ControlName {
    /// An MPEG-4 feature point.
    Fdp(Fdp),
    /// Point `index` of the layout named `set`.
    Point {
        /// The layout's name, `len` bytes of ASCII `[a-z0-9_-]` (zero padded).
        set: [u8; MAX_SET_NAME],
        /// Bytes of `set` in use.
        len: u8,
        /// 0-based point index in that layout.
        index: u16,
    },
}

/// Why a string is not a control name.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ControlNameError {
    /// Neither an FDP nor `layout:index`.
    #[error(
        "`{0}` is neither an MPEG-4 FDP (e.g. 8.3) nor a layout point `layout:index` (e.g. kinect121:23; the layout name is 1-{max} of a-z 0-9 _ -, the index 0-65535)",
        max = MAX_SET_NAME
    )]
    Syntax(String),
    /// An FDP-shaped name that names no FDP.
    #[error(transparent)]
    Fdp(#[from] crate::FdpError),
}

impl ControlName {
    /// Point control `index` of layout `set`; `None` for a name that is empty, longer than
    /// [`MAX_SET_NAME`] or not ASCII `[a-z0-9_-]`, or an index over 65535.
    pub fn point(set: &str, index: usize) -> Option<Self> {
        let ok = !set.is_empty()
            && set.len() <= MAX_SET_NAME
            && set
                .bytes()
                .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_' || b == b'-');
        let index = u16::try_from(index).ok()?;
        if !ok {
            return None;
        }
        let mut bytes = [0u8; MAX_SET_NAME];
        bytes[..set.len()].copy_from_slice(set.as_bytes());
        Some(ControlName::Point {
            set: bytes,
            len: set.len() as u8,
            index,
        })
    }

    /// The FDP, for an FDP control.
    pub fn as_fdp(self) -> Option<Fdp> {
        match self {
            ControlName::Fdp(f) => Some(f),
            ControlName::Point { .. } => None,
        }
    }

    /// Layout name and point index, for a point control.
    pub fn as_point(&self) -> Option<(&str, usize)> {
        match self {
            ControlName::Fdp(_) => None,
            ControlName::Point { set, len, index } => {
                let name = std::str::from_utf8(&set[..usize::from(*len)]).unwrap_or("");
                Some((name, usize::from(*index)))
            }
        }
    }

    /// Whether this is an FDP of `group` (e.g. 3: eyes).
    pub fn is_group(self, group: u8) -> bool {
        self.as_fdp().is_some_and(|f| f.group == group)
    }
}

impl From<Fdp> for ControlName {
    fn from(f: Fdp) -> Self {
        ControlName::Fdp(f)
    }
}

impl From<ControlName> for Option<Fdp> {
    fn from(c: ControlName) -> Self {
        c.as_fdp()
    }
}

impl fmt::Display for ControlName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ControlName::Fdp(fdp) => write!(f, "{fdp}"),
            ControlName::Point { .. } => {
                let (set, index) = self.as_point().unwrap_or(("", 0));
                write!(f, "{set}:{index}")
            }
        }
    }
}

impl fmt::Debug for ControlName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{self}")
    }
}

impl FromStr for ControlName {
    type Err = ControlNameError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let t = s.trim();
        match t.split_once(':') {
            Some((set, index)) => {
                let syntax = || ControlNameError::Syntax(s.to_string());
                let index: usize = index.parse().map_err(|_| syntax())?;
                ControlName::point(set, index).ok_or_else(syntax)
            }
            None => Ok(ControlName::Fdp(t.parse()?)),
        }
    }
}

impl TryFrom<String> for ControlName {
    type Error = ControlNameError;
    fn try_from(s: String) -> Result<Self, Self::Error> {
        s.parse()
    }
}

impl From<ControlName> for String {
    fn from(c: ControlName) -> String {
        c.to_string()
    }
}

/// A tracker's landmark layout and its mapping to the MPEG-4 control points.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Layout {
    /// Short name, e.g. `kinect121`.
    pub name: String,
    /// What the layout is and where it comes from.
    #[serde(default)]
    pub description: String,
    /// Number of points in a frame of this layout.
    pub point_count: usize,
    /// The control points, each an FDP made from one point or the mean of several.
    pub controls: Vec<LayoutControl>,
    /// Points that barely move with expression, used to remove rigid head motion.
    pub stable: Vec<usize>,
    /// Points whose meaning no documentation gives.
    #[serde(default)]
    pub undocumented: Vec<usize>,
    /// Optional names of the points, by index.
    #[serde(default)]
    pub point_names: Vec<String>,
    /// Which CANDIDE-3 vertex or edge point each tracked point corresponds to (for the model fitter).
    #[serde(default)]
    pub candide_correspondences: Vec<ModelCorrespondence>,
    /// Which points are each eye's pupil, corners and lids; `None`: the layout has no pupils and
    /// gives no gaze.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gaze: Option<GazeLayout>,
    /// The tracker's canonical neutral face, one position per point (its own units; the
    /// retargeter removes scale), if the layout ships one: frames are retargeted against it
    /// until the performer's neutral is calibrated (docs/replay.md, "Short clips").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub canonical_neutral: Option<Vec<Vec3>>,
}

/// The eyes' points of a layout (its `[gaze]` table), by the subject's left and right.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GazeLayout {
    /// The subject's left eye.
    pub left: EyePoints,
    /// The subject's right eye.
    pub right: EyePoints,
}

/// One eye's points in a layout.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EyePoints {
    /// Points whose mean is the pupil (or iris) centre.
    pub pupil: Vec<usize>,
    /// The outer (temporal) eye corner.
    pub outer: usize,
    /// The inner (nasal) eye corner.
    pub inner: usize,
    /// Points whose mean is the middle of the upper lid.
    pub upper: Vec<usize>,
    /// Points whose mean is the middle of the lower lid.
    pub lower: Vec<usize>,
}

impl EyePoints {
    /// Every point this eye names, pupil first.
    pub fn all(&self) -> impl Iterator<Item = usize> + '_ {
        self.pupil
            .iter()
            .copied()
            .chain([self.outer, self.inner])
            .chain(self.upper.iter().copied())
            .chain(self.lower.iter().copied())
    }
}

/// One MPEG-4 control point of a layout.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LayoutControl {
    /// The feature point, e.g. `8.3`.
    pub fdp: Fdp,
    /// Layout point indices whose mean is the control's position.
    pub points: Vec<usize>,
    /// Region whose solve this control drives.
    pub region: Region,
    /// Why these points were chosen.
    #[serde(default)]
    pub note: String,
}

/// A layout that does not hold together.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LayoutError {
    /// A control maps to a point the layout does not have.
    #[error("control {fdp} maps to point {point}, but layout `{layout}` has {point_count} points")]
    ControlPointOutOfRange {
        /// Layout name.
        layout: String,
        /// Offending control.
        fdp: Fdp,
        /// Offending point index.
        point: usize,
        /// Points in the layout.
        point_count: usize,
    },
    /// A control maps to no point at all.
    #[error("control {fdp} of layout `{layout}` names no points")]
    ControlWithoutPoints {
        /// Layout name.
        layout: String,
        /// Offending control.
        fdp: Fdp,
    },
    /// Two controls name the same FDP.
    #[error("control {fdp} appears twice in layout `{layout}`")]
    DuplicateControl {
        /// Layout name.
        layout: String,
        /// Duplicated control.
        fdp: Fdp,
    },
    /// A stable point is out of range.
    #[error("stable point {point} is out of range: layout `{layout}` has {point_count} points")]
    StablePointOutOfRange {
        /// Layout name.
        layout: String,
        /// Offending point.
        point: usize,
        /// Points in the layout.
        point_count: usize,
    },
    /// More points than [`crate::limits::MAX_LAYOUT_POINTS`].
    #[error(
        "layout `{layout}` has point_count {point_count}, over the maximum of {max} points",
        max = crate::limits::MAX_LAYOUT_POINTS
    )]
    TooManyPoints {
        /// Layout name.
        layout: String,
        /// Points announced.
        point_count: usize,
    },
    /// An undocumented point is out of range.
    #[error(
        "undocumented point {point} is out of range: layout `{layout}` has {point_count} points"
    )]
    UndocumentedPointOutOfRange {
        /// Layout name.
        layout: String,
        /// Offending point.
        point: usize,
        /// Points in the layout.
        point_count: usize,
    },
    /// More point names than points.
    #[error("layout `{layout}` names {names} points but has {point_count}")]
    TooManyPointNames {
        /// Layout name.
        layout: String,
        /// Names given.
        names: usize,
        /// Points in the layout.
        point_count: usize,
    },
    /// A CANDIDE-3 correspondence that is malformed or out of range.
    #[error("candide_correspondences entry {} (point {point}) of layout `{layout}`: {reason}", index + 1)]
    BadCorrespondence {
        /// Layout name.
        layout: String,
        /// 0-based index of the entry.
        index: usize,
        /// Its layout point.
        point: usize,
        /// What is wrong.
        reason: String,
    },
    /// A `[gaze]` eye names a point out of range, or an empty pupil or lid list.
    #[error("gaze: the {eye} eye of layout `{layout}` {reason}")]
    BadGaze {
        /// Layout name.
        layout: String,
        /// `left` or `right`.
        eye: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// The canonical neutral face has another number of points than the layout, or a
    /// coordinate that is not finite.
    #[error(
        "the canonical neutral of layout `{layout}` has {points} points ({finite} finite); the layout has {point_count}"
    )]
    BadCanonicalNeutral {
        /// Layout name.
        layout: String,
        /// Points in the canonical neutral.
        points: usize,
        /// Of those, points with finite coordinates.
        finite: usize,
        /// Points in the layout.
        point_count: usize,
    },
    /// Fewer than three stable points: head motion cannot be removed.
    #[error("layout `{layout}` has {count} stable points; removing head motion needs at least 3")]
    TooFewStablePoints {
        /// Layout name.
        layout: String,
        /// Stable points given.
        count: usize,
    },
}

impl Layout {
    /// Checks `point_count` against [`crate::limits::MAX_LAYOUT_POINTS`], every index against
    /// `point_count`, that controls are unique and non-empty, and the CANDIDE-3 correspondences
    /// (a point in range, one vertex or an edge with `t` in [0, 1], a finite weight > 0), and the
    /// `[gaze]` eyes (points in range, a pupil and both lids named), and that a canonical neutral
    /// has one finite position per point.
    pub fn validate(&self) -> Result<(), LayoutError> {
        if self.point_count > crate::limits::MAX_LAYOUT_POINTS {
            return Err(LayoutError::TooManyPoints {
                layout: self.name.clone(),
                point_count: self.point_count,
            });
        }
        let mut seen = std::collections::HashSet::new();
        for c in &self.controls {
            if !seen.insert(c.fdp) {
                return Err(LayoutError::DuplicateControl {
                    layout: self.name.clone(),
                    fdp: c.fdp,
                });
            }
            if c.points.is_empty() {
                return Err(LayoutError::ControlWithoutPoints {
                    layout: self.name.clone(),
                    fdp: c.fdp,
                });
            }
            if let Some(&p) = c.points.iter().find(|&&p| p >= self.point_count) {
                return Err(LayoutError::ControlPointOutOfRange {
                    layout: self.name.clone(),
                    fdp: c.fdp,
                    point: p,
                    point_count: self.point_count,
                });
            }
        }
        if let Some(&p) = self.stable.iter().find(|&&p| p >= self.point_count) {
            return Err(LayoutError::StablePointOutOfRange {
                layout: self.name.clone(),
                point: p,
                point_count: self.point_count,
            });
        }
        if self.stable.len() < 3 {
            return Err(LayoutError::TooFewStablePoints {
                layout: self.name.clone(),
                count: self.stable.len(),
            });
        }
        if let Some(c) = &self.canonical_neutral {
            let finite = c.iter().filter(|p| p.is_finite()).count();
            if c.len() != self.point_count || finite != c.len() {
                return Err(LayoutError::BadCanonicalNeutral {
                    layout: self.name.clone(),
                    points: c.len(),
                    finite,
                    point_count: self.point_count,
                });
            }
        }
        if let Some(&p) = self.undocumented.iter().find(|&&p| p >= self.point_count) {
            return Err(LayoutError::UndocumentedPointOutOfRange {
                layout: self.name.clone(),
                point: p,
                point_count: self.point_count,
            });
        }
        if self.point_names.len() > self.point_count {
            return Err(LayoutError::TooManyPointNames {
                layout: self.name.clone(),
                names: self.point_names.len(),
                point_count: self.point_count,
            });
        }
        for (index, c) in self.candide_correspondences.iter().enumerate() {
            let bad = |reason: String| LayoutError::BadCorrespondence {
                layout: self.name.clone(),
                index,
                point: c.point,
                reason,
            };
            if c.point >= self.point_count {
                return Err(bad(format!(
                    "point is out of range ({} points)",
                    self.point_count
                )));
            }
            if !(c.weight.is_finite() && c.weight > 0.0) {
                return Err(bad(format!("weight {} must be finite and > 0", c.weight)));
            }
            if c.blend().is_none() {
                return Err(bad(
                    "needs either `vertex`, or `vertices` (two) with `t` in [0, 1]".to_string(),
                ));
            }
        }
        if let Some(g) = &self.gaze {
            for (eye, e) in [("left", &g.left), ("right", &g.right)] {
                let bad = |reason: String| LayoutError::BadGaze {
                    layout: self.name.clone(),
                    eye,
                    reason,
                };
                if e.pupil.is_empty() || e.upper.is_empty() || e.lower.is_empty() {
                    return Err(bad(
                        "needs at least one pupil, upper and lower lid point".into()
                    ));
                }
                if let Some(p) = e.all().find(|&p| p >= self.point_count) {
                    return Err(bad(format!(
                        "names point {p}, but the layout has {} points",
                        self.point_count
                    )));
                }
                if e.outer == e.inner {
                    return Err(bad(format!("has one point ({}) for both corners", e.outer)));
                }
            }
        }
        Ok(())
    }

    /// Index of the control with this FDP.
    pub fn control_index(&self, fdp: Fdp) -> Option<usize> {
        self.controls.iter().position(|c| c.fdp == fdp)
    }

    /// The points whose mean is the rig control `name` in this layout: an FDP's points from
    /// `controls`, or for `name:index` of this layout that one point; `None` if this layout
    /// cannot drive it (an FDP it does not map, another layout's point, an index out of range).
    pub fn control_points(&self, name: ControlName) -> Option<&[usize]> {
        match name {
            ControlName::Fdp(f) => self
                .controls
                .iter()
                .find(|c| c.fdp == f)
                .map(|c| &c.points[..]),
            ControlName::Point { .. } => {
                let (set, index) = name.as_point()?;
                (set == self.name && index < self.point_count)
                    .then(|| POINT_INDICES.get(index..=index))
                    .flatten()
            }
        }
    }

    /// The FDP that is exactly point `index` of this layout (a control of that one point), if any.
    pub fn fdp_of_point(&self, index: usize) -> Option<Fdp> {
        self.controls
            .iter()
            .find(|c| c.points.len() == 1 && c.points[0] == index)
            .map(|c| c.fdp)
    }

    /// The FDP a rig control stands for in this layout: its own for an FDP control, for a
    /// point control of this layout the FDP that is that point alone (see [`Self::fdp_of_point`]).
    pub fn fdp_of(&self, name: ControlName) -> Option<Fdp> {
        match name {
            ControlName::Fdp(f) => Some(f),
            ControlName::Point { .. } => {
                let (set, index) = name.as_point()?;
                (set == self.name)
                    .then(|| self.fdp_of_point(index))
                    .flatten()
            }
        }
    }

    /// Position of control `c` in `frame`: the mean of its valid points, `None` if none is valid.
    pub fn control_position(&self, c: usize, frame: &LandmarkFrame) -> Option<Vec3> {
        let control = self.controls.get(c)?;
        mean_of_valid(&control.points, frame)
    }
}

/// `0, 1, 2, ...`: one-point slices for [`Layout::control_points`] of point controls.
static POINT_INDICES: [usize; crate::limits::MAX_LAYOUT_POINTS] = {
    let mut a = [0usize; crate::limits::MAX_LAYOUT_POINTS];
    let mut i = 0;
    while i < a.len() {
        a[i] = i;
        i += 1;
    }
    a
};

/// The mean of the valid ones of `points` in `frame`, `None` if none is valid.
#[inline]
pub fn mean_of_valid(points: &[usize], frame: &LandmarkFrame) -> Option<Vec3> {
    // One point (every control of most layouts): itself, as the mean below gives it (x / 1 is
    // x), without its three divisions.
    if let &[p] = points {
        return frame.is_valid(p).then(|| frame.points[p]);
    }
    let (sum, count) = points
        .iter()
        .filter(|&&p| frame.is_valid(p))
        .fold((Vec3::ZERO, 0u32), |(s, n), &p| {
            (s + frame.points[p], n + 1)
        });
    (count > 0).then(|| sum / count as f32)
}

#[cfg(test)]
mod tests;
