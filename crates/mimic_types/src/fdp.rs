//! MPEG-4 facial definition points (FDPs), named `group.index` as in ISO/IEC 14496-2 Annex C.

use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// One MPEG-4 feature point, e.g. `8.3` (left corner of the outer lip contour).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub struct Fdp {
    /// Feature point group (2 ..= 11).
    pub group: u8,
    /// Index inside the group, from 1.
    pub index: u8,
}

/// Why a string is not a valid MPEG-4 FDP name.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FdpError {
    /// Not of the form `group.index`.
    #[error("`{0}` is not an FDP name of the form group.index (e.g. 8.3)")]
    Syntax(String),
    /// Group and index parse but name no point of MPEG-4.
    #[error("`{0}` names no MPEG-4 feature point (group {1} has points 1..={2})")]
    OutOfRange(String, u8, u8),
    /// Group outside 2..=11.
    #[error("`{0}` has group {1}; MPEG-4 feature point groups are 2..=11")]
    Group(String, u8),
}

/// Number of points in each MPEG-4 FDP group, indexed by group number (groups 2..=11).
const GROUP_SIZES: [u8; 12] = [0, 0, 14, 14, 6, 4, 4, 1, 10, 15, 15, 6];

impl Fdp {
    /// Builds an FDP, checking it names a point MPEG-4 defines.
    pub fn new(group: u8, index: u8) -> Result<Self, FdpError> {
        let name = format!("{group}.{index}");
        let size = *GROUP_SIZES
            .get(group as usize)
            .filter(|s| **s > 0)
            .ok_or(FdpError::Group(name.clone(), group))?;
        if index == 0 || index > size {
            return Err(FdpError::OutOfRange(name, group, size));
        }
        Ok(Self { group, index })
    }

    /// Human description of the point, from the MPEG-4 FDP table.
    pub fn description(&self) -> &'static str {
        match (self.group, self.index) {
            (2, 1) => "bottom of the chin",
            (2, 2) => "middle point of inner upper lip contour",
            (2, 3) => "middle point of inner lower lip contour",
            (2, 4) => "left corner of inner lip contour",
            (2, 5) => "right corner of inner lip contour",
            (2, 6) => "midpoint between 2.2 and 2.4 in the inner upper lip contour",
            (2, 7) => "midpoint between 2.2 and 2.5 in the inner upper lip contour",
            (2, 8) => "midpoint between 2.3 and 2.4 in the inner lower lip contour",
            (2, 9) => "midpoint between 2.3 and 2.5 in the inner lower lip contour",
            (2, 10) => "chin boss",
            (2, 11) => "chin left corner",
            (2, 12) => "chin right corner",
            (2, 13) => "left corner of jaw bone",
            (2, 14) => "right corner of jaw bone",
            (3, 1) => "center of upper inner left eyelid",
            (3, 2) => "center of upper inner right eyelid",
            (3, 3) => "center of lower inner left eyelid",
            (3, 4) => "center of lower inner right eyelid",
            (3, 5) => "center of the pupil of left eye",
            (3, 6) => "center of the pupil of right eye",
            (3, 7) => "left corner of left eye",
            (3, 8) => "left corner of right eye",
            (3, 9) => "center of lower outer left eyelid",
            (3, 10) => "center of lower outer right eyelid",
            (3, 11) => "right corner of left eye",
            (3, 12) => "right corner of right eye",
            (3, 13) => "center of upper outer left eyelid",
            (3, 14) => "center of upper outer right eyelid",
            (4, 1) => "right corner of left eyebrow",
            (4, 2) => "left corner of right eyebrow",
            (4, 3) => "uppermost point of the left eyebrow",
            (4, 4) => "uppermost point of the right eyebrow",
            (4, 5) => "left corner of left eyebrow",
            (4, 6) => "right corner of right eyebrow",
            (5, 1) => "center of the left cheek",
            (5, 2) => "center of the right cheek",
            (5, 3) => "left cheek bone",
            (5, 4) => "right cheek bone",
            (6, _) => "tongue",
            (7, 1) => "top of spine (rotation centre of the head)",
            (8, 1) => "middle point of outer upper lip contour",
            (8, 2) => "middle point of outer lower lip contour",
            (8, 3) => "left corner of outer lip contour",
            (8, 4) => "right corner of outer lip contour",
            (8, 5) => "midpoint between 8.3 and 8.1 in outer upper lip contour",
            (8, 6) => "midpoint between 8.4 and 8.1 in outer upper lip contour",
            (8, 7) => "midpoint between 8.3 and 8.2 in outer lower lip contour",
            (8, 8) => "midpoint between 8.4 and 8.2 in outer lower lip contour",
            (8, 9) => "right high point of Cupid's bow",
            (8, 10) => "left high point of Cupid's bow",
            (9, 1) => "left nostril border",
            (9, 2) => "right nostril border",
            (9, 3) => "nose tip",
            (9, 4) => "bottom right edge of nose",
            (9, 5) => "bottom left edge of nose",
            (9, 6) => "right upper edge of nose bone",
            (9, 7) => "left upper edge of nose bone",
            (9, 8) => "top of the upper teeth",
            (9, 9) => "bottom of the lower teeth",
            (9, 10) => "bottom of the upper teeth",
            (9, 11) => "top of the lower teeth",
            (9, 12) => "middle lower edge of nose bone (nose bridge)",
            (9, 13) => "left lower edge of nose bone",
            (9, 14) => "right lower edge of nose bone",
            (9, 15) => "bottom middle edge of nose",
            (10, _) => "ear",
            (11, 1) => "middle border between hair and forehead",
            (11, 2) => "right border between hair and forehead",
            (11, 3) => "left border between hair and forehead",
            (11, _) => "hair",
            _ => "unknown",
        }
    }
}

impl fmt::Display for Fdp {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{}", self.group, self.index)
    }
}

impl FromStr for Fdp {
    type Err = FdpError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let syntax = || FdpError::Syntax(s.to_string());
        let (g, i) = s.trim().split_once('.').ok_or_else(syntax)?;
        let group: u8 = g.parse().map_err(|_| syntax())?;
        let index: u8 = i.parse().map_err(|_| syntax())?;
        Fdp::new(group, index)
    }
}

impl TryFrom<String> for Fdp {
    type Error = FdpError;
    fn try_from(s: String) -> Result<Self, Self::Error> {
        s.parse()
    }
}

impl From<Fdp> for String {
    fn from(f: Fdp) -> String {
        f.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_prints() {
        let f: Fdp = "8.3".parse().unwrap();
        assert_eq!(f, Fdp { group: 8, index: 3 });
        assert_eq!(f.to_string(), "8.3");
        assert_eq!(f.description(), "left corner of outer lip contour");
    }

    #[test]
    fn rejects_bad_names() {
        assert!(matches!("8".parse::<Fdp>(), Err(FdpError::Syntax(_))));
        assert!(matches!("8.x".parse::<Fdp>(), Err(FdpError::Syntax(_))));
        assert!(matches!(
            "8.11".parse::<Fdp>(),
            Err(FdpError::OutOfRange(..))
        ));
        assert!(matches!(
            "4.0".parse::<Fdp>(),
            Err(FdpError::OutOfRange(..))
        ));
        assert!(matches!("1.1".parse::<Fdp>(), Err(FdpError::Group(..))));
        assert!(matches!("12.1".parse::<Fdp>(), Err(FdpError::Group(..))));
    }

    #[test]
    fn every_defined_point_has_a_description() {
        for g in 2..=11u8 {
            for i in 1..=GROUP_SIZES[g as usize] {
                let f = Fdp::new(g, i).unwrap();
                assert_ne!(f.description(), "unknown", "{f}");
            }
        }
    }
}
