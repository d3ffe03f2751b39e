//! Weights sessions from a CSV of named weights (`mimic send --weights`): the CSV's rows as
//! weight frames, and the paced sending of weight frames that a Live Link Face take's sender
//! (`take.rs`) shares.

use super::connection::{TcpSent, connect};
use super::error::SendError;
use super::options::{SendOptions, weights_hello};
use super::pace::Pacer;
use serde_json::Value;
use std::io::Write;
use std::net::TcpStream;
use std::path::Path;

/// Columns of a weights CSV that are not weights.
const NOT_WEIGHTS: [&str; 6] = [
    "frame",
    "t_us",
    "status",
    "label",
    "timecode",
    "blendshapecount",
];

/// The weight frames of a weights CSV: each row's time and its `weights` object.
pub(super) type WeightRows = Vec<(i64, serde_json::Map<String, Value>)>;

/// Weight frames (`t_us` and the `weights` object of a frame line) of a weights CSV.
fn weight_lines(csv: &Path, rate: f64) -> Result<WeightRows, SendError> {
    let table = mimic_capture::named_csv::read_named_csv(csv)?;
    let header: Vec<&str> = table.header.iter().map(String::as_str).collect();
    let time_col = header.iter().position(|h| h.eq_ignore_ascii_case("t_us"));
    let sent: Vec<usize> = (0..header.len())
        .filter(|&c| {
            !NOT_WEIGHTS
                .iter()
                .any(|n| header[c].eq_ignore_ascii_case(n))
        })
        .collect();
    if sent.is_empty() {
        return Err(SendError::NoWeights(csv.to_path_buf()));
    }
    if !(rate > 0.0 && rate.is_finite()) {
        return Err(SendError::Rate);
    }
    let mut out = Vec::new();
    for row in &table.rows {
        let at = |c: usize| row.field(c);
        let t_us = match time_col {
            Some(c) => at(c).parse::<i64>().map_err(|source| SendError::Time {
                path: csv.to_path_buf(),
                line: row.line,
                text: at(c).to_string(),
                source,
            })?,
            None => (out.len() as f64 * 1e6 / rate).round() as i64,
        };
        let mut weights = serde_json::Map::new();
        for &c in &sent {
            let v: f64 = at(c)
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite())
                .ok_or_else(|| SendError::Weight {
                    path: csv.to_path_buf(),
                    line: row.line,
                    column: header[c].to_string(),
                    text: at(c).to_string(),
                })?;
            weights.insert(header[c].to_string(), Value::from(v));
        }
        out.push((t_us, weights));
    }
    Ok(out)
}

/// A weights session fed from a CSV of named weights (`t_us` gives the times, else frames are
/// `1 / rate` apart), at its pace.
pub fn send_weights(csv: &Path, o: &SendOptions) -> Result<TcpSent, SendError> {
    let lines = weight_lines(csv, o.rate)?;
    let hello = weights_hello(o, "mimic send".into(), o.rate);
    let mut conn = connect(&o.to, o.on_reply, None)?;
    conn.stream.write_all(format!("{hello}\n").as_bytes())?;
    let pace = Pacer::new(o.speed, o.fast);
    let first_t = lines.first().map_or(0, |(t, _)| *t);
    let last_t = lines.last().map_or(0, |(t, _)| *t);
    // `--loop` shifts each pass by one frame interval: the mean of the CSV's, else 1 / --rate.
    let gap = if lines.len() >= 2 {
        ((last_t - first_t) / (lines.len() as i64 - 1)).max(1)
    } else {
        (1e6 / o.rate).round().max(1.0) as i64
    };
    let (sent, _, write_failed) =
        send_weight_frames(&mut conn.stream, &pace, o, &lines, first_t, gap);
    let bye = conn.close()?;
    Ok(TcpSent {
        sent,
        bye,
        write_failed,
    })
}

/// Sends weight frames (`t_us`, `weights`) paced from `origin_us`, again and again when
/// looping (each pass's times shifted past the previous pass by `gap_us`, so none is late), up
/// to `max_frames`; returns the frames sent, the last frame's due time (s) and the write error
/// that stopped it, if any.
pub(super) fn send_weight_frames(
    stream: &mut TcpStream,
    pace: &Pacer,
    o: &SendOptions,
    frames: &[(i64, serde_json::Map<String, Value>)],
    origin_us: i64,
    gap_us: i64,
) -> (usize, f64, Option<SendError>) {
    let span = match (frames.first(), frames.last()) {
        (Some(a), Some(b)) => b.0 - a.0,
        _ => 0,
    };
    let (mut sent, mut last_due, mut offset) = (0usize, 0.0f64, 0i64);
    loop {
        for (t, weights) in frames {
            let t_us = t.saturating_add(offset);
            last_due = pace.wait(t_us.saturating_sub(origin_us));
            let mut line = serde_json::json!({"t_us": t_us, "weights": weights}).to_string();
            line.push('\n');
            if let Err(e) = stream.write_all(line.as_bytes()) {
                return (sent, last_due, Some(SendError::WeightFrame(e)));
            }
            sent += 1;
            if o.max_frames.is_some_and(|m| sent >= m) {
                return (sent, last_due, None);
            }
        }
        if !o.looping || frames.is_empty() {
            return (sent, last_due, None);
        }
        offset = offset.saturating_add(span + gap_us);
    }
}
