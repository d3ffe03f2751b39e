//! A server's catalog read from a config folder ([`load_catalog`]): the named rigs, each with
//! its basis and morph targets, and every layout of the folder.

use crate::catalog::{Catalog, CatalogError, RigEntry};
use mimic_assets::{AssetError, ConfigDirs, load_morph_targets, load_rig};
use mimic_solve::{SolveError, build_basis};
use mimic_types::{Rig, SolverSettings};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

/// Why a catalog cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum CatalogLoadError {
    /// A rig, its morph targets or a layout could not be read.
    #[error(transparent)]
    Asset(#[from] AssetError),
    /// A rig's basis could not be built.
    #[error("building the basis of rig `{rig}`")]
    Basis {
        /// The rig.
        rig: String,
        /// Why.
        #[source]
        source: SolveError,
    },
    /// A rig cannot be offered.
    #[error(transparent)]
    Catalog(#[from] CatalogError),
    /// No rig was named.
    #[error("no rig")]
    NoRig,
}

/// The rigs `rigs` names (the first the default; each with its basis, built with the settings
/// `settings` gives for it, and its morph targets) and every layout of `dirs`; and each rig's
/// file by rig name (for the browser viewer's GLBs).
pub fn load_catalog<'a>(
    dirs: &ConfigDirs,
    rigs: impl IntoIterator<Item = &'a str>,
    settings: impl Fn(&Rig) -> SolverSettings,
) -> Result<(Catalog, BTreeMap<String, PathBuf>), CatalogLoadError> {
    let mut entries = Vec::new();
    let mut rig_paths = BTreeMap::new();
    for name in rigs {
        let rig_path = dirs.rig_path(name);
        let rig = load_rig(&rig_path)?;
        rig_paths.insert(rig.name.clone(), rig_path.clone());
        let started = Instant::now();
        let basis =
            build_basis(&rig, &settings(&rig)).map_err(|source| CatalogLoadError::Basis {
                rig: rig.name.clone(),
                source,
            })?;
        let ms = started.elapsed().as_secs_f64() * 1e3;
        tracing::info!(rig = %rig.name, ms, "basis built");
        // Morph targets (for weights sessions), when the rig lists `[[morph_targets]]`.
        let started = Instant::now();
        let targets = load_morph_targets(&rig_path, &rig)?;
        if !targets.is_empty() {
            let ms = started.elapsed().as_secs_f64() * 1e3;
            tracing::info!(rig = %rig.name, targets = targets.len(), ms, "morph targets loaded");
        }
        let fit = mimic_assets::load_blendshape_fit(&rig_path)?;
        entries.push(
            RigEntry::new(rig, basis)?
                .with_morph_targets(targets)?
                .with_blendshape_fit(fit),
        );
    }
    let mut entries = entries.into_iter();
    let mut catalog = Catalog::new(entries.next().ok_or(CatalogLoadError::NoRig)?);
    entries.for_each(|e| catalog.add_rig(e));
    for layout in dirs.layout_names()? {
        catalog.add_layout(dirs.load_layout_named(&layout)?);
    }
    Ok((catalog, rig_paths))
}
