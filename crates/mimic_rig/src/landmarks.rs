//! Landmark files: which mesh vertex carries each of the 68 iBUG points.
//!
//! Three forms are read (docs/rigging.md): a JSON object `{"0": 1225, "1": 1888, ...}` keyed by
//! 0-based iBUG numbers (points the mesh lacks are left out), a JSON list of 68 vertex indices
//! (ICT-FaceKit's `idx_to_landmark_verts`), or text lines `N = V` (blank lines and `#` comments
//! skipped), whose iBUG numbers count from 0 or 1 ([`LandmarkBase`], told or seen from the file)
//! and whose vertices count from 0 unless told otherwise. A text file may be TOML with its
//! mapping in a `[landmark_mappings]` table, as eos ships them for the Surrey and Basel face
//! models (`share/ibug_to_sfm.txt`: iBUG numbers from 1, vertices from 0); other tables in it
//! (`[contour_landmarks]`) are skipped.

use crate::RigNewError;
use mimic_types::FileKind;
use std::path::Path;

/// Number of points of the iBUG 300-W markup.
pub const IBUG_POINTS: usize = 68;

/// Landmark files are small; the cap keeps a wrong path from being read whole.
pub const LANDMARK_FILE: FileKind = FileKind {
    what: "landmark files",
    max_bytes: 1 << 20,
};

/// Where a number of an `N = V` landmark file (the iBUG point or the vertex) starts counting.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum LandmarkBase {
    /// The first is written `0` (C, Python; vertex indices in most files).
    #[default]
    Zero,
    /// The first is written `1` (the iBUG paper's numbering, MATLAB, OBJ numbering).
    One,
}

/// How the numbers of an `N = V` file count.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Numbering {
    /// Base of the iBUG numbers `N`; `None`: seen from the file (a point 68 and no point 0: from
    /// 1; a point 0: from 0).
    pub point: Option<LandmarkBase>,
    /// Base of the vertex indices `V`.
    pub vertex: LandmarkBase,
}

impl LandmarkBase {
    /// The base as a number (0 or 1).
    pub fn offset(self) -> u64 {
        match self {
            LandmarkBase::Zero => 0,
            LandmarkBase::One => 1,
        }
    }
}

impl std::str::FromStr for LandmarkBase {
    type Err = String;

    /// `0` or `1`.
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "0" => Ok(LandmarkBase::Zero),
            "1" => Ok(LandmarkBase::One),
            _ => Err(format!("`{s}`: the landmark base is 0 or 1")),
        }
    }
}

/// The mesh vertex of each iBUG point, where the file gives one.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Landmarks {
    /// `vertex[n]`: the vertex carrying iBUG point `n` (0-based), if known.
    pub vertex: [Option<u32>; IBUG_POINTS],
}

impl Landmarks {
    /// Landmarks from a full list of 68 vertices.
    pub fn from_list(list: [u32; IBUG_POINTS]) -> Self {
        Self {
            vertex: list.map(Some),
        }
    }

    /// The vertex of iBUG point `n`, if known.
    pub fn get(&self, n: usize) -> Option<u32> {
        self.vertex.get(n).copied().flatten()
    }

    /// How many points are known.
    pub fn count(&self) -> usize {
        self.vertex.iter().flatten().count()
    }
}

/// Reads a landmark file (capped at [`LANDMARK_FILE`]).
pub fn load_landmarks(path: &Path, base: Numbering) -> Result<Landmarks, RigNewError> {
    let text = mimic_types::limits::read_capped(path, &LANDMARK_FILE).map_err(|cause| {
        RigNewError::Read {
            path: path.to_path_buf(),
            cause,
        }
    })?;
    parse_landmarks(path, &text, base)
}

/// Parses landmark text; `path` names the file in errors. `base` applies to `N = V` lines only
/// (JSON forms are 0-based).
pub fn parse_landmarks(path: &Path, text: &str, base: Numbering) -> Result<Landmarks, RigNewError> {
    let err = |line: usize, message: String| RigNewError::Landmarks {
        path: path.to_path_buf(),
        line,
        message,
    };
    // JSON: an object, or a list (`[` then a number or `]`); a `[name]` line is a TOML table.
    let mut chars = text.trim_start().chars();
    let first = chars.next();
    let list = first == Some('[')
        && chars
            .find(|c| !c.is_whitespace())
            .is_some_and(|c| c.is_ascii_digit() || c == ']');
    if first == Some('{') || list {
        return parse_json(text).map_err(|(line, m)| err(line, m));
    }
    // (line, N, V) as written, from the lines outside any table or in `[landmark_mappings]`.
    let mut pairs: Vec<(usize, u64, u64)> = Vec::new();
    let mut in_mapping = true;
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let body = raw.split('#').next().unwrap_or("").trim();
        if body.is_empty() {
            continue;
        }
        if let Some(table) = body.strip_prefix('[') {
            let name = table.trim_end_matches(']').trim();
            in_mapping = name == "landmark_mappings";
            continue;
        }
        if !in_mapping {
            continue;
        }
        let Some((n, v)) = body.split_once('=') else {
            return Err(err(
                line,
                format!("`{body}` is not of the form `N = V` (iBUG point = vertex)"),
            ));
        };
        let number = |s: &str, what: &str| -> Result<u64, RigNewError> {
            let s = s.trim();
            s.parse()
                .map_err(|_| err(line, format!("{what} `{s}` is not a whole number")))
        };
        pairs.push((line, number(n, "iBUG point")?, number(v, "vertex")?));
    }
    if pairs.is_empty() {
        return Err(err(1, "no landmarks in the file".into()));
    }
    let point_base = match base.point {
        Some(b) => b,
        None => {
            let has = |k: u64| pairs.iter().any(|p| p.1 == k);
            match (has(0), has(IBUG_POINTS as u64)) {
                (true, _) => LandmarkBase::Zero,
                (false, true) => LandmarkBase::One,
                (false, false) => {
                    return Err(err(
                        pairs[0].0,
                        format!(
                            "the file gives neither iBUG point 0 nor point {IBUG_POINTS}, so where its numbers start is unknown: say --landmark-base 0 or 1"
                        ),
                    ));
                }
            }
        }
    };
    let mut vertex = [None; IBUG_POINTS];
    let mut lines_of = [0usize; IBUG_POINTS];
    for (line, n, v) in pairs {
        let shift = |got: u64, what: &str, b: LandmarkBase| {
            got.checked_sub(b.offset()).ok_or_else(|| {
                err(
                    line,
                    format!("{what} {got} is below its base {}", b.offset()),
                )
            })
        };
        let n = shift(n, "iBUG point", point_base)?;
        let v = shift(v, "vertex", base.vertex)?;
        set(&mut vertex, n, v).map_err(|m| err(line, m))?;
        if let Some(slot) = lines_of.get_mut(n as usize) {
            if *slot != 0 {
                return Err(err(
                    line,
                    format!(
                        "iBUG point {} is given twice (first on line {})",
                        n + point_base.offset(),
                        *slot
                    ),
                ));
            }
            *slot = line;
        }
    }
    Ok(Landmarks { vertex })
}

/// Stores vertex `v` for iBUG point `n` (both 0-based), checking their ranges.
fn set(vertex: &mut [Option<u32>; IBUG_POINTS], n: u64, v: u64) -> Result<(), String> {
    let slot = usize::try_from(n)
        .ok()
        .and_then(|n| vertex.get_mut(n))
        .ok_or_else(|| {
            format!(
                "iBUG point {n} (0-based) is outside 0..={}",
                IBUG_POINTS - 1
            )
        })?;
    let v = u32::try_from(v).map_err(|_| format!("vertex {v} is too large"))?;
    *slot = Some(v);
    Ok(())
}

/// The landmarks as the JSON object `--landmarks` reads: `{"0": 1225, "1": 1888, ...}`, keyed
/// by 0-based iBUG number, unknown points left out, one point a line.
pub fn landmarks_json(marks: &Landmarks) -> String {
    let lines: Vec<String> = marks
        .vertex
        .iter()
        .enumerate()
        .filter_map(|(k, v)| v.map(|v| format!("  \"{k}\": {v}")))
        .collect();
    format!("{{\n{}\n}}\n", lines.join(",\n"))
}

/// The JSON forms; errors carry a 1-based line.
fn parse_json(text: &str) -> Result<Landmarks, (usize, String)> {
    let value: serde_json::Value =
        serde_json::from_str(text).map_err(|e| (e.line().max(1), e.to_string()))?;
    let mut vertex = [None; IBUG_POINTS];
    let as_vertex = |what: String, v: &serde_json::Value| -> Result<u64, (usize, String)> {
        v.as_u64().ok_or_else(|| {
            (
                line_of_key(text, &what),
                format!("{what}: `{v}` is not a vertex index (a whole number >= 0)"),
            )
        })
    };
    match &value {
        serde_json::Value::Array(list) => {
            if list.len() != IBUG_POINTS {
                return Err((
                    1,
                    format!(
                        "a landmark list has {IBUG_POINTS} vertex indices (iBUG 0..=67 in order), this one {}; use an object {{\"0\": V, ...}} for a partial set",
                        list.len()
                    ),
                ));
            }
            for (n, v) in list.iter().enumerate() {
                let v = as_vertex(format!("entry {n}"), v)?;
                set(&mut vertex, n as u64, v).map_err(|m| (1, m))?;
            }
        }
        serde_json::Value::Object(map) => {
            for (key, v) in map {
                let line = line_of_key(text, &format!("\"{key}\""));
                let n: u64 = key.trim().parse().map_err(|_| {
                    (
                        line,
                        format!("key \"{key}\" is not an iBUG point number (0..=67)"),
                    )
                })?;
                let v = as_vertex(format!("\"{key}\""), v)?;
                set(&mut vertex, n, v).map_err(|m| (line, m))?;
            }
        }
        _ => {
            return Err((
                1,
                "a JSON landmark file is an object {\"0\": V, ...} or a list of 68 vertices".into(),
            ));
        }
    }
    let marks = Landmarks { vertex };
    if marks.count() == 0 {
        return Err((1, "no landmarks in the file".into()));
    }
    Ok(marks)
}

/// 1-based line of the first occurrence of `needle` in `text` (1 if absent).
fn line_of_key(text: &str, needle: &str) -> usize {
    text.find(needle)
        .map_or(1, |at| text[..at].matches('\n').count() + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str, point: LandmarkBase) -> Result<Landmarks, String> {
        let base = Numbering {
            point: Some(point),
            vertex: LandmarkBase::Zero,
        };
        parse_landmarks(Path::new("marks.txt"), text, base).map_err(|e| e.to_string())
    }

    /// iBUG numbers and vertices both from 1.
    fn one() -> Numbering {
        Numbering {
            point: Some(LandmarkBase::One),
            vertex: LandmarkBase::One,
        }
    }

    #[test]
    fn written_landmarks_read_back_the_same() {
        let mut marks = Landmarks {
            vertex: [None; IBUG_POINTS],
        };
        marks.vertex[0] = Some(1225);
        marks.vertex[30] = Some(7);
        marks.vertex[67] = Some(5966);
        let text = landmarks_json(&marks);
        assert!(text.starts_with("{\n  \"0\": 1225,\n"), "{text}");
        let back = parse_landmarks(Path::new("m.json"), &text, one()).unwrap();
        assert_eq!(back, marks);
    }

    #[test]
    fn three_forms_give_the_same_points() {
        let list: Vec<u32> = (0..68).map(|n| 1000 + n).collect();
        let json_list = serde_json::to_string(&list).unwrap();
        let a = parse(&json_list, LandmarkBase::Zero).unwrap();
        assert_eq!(a.count(), 68);
        assert_eq!(a.get(0), Some(1000));
        assert_eq!(a.get(67), Some(1067));
        let object = "{\n  \"0\": 1000,\n  \"67\": 1067\n}";
        let b = parse(object, LandmarkBase::Zero).unwrap();
        assert_eq!(
            (b.count(), b.get(0), b.get(67), b.get(5)),
            (2, Some(1000), Some(1067), None)
        );
        let lines = "# iBUG = vertex\n1 = 1001\n\n68 = 1068 # last\n";
        let c = parse_landmarks(Path::new("m.txt"), lines, one()).unwrap();
        assert_eq!(
            (c.count(), c.get(0), c.get(67)),
            (2, Some(1000), Some(1067))
        );
        let c0 = parse("0 = 1000\n67 = 1067\n", LandmarkBase::Zero).unwrap();
        assert_eq!(c0, b);
    }

    #[test]
    fn errors_name_file_and_line() {
        let e = parse("0 = 5\n1 = x\n", LandmarkBase::Zero).unwrap_err();
        assert_eq!(e, "marks.txt:2: vertex `x` is not a whole number");
        let e = parse("0 = 5\n\n0 = 6\n", LandmarkBase::Zero).unwrap_err();
        assert_eq!(
            e,
            "marks.txt:3: iBUG point 0 is given twice (first on line 1)"
        );
        let e = parse("0 = 5\n", LandmarkBase::One).unwrap_err();
        assert_eq!(e, "marks.txt:1: iBUG point 0 is below its base 1");
        let e = parse_landmarks(Path::new("marks.txt"), "3 = 5\n", Numbering::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("marks.txt:1: the file gives neither iBUG point 0 nor point 68"),
            "{e}"
        );
        let e = parse("68 = 5\n", LandmarkBase::Zero).unwrap_err();
        assert_eq!(e, "marks.txt:1: iBUG point 68 (0-based) is outside 0..=67");
        let e = parse("0 5\n", LandmarkBase::Zero).unwrap_err();
        assert!(
            e.starts_with("marks.txt:1: `0 5` is not of the form"),
            "{e}"
        );
        let e = parse("{\n\"0\": 1,\n\"eye\": 2\n}", LandmarkBase::Zero).unwrap_err();
        assert_eq!(
            e,
            "marks.txt:3: key \"eye\" is not an iBUG point number (0..=67)"
        );
        let e = parse("{\n\"0\": 1,\n\"3\": -2\n}", LandmarkBase::Zero).unwrap_err();
        assert!(
            e.starts_with("marks.txt:3: \"3\": `-2` is not a vertex index"),
            "{e}"
        );
        let e = parse("[1, 2, 3]", LandmarkBase::Zero).unwrap_err();
        assert!(e.contains("a landmark list has 68 vertex indices"), "{e}");
        let e = parse("{\n\"0\": 1,\n", LandmarkBase::Zero).unwrap_err();
        assert!(e.starts_with("marks.txt:3: "), "{e}");
        assert!(parse("# nothing\n", LandmarkBase::Zero).is_err());
    }

    /// eos's `share/ibug_to_sfm.txt` (Apache-2.0, github.com/patrikhuber/eos), abridged: a TOML
    /// file, iBUG numbers from 1, SFM vertex indices from 0, a contour table after the mapping.
    const EOS: &str = "# Mapping from the 68-point ibug annotations to the Surrey Face Model (SFM) mesh vertex indices.
# This file uses TOML syntax (https://github.com/toml-lang/toml).

# Mappings from input landmarks (ibug, lhs) to output landmarks (SFM, rhs):
[landmark_mappings]
            # 1 to 8 are the right contour landmarks
 9 =    33  # chin bottom
            # 10 to 17 are the left contour landmarks
18 =   225  # right eyebrow outer-corner (18)
            # 61 not defined - would be right inner corner of the mouth
68 =   404  # lower lip right top outer


# Definitions of which 2D landmarks make up the right and left face contours:
[contour_landmarks]
right = [  1,
           2,
           8
        ]
left  = [ 10,
          17
        ]
";

    #[test]
    fn eos_toml_files_read_with_points_from_one_and_vertices_from_zero() {
        let m = parse_landmarks(Path::new("ibug_to_sfm.txt"), EOS, Numbering::default()).unwrap();
        assert_eq!(
            (m.count(), m.get(8), m.get(17), m.get(67)),
            (3, Some(33), Some(225), Some(404))
        );
        // Told explicitly, the same; vertices from 1 shift the vertices only.
        let told = Numbering {
            point: Some(LandmarkBase::One),
            vertex: LandmarkBase::Zero,
        };
        assert_eq!(parse_landmarks(Path::new("f"), EOS, told).unwrap(), m);
        let m1 = parse_landmarks(Path::new("f"), EOS, one()).unwrap();
        assert_eq!((m1.get(8), m1.get(67)), (Some(32), Some(403)));
        // Told the points count from 0, point 68 is out of range, and the error says where.
        let zero = Numbering {
            point: Some(LandmarkBase::Zero),
            vertex: LandmarkBase::Zero,
        };
        let e = parse_landmarks(Path::new("f"), EOS, zero)
            .unwrap_err()
            .to_string();
        assert_eq!(e, "f:11: iBUG point 68 (0-based) is outside 0..=67");
        // A plain file with point 0 is read from 0 without being told.
        let z = parse_landmarks(Path::new("f"), "0 = 7\n67 = 9\n", Numbering::default()).unwrap();
        assert_eq!((z.get(0), z.get(67)), (Some(7), Some(9)));
    }
}
