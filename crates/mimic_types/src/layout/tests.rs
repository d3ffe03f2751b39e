//! Tests of [`Layout`]: validation, control positions and their errors.

use super::*;

fn layout() -> Layout {
    Layout {
        name: "t".into(),
        description: String::new(),
        point_count: 4,
        controls: vec![LayoutControl {
            fdp: "8.3".parse().unwrap(),
            points: vec![1, 2],
            region: Region::Bottom,
            note: String::new(),
        }],
        stable: vec![0, 1, 3],
        undocumented: vec![],
        point_names: vec![],
        candide_correspondences: vec![],
        gaze: None,
        canonical_neutral: None,
    }
}

#[test]
fn control_is_mean_of_valid_points() {
    let l = layout();
    l.validate().unwrap();
    let mut f = LandmarkFrame::new(0, vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z]);
    assert_eq!(l.control_position(0, &f), Some(Vec3::new(0.5, 0.5, 0.0)));
    f.valid[2] = false;
    assert_eq!(l.control_position(0, &f), Some(Vec3::X));
    f.points[1] = Vec3::NAN;
    assert_eq!(l.control_position(0, &f), None);
}

#[test]
fn one_point_is_its_own_mean() {
    let mut f = LandmarkFrame::new(0, vec![Vec3::new(0.1, -2.3, 7.7), Vec3::Y]);
    // The same value the general mean gives (sum / 1), the point itself.
    assert_eq!(mean_of_valid(&[0], &f), Some(f.points[0] / 1.0));
    assert_eq!(mean_of_valid(&[0, 0], &f), Some(f.points[0]));
    f.valid[0] = false;
    assert_eq!(mean_of_valid(&[0], &f), None);
    f.valid[0] = true;
    f.points[0].y = f32::INFINITY;
    assert_eq!(mean_of_valid(&[0], &f), None);
    // A point outside the frame is not valid.
    assert_eq!(mean_of_valid(&[5], &f), None);
}

#[test]
fn point_count_names_and_correspondences_are_bounded() {
    let mut l = layout();
    l.point_count = 1_000_000_000_000;
    assert_eq!(
        l.validate().unwrap_err().to_string(),
        "layout `t` has point_count 1000000000000, over the maximum of 4096 points"
    );
    l.point_count = crate::limits::MAX_LAYOUT_POINTS;
    l.validate().unwrap();
    let mut l = layout();
    l.undocumented = vec![4];
    assert!(matches!(
        l.validate(),
        Err(LayoutError::UndocumentedPointOutOfRange { point: 4, .. })
    ));
    let mut l = layout();
    l.point_names = vec![String::new(); 5];
    assert!(matches!(
        l.validate(),
        Err(LayoutError::TooManyPointNames { names: 5, .. })
    ));
    let corr = |point, weight, t| ModelCorrespondence {
        point,
        vertex: None,
        vertices: vec![1, 2],
        t: Some(t),
        weight,
        contour: false,
    };
    let mut l = layout();
    l.candide_correspondences = vec![corr(0, 1.0, 0.5)];
    l.validate().unwrap();
    for (c, what) in [
        (corr(4, 1.0, 0.5), "out of range"),
        (corr(0, 0.0, 0.5), "weight 0"),
        (corr(0, f32::NAN, 0.5), "weight NaN"),
        (corr(0, 1.0, 1.5), "`t` in [0, 1]"),
        (corr(0, 1.0, f32::NAN), "`t` in [0, 1]"),
    ] {
        l.candide_correspondences = vec![corr(0, 1.0, 0.5), c];
        let e = l.validate().unwrap_err().to_string();
        assert!(
            e.starts_with("candide_correspondences entry 2 ") && e.contains(what),
            "{e}"
        );
    }
}

#[test]
fn control_names_are_fdps_or_layout_points() {
    let fdp: ControlName = "8.3".parse().unwrap();
    assert_eq!(fdp.as_fdp(), Some("8.3".parse().unwrap()));
    assert_eq!(fdp.to_string(), "8.3");
    let p: ControlName = "kinect121:23".parse().unwrap();
    assert_eq!(p.as_point(), Some(("kinect121", 23)));
    assert_eq!(
        (p.to_string(), p.as_fdp()),
        ("kinect121:23".to_string(), None)
    );
    for bad in [
        "Kinect:1",
        ":3",
        "k:-1",
        "k:70000",
        "k:x",
        "a-very-long-layout-name-xx:1",
    ] {
        assert!(
            matches!(bad.parse::<ControlName>(), Err(ControlNameError::Syntax(_))),
            "{bad}"
        );
    }
    assert!(matches!(
        "8.11".parse::<ControlName>(),
        Err(ControlNameError::Fdp(_))
    ));
    // A layout drives its own points directly, its FDPs through `controls`, no other layout's.
    let l = layout();
    assert_eq!(l.control_points(fdp), Some(&[1usize, 2][..]));
    assert_eq!(
        l.control_points("t:3".parse().unwrap()),
        Some(&[3usize][..])
    );
    assert_eq!(l.control_points("t:4".parse().unwrap()), None);
    assert_eq!(l.control_points("u:1".parse().unwrap()), None);
    assert_eq!(l.control_points("4.1".parse().unwrap()), None);
    let mut one = l.clone();
    one.controls[0].points = vec![2];
    assert_eq!(
        one.fdp_of("t:2".parse().unwrap()),
        Some("8.3".parse().unwrap())
    );
    assert_eq!(one.fdp_of("t:1".parse().unwrap()), None);
}

#[test]
fn out_of_range_control_names_the_control() {
    let mut l = layout();
    l.controls[0].points.push(7);
    let e = l.validate().unwrap_err();
    assert!(e.to_string().contains("control 8.3 maps to point 7"), "{e}");
}

#[test]
fn a_canonical_neutral_needs_one_finite_point_per_layout_point() {
    let mut l = layout();
    l.canonical_neutral = Some(vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z]);
    l.validate().unwrap();
    l.canonical_neutral = Some(vec![Vec3::ZERO; 3]);
    let e = l.validate().unwrap_err().to_string();
    assert_eq!(
        e,
        "the canonical neutral of layout `t` has 3 points (3 finite); the layout has 4"
    );
    l.canonical_neutral = Some(vec![Vec3::ZERO, Vec3::X, Vec3::NAN, Vec3::Z]);
    let e = l.validate().unwrap_err().to_string();
    assert!(e.contains("4 points (3 finite)"), "{e}");
}
