//! The file's animations: each channel's node, path, key times and values (read to check what a
//! writer wrote, and to keep an avatar's own clips in view).

use crate::AvatarError;
use crate::accessor::Reader;

/// What a channel animates (glTF `target.path`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChannelPath {
    /// `translation` (VEC3 per key).
    Translation,
    /// `rotation` (VEC4 quaternion x, y, z, w per key).
    Rotation,
    /// `scale` (VEC3 per key).
    Scale,
    /// `weights` (one per morph target per key).
    Weights,
}

/// One channel: a node's property over time.
#[derive(Clone, Debug, PartialEq)]
pub struct Channel {
    /// The node it moves.
    pub node: usize,
    /// What it moves.
    pub path: ChannelPath,
    /// Key times, seconds.
    pub times: Vec<f32>,
    /// Values, key-major (cubic spline keys hold in-tangent, value, out-tangent).
    pub values: Vec<f32>,
    /// `LINEAR`, `STEP` or `CUBICSPLINE`.
    pub interpolation: String,
}

/// An animation: its name and channels.
#[derive(Clone, Debug, PartialEq)]
pub struct Animation {
    /// Its name, if it has one.
    pub name: Option<String>,
    /// Its channels, in file order.
    pub channels: Vec<Channel>,
}

/// Every animation of `doc`.
pub(crate) fn read_animations(
    r: &Reader<'_>,
    doc: &gltf::Document,
) -> Result<Vec<Animation>, AvatarError> {
    let mut out = Vec::new();
    for a in doc.animations() {
        let mut channels = Vec::new();
        for c in a.channels() {
            use gltf::animation::{Interpolation, Property};
            let target = c.target();
            let sampler = c.sampler();
            let (path, dims) = match target.property() {
                Property::Translation => (ChannelPath::Translation, 3),
                Property::Rotation => (ChannelPath::Rotation, 4),
                Property::Scale => (ChannelPath::Scale, 3),
                Property::MorphTargetWeights => (ChannelPath::Weights, 1),
            };
            channels.push(Channel {
                node: target.node().index(),
                path,
                times: r.floats(&sampler.input(), &[1])?,
                values: r.floats(&sampler.output(), &[dims])?,
                interpolation: match sampler.interpolation() {
                    Interpolation::Linear => "LINEAR",
                    Interpolation::Step => "STEP",
                    Interpolation::CubicSpline => "CUBICSPLINE",
                }
                .to_string(),
            });
        }
        out.push(Animation {
            name: a.name().map(str::to_string),
            channels,
        });
    }
    Ok(out)
}
