//! The CANDIDE-3 face model parsed from its `.wfm` file (Ahlberg 2001, Appendix D).

use glam::DVec3;

/// Number of CANDIDE-3 animation-unit vectors (AUV0 .. AUV10), the first units of the file.
pub const AUV_COUNT: usize = 11;

/// A `.wfm` file that cannot be read as a CANDIDE-3 model.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ModelError {
    /// A section the model needs is missing.
    #[error("the model has no `{0}` section")]
    MissingSection(&'static str),
    /// A line does not hold what its section needs.
    #[error("line {line}: {reason}")]
    Line {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        reason: String,
    },
}

/// One animation or shape unit: a named sparse displacement field over the vertices.
#[derive(Clone, Debug, PartialEq)]
pub struct Unit {
    /// The comment line naming the unit, e.g. `AUV11 Jaw drop (AU26/27)`.
    pub name: String,
    /// Displaced vertices and their displacement at coefficient 1 (model units).
    pub deltas: Vec<(usize, DVec3)>,
}

/// The CANDIDE-3 wireframe model: neutral vertices, triangles, animation and shape units.
#[derive(Clone, Debug, PartialEq)]
pub struct Candide3 {
    /// Neutral vertex positions (model units; x = subject's left, y up, z out of the face).
    pub vertices: Vec<DVec3>,
    /// Triangles (0-based vertex indices, winding as in the file).
    pub faces: Vec<[usize; 3]>,
    /// Animation units in file order: the 11 AUVs, then the MPEG-4 FAP units.
    pub animation_units: Vec<Unit>,
    /// Shape units in file order.
    pub shape_units: Vec<Unit>,
}

/// Non-empty, non-comment lines with their 1-based numbers and the comments just before them.
struct Lines<'a> {
    inner: std::iter::Enumerate<std::str::Lines<'a>>,
    comments: Vec<&'a str>,
}

impl<'a> Lines<'a> {
    /// Next data line: (line number, text, comments since the previous data line).
    fn next_data(&mut self) -> Option<(usize, &'a str, Vec<&'a str>)> {
        for (i, raw) in self.inner.by_ref() {
            let l = raw.trim();
            if l.is_empty() {
                continue;
            }
            if let Some(c) = l.strip_prefix('#') {
                self.comments.push(c.trim());
                continue;
            }
            return Some((i + 1, l, std::mem::take(&mut self.comments)));
        }
        None
    }
}

fn line_error(line: usize, reason: impl Into<String>) -> ModelError {
    ModelError::Line {
        line,
        reason: reason.into(),
    }
}

fn numbers<T: std::str::FromStr>(
    line: usize,
    text: &str,
    want: usize,
) -> Result<Vec<T>, ModelError> {
    let v: Vec<T> = text
        .split_whitespace()
        .map(|t| t.parse::<T>())
        .collect::<Result<_, _>>()
        .map_err(|_| line_error(line, format!("`{text}` is not {want} numbers")))?;
    if v.len() != want {
        return Err(line_error(line, format!("`{text}` is not {want} numbers")));
    }
    Ok(v)
}

fn count(
    lines: &mut Lines<'_>,
    section: &'static str,
) -> Result<(usize, usize, Vec<String>), ModelError> {
    let (n, text, comments) = lines
        .next_data()
        .ok_or(ModelError::MissingSection(section))?;
    let c = numbers::<usize>(n, text, 1)?[0];
    Ok((n, c, comments.iter().map(|s| s.to_string()).collect()))
}

impl Candide3 {
    /// Parses the text of a `.wfm` file (read it as lossy UTF-8: the header has a non-UTF-8 byte).
    pub fn parse(text: &str) -> Result<Candide3, ModelError> {
        let mut lines = Lines {
            inner: text.lines().enumerate(),
            comments: Vec::new(),
        };
        let (_, nv, _) = count(&mut lines, "VERTEX LIST")?;
        let mut vertices = Vec::with_capacity(nv);
        for _ in 0..nv {
            let (n, t, _) = lines
                .next_data()
                .ok_or(ModelError::MissingSection("VERTEX LIST"))?;
            let v = numbers::<f64>(n, t, 3)?;
            vertices.push(DVec3::new(v[0], v[1], v[2]));
        }
        let (_, nf, _) = count(&mut lines, "FACE LIST")?;
        let mut faces = Vec::with_capacity(nf);
        for _ in 0..nf {
            let (n, t, _) = lines
                .next_data()
                .ok_or(ModelError::MissingSection("FACE LIST"))?;
            let f = numbers::<usize>(n, t, 3)?;
            if f.iter().any(|&i| i >= nv) {
                return Err(line_error(n, format!("face `{t}` names a vertex >= {nv}")));
            }
            faces.push([f[0], f[1], f[2]]);
        }
        let animation_units = units(&mut lines, "ANIMATION UNITS LIST", nv)?;
        let shape_units = units(&mut lines, "SHAPE UNITS LIST", nv)?;
        if animation_units.len() < AUV_COUNT {
            return Err(ModelError::MissingSection("ANIMATION UNITS LIST"));
        }
        Ok(Candide3 {
            vertices,
            faces,
            animation_units,
            shape_units,
        })
    }

    /// The 11 animation-unit vectors AUV0 .. AUV10 (in file order: AUV0, AUV11, AUV2, ...).
    pub fn auvs(&self) -> &[Unit] {
        &self.animation_units[..AUV_COUNT]
    }
}

fn units(lines: &mut Lines<'_>, section: &'static str, nv: usize) -> Result<Vec<Unit>, ModelError> {
    let (_, nu, _) = count(lines, section)?;
    let mut out = Vec::with_capacity(nu);
    for _ in 0..nu {
        let (n, k, comments) = count(lines, section)?;
        let name = comments.first().cloned().unwrap_or_default();
        let mut deltas = Vec::with_capacity(k);
        for _ in 0..k {
            let (m, t, _) = lines
                .next_data()
                .ok_or(ModelError::MissingSection(section))?;
            let parts: Vec<&str> = t.split_whitespace().collect();
            if parts.len() != 4 {
                return Err(line_error(m, format!("`{t}` is not `vertex dx dy dz`")));
            }
            let v: usize = parts[0].parse().ok().filter(|&v| v < nv).ok_or_else(|| {
                line_error(m, format!("`{}` is not a vertex index < {nv}", parts[0]))
            })?;
            let d = numbers::<f64>(m, &parts[1..].join(" "), 3)?;
            deltas.push((v, DVec3::new(d[0], d[1], d[2])));
        }
        let _ = n;
        out.push(Unit { name, deltas });
    }
    Ok(out)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// The shipped model.
    pub(crate) fn model() -> Candide3 {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../configs/models/candide3/candide3.wfm"
        );
        let bytes = std::fs::read(path).unwrap();
        Candide3::parse(&String::from_utf8_lossy(&bytes)).unwrap()
    }

    #[test]
    fn shipped_model_has_the_documented_counts() {
        // Counts from the file's own section headers and configs/models/candide3/SOURCE.md.
        let m = model();
        assert_eq!(m.vertices.len(), 113);
        assert_eq!(m.faces.len(), 184);
        assert_eq!(m.animation_units.len(), 65);
        assert_eq!(m.shape_units.len(), 14);
        assert!(
            m.auvs()[1].name.starts_with("AUV11 Jaw drop"),
            "{}",
            m.auvs()[1].name
        );
        assert_eq!(m.auvs()[1].deltas.len(), 12);
        // AUV11 moves vertex 8 (lower lip middle) by (0, -0.26, -0.05): the file's second unit, second row.
        assert!(
            m.auvs()[1]
                .deltas
                .contains(&(8, DVec3::new(0.0, -0.26, -0.05)))
        );
        assert_eq!(m.shape_units[0].name, "Head height");
        assert_eq!(m.vertices[0], DVec3::new(0.0, 1.061, -0.371));
    }

    #[test]
    fn truncated_file_is_an_error() {
        assert!(matches!(
            Candide3::parse("# VERTEX LIST:\n2\n0 0 0\n"),
            Err(ModelError::MissingSection("VERTEX LIST"))
        ));
        assert!(matches!(
            Candide3::parse("3\n0 0 0\n1 x 0\n"),
            Err(ModelError::Line { line: 3, .. })
        ));
    }
}
