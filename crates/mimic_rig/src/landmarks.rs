//! Landmark files: which mesh vertex carries each of the 68 iBUG points.
//!
//! Three forms are read (docs/rigging.md): a JSON object `{"0": 1225, "1": 1888, ...}` keyed by
//! 0-based iBUG numbers (points the mesh lacks are left out), a JSON list of 68 vertex indices
//! (ICT-FaceKit's `idx_to_landmark_verts`), or text lines `N = V` (blank lines and `#` comments
//! skipped), whose numbers count from [`LandmarkBase`].

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

/// Where the numbers of an `N = V` landmark file start counting.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum LandmarkBase {
    /// iBUG point 0 is written `0`, vertex 0 is `0` (C, Python).
    #[default]
    Zero,
    /// iBUG point 0 is written `1`, vertex 0 is `1` (MATLAB, OBJ numbering).
    One,
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
pub fn load_landmarks(path: &Path, base: LandmarkBase) -> Result<Landmarks, RigNewError> {
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
pub fn parse_landmarks(
    path: &Path,
    text: &str,
    base: LandmarkBase,
) -> Result<Landmarks, RigNewError> {
    let err = |line: usize, message: String| RigNewError::Landmarks {
        path: path.to_path_buf(),
        line,
        message,
    };
    let first = text.trim_start().chars().next();
    if matches!(first, Some('{') | Some('[')) {
        return parse_json(text).map_err(|(line, m)| err(line, m));
    }
    let mut vertex = [None; IBUG_POINTS];
    let mut lines_of = [0usize; IBUG_POINTS];
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let body = raw.split('#').next().unwrap_or("").trim();
        if body.is_empty() {
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
            let got: u64 = s
                .parse()
                .map_err(|_| err(line, format!("{what} `{s}` is not a whole number")))?;
            got.checked_sub(base.offset()).ok_or_else(|| {
                err(
                    line,
                    format!("{what} {got} is below the landmark base {}", base.offset()),
                )
            })
        };
        let n = number(n, "iBUG point")?;
        let v = number(v, "vertex")?;
        set(&mut vertex, n, v).map_err(|m| err(line, m))?;
        if let Some(slot) = lines_of.get_mut(n as usize) {
            if *slot != 0 {
                return Err(err(
                    line,
                    format!(
                        "iBUG point {} is given twice (first on line {})",
                        n + base.offset(),
                        *slot
                    ),
                ));
            }
            *slot = line;
        }
    }
    let marks = Landmarks { vertex };
    if marks.count() == 0 {
        return Err(err(1, "no landmarks in the file".into()));
    }
    Ok(marks)
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

    fn parse(text: &str, base: LandmarkBase) -> Result<Landmarks, String> {
        parse_landmarks(Path::new("marks.txt"), text, base).map_err(|e| e.to_string())
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
        let back = parse_landmarks(Path::new("m.json"), &text, LandmarkBase::One).unwrap();
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
        let c = parse(lines, LandmarkBase::One).unwrap();
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
        assert_eq!(e, "marks.txt:1: iBUG point 0 is below the landmark base 1");
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
}
