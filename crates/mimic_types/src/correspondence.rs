//! Which model vertex (or point on a model edge) a tracked landmark corresponds to.

use serde::{Deserialize, Serialize};

/// One tracked point of a layout and the CANDIDE-3 vertex, or edge point, it corresponds to.
///
/// In a layout file: `{ point = 48, vertex = 64 }` for a vertex, or
/// `{ point = 1, vertices = [56, 54], t = 0.45 }` for the point `(1 - t) v_a + t v_b` on an edge.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelCorrespondence {
    /// Layout point index.
    pub point: usize,
    /// The model vertex the point sits on (exclusive with `vertices`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vertex: Option<usize>,
    /// The two end vertices of the model edge the point lies on (exclusive with `vertex`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub vertices: Vec<usize>,
    /// Position along `vertices` (0 = first, 1 = second).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub t: Option<f32>,
    /// Relative weight of the point in the fit (default 1).
    #[serde(default = "one", skip_serializing_if = "is_one")]
    pub weight: f32,
    /// A silhouette point (face contour): only its image position is used, never its depth.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub contour: bool,
}

fn one() -> f32 {
    1.0
}

fn is_one(w: &f32) -> bool {
    *w == 1.0
}

impl ModelCorrespondence {
    /// The model vertices and their blend weights (summing to 1), or `None` if the entry is malformed.
    pub fn blend(&self) -> Option<Vec<(usize, f32)>> {
        match (self.vertex, self.vertices.as_slice(), self.t) {
            (Some(v), [], None) => Some(vec![(v, 1.0)]),
            (None, &[a, b], Some(t)) if (0.0..=1.0).contains(&t) => {
                Some(vec![(a, 1.0 - t), (b, t)])
            }
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(vertex: Option<usize>, vertices: Vec<usize>, t: Option<f32>) -> ModelCorrespondence {
        ModelCorrespondence {
            point: 3,
            vertex,
            vertices,
            t,
            weight: 1.0,
            contour: false,
        }
    }

    #[test]
    fn vertex_and_edge_forms_blend() {
        assert_eq!(entry(Some(7), vec![], None).blend(), Some(vec![(7, 1.0)]));
        assert_eq!(
            entry(None, vec![1, 2], Some(0.25)).blend(),
            Some(vec![(1, 0.75), (2, 0.25)])
        );
        assert_eq!(entry(Some(1), vec![1, 2], Some(0.5)).blend(), None);
        assert_eq!(entry(None, vec![1, 2], Some(1.5)).blend(), None);
    }
}
