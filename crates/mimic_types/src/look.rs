//! How a rig is drawn: the `[look]` table of a rig file (hidden parts, skin materials, eyeballs).

use serde::{Deserialize, Serialize};

/// How a rig is drawn by `mimic render` and `mimic view`; empty (everything drawn, material
/// colours as the mesh's MTL gives them) when the rig file has no `[look]`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigLook {
    /// Inclusive vertex index ranges whose triangles are not drawn by default (e.g. see-through
    /// shells that opaque would cover the eyes).
    #[serde(default)]
    pub hidden: Vec<[u32; 2]>,
    /// Materials drawn in the renderer's skin colour instead of their MTL colour (e.g. a flat
    /// `Kd` meant to multiply a skin texture that is not shipped).
    #[serde(default)]
    pub skin_materials: Vec<String>,
    /// Eyeballs coloured by angle from their front: pupil, iris, white.
    #[serde(default)]
    pub eyeballs: Vec<Eyeball>,
}

/// One eyeball of a rig's look, by material names.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Eyeball {
    /// Material of the whole eyeball mesh; its `Kd` colours the iris.
    pub iris: String,
    /// Material whose `Kd` colours the rest of the eyeball (the white).
    pub white: String,
}

impl RigLook {
    /// Whether vertex `v` lies in a hidden range.
    pub fn hides(&self, v: u32) -> bool {
        self.hidden.iter().any(|[a, b]| (*a..=*b).contains(&v))
    }
}
