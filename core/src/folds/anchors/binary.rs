//! The binary form of detected anchors, for hand-offs between tasks of one job.
//!
//! A paper-scale stretch job detects some 45K anchors per frame, each with its fold's control lines; as JSON a
//! 20-frame job moved hundreds of megabytes through text three times (tracing chunks → merge →
//! `anchors.json` → every weight task), and parsing dominated the merge. Here the same values are stored as
//! their bits, so a reader gets exactly what the writer had (no decimal round trip) at memory speed.
//! `anchors.json` stays the user-facing file; this form only travels under `.crease-work/`.
//!
//! Layout, all little-endian: the magic `CREASEAB`, a `u32` format version ([`VERSION`]), a `u32` [`Kind`]
//! saying what the payload holds, a `u64` payload length, then the payload. Counts inside the payload are
//! `u64`s checked against the bytes left before anything is allocated, so a truncated or damaged file gives an
//! error naming the file and the field where it ends, never a panic or a silently shorter list.

use super::{Anchor, AnchorSet, FrameAnchors, FrameDetection};
use crate::error::{Error, Result};
use crate::vec3::V3;
use std::path::Path;

/// Bumped whenever the payload layout changes; a reader refuses any other version.
pub const VERSION: u32 = 1;
const MAGIC: &[u8; 8] = b"CREASEAB";
const HEADER: usize = 8 + 4 + 4 + 8;

/// What a binary anchors file holds, so that one kind is never read as another.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// A whole sequence's anchors ([`AnchorSet::to_binary`]).
    AnchorSet = 1,
    /// A stretch tracing chunk ([`crate::folds::stretch::split::TracedChunk`]).
    TracedChunk = 2,
    /// A detection chunk's frames with their detection figures ([`frames_to_binary`]).
    Frames = 3,
}

impl Kind {
    fn name(code: u32) -> &'static str {
        match code {
            1 => "an anchor set",
            2 => "a stretch tracing chunk",
            3 => "a detection chunk",
            _ => "an unknown kind",
        }
    }
}

/// Builds one binary file: header, then values appended in order.
pub struct Writer {
    buf: Vec<u8>,
}

impl Writer {
    pub fn new(kind: Kind) -> Self {
        let mut buf = Vec::with_capacity(1 << 16);
        buf.extend_from_slice(MAGIC);
        buf.extend_from_slice(&VERSION.to_le_bytes());
        buf.extend_from_slice(&(kind as u32).to_le_bytes());
        buf.extend_from_slice(&0u64.to_le_bytes());
        Writer { buf }
    }

    pub fn u32(&mut self, v: u32) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    pub fn u64(&mut self, v: u64) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A count or index (stored as `u64` whatever the platform's `usize`).
    pub fn size(&mut self, v: usize) {
        self.u64(v as u64);
    }

    pub fn f64(&mut self, v: f64) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A `u64` count followed by the values.
    pub fn u32s(&mut self, v: &[u32]) {
        self.size(v.len());
        self.buf.reserve(4 * v.len());
        for &x in v {
            self.u32(x);
        }
    }

    /// The finished bytes, with the payload length filled in.
    pub fn finish(mut self) -> Vec<u8> {
        let n = (self.buf.len() - HEADER) as u64;
        self.buf[16..24].copy_from_slice(&n.to_le_bytes());
        self.buf
    }
}

/// Reads one binary file written by [`Writer`]; every error names `path` and the field being read.
pub struct Reader<'a> {
    path: &'a Path,
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    /// Checks the header: magic, version, kind and that the payload is all there.
    pub fn open(path: &'a Path, bytes: &'a [u8], kind: Kind) -> Result<Self> {
        let bad = |msg: String| Error::format(path, None, msg);
        if bytes.len() < HEADER || &bytes[..8] != MAGIC {
            return Err(bad(format!(
                "not a crease binary anchors file ({} bytes, no `CREASEAB` header)",
                bytes.len()
            )));
        }
        let word = |i: usize| u32::from_le_bytes(bytes[i..i + 4].try_into().expect("4 bytes"));
        let version = word(8);
        if version != VERSION {
            return Err(bad(format!(
                "binary anchors format version {version}; this crease reads version {VERSION} \
                 (written by a different crease: run the job again)"
            )));
        }
        let code = word(12);
        if code != kind as u32 {
            return Err(bad(format!(
                "holds {}, expected {}",
                Kind::name(code),
                Kind::name(kind as u32)
            )));
        }
        let declared = u64::from_le_bytes(bytes[16..24].try_into().expect("8 bytes"));
        let have = (bytes.len() - HEADER) as u64;
        if declared != have {
            return Err(bad(format!(
                "{} payload bytes where the header says {declared}: the file is {}",
                have,
                if have < declared {
                    "truncated"
                } else {
                    "longer than written"
                }
            )));
        }
        Ok(Reader {
            path,
            bytes,
            pos: HEADER,
        })
    }

    fn error(&self, msg: String) -> Error {
        Error::format(self.path, None, msg)
    }

    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8]> {
        let left = self.bytes.len() - self.pos;
        if n > left {
            return Err(self.error(format!(
                "{what}: needs {n} bytes at offset {}, {left} left (truncated or damaged)",
                self.pos
            )));
        }
        let s = &self.bytes[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }

    pub fn u32(&mut self, what: &str) -> Result<u32> {
        Ok(u32::from_le_bytes(
            self.take(4, what)?.try_into().expect("4 bytes"),
        ))
    }

    pub fn u64(&mut self, what: &str) -> Result<u64> {
        Ok(u64::from_le_bytes(
            self.take(8, what)?.try_into().expect("8 bytes"),
        ))
    }

    pub fn f64(&mut self, what: &str) -> Result<f64> {
        Ok(f64::from_bits(self.u64(what)?))
    }

    /// A count of items of `item_bytes` bytes each that must still fit in the file.
    pub fn count(&mut self, item_bytes: usize, what: &str) -> Result<usize> {
        let n = self.u64(what)?;
        let left = (self.bytes.len() - self.pos) as u64;
        if n.saturating_mul(item_bytes as u64) > left {
            return Err(self.error(format!(
                "{what}: {n} entries of {item_bytes} bytes do not fit in the {left} bytes left \
                 (truncated or damaged)"
            )));
        }
        Ok(n as usize)
    }

    /// A `u64` count followed by that many `u32`s.
    pub fn u32s(&mut self, what: &str) -> Result<Vec<u32>> {
        let n = self.count(4, what)?;
        let raw = self.take(4 * n, what)?;
        Ok(raw
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes(c.try_into().expect("4 bytes")))
            .collect())
    }

    /// Exactly `n` `f64`s (`n` already checked by [`Reader::count`] or known).
    pub fn f64s(&mut self, n: usize, what: &str) -> Result<Vec<f64>> {
        let raw = self.take(n.saturating_mul(8), what)?;
        Ok(raw
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
            .collect())
    }

    /// Fails if anything follows what was read.
    pub fn end(self) -> Result<()> {
        match self.bytes.len() - self.pos {
            0 => Ok(()),
            n => Err(self.error(format!("{n} bytes after the last field"))),
        }
    }
}

const NO_VALUE: u64 = u64::MAX;

/// Writes `frames` columnwise: per frame its number, counts and detection figures; then every anchor's
/// triangle, every anchor's axis and angle, every control line's length and every line point.
pub fn write_frames(w: &mut Writer, frames: &[FrameAnchors]) {
    w.size(frames.len());
    for f in frames {
        w.size(f.frame);
        w.size(f.anchors.len());
        w.size(f.control_lines.len());
        match f.detection {
            None => {
                w.u64(NO_VALUE);
                w.u64(NO_VALUE);
            }
            Some(d) => {
                w.size(d.folds);
                w.u64(d.seeds_tried.map_or(NO_VALUE, |s| s as u64));
            }
        }
    }
    write_anchors(w, frames.iter().flat_map(|f| &f.anchors));
    for f in frames {
        for line in &f.control_lines {
            w.size(line.len());
        }
    }
    for f in frames {
        for p in f.control_lines.iter().flatten() {
            for &c in p {
                w.f64(c);
            }
        }
    }
}

fn write_anchors<'a>(w: &mut Writer, anchors: impl Iterator<Item = &'a Anchor> + Clone) {
    for a in anchors.clone() {
        w.u32(a.triangle);
    }
    for a in anchors {
        for c in a.axis {
            w.f64(c);
        }
        w.f64(a.angle);
    }
}

/// `n` anchors as [`write_anchors`] stores them.
pub fn read_anchors(r: &mut Reader, n: usize, what: &str) -> Result<Vec<Anchor>> {
    let tri = r.take(4 * n, what)?;
    let vals = r.f64s(4 * n, what)?;
    Ok(tri
        .chunks_exact(4)
        .zip(vals.chunks_exact(4))
        .map(|(t, v)| Anchor {
            triangle: u32::from_le_bytes(t.try_into().expect("4 bytes")),
            axis: [v[0], v[1], v[2]],
            angle: v[3],
        })
        .collect())
}

/// Writes `anchors` with their count first (the form [`read_anchor_list`] reads).
pub fn write_anchor_list(w: &mut Writer, anchors: &[Anchor]) {
    w.size(anchors.len());
    write_anchors(w, anchors.iter());
}

pub fn read_anchor_list(r: &mut Reader, what: &str) -> Result<Vec<Anchor>> {
    let n = r.count(36, what)?;
    read_anchors(r, n, what)
}

/// Reads what [`write_frames`] wrote.
pub fn read_frames(r: &mut Reader) -> Result<Vec<FrameAnchors>> {
    let n = r.count(40, "frame table")?;
    let mut frames = Vec::with_capacity(n);
    let (mut n_anchors, mut n_lines) = (0usize, 0usize);
    for i in 0..n {
        let what = format!("frame table entry {i}");
        let frame = r.u64(&what)? as usize;
        let a = r.u64(&what)? as usize;
        let l = r.u64(&what)? as usize;
        let folds = r.u64(&what)?;
        let seeds = r.u64(&what)?;
        n_anchors = n_anchors
            .checked_add(a)
            .ok_or_else(|| r.error(format!("{what}: anchor count overflows")))?;
        n_lines = n_lines
            .checked_add(l)
            .ok_or_else(|| r.error(format!("{what}: line count overflows")))?;
        let detection = (folds != NO_VALUE).then(|| FrameDetection {
            folds: folds as usize,
            seeds_tried: (seeds != NO_VALUE).then_some(seeds as usize),
        });
        frames.push((frame, a, l, detection));
    }
    if n_anchors.saturating_mul(36) > r.bytes.len() - r.pos {
        return Err(r.error(format!(
            "anchors: the frame table lists {n_anchors}, more than the file holds (truncated or damaged)"
        )));
    }
    let mut anchors = read_anchors(r, n_anchors, "anchors")?.into_iter();
    if n_lines.saturating_mul(8) > r.bytes.len() - r.pos {
        return Err(r.error(format!(
            "control lines: the frame table lists {n_lines}, more than the file holds (truncated or damaged)"
        )));
    }
    let mut lengths = Vec::with_capacity(n_lines);
    let mut n_points = 0usize;
    for k in 0..n_lines {
        let len = r.u64("control line lengths")? as usize;
        n_points = n_points
            .checked_add(len)
            .ok_or_else(|| r.error(format!("control line {k}: point count overflows")))?;
        lengths.push(len);
    }
    let points = r.f64s(n_points.saturating_mul(3), "control line points")?;
    let mut points = points.chunks_exact(3).map(|c| [c[0], c[1], c[2]]);
    let mut lengths = lengths.into_iter();
    Ok(frames
        .into_iter()
        .map(|(frame, a, l, detection)| FrameAnchors {
            frame,
            anchors: anchors.by_ref().take(a).collect(),
            control_lines: lengths
                .by_ref()
                .take(l)
                .map(|len| points.by_ref().take(len).collect::<Vec<V3>>())
                .collect(),
            detection,
        })
        .collect())
}

/// A detection chunk's frames (detection figures included) in the binary form.
pub fn frames_to_binary(frames: &[FrameAnchors]) -> Vec<u8> {
    let mut w = Writer::new(Kind::Frames);
    write_frames(&mut w, frames);
    w.finish()
}

/// Reads [`frames_to_binary`]'s bytes as written (no validation: the merge validates the whole set).
pub fn frames_from_binary(bytes: &[u8], path: &Path) -> Result<Vec<FrameAnchors>> {
    let mut r = Reader::open(path, bytes, Kind::Frames)?;
    let frames = read_frames(&mut r)?;
    r.end()?;
    Ok(frames)
}

impl AnchorSet {
    /// The set in the binary form (see the module documentation), every value bit for bit.
    pub fn to_binary(&self) -> Vec<u8> {
        let mut w = Writer::new(Kind::AnchorSet);
        write_frames(&mut w, &self.frames);
        w.finish()
    }

    /// Reads [`AnchorSet::to_binary`]'s bytes and validates them for a sequence of `n_frames` frames and
    /// `n_triangles` triangles exactly as [`AnchorSet::parse`] validates a file (so a set read either way is
    /// the same); `path` names the file in errors.
    pub fn from_binary(
        bytes: &[u8],
        path: &Path,
        n_frames: usize,
        n_triangles: usize,
    ) -> Result<Self> {
        let mut r = Reader::open(path, bytes, Kind::AnchorSet)?;
        let frames = read_frames(&mut r)?;
        r.end()?;
        AnchorSet::from_stored_frames(frames, path, n_frames, n_triangles)
    }

    /// [`AnchorSet::from_binary`] of frames already read from the binary form (`read_frames`): the same checks
    /// against the sequence, for a caller that also needs the values as stored.
    pub fn from_stored_frames(
        frames: Vec<FrameAnchors>,
        path: &Path,
        n_frames: usize,
        n_triangles: usize,
    ) -> Result<Self> {
        if frames.len() != n_frames {
            return Err(Error::Anchors {
                path: Some(path.to_path_buf()),
                msg: format!(
                    "anchors for {} frames, the sequence has {n_frames}",
                    frames.len()
                ),
            });
        }
        AnchorSet::from_frame_anchors(frames, n_triangles, Some(path))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> AnchorSet {
        let frames = vec![
            FrameAnchors {
                frame: 0,
                anchors: vec![
                    Anchor {
                        triangle: 3,
                        axis: [0.0, 0.6, 0.8],
                        angle: 0.25,
                    },
                    Anchor {
                        triangle: 7,
                        axis: [1.0, 0.0, 0.0],
                        angle: -1.0e-300,
                    },
                ],
                control_lines: vec![vec![[0.1, 0.2, 0.3], [0.4, 0.5, 0.6]], vec![[1.0; 3]]],
                detection: None,
            },
            FrameAnchors {
                frame: 1,
                ..Default::default()
            },
            FrameAnchors {
                frame: 2,
                anchors: vec![Anchor {
                    triangle: 9,
                    axis: [0.0, 0.0, 1.0],
                    angle: std::f64::consts::PI,
                }],
                control_lines: vec![],
                detection: None,
            },
        ];
        AnchorSet::from_frame_anchors(frames, 10, None).unwrap()
    }

    fn bits(s: &AnchorSet) -> Vec<u64> {
        let mut out = Vec::new();
        for t in 0..s.n_frames() {
            out.push(t as u64);
            for a in s.frame(t) {
                out.push(a.triangle as u64);
                out.extend(a.axis.iter().map(|x| x.to_bits()));
                out.push(a.angle.to_bits());
            }
            for l in s.control_lines(t) {
                out.push(l.len() as u64);
                out.extend(l.iter().flatten().map(|x| x.to_bits()));
            }
        }
        out
    }

    #[test]
    fn round_trips_bit_for_bit_and_agrees_with_the_json() {
        let s = sample();
        let bytes = s.to_binary();
        let back = AnchorSet::from_binary(&bytes, Path::new("a.bin"), 3, 10).unwrap();
        assert_eq!(bits(&back), bits(&s));
        assert_eq!(back.to_json(), s.to_json());
        let via_json = AnchorSet::parse(&s.to_json(), None, 3, 10).unwrap();
        assert_eq!(bits(&back), bits(&via_json));
    }

    #[test]
    fn every_truncation_and_wrong_header_is_an_error_naming_the_file() {
        let bytes = sample().to_binary();
        for cut in 0..bytes.len() {
            let e = AnchorSet::from_binary(&bytes[..cut], Path::new("dir/a.bin"), 3, 10)
                .unwrap_err()
                .to_string();
            assert!(e.contains("dir/a.bin"), "cut at {cut}: {e}");
        }
        let mut v2 = bytes.clone();
        v2[8] = 2;
        let e = AnchorSet::from_binary(&v2, Path::new("a.bin"), 3, 10).unwrap_err();
        assert!(e.to_string().contains("version 2"), "{e}");
        let mut other = bytes.clone();
        other[12] = Kind::TracedChunk as u8;
        let e = AnchorSet::from_binary(&other, Path::new("a.bin"), 3, 10).unwrap_err();
        assert!(e.to_string().contains("tracing chunk"), "{e}");
        let e = AnchorSet::from_binary(&bytes, Path::new("a.bin"), 4, 10).unwrap_err();
        assert!(e.to_string().contains("3 frames"), "{e}");
        let e = AnchorSet::from_binary(&bytes, Path::new("a.bin"), 3, 8).unwrap_err();
        assert!(e.to_string().contains("triangle 9 is out of range"), "{e}");
    }

    #[test]
    fn detection_chunks_keep_their_figures() {
        let mut frames: Vec<FrameAnchors> = (0..3).map(|t| sample().frames[t].clone()).collect();
        frames[1].detection = Some(FrameDetection {
            folds: 2,
            seeds_tried: None,
        });
        frames[2].detection = Some(FrameDetection {
            folds: 0,
            seeds_tried: Some(0),
        });
        let back = frames_from_binary(&frames_to_binary(&frames), Path::new("c.bin")).unwrap();
        assert_eq!(
            serde_json::to_string(&back).unwrap(),
            serde_json::to_string(&frames).unwrap()
        );
        let e = frames_from_binary(&sample().to_binary(), Path::new("c.bin")).unwrap_err();
        assert!(e.to_string().contains("holds an anchor set"), "{e}");
    }

    #[test]
    fn a_damaged_count_is_refused_before_allocating() {
        let mut bytes = sample().to_binary();
        // The frame count (first payload word) claims 2^60 frames; the payload length is left as written.
        bytes[HEADER..HEADER + 8].copy_from_slice(&(1u64 << 60).to_le_bytes());
        let e = AnchorSet::from_binary(&bytes, Path::new("a.bin"), 3, 10).unwrap_err();
        assert!(e.to_string().contains("frame table"), "{e}");
        let mut bytes = sample().to_binary();
        // Frame 0's anchor count (second word of its table entry).
        let at = HEADER + 8 + 8;
        bytes[at..at + 8].copy_from_slice(&u64::MAX.to_le_bytes());
        let e = AnchorSet::from_binary(&bytes, Path::new("a.bin"), 3, 10).unwrap_err();
        assert!(e.to_string().contains("a.bin"), "{e}");
    }
}
