//! A rig's `[orientation]`: which of its mesh file's axes point up and forward for the face, so
//! that [`crate::load_rig`] stands the mesh up (y up, +z out of the face) as it loads it
//! (docs/rigging.md, "Orientation"). One of the 24 axis-aligned proper rotations: each turned
//! coordinate is a file coordinate, perhaps negated, so the turn is exact in floats.

use glam::{Mat3, Vec3};
use serde::Deserialize;

/// A signed coordinate axis of a mesh file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Axis {
    /// 0, 1, 2: x, y, z.
    pub index: usize,
    /// Pointing along minus the coordinate.
    pub negative: bool,
}

impl Axis {
    /// +x, +y, +z.
    pub const X: Self = Self::new(0, false);
    /// +y.
    pub const Y: Self = Self::new(1, false);
    /// +z.
    pub const Z: Self = Self::new(2, false);

    /// The axis `index` (0..3), negated or not.
    pub const fn new(index: usize, negative: bool) -> Self {
        Self { index, negative }
    }

    /// The six signed axes: +x, -x, +y, -y, +z, -z.
    pub fn all() -> [Self; 6] {
        [
            Self::new(0, false),
            Self::new(0, true),
            Self::new(1, false),
            Self::new(1, true),
            Self::new(2, false),
            Self::new(2, true),
        ]
    }

    /// The signed axis nearest to the direction `v` (largest component by magnitude).
    pub fn nearest(v: Vec3) -> Self {
        let a = v.abs();
        let index = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        Self::new(index, v[index] < 0.0)
    }

    /// The unit vector.
    pub fn vector(self) -> Vec3 {
        let mut v = Vec3::ZERO;
        v[self.index] = if self.negative { -1.0 } else { 1.0 };
        v
    }

    /// `+x`, `-z`, ...
    pub fn name(self) -> String {
        format!(
            "{}{}",
            if self.negative { '-' } else { '+' },
            ['x', 'y', 'z'][self.index]
        )
    }

    /// Parses `+x`, `x`, `-z`, ... (case-insensitive).
    pub fn parse(s: &str) -> Option<Self> {
        let s = s.trim().to_ascii_lowercase();
        let (negative, rest) = match s.strip_prefix('-') {
            Some(r) => (true, r),
            None => (false, s.strip_prefix('+').unwrap_or(&s)),
        };
        let index = ["x", "y", "z"].iter().position(|a| *a == rest)?;
        Some(Self::new(index, negative))
    }
}

/// The turn of a rig's mesh: its file's axis that points up for the face and the one that
/// points out of the face; [`Orientation::to_rig`] maps them to +y and +z.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Orientation {
    /// The file's up axis.
    pub up: Axis,
    /// The file's forward axis (out of the face), not along `up`.
    pub forward: Axis,
}

impl Default for Orientation {
    fn default() -> Self {
        Self {
            up: Axis::Y,
            forward: Axis::Z,
        }
    }
}

/// The on-disk `[orientation]` table: `up = "+z"`, `forward = "-y"`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OrientationTable {
    /// The file's up axis (`+x`, `-y`, ...).
    pub up: String,
    /// The file's forward axis.
    pub forward: String,
}

impl OrientationTable {
    /// The turn it names, or why it names none.
    pub fn orientation(&self) -> Result<Orientation, String> {
        let axis = |key: &str, s: &str| {
            Axis::parse(s).ok_or_else(|| {
                format!("orientation.{key} = {s:?} is not an axis (`+x`, `-x`, ... `-z`)")
            })
        };
        Orientation::new(axis("up", &self.up)?, axis("forward", &self.forward)?).ok_or_else(|| {
            format!(
                "orientation: up = {:?} and forward = {:?} are on one axis",
                self.up, self.forward
            )
        })
    }
}

impl Orientation {
    /// The turn with these file axes up and forward; `None` when they are on one axis.
    pub fn new(up: Axis, forward: Axis) -> Option<Self> {
        (up.index != forward.index).then_some(Self { up, forward })
    }

    /// The 24 turns (6 up axes, 4 forward axes each), the identity first.
    pub fn all() -> Vec<Self> {
        let mut all = vec![Self::default()];
        for up in Axis::all() {
            for forward in Axis::all() {
                if let Some(o) = Self::new(up, forward)
                    && o != Self::default()
                {
                    all.push(o);
                }
            }
        }
        all
    }

    /// The turn nearest to a face whose up and forward directions (file coordinates) are
    /// `up` and `forward`: up snapped to the nearest axis, forward to the nearest of the rest.
    pub fn nearest(up: Vec3, forward: Vec3) -> Self {
        let up = Axis::nearest(up);
        let mut f = forward;
        f[up.index] = 0.0;
        Self {
            up,
            forward: Axis::nearest(f),
        }
    }

    /// Whether the file is already y up, +z forward.
    pub fn is_identity(self) -> bool {
        self == Self::default()
    }

    /// The file's axis to the face's left (+x of the rig): up x forward.
    pub fn side(self) -> Vec3 {
        self.up.vector().cross(self.forward.vector())
    }

    /// The rotation from the rig's frame to the file's (columns: where +x, +y, +z go).
    pub fn rig_to_file(self) -> Mat3 {
        Mat3::from_cols(self.side(), self.up.vector(), self.forward.vector())
    }

    /// A file point in the rig's frame (exact: each coordinate is a file coordinate or its
    /// negation).
    pub fn to_rig(self, p: Vec3) -> Vec3 {
        let pick = |a: Vec3| {
            let i = Axis::nearest(a);
            if i.negative { -p[i.index] } else { p[i.index] }
        };
        Vec3::new(
            pick(self.side()),
            pick(self.up.vector()),
            pick(self.forward.vector()),
        )
    }

    /// A rig point in the file's frame (the inverse of [`Orientation::to_rig`], exact).
    pub fn to_file(self, p: Vec3) -> Vec3 {
        let mut out = Vec3::ZERO;
        for (axis, value) in [
            (self.side(), p.x),
            (self.up.vector(), p.y),
            (self.forward.vector(), p.z),
        ] {
            let i = Axis::nearest(axis);
            out[i.index] = if i.negative { -value } else { value };
        }
        out
    }

    /// "faces -y with +z up", as `rig new` says it.
    pub fn describe(self) -> String {
        format!("faces {} with {} up", self.forward.name(), self.up.name())
    }

    /// The `[orientation]` table as the rig file writes it.
    pub fn toml(self) -> String {
        format!(
            "[orientation]  # the mesh file {}: loaded turned to y up, +z forward (docs/rigging.md, \"Orientation\")\nup = \"{}\"\nforward = \"{}\"\n",
            self.describe(),
            self.up.name(),
            self.forward.name()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_24_turns_are_proper_rotations_and_round_trip_exactly() {
        let all = Orientation::all();
        assert_eq!(all.len(), 24);
        assert!(all[0].is_identity());
        let p = Vec3::new(0.123_456_7, -4.5e-3, 789.25);
        for o in &all {
            let m = o.rig_to_file();
            assert!((m.determinant() - 1.0).abs() < 1e-6, "{o:?}");
            assert_eq!(o.to_file(o.to_rig(p)), p);
            assert_eq!(o.to_file(Vec3::Y), o.up.vector());
            assert_eq!(o.to_file(Vec3::Z), o.forward.vector());
            assert!((m * o.to_rig(p) - p).length() < 1e-3, "{o:?}");
            assert_eq!(
                Orientation::nearest(o.up.vector() + 0.2, o.forward.vector() - 0.1),
                *o
            );
        }
        let scan = Orientation::new(Axis::Z, Axis::new(1, true)).unwrap();
        assert_eq!(scan.describe(), "faces -y with +z up");
        assert_eq!(
            scan.to_rig(Vec3::new(1.0, -2.0, 3.0)),
            Vec3::new(1.0, 3.0, 2.0)
        );
    }

    #[test]
    fn tables_parse_and_bad_ones_say_why() {
        let t = |up: &str, forward: &str| {
            OrientationTable {
                up: up.into(),
                forward: forward.into(),
            }
            .orientation()
        };
        assert_eq!(
            t("+z", "-y"),
            Ok(Orientation::new(Axis::Z, Axis::new(1, true)).unwrap())
        );
        assert_eq!(t("Y", "z"), Ok(Orientation::default()));
        assert!(t("up", "z").unwrap_err().contains("is not an axis"));
        assert!(t("z", "-z").unwrap_err().contains("on one axis"));
    }
}
