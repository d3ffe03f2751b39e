//! Files for mimic: OBJ meshes (through tobj) and avatar faces (through mimic_avatar), landmark layouts and target rigs from `configs/`.
//!
//! Entry points: [`load_obj`], [`write_obj`], [`load_layout`], [`load_rig`], [`ConfigDirs`].
//! Every error is an [`AssetError`] that names the file and, where the problem sits on a line,
//! that line. This crate knows nothing of recordings (that is `mimic_capture`) or solvers.

mod avatar_rig;
mod error;
mod frames;
mod layout;
mod look;
mod material;
mod morph;
mod obj;
mod obj_write;
mod orientation;
mod read;
mod rig;
mod shape_pack;
mod sinks;
mod span;
mod texture;

pub use avatar_rig::{
    AvatarSection, DRAWN_PARTS, PART_KINDS, RigAvatar, avatar_face, load_rig_avatar,
    read_avatar_face,
};
pub use error::AssetError;
pub use frames::{FRAMES_MAGIC, FRAMES_VERSION, FrameRecord, FramesReader, FramesWriter};
pub use layout::{ConfigDirs, load_layout, parse_layout};
pub use look::{IRIS_DEGREES, PUPIL_COLOR, PUPIL_DEGREES, load_rig_look, look_colors};
pub use material::{
    Material, MeshMaterials, load_rig_materials, parse_mtl, parse_obj_materials, rig_mesh_path,
};
pub use morph::{
    MORPH_FILE_DECIMALS, MorphTargetEntry, compare_deltas, load_morph_file, load_morph_targets,
    morph_target, packed_target, read_morph_file, round_trip_tolerance, save_morph_file,
    write_morph_file,
};
pub use obj::{load_obj, parse_obj, write_obj};
pub use obj_write::{ObjExtras, ObjFrames, write_mtl, write_obj_with};
pub use orientation::{Axis, Orientation, OrientationTable};
pub use rig::{RigFile, load_blendshape_fit, load_rig, parse_rig};
pub use shape_pack::{
    PackedShape, SHAPE_PACK_MAGIC, ShapePack, load_shape_pack, pack_tolerance, read_shape_pack,
    save_shape_pack, write_shape_pack,
};
pub use sinks::{BinSink, ControlsCsv, MetricsCsv, ObjSink, obj_frame_path, write_obj_frame};
pub use texture::{decode_texture, load_rig_textures, load_texture};
