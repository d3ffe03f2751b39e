//! Numeric core of mimic: builds the n x m deformation basis `B` once per rig, applies it per frame.
//!
//! Entry points: [`build_basis`] (RBF with Euclidean or along-the-skin [`geodesic`] distances, or
//! sparse Laplacian editing, or the cotangent [`shell`] (thin-shell) energy, optionally per face region, folded into one [`Basis`]),
//! [`Basis::apply`] (`u = B d`, allocation-free, AVX2 + FMA where the CPU has it), [`vertex_normals`],
//! [`kabsch::fit_similarity`] (head pose) and [`morph_fit::MorphFit`] (blendshape weights).
//! Setup allocates and may fail with [`SolveError`]; the per-frame steps take `&self`, inputs and
//! `&mut` outputs and allocate nothing. No I/O, no tokio, no wgpu.

pub mod basis;
pub mod border;
mod build;
pub mod cotangent;
pub mod deform;
pub mod error;
pub mod geodesic;
pub mod jaw;
pub mod kabsch;
pub mod kernel;
pub mod laplacian;
pub mod morph_basis;
pub mod morph_fit;
pub mod normals;
pub mod rbf;
pub mod regions;
pub mod rigid;
pub mod shell;
pub mod stats;
#[cfg(test)]
mod test_meshes;
#[cfg(test)]
mod tests;

pub use basis::Basis;
pub use build::build_basis;
pub use error::SolveError;
pub use kernel::VectorKernel;
pub use normals::vertex_normals;
