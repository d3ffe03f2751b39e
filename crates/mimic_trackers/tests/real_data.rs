//! The parsers on the real captures in `tests/data` (OpenSeeFace's `megamind.osf`, the two Live
//! Link Face takes, copied from the shared data), and the shipped name map. Expected values are
//! those that `tests/data/*/SOURCE.md` states, found there by other tools.

#![allow(
    clippy::unwrap_used,
    reason = "a test: a failed unwrap is the failure report"
)]

use mimic_trackers::livelink::{BLENDSHAPES, CURVE_NAMES, curve_index};
use mimic_trackers::namemap::NameMap;
use mimic_trackers::openseeface::{FACE_BYTES, decode_packet, encode_packet, read_capture};
use mimic_trackers::osf_frames::to_frame;
use mimic_trackers::take::read_take;
use std::path::{Path, PathBuf};

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// `tests/data` of the repository (copies of the shared data's captures, with SOURCE.md and licences).
fn shared_data() -> Option<PathBuf> {
    let found = ["tests/data"]
        .iter()
        .map(|p| repo_root().join(p))
        .find(|d| d.join("openseeface").is_dir());
    if found.is_none() {
        panic!("tests/data/openseeface missing: the repository ships the real captures");
    }
    found
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

#[test]
fn megamind_capture_decodes_as_its_source_says() {
    let Some(data) = shared_data() else { return };
    let records = read_capture(&data.join("openseeface/megamind.osf")).unwrap();
    assert_eq!(records.len(), 231);
    let mut prev_t = f64::NEG_INFINITY;
    for r in &records {
        assert_eq!(r.datagram.len(), FACE_BYTES);
        let faces = decode_packet(&r.datagram).unwrap();
        assert_eq!(faces.len(), 1);
        let f = &faces[0];
        assert_eq!(
            (f.face_id, f.width, f.height, f.success),
            (0, 720.0, 528.0, 1)
        );
        assert!(f.timestamp > prev_t, "timestamps increase strictly");
        prev_t = f.timestamp;
        assert_eq!(encode_packet(&faces), r.datagram, "byte-exact re-encode");
    }
    // Packet 0 as SOURCE.md decodes it (printed to 5 or 6 significant digits there).
    let f = &decode_packet(&records[0].datagram).unwrap()[0];
    assert!(close(f.timestamp, 1796149943.4854996, 1e-6));
    assert!(close(f64::from(f.pnp_error), 24.00607, 1e-4));
    let q = [0.68531, 0.68368, -0.09190, -0.23342];
    for (a, b) in f.quaternion.iter().zip(q) {
        assert!(close(f64::from(*a), b, 1e-5), "{:?}", f.quaternion);
    }
    assert!(close(f64::from(f.points_2d[8][0]), 304.960, 1e-3));
    assert!(close(f64::from(f.points_2d[8][1]), 338.736, 1e-3));
    assert!(close(f64::from(f.points_2d[67][0]), 338.608, 1e-3));
    assert!(close(f64::from(f.points_3d[30][2]), -0.0454, 1e-4));
    assert!(close(f64::from(f.points_3d[69][0]), -0.1865, 1e-4));
    assert!(f.features.iter().all(|x| *x == 0.0));
    let p100 = &decode_packet(&records[100].datagram).unwrap()[0];
    assert!(close(f64::from(p100.features[3]), -0.567, 1e-3));
    assert!(close(f64::from(p100.features[12]), 0.243, 1e-3));
    // As a frame: every point valid, the subject's left jaw top at image right.
    let frame = to_frame(f, 0);
    assert!(frame.tracked);
    assert_eq!(frame.valid_count(), 68);
    assert!(frame.points[16].x > frame.points[0].x);
}

#[test]
fn live_link_takes_parse_by_name_with_their_timecode() {
    let Some(data) = shared_data() else { return };
    let s07_path = data.join("livelinkface/S07-001.csv");
    let s07 = read_take(&s07_path).unwrap();
    assert_eq!(s07.rows.len(), 2028);
    assert!(s07.rows.iter().all(|r| r.tracked));
    assert_eq!(s07.timecode_rate, 60);
    assert_eq!(s07.curve_names().count(), 61);
    // 12:27:47:47.169 -> 12:28:55:24.614 at 60 fps timecode.
    let want = (12.0 * 3600.0 + 28.0 * 60.0 + 55.0 + 24.614 / 60.0)
        - (12.0 * 3600.0 + 27.0 * 60.0 + 47.0 + 47.169 / 60.0);
    assert!(close(s07.duration_s(), want, 1e-6), "{}", s07.duration_s());
    assert!(close(s07.sample_rate_hz(), 29.975, 0.01));
    // The CSV's JawRight is its 18th column (1-based), before JawLeft: read by name, it lands at
    // the stream's JawRight index.
    let text = std::fs::read_to_string(&s07_path).unwrap();
    let second: Vec<&str> = text.lines().nth(1).unwrap().split(',').collect();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    assert_eq!((header[17], header[18]), ("JawRight", "JawLeft"));
    let jr: f32 = second[17].parse().unwrap();
    assert_eq!(s07.rows[0].curves[curve_index("JawRight").unwrap()], jr);
    assert!(curve_index("JawLeft").unwrap() < curve_index("JawRight").unwrap());

    let s88 = read_take(&data.join("livelinkface/S88-001.csv")).unwrap();
    assert_eq!(s88.rows.len(), 1939);
    let lost: Vec<usize> = s88
        .rows
        .iter()
        .enumerate()
        .filter(|(_, r)| !r.tracked)
        .map(|(i, _)| i)
        .collect();
    assert_eq!(lost.len(), 277);
    assert_eq!((lost[0], *lost.last().unwrap()), (382, 1863));
    assert!(close(s88.duration_s(), 64.69, 0.01));
}

#[test]
fn the_shipped_name_map_covers_every_arkit_blendshape() {
    let m = NameMap::load(&repo_root().join("configs/namemaps/arkit.toml")).unwrap();
    let inputs: Vec<&str> = CURVE_NAMES[..BLENDSHAPES].to_vec();
    let mapping = m.resolve(&inputs);
    assert!(mapping.unmapped.is_empty(), "{:?}", mapping.unmapped);
    assert_eq!(mapping.targets.len(), BLENDSHAPES);
    // Live Link's `JawOpen`, MediaPipe's `jawOpen` and ICT's `eyeBlink_L` spellings.
    assert_eq!(m.entry("JawOpen").unwrap().targets, vec!["jawOpen"]);
    assert_eq!(m.entry("eyeBlink_L").unwrap().source, "eyeBlinkLeft");
    assert!(m.entry("_neutral").unwrap().targets.is_empty());
}
