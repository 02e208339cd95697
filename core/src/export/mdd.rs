//! MDD point caches (LightWave's format, read by Blender's Mesh Cache modifier, Maya and Max): big-endian
//! `i32 frames, i32 points, f32 time[frames]` (seconds), then every frame's points as `f32 x, y, z`. The header
//! holds only counts and times, so frames stream straight after it.

use super::staging::{put, write_staged};
use super::{to_f32, ExportOptions, FrameReader};
use crate::error::{Error, Result};
use std::path::Path;

pub fn write_mdd(frames: &FrameReader, out: &Path, opts: &ExportOptions) -> Result<()> {
    let n = frames.n_frames();
    let points = frames.source.topology().n_vertices();
    let (n32, p32) = match (i32::try_from(n), i32::try_from(points)) {
        (Ok(a), Ok(b)) => (a, b),
        _ => {
            return Err(Error::param(
                "input",
                format!("{n} frames of {points} points do not fit MDD's 32-bit counts"),
            ))
        }
    };
    write_staged(out, |w| {
        put(w, out, &n32.to_be_bytes())?;
        put(w, out, &p32.to_be_bytes())?;
        for t in 0..n {
            put(w, out, &((t as f64 / opts.fps) as f32).to_be_bytes())?;
        }
        let mut buf = Vec::with_capacity(points * 12);
        for t in 0..n {
            let frame = frames.read(t)?;
            buf.clear();
            for p in frame {
                for c in to_f32(p) {
                    buf.extend_from_slice(&c.to_be_bytes());
                }
            }
            put(w, out, &buf)?;
        }
        Ok(())
    })
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::super::test_support::{read_be_f32, read_be_i32, two_triangles};
    use super::super::{export, ExportFormat, ExportOptions};
    use crate::progress::NoProgress;

    #[test]
    fn header_times_and_points_are_big_endian_in_frame_order() {
        let seq = two_triangles(3);
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("a.mdd");
        let opts = ExportOptions {
            fps: 24.0,
            ..Default::default()
        };
        let s = export(&seq, ExportFormat::Mdd, &out, &opts, &NoProgress).unwrap();
        let b = std::fs::read(&out).unwrap();
        assert_eq!(s.bytes as usize, b.len());
        assert_eq!(b.len(), 8 + 3 * 4 + 3 * 4 * 12);
        assert_eq!(read_be_i32(&b, 0), 3);
        assert_eq!(read_be_i32(&b, 4), 4);
        assert_eq!(read_be_f32(&b, 8 + 2 * 4), 2.0 / 24.0);
        let at = |t: usize, v: usize, c: usize| read_be_f32(&b, 20 + (t * 4 + v) * 12 + c * 4);
        for t in 0..3 {
            for v in 0..4 {
                for c in 0..3 {
                    assert_eq!(at(t, v, c), seq.frames[t][v][c] as f32, "t{t} v{v} c{c}");
                }
            }
        }
    }
}
