//! One frame as the page reads it: a fixed header, then arrays the page wraps as typed arrays without copying
//! (every section is a multiple of 4 bytes, so each starts 4-byte aligned).
//!
//! Layout, little-endian:
//!
//! | bytes | field |
//! | --- | --- |
//! | 4 | magic `CRVF` |
//! | 4 | `u32` version (1) |
//! | 4 | `u32` frame (0-based) |
//! | 4 | `u32` flags: 1 input, 2 output, 4 displacement, 8 stretch |
//! | 4 | `u32` vertices V |
//! | 4 | `u32` triangles T |
//! | 4 | `u32` anchors A |
//! | 4 | `u32` control lines L |
//! | 4 | `u32` control-line points P |
//! | 4 | reserved, 0 |
//!
//! then, each only when its flag is set: input positions (`f32` × 3V), output positions (`f32` × 3V),
//! displacement |output − input| per vertex (`f32` × V), stretch per triangle (`f32` × T); then always the
//! anchors' triangles (`u32` × A), the control lines' point counts (`u32` × L) and their points (`f32` × 3P).
//!
//! Positions and control-line points are sent relative to the scene's origin (`meta.json`'s `origin`): `f32`
//! keeps about seven digits, which is sub-micrometre for a metre-sized garment near the origin, but not for
//! one captured a few hundred metres from it.

use crease_core::vec3::V3;

pub const MAGIC: &[u8; 4] = b"CRVF";
pub const VERSION: u32 = 1;
pub const HEADER_BYTES: usize = 40;

pub const HAS_INPUT: u32 = 1;
pub const HAS_OUTPUT: u32 = 2;
pub const HAS_DISPLACEMENT: u32 = 4;
pub const HAS_STRETCH: u32 = 8;

/// What goes into one frame's buffer.
#[derive(Debug, Clone, Default)]
pub struct FrameParts<'a> {
    pub frame: usize,
    pub n_vertices: usize,
    pub n_triangles: usize,
    pub origin: V3,
    pub input: Option<&'a [V3]>,
    pub output: Option<&'a [V3]>,
    pub displacement: Option<&'a [f64]>,
    pub stretch: Option<&'a [f64]>,
    pub anchors: &'a [u32],
    pub lines: &'a [Vec<V3>],
}

/// The decoded form (tests and tools; the page has its own reader of the same layout).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Decoded {
    pub frame: u32,
    pub n_vertices: usize,
    pub n_triangles: usize,
    pub input: Option<Vec<f32>>,
    pub output: Option<Vec<f32>>,
    pub displacement: Option<Vec<f32>>,
    pub stretch: Option<Vec<f32>>,
    pub anchors: Vec<u32>,
    pub line_lengths: Vec<u32>,
    pub line_points: Vec<f32>,
}

fn u32_of(n: usize, what: &str) -> u32 {
    u32::try_from(n).unwrap_or_else(|_| panic!("{what} {n} does not fit the frame buffer's u32"))
}

fn push_u32(out: &mut Vec<u8>, v: u32) {
    out.extend_from_slice(&v.to_le_bytes());
}

fn push_f32(out: &mut Vec<u8>, v: f64) {
    out.extend_from_slice(&(v as f32).to_le_bytes());
}

fn push_points(out: &mut Vec<u8>, points: &[V3], origin: V3) {
    for p in points {
        for k in 0..3 {
            push_f32(out, p[k] - origin[k]);
        }
    }
}

/// Encodes one frame. Array lengths must match the counts (a mismatch is a bug in the caller, not bad input:
/// the scene checks every frame against the topology before it gets here).
pub fn encode(p: &FrameParts) -> Vec<u8> {
    let (v, t) = (p.n_vertices, p.n_triangles);
    for (name, len, want) in [
        ("input", p.input.map(<[V3]>::len), v),
        ("output", p.output.map(<[V3]>::len), v),
        ("displacement", p.displacement.map(<[f64]>::len), v),
        ("stretch", p.stretch.map(<[f64]>::len), t),
    ] {
        if let Some(len) = len {
            assert_eq!(len, want, "frame {}: {name} has {len} values", p.frame);
        }
    }
    let points: usize = p.lines.iter().map(Vec::len).sum();
    let flags = [
        (p.input.is_some(), HAS_INPUT),
        (p.output.is_some(), HAS_OUTPUT),
        (p.displacement.is_some(), HAS_DISPLACEMENT),
        (p.stretch.is_some(), HAS_STRETCH),
    ]
    .iter()
    .filter(|(on, _)| *on)
    .fold(0, |f, (_, bit)| f | bit);
    let floats = p.input.map_or(0, |_| 3 * v)
        + p.output.map_or(0, |_| 3 * v)
        + p.displacement.map_or(0, |_| v)
        + p.stretch.map_or(0, |_| t);
    let mut out = Vec::with_capacity(
        HEADER_BYTES + 4 * (floats + p.anchors.len() + p.lines.len() + 3 * points),
    );
    out.extend_from_slice(MAGIC);
    for x in [
        VERSION,
        u32_of(p.frame, "frame"),
        flags,
        u32_of(v, "vertices"),
        u32_of(t, "triangles"),
        u32_of(p.anchors.len(), "anchors"),
        u32_of(p.lines.len(), "control lines"),
        u32_of(points, "control-line points"),
        0,
    ] {
        push_u32(&mut out, x);
    }
    for positions in [p.input, p.output].into_iter().flatten() {
        push_points(&mut out, positions, p.origin);
    }
    for values in [p.displacement, p.stretch].into_iter().flatten() {
        for &x in values {
            push_f32(&mut out, x);
        }
    }
    for &a in p.anchors {
        push_u32(&mut out, a);
    }
    for line in p.lines {
        push_u32(&mut out, u32_of(line.len(), "control-line length"));
    }
    for line in p.lines {
        push_points(&mut out, line, p.origin);
    }
    out
}

/// Reads a buffer written by [`encode`]; an error names the field that does not fit.
pub fn decode(bytes: &[u8]) -> Result<Decoded, String> {
    let mut at = 0usize;
    let mut word = |what: &str| -> Result<[u8; 4], String> {
        let w = bytes
            .get(at..at + 4)
            .ok_or_else(|| format!("truncated at {what} (byte {at} of {})", bytes.len()))?;
        at += 4;
        Ok([w[0], w[1], w[2], w[3]])
    };
    if &word("magic")? != MAGIC {
        return Err("not a viewer frame (magic is not CRVF)".into());
    }
    let mut header = [0u32; 9];
    for (k, h) in header.iter_mut().enumerate() {
        *h = u32::from_le_bytes(word(&format!("header word {k}"))?);
    }
    let [version, frame, flags, v, t, a, l, p, _] = header;
    if version != VERSION {
        return Err(format!(
            "frame buffer version {version}, expected {VERSION}"
        ));
    }
    let (v, t) = (v as usize, t as usize);
    let mut floats = |n: usize, what: &str| -> Result<Vec<f32>, String> {
        (0..n).map(|_| word(what).map(f32::from_le_bytes)).collect()
    };
    let mut d = Decoded {
        frame,
        n_vertices: v,
        n_triangles: t,
        ..Default::default()
    };
    if flags & HAS_INPUT != 0 {
        d.input = Some(floats(3 * v, "input positions")?);
    }
    if flags & HAS_OUTPUT != 0 {
        d.output = Some(floats(3 * v, "output positions")?);
    }
    if flags & HAS_DISPLACEMENT != 0 {
        d.displacement = Some(floats(v, "displacement")?);
    }
    if flags & HAS_STRETCH != 0 {
        d.stretch = Some(floats(t, "stretch")?);
    }
    d.anchors = floats(a as usize, "anchors")?
        .into_iter()
        .map(f32::to_bits)
        .collect();
    d.line_lengths = floats(l as usize, "control-line lengths")?
        .into_iter()
        .map(f32::to_bits)
        .collect();
    let points: u64 = d.line_lengths.iter().map(|&n| n as u64).sum();
    if points != p as u64 {
        return Err(format!(
            "control lines hold {points} points, the header says {p}"
        ));
    }
    d.line_points = floats(3 * p as usize, "control-line points")?;
    if at != bytes.len() {
        return Err(format!("{} bytes after the last section", bytes.len() - at));
    }
    Ok(d)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_reads_back_as_written_relative_to_the_origin() {
        let origin = [100.0, -50.0, 2.0];
        let input = vec![
            [100.0, -50.0, 2.0],
            [101.0, -50.0, 2.0],
            [100.0, -49.0, 2.5],
        ];
        let output = vec![
            [100.0, -50.0, 2.25],
            [101.0, -50.0, 2.0],
            [100.0, -49.0, 2.5],
        ];
        let lines = vec![
            vec![[100.5, -50.0, 2.0], [100.5, -49.5, 2.0]],
            vec![[101.0, -49.0, 2.0]],
        ];
        let bytes = encode(&FrameParts {
            frame: 7,
            n_vertices: 3,
            n_triangles: 1,
            origin,
            input: Some(&input),
            output: Some(&output),
            displacement: Some(&[0.25, 0.0, 0.0]),
            stretch: Some(&[0.125]),
            anchors: &[0],
            lines: &lines,
        });
        assert_eq!(bytes.len() % 4, 0);
        let d = decode(&bytes).unwrap();
        assert_eq!(d.frame, 7);
        assert_eq!(
            d.input.unwrap(),
            [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.5]
        );
        assert_eq!(d.output.unwrap()[..3], [0.0, 0.0, 0.25]);
        assert_eq!(d.displacement.unwrap(), [0.25, 0.0, 0.0]);
        assert_eq!(d.stretch.unwrap(), [0.125]);
        assert_eq!(d.anchors, [0]);
        assert_eq!(d.line_lengths, [2, 1]);
        assert_eq!(d.line_points, [0.5, 0.0, 0.0, 0.5, 0.5, 0.0, 1.0, 1.0, 0.0]);
    }

    /// One triangle's input alone.
    fn input_alone() -> Vec<u8> {
        let input = vec![[0.0; 3]; 3];
        encode(&FrameParts {
            n_vertices: 3,
            n_triangles: 1,
            input: Some(&input),
            ..Default::default()
        })
    }

    #[test]
    fn an_input_alone_has_no_output_sections() {
        let bytes = input_alone();
        assert_eq!(bytes.len(), HEADER_BYTES + 9 * 4);
        let d = decode(&bytes).unwrap();
        assert!(d.output.is_none() && d.stretch.is_none() && d.displacement.is_none());
    }

    #[test]
    fn truncated_or_foreign_buffers_are_refused_with_the_field() {
        let bytes = input_alone();
        let e = decode(&bytes[..bytes.len() - 4]).unwrap_err();
        assert!(e.contains("input positions"), "{e}");
        let e = decode(b"PNG\0").unwrap_err();
        assert!(e.contains("magic"), "{e}");
        let mut extra = bytes.clone();
        extra.extend_from_slice(&[0; 4]);
        assert!(decode(&extra)
            .unwrap_err()
            .contains("after the last section"));
    }
}
