//! Numeric core of mimic: builds the n x m deformation basis `B` once per rig, applies it per frame.
//!
//! No I/O, no tokio, no wgpu.
