//! The rigs and layouts a server offers; each rig's basis is built once and shared by its sessions.

use crate::queue::Message;
use glam::Vec3;
use mimic_retarget::WeightMap;
use mimic_solve::Basis;
use mimic_solve::basis::MovingRows;
use mimic_types::{Layout, MorphTarget, Rig};
use mimic_wire::{BasisRows, encode_morph_rig, encode_rig};
use std::collections::BTreeMap;
use std::sync::Arc;

/// Why a rig cannot be offered.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CatalogError {
    /// The basis was built for another mesh or control set.
    #[error(
        "rig `{rig}`: basis is {rows} x {cols}, the rig has {vertices} vertices and {controls} columns (controls and rigid parts)"
    )]
    BasisShape {
        /// Rig name.
        rig: String,
        /// Basis rows.
        rows: usize,
        /// Basis columns.
        cols: usize,
        /// Rig vertices.
        vertices: usize,
        /// Rig controls.
        controls: usize,
    },
    /// A morph target that does not cover the rig's vertices.
    #[error(
        "rig `{rig}`: morph target `{target}` has {got} vertex deltas, the mesh has {vertices}"
    )]
    MorphTarget {
        /// Rig name.
        rig: String,
        /// Target name.
        target: String,
        /// Deltas the target has.
        got: usize,
        /// Rig vertices.
        vertices: usize,
    },
}

/// A rig's morph targets, for weights sessions: names, the name map, deltas and the rig message.
#[derive(Debug)]
pub struct MorphSet {
    /// Target names, in weight order.
    pub names: Vec<String>,
    /// ARKit-style names -> targets.
    pub map: WeightMap,
    /// Position deltas, target-major: target `k` is `deltas[k * n..(k + 1) * n]`.
    deltas: Vec<Vec3>,
    /// The rig message weights-session viewers get (morph basis, three columns per target).
    pub message: Message,
    /// The targets themselves (for a landmark session's blendshape fit when it forwards).
    targets: Vec<MorphTarget>,
    /// The rig's `[blendshape_fit]`: the terms of that fit.
    pub fit: mimic_types::BlendshapeFit,
}

impl MorphSet {
    /// Number of targets.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// The morph targets, in weight order.
    pub fn targets(&self) -> &[MorphTarget] {
        &self.targets
    }

    /// True without targets (never, for a set attached to a rig).
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// `positions = rest + sum_k w_k dP_k` (`positions` and `rest` one per vertex, `weights` one
    /// per target); allocates nothing.
    pub fn blend(&self, rest: &[Vec3], weights: &[f32], positions: &mut [Vec3]) {
        positions.copy_from_slice(rest);
        let n = rest.len();
        for (k, &w) in weights.iter().enumerate() {
            if w == 0.0 {
                continue;
            }
            if let Some(dp) = self.deltas.get(k * n..(k + 1) * n) {
                for (p, d) in positions.iter_mut().zip(dp) {
                    *p += w * *d;
                }
            }
        }
    }
}

/// A rig ready for sessions: the rig, its shared basis, the moving rows and the encoded rig message.
#[derive(Debug)]
pub struct RigEntry {
    /// The rig.
    pub rig: Rig,
    /// `B` (n x m), shared by every session on this rig.
    pub basis: Arc<Basis>,
    /// Vertices with a non-zero row of `B`, and `B` restricted to them.
    moving: MovingRows,
    /// The rig message viewers get once.
    pub message: Message,
    /// Morph targets, when the rig has `[[morph_targets]]` (weights sessions need them).
    pub morph: Option<MorphSet>,
}

impl RigEntry {
    /// Prepares `rig` with its basis.
    pub fn new(rig: Rig, basis: Basis) -> Result<Self, CatalogError> {
        let n = rig.mesh.vertex_count();
        let m = rig.controls.len() + rig.parts.column_count();
        if basis.vertex_count() != n || basis.control_count() != m {
            return Err(CatalogError::BasisShape {
                rig: rig.name.clone(),
                rows: basis.vertex_count(),
                cols: basis.control_count(),
                vertices: n,
                controls: m,
            });
        }
        let moving = basis.moving_rows(n);
        let message = Arc::new(encode_rig(&rig, rows(&basis)));
        Ok(Self {
            rig,
            basis: Arc::new(basis),
            moving,
            message,
            morph: None,
        })
    }

    /// Attaches the rig's morph targets (e.g. `mimic_assets::load_morph_targets`) so weights
    /// sessions can drive it; an empty list leaves the rig without targets.
    pub fn with_morph_targets(mut self, targets: Vec<MorphTarget>) -> Result<Self, CatalogError> {
        if targets.is_empty() {
            self.morph = None;
            return Ok(self);
        }
        let n = self.rig.mesh.vertex_count();
        let bad = |t: &MorphTarget| CatalogError::MorphTarget {
            rig: self.rig.name.clone(),
            target: t.name.clone(),
            got: t.position_deltas.len(),
            vertices: n,
        };
        if let Some(t) = targets.iter().find(|t| t.position_deltas.len() != n) {
            return Err(bad(t));
        }
        let basis =
            mimic_solve::morph_basis::morph_basis(&targets, n).ok_or_else(|| bad(&targets[0]))?;
        let names: Vec<String> = targets.iter().map(|t| t.name.clone()).collect();
        let message = Arc::new(encode_morph_rig(&self.rig, rows(&basis), &names));
        let deltas = targets
            .iter()
            .flat_map(|t| t.position_deltas.iter().copied())
            .collect();
        self.morph = Some(MorphSet {
            map: WeightMap::new(&names),
            names,
            deltas,
            message,
            targets,
            fit: mimic_types::BlendshapeFit::default(),
        });
        Ok(self)
    }

    /// Sets the terms of the blend-shape fit of the rig's morph targets (its `[blendshape_fit]`,
    /// e.g. `mimic_assets::load_blendshape_fit`); nothing without morph targets.
    pub fn with_blendshape_fit(mut self, fit: mimic_types::BlendshapeFit) -> Self {
        if let Some(m) = self.morph.as_mut() {
            m.fit = fit;
        }
        self
    }

    /// Rig name.
    pub fn name(&self) -> &str {
        &self.rig.name
    }

    /// `positions = rest + B d`, over the moving rows only (`positions` starts as the rest mesh
    /// and frozen vertices are never written).
    pub fn deform(&self, d: &[Vec3], scratch: &mut Vec<Vec3>, positions: &mut [Vec3]) {
        scratch.resize(self.moving.rows.len(), Vec3::ZERO);
        self.moving.basis.apply(d, scratch);
        for (&v, u) in self.moving.rows.iter().zip(scratch.iter()) {
            let v = v as usize;
            if let (Some(p), Some(r)) = (positions.get_mut(v), self.rig.mesh.positions.get(v)) {
                *p = *r + *u;
            }
        }
    }
}

/// Rigs (by name, one of them the default) and layouts (by name) a server offers.
#[derive(Debug)]
pub struct Catalog {
    rigs: BTreeMap<String, Arc<RigEntry>>,
    layouts: BTreeMap<String, Layout>,
    default_rig: String,
}

impl Catalog {
    /// A catalog whose default rig is `rig`.
    pub fn new(rig: RigEntry) -> Self {
        let default_rig = rig.name().to_string();
        let mut rigs = BTreeMap::new();
        rigs.insert(default_rig.clone(), Arc::new(rig));
        Self {
            rigs,
            layouts: BTreeMap::new(),
            default_rig,
        }
    }

    /// Adds another rig a hello may name.
    pub fn add_rig(&mut self, rig: RigEntry) {
        self.rigs.insert(rig.name().to_string(), Arc::new(rig));
    }

    /// Adds a layout trackers may send.
    pub fn add_layout(&mut self, layout: Layout) {
        self.layouts.insert(layout.name.clone(), layout);
    }

    /// The named rig, or the default one for `None`.
    pub fn rig(&self, name: Option<&str>) -> Option<&Arc<RigEntry>> {
        self.rigs.get(name.unwrap_or(&self.default_rig))
    }

    /// The named layout.
    pub fn layout(&self, name: &str) -> Option<&Layout> {
        self.layouts.get(name)
    }

    /// Names of the rigs offered.
    pub fn rig_names(&self) -> Vec<String> {
        self.rigs.keys().cloned().collect()
    }
}

/// A basis as the rig message carries it.
fn rows(basis: &mimic_solve::Basis) -> BasisRows<'_> {
    BasisRows {
        weights: basis.as_slice(),
        columns: basis.control_count(),
    }
}
