//! The rules on the ICT head against the hand-made `configs/rigs/ict-face.toml`.

#![allow(
    clippy::unwrap_used,
    reason = "a test: a failed unwrap is the failure report"
)]

use mimic_rig::{Defaults, Numbering, load_landmarks, make_rig};
use std::path::PathBuf;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

#[test]
fn rules_reproduce_the_hand_rig_on_the_ict_head() {
    let hand = mimic_assets::load_rig(&repo().join("configs/rigs/ict-face.toml")).unwrap();
    let marks = load_landmarks(
        &repo().join("configs/rigs/ict-face.landmarks.json"),
        Numbering::default(),
    )
    .unwrap();
    let rig = make_rig(&hand.mesh, &marks, "t", None, Defaults::default()).unwrap();
    assert_eq!(rig.units, "cm", "guessed from the eye distance");
    assert!(rig.warnings.is_empty(), "{:?}", rig.warnings);
    let iod = rig.frame.iod;
    // ICT's eye centres (midpoints of the corners) are 6.30 cm apart.
    assert!((iod - 6.303).abs() < 1e-3, "{iod}");
    assert_eq!(rig.controls.len(), 38);
    let mut same = 0;
    for c in &hand.controls {
        let g = rig.controls.iter().find(|g| c.fdp == g.fdp.into()).unwrap();
        assert_eq!(g.region, c.region, "{}", c.fdp);
        let (a, b) = (
            hand.mesh.positions[c.vertex as usize],
            hand.mesh.positions[g.vertex as usize],
        );
        // The hand rig picked its cheeks on a coarser search: within 0.06 IOD of it.
        assert!(
            a.distance(b) <= 0.06 * iod,
            "{}: hand vertex {} vs rule vertex {} ({} cm apart)",
            c.fdp,
            c.vertex,
            g.vertex,
            a.distance(b)
        );
        same += usize::from(c.vertex == g.vertex);
    }
    assert!(same >= 34, "{same} of 38 on the hand rig's vertex");
    // Every piece with no control is frozen (the hand rig's 14062-26718), no control is.
    assert!(rig.frozen[14062..].iter().all(|f| *f));
    assert!(rig.controls.iter().all(|c| !rig.frozen[c.vertex as usize]));
    // Region borders and the top split near the hand rig's (0.02 IOD).
    let near = |got: f32, want: f32, what: &str| {
        assert!((got - want).abs() <= 0.02 * iod, "{what}: {got} vs {want}");
    };
    near(rig.regions.top_from, hand.regions.top_from, "top_from");
    near(
        rig.regions.bottom_below,
        hand.regions.bottom_below,
        "bottom_below",
    );
    near(rig.regions.band, hand.regions.band, "band");
    let (s, h) = (
        rig.solver.top_split.unwrap(),
        hand.solver.top_split.unwrap(),
    );
    near(s.at, h.at, "top_split.at");
}
