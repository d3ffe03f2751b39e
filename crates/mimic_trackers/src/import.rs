//! A `.osf` capture as a v1 `openseeface68` recording (`mimic import openseeface`): one face id's
//! datagrams in capture order, timed by the datagrams' own timestamps (the tracker's clock when it
//! read each frame) relative to the first.

use crate::error::TrackerError;
use crate::openseeface::{OsfFace, decode_packet, read_capture};
use crate::osf_frames::{LAYOUT, POINT_COUNT, to_frame};
use mimic_capture::{Imported, RecordedFrame, RecordingHeader};
use std::path::Path;

/// An imported capture and what was left out.
#[derive(Clone, Debug, PartialEq)]
pub struct OsfImport {
    /// The recording.
    pub imported: Imported,
    /// The face id imported.
    pub face_id: i32,
    /// Datagrams in the capture.
    pub datagrams: usize,
    /// Faces of other ids, not imported.
    pub other_faces: usize,
}

/// Frame-times CSV files (`megamind_frames.csv` is 3.5 KB).
pub const FRAME_TIMES_FILE: mimic_types::limits::FileKind = mimic_types::limits::FileKind {
    what: "frame-times CSV files",
    max_bytes: 64 << 20,
};

/// Frame times from a CSV of named columns: `packet` (0-based datagram number) and `t_us` or
/// `video_t_us` (microseconds), e.g. `megamind_frames.csv`: the video time behind each datagram,
/// for captures of a video file, where OpenSeeFace's own timestamps follow its processing speed.
pub fn read_frame_times(
    path: &Path,
) -> Result<std::collections::HashMap<usize, i64>, TrackerError> {
    let text = mimic_types::limits::read_capped(path, &FRAME_TIMES_FILE).map_err(|source| {
        TrackerError::Io {
            path: path.to_path_buf(),
            source,
        }
    })?;
    let err = |line: usize, reason: String| TrackerError::Line {
        path: path.to_path_buf(),
        line,
        reason,
    };
    let csv = mimic_capture::named_csv::parse_named_csv(&text)
        .ok_or_else(|| err(1, "empty file".into()))?;
    let col = |names: &[&str]| {
        csv.header
            .iter()
            .position(|h| names.iter().any(|n| h.eq_ignore_ascii_case(n)))
    };
    let packet = col(&["packet"]).ok_or_else(|| err(1, "no `packet` column".into()))?;
    let time = col(&["t_us", "video_t_us"])
        .ok_or_else(|| err(1, "no `t_us` or `video_t_us` column".into()))?;
    let mut times = std::collections::HashMap::new();
    for row in &csv.rows {
        let p: usize = row.field(packet).parse().map_err(|_| {
            err(
                row.line,
                format!("packet `{}` is not a number", row.field(packet)),
            )
        })?;
        let t: i64 = row.field(time).parse().map_err(|_| {
            err(
                row.line,
                format!("time `{}` is not an integer", row.field(time)),
            )
        })?;
        times.insert(p, t);
    }
    Ok(times)
}

/// Imports face `face` (default: the first face id of the capture) of a `.osf` capture, timed by
/// the datagrams' timestamps or, with `times`, by [`read_frame_times`]' times per datagram.
pub fn import_osf(
    path: &Path,
    face: Option<i32>,
    source: Option<&str>,
    times: Option<&std::collections::HashMap<usize, i64>>,
) -> Result<OsfImport, TrackerError> {
    let records = read_capture(path)?;
    let mut faces: Vec<(usize, u64, OsfFace)> = Vec::new();
    for (i, r) in records.iter().enumerate() {
        let decoded = decode_packet(&r.datagram).map_err(|e| TrackerError::Record {
            path: path.to_path_buf(),
            record: i,
            file_offset: r.file_offset,
            reason: format!("datagram {e}"),
        })?;
        faces.extend(decoded.into_iter().map(|f| (i, r.file_offset, f)));
    }
    let face_id = face
        .or_else(|| faces.first().map(|f| f.2.face_id))
        .unwrap_or(0);
    let total = faces.len();
    let mut frames = Vec::new();
    let mut first_t = None;
    let mut prev_us = i64::MIN;
    for (i, offset, f) in faces.iter().filter(|f| f.2.face_id == face_id) {
        let t = match times {
            None => f.timestamp,
            Some(m) => match m.get(i) {
                Some(&us) => us as f64 * 1e-6,
                None => {
                    return Err(TrackerError::Record {
                        path: path.to_path_buf(),
                        record: *i,
                        file_offset: *offset,
                        reason: "the frame times list no time for this datagram".into(),
                    });
                }
            },
        };
        let t0 = *first_t.get_or_insert(t);
        let t_us = ((t - t0) * 1e6).round();
        if !t_us.is_finite() || t_us.abs() > 1e15 || (t_us as i64) <= prev_us {
            return Err(TrackerError::Record {
                path: path.to_path_buf(),
                record: *i,
                file_offset: *offset,
                reason: format!("face {face_id}: time {t} s does not come after the previous one"),
            });
        }
        prev_us = t_us as i64;
        frames.push(RecordedFrame::unlabelled(to_frame(f, prev_us)));
    }
    if frames.is_empty() {
        return Err(TrackerError::Record {
            path: path.to_path_buf(),
            record: 0,
            file_offset: 0,
            reason: format!("no datagram holds face {face_id}"),
        });
    }
    let rate_hz = mimic_capture::mean_rate_hz(&frames).unwrap_or(30.0);
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let default_source = format!("OpenSeeFace UDP capture ({name}), face {face_id}");
    let mut header = RecordingHeader::new(
        LAYOUT,
        source.unwrap_or(&default_source),
        rate_hz,
        Some(POINT_COUNT),
    );
    header.description = Some(
        "OpenSeeFace's pose-free 3D points 0-67 (x, -y, -z as packed) turned to the recording \
         convention, (-x, -y, -z) * 0.15/0.91 m, and placed with the head pose (the quaternion \
         depth-mirrored to a proper in-front pose, refined on the 2D landmarks)"
            .to_string()
            + if times.is_some() {
                "; times from a frame-times CSV"
            } else {
                "; times from the datagrams' timestamps"
            },
    );
    let other_faces = total - frames.len();
    Ok(OsfImport {
        imported: Imported { header, frames },
        face_id,
        datagrams: records.len(),
        other_faces,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::openseeface::{encode_packet, encode_record};

    #[test]
    fn captures_import_and_bad_ones_name_the_record() {
        let dir =
            std::env::temp_dir().join(format!("mimic-trackers-import-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let face = |t: f64, id: i32| OsfFace {
            timestamp: t,
            face_id: id,
            success: 1,
            ..OsfFace::default()
        };
        let mut cap = Vec::new();
        encode_record(0, &encode_packet(&[face(10.0, 1), face(10.0, 2)]), &mut cap);
        encode_record(40, &encode_packet(&[face(10.04, 1)]), &mut cap);
        let path = dir.join("two.osf");
        std::fs::write(&path, &cap).unwrap();
        let got = import_osf(&path, None, None, None).unwrap();
        assert_eq!((got.face_id, got.datagrams, got.other_faces), (1, 2, 1));
        let times: Vec<i64> = got
            .imported
            .frames
            .iter()
            .map(|f| f.frame.timestamp_us)
            .collect();
        assert_eq!(times, vec![0, 40_000]);
        assert_eq!(got.imported.header.layout, LAYOUT);
        // A datagram of the wrong size, and one going back in time.
        let mut bad = cap.clone();
        encode_record(80, &[0u8; 100], &mut bad);
        std::fs::write(&path, &bad).unwrap();
        let e = import_osf(&path, None, None, None).unwrap_err().to_string();
        assert!(e.contains("two.osf: record 2 (file offset"), "{e}");
        let mut back = cap;
        encode_record(80, &encode_packet(&[face(9.0, 1)]), &mut back);
        std::fs::write(&path, &back).unwrap();
        let e = import_osf(&path, None, None, None).unwrap_err().to_string();
        assert!(
            e.contains("record 2") && e.contains("does not come after"),
            "{e}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
