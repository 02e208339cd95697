//! Polygon lists as read from a frame file, before fan triangulation.
//!
//! Frames keep their original polygons (not just triangles) so that "same connectivity in every frame" can be
//! checked face by face, and errors can name the face the way the file numbers it.

/// Polygons in a flat layout (one allocation for all indices, one for the offsets), 0-based vertex indices.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Polygons {
    /// `starts[k]..starts[k + 1]` is face `k` in `indices`; always holds one more entry than there are faces.
    starts: Vec<usize>,
    indices: Vec<u32>,
}

impl Default for Polygons {
    fn default() -> Self {
        Polygons::with_capacity(0, 0)
    }
}

impl Polygons {
    pub(crate) fn with_capacity(faces: usize, indices: usize) -> Self {
        let mut starts = Vec::with_capacity(faces + 1);
        starts.push(0);
        Polygons {
            starts,
            indices: Vec::with_capacity(indices),
        }
    }

    pub(crate) fn push(&mut self, face: &[u32]) {
        self.indices.extend_from_slice(face);
        self.starts.push(self.indices.len());
    }

    pub(crate) fn len(&self) -> usize {
        self.starts.len().saturating_sub(1)
    }

    pub(crate) fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Face `k`, or an empty slice when out of range.
    pub(crate) fn get(&self, k: usize) -> &[u32] {
        match (self.starts.get(k), self.starts.get(k + 1)) {
            (Some(&a), Some(&b)) => self.indices.get(a..b).unwrap_or(&[]),
            _ => &[],
        }
    }

    pub(crate) fn iter(&self) -> impl Iterator<Item = &[u32]> {
        (0..self.len()).map(move |k| self.get(k))
    }

    /// Fan triangulation: face `(a, b, c, d, …)` becomes `(a, b, c), (a, c, d), …`. Fans keep the winding of the
    /// polygon and need no geometry, so every frame triangulates identically.
    pub(crate) fn triangulate(&self) -> Vec<[u32; 3]> {
        let mut tris = Vec::with_capacity(self.indices.len().saturating_sub(2 * self.len()));
        for face in self.iter() {
            if let Some((&a, rest)) = face.split_first() {
                for w in rest.windows(2) {
                    if let [b, c] = *w {
                        tris.push([a, b, c]);
                    }
                }
            }
        }
        tris
    }

    /// Index of the first face that differs between `self` and `other` (or the first face present in only one of
    /// them), `None` when both lists are identical.
    pub(crate) fn first_difference(&self, other: &Polygons) -> Option<usize> {
        if self == other {
            return None;
        }
        let n = self.len().min(other.len());
        (0..n).find(|&k| self.get(k) != other.get(k)).or(Some(n))
    }
}

impl Polygons {
    /// Whether any face has more than three vertices (then triangle and face numbers differ).
    pub(crate) fn has_polygons(&self) -> bool {
        self.iter().any(|f| f.len() > 3)
    }
}

/// Adds to a mesh error that names a triangle how triangles are numbered when the file has polygons, since the
/// triangle index then differs from the face index a user sees in the file.
pub(crate) fn explain_triangle_numbers(e: crate::Error, has_polygons: bool) -> crate::Error {
    match e {
        crate::Error::Mesh { path, frame, msg } if has_polygons && msg.contains("triangle") => crate::Error::Mesh {
            path,
            frame,
            msg: format!("{msg} (triangles count from 0 in face order, each polygon split into a fan of n-2 triangles)"),
        },
        other => other,
    }
}

/// A face as text for messages, with `base` added to every index (1 for OBJ, 0 for PLY) and long polygons
/// shortened.
pub(crate) fn describe_face(face: &[u32], base: u64) -> String {
    const MAX: usize = 8;
    let mut s: Vec<String> = face
        .iter()
        .take(MAX)
        .map(|&v| (u64::from(v) + base).to_string())
        .collect();
    if face.len() > MAX {
        s.push(format!("… ({} vertices)", face.len()));
    }
    if s.is_empty() {
        "(none)".to_string()
    } else {
        s.join(" ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fan_and_difference() {
        let mut p = Polygons::default();
        p.push(&[0, 1, 2, 3]);
        p.push(&[3, 2, 4]);
        assert_eq!(p.triangulate(), vec![[0, 1, 2], [0, 2, 3], [3, 2, 4]]);
        let mut q = Polygons::default();
        q.push(&[0, 1, 2, 3]);
        assert_eq!(p.first_difference(&q), Some(1));
        q.push(&[3, 2, 5]);
        assert_eq!(p.first_difference(&q), Some(1));
        assert_eq!(p.first_difference(&p.clone()), None);
        assert_eq!(describe_face(p.get(1), 1), "4 3 5");
    }
}
