//! CSV files of named columns: a header row of names, then one row per frame, as face-capture
//! apps export weights (ARKit and the like) and `mimic replay --weights` writes them.

use std::path::{Path, PathBuf};

/// A CSV of named columns, split into trimmed fields (no quoting: names and numbers only).
#[derive(Clone, Debug, PartialEq)]
pub struct NamedCsv {
    /// Column names from the first line.
    pub header: Vec<String>,
    /// Non-blank rows after the header, in file order.
    pub rows: Vec<CsvRow>,
}

/// One row of a [`NamedCsv`].
#[derive(Clone, Debug, PartialEq)]
pub struct CsvRow {
    /// 1-based line number in the file.
    pub line: usize,
    /// Trimmed fields, as many as the line has.
    pub fields: Vec<String>,
}

impl CsvRow {
    /// Field `column`, or `""` when the row is shorter.
    pub fn field(&self, column: usize) -> &str {
        self.fields.get(column).map_or("", String::as_str)
    }
}

/// A named-column CSV that cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum CsvError {
    /// The file cannot be read.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The file has no header line.
    #[error("{}: empty file", path.display())]
    Empty {
        /// The file.
        path: PathBuf,
    },
}

/// Parses named-column CSV text.
pub fn parse_named_csv(text: &str) -> Option<NamedCsv> {
    let split = |l: &str| {
        l.split(',')
            .map(|f| f.trim().to_string())
            .collect::<Vec<_>>()
    };
    let mut lines = text.lines();
    let header = split(lines.next()?);
    let rows = lines
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| CsvRow {
            line: i + 2,
            fields: split(l),
        })
        .collect();
    Some(NamedCsv { header, rows })
}

/// Reads a named-column CSV file.
pub fn read_named_csv(path: &Path) -> Result<NamedCsv, CsvError> {
    let text = mimic_types::limits::read_capped(path, &mimic_types::limits::WEIGHTS_FILE).map_err(
        |e| CsvError::Io {
            path: path.to_path_buf(),
            source: e.into(),
        },
    )?;
    parse_named_csv(&text).ok_or_else(|| CsvError::Empty {
        path: path.to_path_buf(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_rows_and_line_numbers() {
        let csv = parse_named_csv("t_us, jawOpen\n0,0.5\n\n33333 , 1,extra\n").unwrap();
        assert_eq!(csv.header, vec!["t_us", "jawOpen"]);
        assert_eq!(csv.rows.len(), 2);
        assert_eq!(csv.rows[0].line, 2);
        assert_eq!(csv.rows[1].line, 4);
        assert_eq!(csv.rows[1].field(0), "33333");
        assert_eq!(csv.rows[1].field(2), "extra");
        assert_eq!(csv.rows[0].field(5), "");
        assert!(parse_named_csv("").is_none());
    }
}
