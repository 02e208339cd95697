//! The PC2 point-cache format (Maya/Max/Blender): a 32-byte header followed by `samples × points` positions as
//! little-endian `f32` triples, one block per sample. The fixed layout is what lets a sample be read with a
//! single seek, so a long cache never has to be held in memory.
//!
//! Header: `POINTCACHE2\0`, i32 version (1), i32 point count, f32 start frame, f32 sample rate, i32 sample count.

use crate::error::{Error, Result};
use crate::fsutil;
use crate::vec3::V3;
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::Path;

const MAGIC: &[u8; 12] = b"POINTCACHE2\0";

/// The header of a PC2 file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pc2Header {
    pub num_points: usize,
    pub start_frame: f32,
    pub sample_rate: f32,
    pub num_samples: usize,
}

impl Pc2Header {
    /// Size of the header in bytes.
    pub const LEN: u64 = 32;

    /// Bytes of one sample (`num_points` × 3 × f32).
    pub fn sample_len(&self) -> Option<u64> {
        (self.num_points as u64).checked_mul(12)
    }

    /// Byte offset of sample `t`.
    pub fn sample_offset(&self, t: usize) -> Option<u64> {
        self.sample_len()?
            .checked_mul(t as u64)?
            .checked_add(Self::LEN)
    }

    /// Exact size of a well-formed file with this header.
    pub fn file_len(&self) -> Option<u64> {
        self.sample_offset(self.num_samples)
    }

    /// The 32 header bytes. Counts must fit in an i32 (checked by the writers before calling this).
    pub(crate) fn to_bytes(self) -> [u8; 32] {
        let mut b = [0u8; 32];
        b[..12].copy_from_slice(MAGIC);
        b[12..16].copy_from_slice(&1i32.to_le_bytes());
        b[16..20].copy_from_slice(&(self.num_points as i32).to_le_bytes());
        b[20..24].copy_from_slice(&self.start_frame.to_le_bytes());
        b[24..28].copy_from_slice(&self.sample_rate.to_le_bytes());
        b[28..32].copy_from_slice(&(self.num_samples as i32).to_le_bytes());
        b
    }
}

fn le_i32(b: &[u8; 32], at: usize) -> i32 {
    let mut a = [0u8; 4];
    a.copy_from_slice(&b[at..at + 4]);
    i32::from_le_bytes(a)
}

fn le_f32(b: &[u8; 32], at: usize) -> f32 {
    f32::from_bits(le_i32(b, at) as u32)
}

/// Reads and validates a PC2 header: magic, version 1, positive point and sample counts, and a file size that
/// is exactly header + data. Checking the size up front turns a truncated or over-long cache (an interrupted
/// copy, a wrong file) into an error when the sequence is opened instead of a failure hours into a run.
pub fn read_pc2_header(path: &Path) -> Result<Pc2Header> {
    let mut file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    read_pc2_header_from(path, &mut file)
}

/// [`read_pc2_header`] on any seekable reader (a file, or bytes in memory); `path` only names it in errors.
/// Reads the 32 header bytes and the stream's length, nothing else.
pub fn read_pc2_header_from<R: Read + Seek>(path: &Path, reader: &mut R) -> Result<Pc2Header> {
    let actual = reader
        .seek(SeekFrom::End(0))
        .and_then(|len| reader.seek(SeekFrom::Start(0)).map(|_| len))
        .map_err(|e| Error::io(path, e))?;
    let bad = |msg: String| Error::format(path, None, msg);
    if actual < Pc2Header::LEN {
        return Err(bad(format!(
            "the file is {actual} bytes, shorter than the {}-byte PC2 header",
            Pc2Header::LEN
        )));
    }
    let mut b = [0u8; 32];
    reader.read_exact(&mut b).map_err(|e| Error::io(path, e))?;
    if &b[..12] != MAGIC {
        return Err(bad(format!(
            "not a PC2 point cache: the file starts with {:?} instead of \"POINTCACHE2\\0\"",
            String::from_utf8_lossy(&b[..12])
        )));
    }
    let version = le_i32(&b, 12);
    if version != 1 {
        return Err(bad(format!(
            "unsupported PC2 version {version} (only version 1 exists)"
        )));
    }
    let points = le_i32(&b, 16);
    let samples = le_i32(&b, 28);
    if points <= 0 {
        return Err(bad(format!("the header declares {points} points")));
    }
    if samples <= 0 {
        return Err(bad(format!(
            "the header declares {samples} samples; at least one is needed"
        )));
    }
    let header = Pc2Header {
        num_points: points as usize,
        start_frame: le_f32(&b, 20),
        sample_rate: le_f32(&b, 24),
        num_samples: samples as usize,
    };
    let expected = header
        .file_len()
        .ok_or_else(|| bad("the header's sizes overflow".into()))?;
    if actual != expected {
        return Err(bad(format!(
            "the file is {actual} bytes, but its header ({points} points × {samples} samples) needs exactly \
             {expected} bytes: the cache is {}",
            if actual < expected { "truncated" } else { "over-long (trailing data)" }
        )));
    }
    Ok(header)
}

/// Reads sample `t` (0-based) of a cache from any seekable reader holding the whole cache (a file, or bytes in
/// memory); `path` only names it in errors. `header` should come from [`read_pc2_header_from`] on the same
/// stream.
pub fn read_pc2_sample_from<R: Read + Seek>(
    path: &Path,
    reader: &mut R,
    header: &Pc2Header,
    t: usize,
) -> Result<Vec<V3>> {
    if t >= header.num_samples {
        return Err(Error::param(
            "frame",
            format!(
                "sample {t} is out of range: {} has {} samples",
                path.display(),
                header.num_samples
            ),
        ));
    }
    let offset = header
        .sample_offset(t)
        .ok_or_else(|| Error::format(path, None, "sample offset overflows"))?;
    let len = header.sample_len().and_then(|l| usize::try_from(l).ok());
    let len = len.ok_or_else(|| Error::format(path, None, "sample size overflows"))?;
    reader
        .seek(SeekFrom::Start(offset))
        .map_err(|e| Error::io(path, e))?;
    // Grown as the data arrives rather than sized from the header, so a header that was not checked against
    // this stream cannot make a huge allocation.
    let mut buf = Vec::with_capacity(len.min(1 << 20));
    reader
        .by_ref()
        .take(len as u64)
        .read_to_end(&mut buf)
        .map_err(|e| Error::io(path, e))?;
    if buf.len() < len {
        return Err(Error::format(
            path,
            None,
            format!("sample {t} is cut short (the file changed after it was opened)"),
        ));
    }
    Ok(decode_sample(&buf))
}

/// Little-endian f32 triples → positions.
fn decode_sample(buf: &[u8]) -> Vec<V3> {
    buf.chunks_exact(12)
        .map(|c| {
            let f = |k: usize| {
                let mut a = [0u8; 4];
                a.copy_from_slice(&c[4 * k..4 * k + 4]);
                f64::from(f32::from_le_bytes(a))
            };
            [f(0), f(1), f(2)]
        })
        .collect()
}

/// Positions → little-endian f32 triples. Errors (naming the vertex) when a value is not finite or does not fit
/// in an f32, which would otherwise be written as an infinity that no reader accepts.
pub(crate) fn encode_sample(
    positions: &[V3],
    out: &mut Vec<u8>,
) -> std::result::Result<(), String> {
    out.clear();
    out.reserve(positions.len() * 12);
    for (i, p) in positions.iter().enumerate() {
        for &c in p {
            let v = c as f32;
            if !v.is_finite() {
                return Err(format!(
                    "vertex {i} has coordinate {c}, which a PC2 file (f32) cannot store"
                ));
            }
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    Ok(())
}

/// Checks that counts fit the header's i32 fields.
pub(crate) fn check_counts(path: &Path, points: usize, samples: usize) -> Result<()> {
    if points == 0 || samples == 0 {
        return Err(Error::param(
            "pc2",
            format!(
                "{}: a point cache needs at least one point and one sample",
                path.display()
            ),
        ));
    }
    if points > i32::MAX as usize || samples > i32::MAX as usize {
        return Err(Error::param(
            "pc2",
            format!(
                "{}: {points} points × {samples} samples exceed the PC2 format's limits",
                path.display()
            ),
        ));
    }
    Ok(())
}

/// Writes a whole point cache atomically (all frames must have the same number of points). Used for tests and
/// generated data; [`super::create_sink`] writes caches frame by frame.
pub fn write_pc2(path: &Path, frames: &[Vec<V3>], start: f32, rate: f32) -> Result<()> {
    let points = frames.first().map_or(0, |f| f.len());
    check_counts(path, points, frames.len())?;
    if let Some((t, f)) = frames.iter().enumerate().find(|(_, f)| f.len() != points) {
        return Err(
            Error::mesh(format!("has {} points, frame 0 has {points}", f.len()))
                .at(Some(path.to_path_buf()), Some(t)),
        );
    }
    let header = Pc2Header {
        num_points: points,
        start_frame: start,
        sample_rate: rate,
        num_samples: frames.len(),
    };
    let mut encoded = Vec::with_capacity(frames.len());
    let mut buf = Vec::new();
    for (t, f) in frames.iter().enumerate() {
        encode_sample(f, &mut buf)
            .map_err(|m| Error::mesh(m).at(Some(path.to_path_buf()), Some(t)))?;
        encoded.push(std::mem::take(&mut buf));
    }
    fsutil::write_atomic_with(path, |w| {
        w.write_all(&header.to_bytes())?;
        for sample in &encoded {
            w.write_all(sample)?;
        }
        Ok(())
    })
}
