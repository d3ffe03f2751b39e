//! Unit tests of the MediaPipe importer: the Procrustes table against the shipped canonical
//! model, the conversion against a face projected through a known pinhole, and bad lines.

use super::*;

/// The shipped canonical model with irises (cm), vertex i = landmark i.
fn canonical() -> Vec<DVec3> {
    include_str!("../../../../configs/models/mediapipe/face_model_with_iris.obj")
        .lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|t| t.parse().unwrap()).collect();
            DVec3::new(v[0], v[1], v[2])
        })
        .collect()
}

#[test]
fn procrustes_table_matches_the_shipped_canonical_model() {
    let c = canonical();
    assert_eq!(c.len(), POINT_COUNT);
    let mut total = 0.0;
    for &(i, w, p) in &PROCRUSTES {
        assert!(i < MESH_POINTS && w > 0.0);
        assert!(
            (c[i] - DVec3::from_array(p)).abs().max_element() < 1e-6,
            "{i}"
        );
        total += w;
    }
    // As MediaPipe's pbtxt gives them (they sum to 1.055, not 1; only ratios matter).
    assert!((total - 1.055).abs() < 1e-6, "{total}");
}

/// A camera looking down -z: image `w` x `h`, vertical field of view `fov_deg`.
struct Camera {
    w: f64,
    h: f64,
    fov_deg: f64,
}

impl Camera {
    /// The dump frame MediaPipe would give for camera-space points `p` (cm, 468 or 478): x, y
    /// normalised by the image size, z the depth relative to the face's centre on the scale of
    /// x (weak-perspective pixels at the centre's depth, divided by w), the centre being the
    /// Procrustes landmarks' weighted centroid (MediaPipe says only "the centre of the head").
    fn dump(&self, p: &[DVec3]) -> DumpFrame {
        let f = focal_px(self.h, self.fov_deg);
        let sw: f64 = PROCRUSTES.iter().map(|e| e.1).sum();
        let centre = -PROCRUSTES.iter().map(|&(i, w, _)| w * p[i].z).sum::<f64>() / sw;
        let landmarks = p
            .iter()
            .map(|q| {
                let d = -q.z;
                let u = self.w * 0.5 + f * q.x / d;
                let v = self.h * 0.5 - f * q.y / d;
                [u / self.w, v / self.h, (d - centre) * f / centre / self.w]
            })
            .collect();
        DumpFrame {
            t_us: 0,
            image_size: Some([self.w as u32, self.h as u32]),
            landmarks,
        }
    }
}

/// The canonical face turned by yaw and pitch (radians), at `offset` (cm) in camera space.
fn posed(yaw: f64, pitch: f64, offset: DVec3) -> Vec<DVec3> {
    let r = glam::DQuat::from_rotation_y(yaw) * glam::DQuat::from_rotation_x(pitch);
    canonical().iter().map(|&c| r * c + offset).collect()
}

/// Mean distance (cm) between recovered metres and the truth in cm.
fn mean_error_cm(got: &[Vec3], truth: &[DVec3]) -> f64 {
    got.iter()
        .zip(truth)
        .map(|(g, t)| (g.as_dvec3() * 100.0 - *t).length())
        .sum::<f64>()
        / truth.len() as f64
}

#[test]
fn a_canonical_face_through_a_pinhole_comes_back_in_metres() {
    let cam = Camera {
        w: 1280.0,
        h: 720.0,
        fov_deg: 50.0,
    };
    let sw: f64 = PROCRUSTES.iter().map(|e| e.1).sum();
    for distance in [30.0, 60.0, 250.0] {
        for (yaw, pitch) in [(0.0, 0.0), (0.35, -0.15), (-0.6, 0.3)] {
            let truth = posed(yaw, pitch, DVec3::new(4.0, -2.0, -distance));
            let mut out = Vec::new();
            let d = to_camera_space(&cam.dump(&truth), cam.fov_deg, &mut out).unwrap();
            assert_eq!(out.len(), POINT_COUNT);
            // The dump is this camera model's exact image of a canonical-sized face, so the
            // conversion inverts it up to rounding: f64 throughout, f32 output (relative
            // 6e-8 of the distance), well under a micrometre.
            let err = mean_error_cm(&out, &truth);
            let bound = 1e-6 * distance;
            assert!(err < bound, "D {distance} yaw {yaw}: {err} cm >= {bound}");
            let centre = -PROCRUSTES
                .iter()
                .map(|&(i, w, _)| w * truth[i].z)
                .sum::<f64>()
                / sw;
            assert!(
                (d * 100.0 - centre).abs() < 1e-9 * centre,
                "{d} m vs {centre} cm"
            );
        }
    }
}

#[test]
fn the_field_of_view_moves_the_face_but_keeps_its_size() {
    let cam = Camera {
        w: 640.0,
        h: 480.0,
        fov_deg: 63.0,
    };
    let truth = posed(-0.2, 0.1, DVec3::new(0.0, 0.0, -50.0));
    let frame = cam.dump(&truth);
    let size = |fov: f64| {
        let mut out = Vec::new();
        let d = to_camera_space(&frame, fov, &mut out).unwrap();
        // Outer eye corners 33 and 263: 8.89 cm apart on the canonical face.
        (d, f64::from(out[33].distance(out[263])))
    };
    let (d63, iod63) = size(63.0);
    let (d30, iod30) = size(30.0);
    let canonical_iod = canonical()[33].distance(canonical()[263]) * 0.01;
    // With the right field of view the face comes back at the canonical size; with a wrong
    // one the Procrustes spread is still the canonical one, and a single distance moves only
    // through the perspective term (S.z - centre) / f: under the face's relief over its
    // distance (about 10 / 50 here) times the focal lengths' relative change (0.5), shared
    // with the other points by the spread fit: 2 % of the distance (1.2 % measured).
    assert!(
        (iod63 - canonical_iod).abs() < 1e-6 * canonical_iod,
        "{iod63}"
    );
    assert!(
        (iod30 - iod63).abs() < 0.02 * canonical_iod,
        "{iod30} vs {iod63}"
    );
    let ratio = focal_px(480.0, 30.0) / focal_px(480.0, 63.0);
    // Up to the same 2 %: the spread fit's scale moves with the shape (1.7 % measured).
    assert!((d30 / d63 - ratio).abs() < 0.02 * ratio, "{d30} / {d63}");
}

/// A dump line with `n` landmarks at the canonical face seen by `cam`.
fn line(t_us: i64, n: usize) -> String {
    let cam = Camera {
        w: 720.0,
        h: 528.0,
        fov_deg: 63.0,
    };
    let truth = posed(0.0, 0.0, DVec3::new(0.0, 0.0, -60.0));
    let mut f = cam.dump(&truth);
    f.landmarks.truncate(n);
    let pts: Vec<String> = f
        .landmarks
        .iter()
        .map(|p| format!("[{:.5},{:.5},{:.5}]", p[0], p[1], p[2]))
        .collect();
    format!(
        r#"{{"frame":0,"t_us":{t_us},"image_size":[720,528],"landmarks":[{}]}}"#,
        pts.join(",")
    )
}

#[test]
fn lost_faces_and_dumps_without_irises() {
    let text = format!(
        "{{\"frame\":0,\"t_us\":0,\"landmarks\":[]}}\n\n{}\n{}\n",
        line(41_708, POINT_COUNT),
        line(83_417, MESH_POINTS)
    );
    let imp = convert_dump(&text, Path::new("d.jsonl"), 63.0, "test").unwrap();
    assert_eq!(imp.header.layout, LAYOUT);
    assert_eq!(imp.header.point_count, Some(POINT_COUNT));
    // Two gaps of ~41.7 ms: 23.98 frames/s.
    assert!((imp.header.rate_hz - 2.0 / 0.083_417).abs() < 1e-9);
    let f: Vec<&LandmarkFrame> = imp.frames.iter().map(|r| &r.frame).collect();
    assert!(!f[0].tracked && f[0].points.is_empty());
    assert!(f[1].tracked && f[1].valid_count() == POINT_COUNT);
    assert_eq!(f[2].points.len(), POINT_COUNT);
    assert_eq!(f[2].valid_count(), MESH_POINTS);
    assert!(!f[2].is_valid(468) && !f[2].is_valid(477) && f[2].is_valid(467));
    assert_eq!(imp.lost_frames(), 1);
    assert_eq!(imp.invalid_points(), POINT_COUNT - MESH_POINTS);
    // The round trip through the writer and reader keeps the frames.
    let bytes = imp.write_to(Vec::new()).unwrap();
    let r = mimic_capture::RecordingReader::new(bytes.as_slice(), "r.jsonl", Some(POINT_COUNT))
        .unwrap();
    let read = r.read_all();
    assert_eq!(read.frames.len(), 3);
    assert_eq!(read.stats.rejected.total(), 0);
}

#[test]
fn bad_lines_are_named_by_file_and_line() {
    let good = line(0, POINT_COUNT);
    let cases = [
        (format!("{good}\n{{\"t_us\":1,"), "d.jsonl:2: invalid JSON"),
        (
            format!("{good}\n{}", line(1, 100)),
            "d.jsonl:2: 100 landmarks; MediaPipe Face Mesh gives 478",
        ),
        (
            format!("{good}\n{}", line(0, POINT_COUNT)),
            "d.jsonl:2: t_us 0 is not after the previous frame's 0",
        ),
        (
            good.replace(r#""image_size":[720,528],"#, ""),
            "d.jsonl:1: landmarks without `image_size`",
        ),
        (
            good.replace("[720,528]", "[0,528]"),
            "d.jsonl:1: image_size [0, 528] is not a size",
        ),
        (
            good.replacen("[[0.", "[[2000.0", 1),
            "d.jsonl:1: landmark 0 is",
        ),
        (
            "{\"t_us\":1.5,\"landmarks\":[]}".to_string(),
            "d.jsonl:1: invalid JSON",
        ),
    ];
    for (text, want) in cases {
        let e = convert_dump(&text, Path::new("d.jsonl"), 63.0, "t").unwrap_err();
        assert!(e.to_string().starts_with(want), "{e} (wanted {want})");
    }
    let e = convert_dump("\n\n", Path::new("d.jsonl"), 63.0, "t").unwrap_err();
    assert_eq!(
        e.to_string(),
        "d.jsonl: no frames (an empty MediaPipe dump)"
    );
    for fov in [0.0, 180.0, f64::NAN] {
        let e = convert_dump(&good, Path::new("d.jsonl"), fov, "t").unwrap_err();
        assert!(matches!(e, MediaPipeError::Fov(_)), "{e}");
    }
}

#[test]
fn landmarks_all_in_one_spot_make_a_lost_frame_not_a_crash() {
    let pts = vec!["[0.5,0.5,0.0]"; POINT_COUNT].join(",");
    let text = format!(r#"{{"t_us":5,"image_size":[64,64],"landmarks":[{pts}]}}"#);
    let imp = convert_dump(&text, Path::new("d.jsonl"), 63.0, "t").unwrap();
    assert!(!imp.frames[0].frame.tracked);
    assert!(
        imp.header
            .description
            .as_deref()
            .unwrap()
            .contains("1 frames with degenerate landmarks written as lost")
    );
}
