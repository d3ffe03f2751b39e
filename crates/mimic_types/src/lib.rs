//! Value types shared by every mimic crate.
//!
//! Entry types: [`LandmarkFrame`], [`Layout`], [`Mesh`], [`Rig`], [`HeadPose`], [`Fdp`], [`Region`].
//! This crate depends on nothing but glam, serde (serde_json for a recording header's extra
//! fields) and thiserror, and does no I/O but the capped
//! whole-file reads of [`limits`] (shared by every loader); loading these values from files is
//! `mimic_assets`' job, producing frames is `mimic_capture`'s.

pub mod arkit;
pub mod blend_fit;
pub mod correspondence;
pub mod fdp;
pub mod frame;
pub mod frame_metrics;
pub mod layout;
pub mod limits;
pub mod look;
pub mod mesh;
pub mod morph;
pub mod overrides;
pub mod parse;
pub mod parts;
pub mod pose;
pub mod recording;
pub mod region;
pub mod rig;
pub mod shell;
pub mod sink;
pub mod status;
pub mod weight_map;

pub use blend_fit::BlendshapeFit;
pub use correspondence::ModelCorrespondence;
pub use fdp::{Fdp, FdpError};
pub use frame::LandmarkFrame;
pub use layout::{
    ControlName, ControlNameError, EyePoints, GazeLayout, Layout, LayoutControl, LayoutError,
};
pub use limits::{FileKind, ReadError, SettingError};
pub use look::{
    Eyeball, MAX_TEXTURE_SIDE, MeshTextures, RigLook, TEXTURE_FILE, TextureImage, TriangleTexture,
};
pub use mesh::{Mesh, MeshError};
pub use morph::MorphTarget;
pub use parts::{EyePart, JawPart, PartError, RigParts};
pub use pose::HeadPose;
pub use recording::{FORMAT_NAME, FORMAT_VERSION, RecordingHeader, UNITS_METRES};
pub use region::{Region, RegionBands};
pub use rig::{
    LaplacianWeights, RbfDistance, RbfKernel, Rig, RigControl, RigError, ShellSettings, Socket,
    SocketMode, Sockets, SolverKind, SolverSettings, TopSplit,
};
pub use sink::{FrameSink, SinkError, SinkFrame, SinkReport};
pub use status::{FrameStatus, FrameView};
pub use weight_map::WeightMap;

/// Nominal number of MPEG-4 control points mimic drives a face with (the `mpeg4` set); rigs
/// may have any count (dense sets of a layout's own points), nothing may assume this one.
pub const NOMINAL_CONTROL_COUNT: usize = 38;
