//! mimic's weights CSV (`frame,t_us,status,label` and ARKit-named columns, as `mimic import
//! audio` writes) read as a take ([`parse_weights_take`]), so that `mimic replay W.weights.csv
//! --rig R` plays it through the name map like a Live Link Face take. A weights CSV is read so
//! when it has a `t_us` column and every other column but `frame`, `status` and `label` is a
//! Live Link curve (ARKit's names in any case, [`is_weights_take_header`]).

use crate::error::TrackerError;
use crate::livelink::{CURVES, curve_index};
use crate::take::{
    Take, TakeRow, WRITTEN_TIMECODE_RATE, curve_columns, curve_value, is_take_header,
};
use std::path::Path;

/// Columns of a weights CSV that are not weights.
const META: [&str; 4] = ["frame", "t_us", "status", "label"];

/// True when `header` is a weights CSV of ARKit curves (module docs).
pub fn is_weights_take_header(header: &str) -> bool {
    let cols: Vec<&str> = header.trim_end().split(',').map(str::trim).collect();
    let meta = |c: &str| META.iter().any(|m| m.eq_ignore_ascii_case(c));
    cols.iter().any(|c| c.eq_ignore_ascii_case("t_us"))
        && cols.iter().any(|c| !meta(c))
        && cols.iter().all(|c| meta(c) || curve_index(c).is_some())
}

/// Whether the file at `path` is a Live Link Face take or a weights CSV of ARKit curves (its
/// first line, up to 64 KiB).
pub fn is_replayable_take(path: &Path) -> Result<bool, TrackerError> {
    Ok(crate::take::first_line(path)?
        .is_some_and(|l| is_take_header(&l) || is_weights_take_header(&l)))
}

/// Parses a weights CSV of ARKit curves as a take: times from `t_us` (from the first row's),
/// rows with `status` other than 1 untracked.
pub fn parse_weights_take(text: &str, path: &Path) -> Result<Take, TrackerError> {
    let err = |line: usize, reason: String| TrackerError::Line {
        path: path.to_path_buf(),
        line,
        reason,
    };
    let mut lines = text.lines().enumerate();
    let header = lines.next().map_or("", |(_, l)| l);
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let find = |n: &str| names.iter().position(|c| c.eq_ignore_ascii_case(n));
    let t_col = find("t_us").ok_or_else(|| err(1, "no `t_us` column".into()))?;
    let status = find("status");
    let columns = curve_columns(&names).map_err(|r| err(1, r))?;
    let mut rows: Vec<TakeRow> = Vec::new();
    let mut t0 = None;
    for (i, l) in lines {
        if l.trim().is_empty() {
            continue;
        }
        let line = i + 1;
        let fields: Vec<&str> = l.split(',').map(str::trim).collect();
        let field = |c: usize| {
            fields.get(c).copied().ok_or_else(|| {
                err(
                    line,
                    format!("{} fields; field {} is missing", fields.len(), c + 1),
                )
            })
        };
        let t_text = field(t_col)?;
        let t: i64 = t_text
            .parse()
            .map_err(|_| err(line, format!("t_us `{t_text}` is not a whole number")))?;
        let t0 = *t0.get_or_insert(t);
        if let Some(prev) = rows.last().filter(|r| t - t0 < r.t_us) {
            return Err(err(
                line,
                format!("t_us goes back from {} µs", prev.t_us + t0),
            ));
        }
        let tracked = match status {
            Some(c) => field(c)? == "1",
            None => true,
        };
        let mut curves = [0.0f32; CURVES];
        for (k, col) in columns.iter().enumerate() {
            let Some(c) = *col else { continue };
            let v = field(c)?;
            curves[k] = curve_value(v, names[c]).map_err(|r| err(line, r))?;
        }
        rows.push(TakeRow {
            line,
            t_us: t - t0,
            tracked,
            curves,
        });
    }
    Ok(Take {
        rows,
        timecode_rate: WRITTEN_TIMECODE_RATE,
        present: columns.map(|c| c.is_some()),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::livelink::curve_index;

    #[test]
    fn an_arkit_weights_csv_reads_as_a_take_and_other_csvs_do_not() {
        assert!(is_weights_take_header(
            "frame,t_us,status,label,jawOpen,mouthPressLeft\n"
        ));
        assert!(!is_weights_take_header(
            "frame,t_us,status,label,chin_down\n"
        ));
        assert!(!is_weights_take_header("frame,t_us,status,label\n"));
        assert!(!is_weights_take_header("Timecode,BlendShapeCount,JawOpen"));
        let text = "frame,t_us,status,label,jawOpen,mouthClose\n0,1000,1,SIL,0.0000,0.0000\n\
                    1,17667,1,AA,0.5000,0.1000\n2,34333,2,,0.2,0\n";
        let t = parse_weights_take(text, Path::new("w.csv")).unwrap();
        assert_eq!(t.rows.len(), 3);
        assert_eq!(t.rows[1].t_us, 16_667);
        let jaw = curve_index("jawOpen").unwrap();
        assert_eq!(t.rows[1].curves[jaw], 0.5);
        assert!(t.rows[1].tracked && !t.rows[2].tracked);
        assert!(t.present[jaw] && t.present[curve_index("mouthClose").unwrap()]);
        let e = parse_weights_take("t_us,jawOpen\n5,0.1\n4,0.1\n", Path::new("w.csv"));
        assert!(
            e.unwrap_err()
                .to_string()
                .contains("w.csv:3: t_us goes back")
        );
    }
}
