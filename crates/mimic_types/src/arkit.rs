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
