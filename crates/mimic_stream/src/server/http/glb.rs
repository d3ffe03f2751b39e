//! The rigs as GLB files for the browser viewer, built once per rig and kind and kept.

use crate::server::state::Shared;
use crate::settings::HttpSettings;
use crate::sync::lock;
use axum::body::Bytes;
use mimic_gltf::{control_morphs, target_morphs, write_rig_glb};
use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use tokio::sync::OnceCell;

/// Morph targets on the page's number keys 1-9 (as `mimic view`'s): the rig's first nine.
pub(super) const EXPRESSION_KEYS: usize = 9;

/// One rig's GLB (or why it could not be written), built on first request.
type Slot = Arc<OnceCell<Result<Bytes, String>>>;

/// GLBs by (rig, weights session): free-form (one morph target per control and axis, the
/// columns of the server's basis `B`, weights `d` in metres, then the rig's first
/// [`EXPRESSION_KEYS`] morph targets for the page's number keys) or the rig's own morph targets
/// (weights sessions, weights as they are).
#[derive(Debug)]
pub(super) struct GlbCache {
    web: HttpSettings,
    slots: Mutex<HashMap<(String, bool), Slot>>,
}

impl GlbCache {
    /// An empty cache over these rig files.
    pub(super) fn new(web: HttpSettings) -> Self {
        Self {
            web,
            slots: Mutex::new(HashMap::new()),
        }
    }

    /// The GLB of `rig` for a landmark (`weights` false) or weights session: built on the
    /// blocking pool the first time (concurrent requests wait for that one build), then shared.
    pub(super) async fn get(
        &self,
        shared: &Arc<Shared>,
        rig: &str,
        weights: bool,
    ) -> Result<Bytes, String> {
        let slot = lock(&self.slots)
            .entry((rig.to_string(), weights))
            .or_default()
            .clone();
        let built = slot
            .get_or_init(|| async {
                let shared = shared.clone();
                let (rig, web) = (rig.to_string(), self.web.clone());
                let started = std::time::Instant::now();
                let r = tokio::task::spawn_blocking(move || build(&shared, &web, &rig, weights))
                    .await
                    .unwrap_or_else(|e| Err(format!("building the GLB failed: {e}")));
                if let Ok(b) = &r {
                    let ms = started.elapsed().as_secs_f64() * 1e3;
                    tracing::info!(
                        bytes = b.len(),
                        ms,
                        weights,
                        "GLB built for the browser viewer"
                    );
                }
                r
            })
            .await;
        built.clone()
    }
}

/// The rig's first [`EXPRESSION_KEYS`] morph targets (the catalog's, as weights sessions use
/// them) as glTF targets after the basis columns: positions only, like the basis columns (a
/// normal delta on some targets would make three.js's GLTFLoader take the rest normal as the
/// delta of every target without one).
fn expression_morphs(
    entry: &crate::catalog::RigEntry,
    r: &mimic_types::Rig,
) -> Result<Vec<mimic_gltf::Morph>, String> {
    let Some(set) = entry.morph.as_ref() else {
        return Ok(Vec::new());
    };
    let scale = mimic_gltf::metres_per_unit(&r.units)
        .ok_or_else(|| format!("rig units `{}` have no length in metres", r.units))?;
    let keys = &set.targets()[..set.len().min(EXPRESSION_KEYS)];
    let mut morphs = target_morphs(keys, scale);
    for m in &mut morphs {
        m.normals.clear();
    }
    Ok(morphs)
}

/// Writes the GLB of `rig` with mimic_gltf's writer.
fn build(shared: &Shared, web: &HttpSettings, rig: &str, weights: bool) -> Result<Bytes, String> {
    let entry = shared
        .catalog
        .rig(Some(rig))
        .ok_or_else(|| format!("no rig `{rig}`"))?;
    let path = web
        .rig_paths
        .get(rig)
        .ok_or_else(|| format!("the rig file of `{rig}` is not known to the HTTP server"))?;
    let r = &entry.rig;
    let morphs = if weights {
        let scale = mimic_gltf::metres_per_unit(&r.units)
            .ok_or_else(|| format!("rig units `{}` have no length in metres", r.units))?;
        let targets = mimic_assets::load_morph_targets(path, r).map_err(|e| e.to_string())?;
        target_morphs(&targets, scale)
    } else {
        let mut morphs = control_morphs(&entry.basis, r);
        morphs.extend(expression_morphs(entry, r)?);
        morphs
    };
    let mut out = Vec::new();
    write_rig_glb(path, r, &morphs, None, web.skin, &mut out).map_err(|e| e.to_string())?;
    Ok(Bytes::from(out))
}
