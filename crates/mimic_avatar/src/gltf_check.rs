//! Checks a glTF document's structure before anything walks or reads it: every index the readers
//! follow is in range, the node graph is a set of trees (no node its own ancestor, none with two
//! parents) no deeper than [`MAX_NODE_DEPTH`], with at most [`MAX_NODES`] nodes, and every
//! accessor and buffer view lies inside its buffer. A fault is one line naming the JSON pointer.
//!
//! The `gltf` crate's own validation indexes the accessors of a primitive's `POSITION` without a
//! bounds check (gltf-json 1.4.1, `primitive_validate_hook`), so these checks run first, on the
//! document read without validation; the crate's validation runs after them.

use gltf::json;

/// The most nodes a glTF file may have (avatars have a few hundred).
pub const MAX_NODES: usize = 65_536;
/// The deepest node hierarchy read (a skeleton is a few dozen levels).
pub const MAX_NODE_DEPTH: usize = 256;

/// A structural fault: the JSON pointer of the offending value and what is wrong with it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Fault {
    /// JSON pointer (RFC 6901) of the value, e.g. `/nodes/3/children/0`.
    pub pointer: String,
    /// What is wrong, in words.
    pub message: String,
}

impl std::fmt::Display for Fault {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.pointer, self.message)
    }
}

fn fault(pointer: String, message: impl Into<String>) -> Fault {
    Fault {
        pointer,
        message: message.into(),
    }
}

/// Checks `root` (see the module docs); the first fault found is the error.
pub fn check(root: &json::Root) -> Result<(), Fault> {
    if root.nodes.len() > MAX_NODES {
        return Err(fault(
            "/nodes".into(),
            format!(
                "{} nodes, more than the {MAX_NODES} mimic reads",
                root.nodes.len()
            ),
        ));
    }
    check_meshes(root)?;
    check_accessors(root)?;
    check_nodes(root)?;
    Ok(())
}

/// Every accessor a primitive names (attributes, indices, morph targets) exists.
fn check_meshes(root: &json::Root) -> Result<(), Fault> {
    let n = root.accessors.len();
    let in_range = |i: usize, pointer: &dyn Fn() -> String| {
        if i < n {
            Ok(())
        } else {
            Err(fault(
                pointer(),
                format!("accessor {i} does not exist ({n} accessors)"),
            ))
        }
    };
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let at = format!("/meshes/{m}/primitives/{p}");
            for (semantic, index) in &prim.attributes {
                let name = match semantic {
                    json::validation::Checked::Valid(s) => s.to_string(),
                    json::validation::Checked::Invalid => "?".into(),
                };
                in_range(index.value(), &|| format!("{at}/attributes/{name}"))?;
            }
            if let Some(index) = prim.indices {
                in_range(index.value(), &|| format!("{at}/indices"))?;
            }
            for (t, target) in prim.targets.iter().flatten().enumerate() {
                let named = [
                    ("POSITION", target.positions),
                    ("NORMAL", target.normals),
                    ("TANGENT", target.tangents),
                ];
                for (name, index) in named {
                    if let Some(index) = index {
                        in_range(index.value(), &|| format!("{at}/targets/{t}/{name}"))?;
                    }
                }
            }
        }
    }
    Ok(())
}

/// Bytes of one element of an accessor (components times component size; matrix column
/// padding left out, so this is a lower bound).
fn element_bytes(a: &json::Accessor) -> Option<u64> {
    use json::accessor::{ComponentType, GenericComponentType, Type};
    use json::validation::Checked;
    let component = match a.component_type {
        Checked::Valid(GenericComponentType(c)) => match c {
            ComponentType::I8 | ComponentType::U8 => 1,
            ComponentType::I16 | ComponentType::U16 => 2,
            ComponentType::U32 | ComponentType::F32 => 4,
        },
        Checked::Invalid => return None,
    };
    let components = match a.type_ {
        Checked::Valid(t) => match t {
            Type::Scalar => 1,
            Type::Vec2 => 2,
            Type::Vec3 => 3,
            Type::Vec4 | Type::Mat2 => 4,
            Type::Mat3 => 9,
            Type::Mat4 => 16,
        },
        Checked::Invalid => return None,
    };
    Some(component * components)
}

/// Every buffer view lies inside its buffer, every accessor inside its buffer view.
fn check_accessors(root: &json::Root) -> Result<(), Fault> {
    for (v, view) in root.buffer_views.iter().enumerate() {
        let at = format!("/bufferViews/{v}");
        let Some(buffer) = root.buffers.get(view.buffer.value()) else {
            return Err(fault(
                format!("{at}/buffer"),
                format!("buffer {} does not exist", view.buffer.value()),
            ));
        };
        let end = view
            .byte_offset
            .map_or(0, |o| o.0)
            .checked_add(view.byte_length.0);
        if end.is_none_or(|e| e > buffer.byte_length.0) {
            return Err(fault(
                at,
                format!(
                    "reaches past the end of buffer {} ({} bytes)",
                    view.buffer.value(),
                    buffer.byte_length.0
                ),
            ));
        }
    }
    for (k, a) in root.accessors.iter().enumerate() {
        let at = format!("/accessors/{k}");
        let Some(view_index) = a.buffer_view else {
            continue;
        };
        let Some(view) = root.buffer_views.get(view_index.value()) else {
            return Err(fault(
                format!("{at}/bufferView"),
                format!("buffer view {} does not exist", view_index.value()),
            ));
        };
        let Some(element) = element_bytes(a) else {
            continue; // The crate's validation names an invalid type.
        };
        let stride = view.byte_stride.map_or(element, |s| s.0 as u64);
        let count = a.count.0;
        let end = match count.checked_sub(1) {
            None => Some(0),
            Some(last) => last
                .checked_mul(stride)
                .and_then(|x| x.checked_add(element))
                .and_then(|x| x.checked_add(a.byte_offset.map_or(0, |o| o.0))),
        };
        if end.is_none_or(|e| e > view.byte_length.0) {
            return Err(fault(
                at,
                format!(
                    "{count} elements reach past the end of buffer view {} ({} bytes)",
                    view_index.value(),
                    view.byte_length.0
                ),
            ));
        }
    }
    Ok(())
}

/// The node graph is a set of trees no deeper than [`MAX_NODE_DEPTH`], its indices in range, and
/// every scene's roots exist (walked without recursion, each node once).
fn check_nodes(root: &json::Root) -> Result<(), Fault> {
    let n = root.nodes.len();
    let mut parent: Vec<Option<usize>> = vec![None; n];
    for (p, node) in root.nodes.iter().enumerate() {
        if let Some(m) = node.mesh
            && m.value() >= root.meshes.len()
        {
            return Err(fault(
                format!("/nodes/{p}/mesh"),
                format!("mesh {} does not exist", m.value()),
            ));
        }
        for (k, child) in node.children.iter().flatten().enumerate() {
            let c = child.value();
            let at = || format!("/nodes/{p}/children/{k}");
            if c >= n {
                return Err(fault(at(), format!("node {c} does not exist ({n} nodes)")));
            }
            if c == p {
                return Err(fault(at(), format!("node {p} is its own child")));
            }
            if parent[c] == Some(p) {
                return Err(fault(at(), format!("node {c} is listed twice as a child")));
            }
            if let Some(other) = parent[c] {
                return Err(fault(
                    at(),
                    format!(
                        "node {c} has two parents (nodes {other} and {p}); glTF nodes form trees"
                    ),
                ));
            }
            parent[c] = Some(p);
        }
    }
    // Each node's depth, climbing parents from every node (0: not seen, 1: on the climb, 2: done);
    // meeting a node of the current climb is a cycle.
    let mut depth = vec![0usize; n];
    let mut state = vec![0u8; n];
    let mut path = Vec::new();
    for start in 0..n {
        path.clear();
        let mut at = start;
        let top_depth = loop {
            match state[at] {
                1 => {
                    return Err(fault(
                        format!("/nodes/{at}/children"),
                        format!("node {at} is its own ancestor (a cycle)"),
                    ));
                }
                2 => break depth[at] + 1,
                _ => {
                    state[at] = 1;
                    path.push(at);
                    match parent[at] {
                        None => break 0,
                        Some(p) => at = p,
                    }
                }
            }
        };
        for (k, &node) in path.iter().rev().enumerate() {
            let d = top_depth + k;
            if d >= MAX_NODE_DEPTH {
                return Err(fault(
                    format!("/nodes/{node}"),
                    format!("deeper than {MAX_NODE_DEPTH} levels of nodes"),
                ));
            }
            depth[node] = d;
            state[node] = 2;
        }
    }
    for (s, scene) in root.scenes.iter().enumerate() {
        for (k, node) in scene.nodes.iter().enumerate() {
            if node.value() >= n {
                return Err(fault(
                    format!("/scenes/{s}/nodes/{k}"),
                    format!("node {} does not exist ({n} nodes)", node.value()),
                ));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A document of `nodes` (JSON) over one triangle's accessor, with `extra` fields.
    fn doc(nodes: &str, extra: &str) -> json::Root {
        let text = format!(
            r#"{{"asset":{{"version":"2.0"}},"scenes":[{{"nodes":[0]}}],"nodes":{nodes},
            "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
            "buffers":[{{"byteLength":36}}],
            "bufferViews":[{{"buffer":0,"byteLength":36}}],
            "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"}}]{extra}}}"#
        );
        json::Root::from_slice(text.as_bytes()).unwrap()
    }

    fn pointer(root: &json::Root) -> String {
        check(root).unwrap_err().pointer
    }

    /// A chain of `n` nodes, each the child of the one before.
    fn chain(n: usize) -> String {
        let nodes: Vec<String> = (0..n)
            .map(|k| match k + 1 < n {
                true => format!(r#"{{"children":[{}]}}"#, k + 1),
                false => r#"{"mesh":0}"#.to_string(),
            })
            .collect();
        format!("[{}]", nodes.join(","))
    }

    #[test]
    fn trees_pass_and_a_chain_fails_one_level_past_the_depth_limit() {
        check(&doc(
            r#"[{"children":[1,2]},{"mesh":0},{"children":[3]},{}]"#,
            "",
        ))
        .unwrap();
        check(&doc(&chain(MAX_NODE_DEPTH), "")).unwrap();
        let deep = doc(&chain(MAX_NODE_DEPTH + 1), "");
        assert_eq!(pointer(&deep), format!("/nodes/{MAX_NODE_DEPTH}"));
    }

    #[test]
    fn cycles_shared_children_and_missing_nodes_name_their_pointer() {
        assert_eq!(
            pointer(&doc(r#"[{"children":[0]}]"#, "")),
            "/nodes/0/children/0"
        );
        let cycle = doc(
            r#"[{"children":[1]},{"children":[2]},{"children":[1]}]"#,
            "",
        );
        // Node 1 has parents 0 and 2: two parents is found before the cycle 1 -> 2 -> 1.
        assert_eq!(pointer(&cycle), "/nodes/2/children/0");
        let ring = doc(r#"[{"children":[1]},{"children":[0]}]"#, "");
        assert!(check(&ring).unwrap_err().message.contains("own ancestor"));
        let twice = doc(r#"[{"children":[1,1]},{}]"#, "");
        assert_eq!(pointer(&twice), "/nodes/0/children/1");
        assert_eq!(
            pointer(&doc(r#"[{"children":[5]}]"#, "")),
            "/nodes/0/children/0"
        );
        assert_eq!(pointer(&doc(r#"[{"mesh":3}]"#, "")), "/nodes/0/mesh");
    }

    #[test]
    fn accessors_and_views_out_of_range_name_their_pointer() {
        let mut root = doc("[{}]", "");
        root.accessors[0].count = json::validation::USize64(4);
        assert_eq!(pointer(&root), "/accessors/0");
        let mut root = doc("[{}]", "");
        root.accessors[0].count = json::validation::USize64(u64::MAX);
        assert_eq!(pointer(&root), "/accessors/0");
        let mut root = doc("[{}]", "");
        root.buffer_views[0].byte_offset = Some(json::validation::USize64(4));
        assert_eq!(pointer(&root), "/bufferViews/0");
        let mut root = doc("[{}]", "");
        root.meshes[0].primitives[0].indices = Some(json::Index::new(1));
        assert_eq!(pointer(&root), "/meshes/0/primitives/0/indices");
        let root = doc("[{}]", r#","extensionsUsed":[]"#);
        check(&root).unwrap();
    }
}
