//! Apple's 52 ARKit blend shape names (the vocabulary avatars, trackers and engines share) and
//! the ARKit name a morph target's name stands for.

/// Apple's 52 ARKit blend shape names, in ARKit's documented order.
pub const ARKIT_NAMES: [&str; 52] = [
    "eyeBlinkLeft",
    "eyeLookDownLeft",
    "eyeLookInLeft",
    "eyeLookOutLeft",
    "eyeLookUpLeft",
    "eyeSquintLeft",
    "eyeWideLeft",
    "eyeBlinkRight",
    "eyeLookDownRight",
    "eyeLookInRight",
    "eyeLookOutRight",
    "eyeLookUpRight",
    "eyeSquintRight",
    "eyeWideRight",
    "jawForward",
    "jawLeft",
    "jawRight",
    "jawOpen",
    "mouthClose",
    "mouthFunnel",
    "mouthPucker",
    "mouthLeft",
    "mouthRight",
    "mouthSmileLeft",
    "mouthSmileRight",
    "mouthFrownLeft",
    "mouthFrownRight",
    "mouthDimpleLeft",
    "mouthDimpleRight",
    "mouthStretchLeft",
    "mouthStretchRight",
    "mouthRollLower",
    "mouthRollUpper",
    "mouthShrugLower",
    "mouthShrugUpper",
    "mouthPressLeft",
    "mouthPressRight",
    "mouthLowerDownLeft",
    "mouthLowerDownRight",
    "mouthUpperUpLeft",
    "mouthUpperUpRight",
    "browDownLeft",
    "browDownRight",
    "browInnerUp",
    "browOuterUpLeft",
    "browOuterUpRight",
    "cheekPuff",
    "cheekSquintLeft",
    "cheekSquintRight",
    "noseSneerLeft",
    "noseSneerRight",
    "tongueOut",
];

/// The ARKit name a morph target's `name` stands for: ARKit's own spelling in any case
/// (`jawOpen`, `JawOpen`), or ICT-FaceKit's `_L` / `_R` form (`eyeBlink_L` -> `eyeBlinkLeft`,
/// `browInnerUp_L` -> `browInnerUp`, its one shape split in two).
pub fn arkit_name(name: &str) -> Option<&'static str> {
    let find = |n: &str| {
        ARKIT_NAMES
            .iter()
            .copied()
            .find(|a| a.eq_ignore_ascii_case(n))
    };
    find(name).or_else(|| {
        let (base, side) = name
            .strip_suffix("_L")
            .map(|b| (b, "Left"))
            .or_else(|| name.strip_suffix("_R").map(|b| (b, "Right")))?;
        find(&format!("{base}{side}")).or_else(|| find(base))
    })
}

/// The left/right mirror pairs among morph targets `names`, as `(left, right)` indices: two
/// targets that stand for ARKit's `...Left` and `...Right` of one shape (`eyeBlinkLeft` and
/// `eyeBlink_R`), or ICT's two halves of one ARKit shape (`browInnerUp_L`, `browInnerUp_R`).
/// The gaze shapes (`eyeLook*`: the two eyes turn the same way, not mirrored) and the sideways
/// motions (`jawLeft` / `jawRight`, `mouthLeft` / `mouthRight`: opposites) are not pairs. Each
/// target is in one pair at most.
pub fn mirror_pairs<S: AsRef<str>>(names: &[S]) -> Vec<(usize, usize)> {
    /// The shape a target mirrors across, and whether it is the left one.
    fn side(name: &str) -> Option<(&'static str, bool)> {
        let a = arkit_name(name)?;
        if a.starts_with("eyeLook")
            || matches!(a, "jawLeft" | "jawRight" | "mouthLeft" | "mouthRight")
        {
            return None;
        }
        if let Some(base) = a.strip_suffix("Left") {
            return Some((base, true));
        }
        if let Some(base) = a.strip_suffix("Right") {
            return Some((base, false));
        }
        // One ARKit shape split in two: its halves by their own suffix.
        if name.ends_with("_L") {
            Some((a, true))
        } else if name.ends_with("_R") {
            Some((a, false))
        } else {
            None
        }
    }
    let sides: Vec<Option<(&str, bool)>> = names.iter().map(|n| side(n.as_ref())).collect();
    let mut taken = vec![false; names.len()];
    let mut pairs = Vec::new();
    for (l, s) in sides.iter().enumerate() {
        let Some((base, true)) = *s else { continue };
        if let Some(r) = (0..names.len()).find(|&r| !taken[r] && sides[r] == Some((base, false))) {
            taken[r] = true;
            pairs.push((l, r));
        }
    }
    pairs
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mirror_pairs_are_found_by_name() {
        let names = [
            "eyeBlinkLeft",
            "jawLeft",
            "eyeBlink_R",
            "browInnerUp_R",
            "jawRight",
            "browInnerUp_L",
            "eyeLookInLeft",
            "eyeLookInRight",
            "jawOpen",
            "mouthSmileLeft",
        ];
        assert_eq!(mirror_pairs(&names), [(0, 2), (5, 3)]);
        // Every one of ARKit's Left shapes but the gaze and sideways ones has its Right.
        let all = mirror_pairs(&ARKIT_NAMES);
        assert_eq!(all.len(), 20 - 4 - 2, "20 Left names, 4 gaze, 2 sideways");
        for (l, r) in all {
            assert_eq!(
                ARKIT_NAMES[l].strip_suffix("Left"),
                ARKIT_NAMES[r].strip_suffix("Right")
            );
        }
    }
}
