//! The text of the contract's OBJ files, built fast without changing a byte.
//!
//! `crease deep apply` writes one OBJ per frame; formatting its numbers with `format!("{}")` was most of the
//! CPU time of the default apply. Two things make it cheap while keeping the files byte-identical to what
//! `{}` writes (shortest digits that read back to the same f64, never an exponent, so every reader gets the
//! exact positions back):
//! - the `vt` and `f` lines never change within a model, so they are formatted once ([`ObjText`]);
//! - the numbers are written by [`crease_core::float_text`] (Ryū's shortest digits in std's layout, the same
//!   text the output frames use), tested there against `format!` on millions of values.

use crease_core::float_text::{push_f64, push_u64};
use crease_core::mesh::Topology;
use crease_core::vec3::V3;

/// First line of every contract OBJ.
pub const HEADER: &str = "# crease deep: coarse mesh with the normal map's UV layout\n";

/// The constant part of a contract OBJ (the `vt` and `f` lines of one layout), formatted once; each frame adds
/// its `v` lines in front.
#[derive(Debug, Clone)]
pub struct ObjText {
    tail: Vec<u8>,
    n_vertices: usize,
}

impl ObjText {
    /// `uv` per layout corner, `corners` per triangle (indices into `uv`), faces `f v/vt` 1-based.
    pub fn new(topo: &Topology, uv: &[[f64; 2]], corners: &[[u32; 3]]) -> Self {
        let mut tail = Vec::with_capacity(40 * uv.len() + 48 * topo.n_triangles());
        for t in uv {
            tail.extend_from_slice(b"vt ");
            push_f64(&mut tail, t[0]);
            tail.push(b' ');
            push_f64(&mut tail, t[1]);
            tail.push(b'\n');
        }
        for (tri, c) in topo.triangles().iter().zip(corners) {
            tail.push(b'f');
            for k in 0..3 {
                tail.push(b' ');
                push_u64(&mut tail, tri[k] as u64 + 1);
                tail.push(b'/');
                push_u64(&mut tail, c[k] as u64 + 1);
            }
            tail.push(b'\n');
        }
        ObjText {
            tail,
            n_vertices: topo.n_vertices(),
        }
    }

    /// The header, the `# normals: {note}` line that says what the frame's map holds, and the `v` lines of
    /// one frame, into `head` (cleared first); the file is `head` then [`ObjText::tail`].
    pub fn head(&self, positions: &[V3], note: &str, head: &mut Vec<u8>) {
        debug_assert_eq!(positions.len(), self.n_vertices);
        head.clear();
        head.reserve(HEADER.len() + note.len() + 12 + 64 * positions.len());
        head.extend_from_slice(HEADER.as_bytes());
        head.extend_from_slice(b"# normals: ");
        // One line, whatever the note holds.
        head.extend(note.bytes().map(|b| if b == b'\n' { b' ' } else { b }));
        head.push(b'\n');
        for p in positions {
            head.extend_from_slice(b"v ");
            push_f64(head, p[0]);
            head.push(b' ');
            push_f64(head, p[1]);
            head.push(b' ');
            push_f64(head, p[2]);
            head.push(b'\n');
        }
    }

    /// The `vt` and `f` lines.
    pub fn tail(&self) -> &[u8] {
        &self.tail
    }

    /// The whole file of one frame (for callers that write a single OBJ).
    pub fn file(&self, positions: &[V3], note: &str) -> Vec<u8> {
        let mut bytes = Vec::new();
        self.head(positions, note, &mut bytes);
        bytes.extend_from_slice(&self.tail);
        bytes
    }
}
