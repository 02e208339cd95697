//! PC2 point caches as an export: the same little-endian layout `crease run` writes for point-cache inputs
//! (see [`crate::mesh::io`]), here from any source, with the export's start frame and one sample per frame.

use super::staging::{put, write_staged};
use super::{ExportOptions, FrameReader};
use crate::error::{Error, Result};
use crate::mesh::io::Pc2Header;
use std::path::Path;

pub fn write_pc2_cache(frames: &FrameReader, out: &Path, opts: &ExportOptions) -> Result<()> {
    let header = Pc2Header {
        num_points: frames.source.topology().n_vertices(),
        start_frame: opts.first_frame as f32,
        sample_rate: 1.0,
        num_samples: frames.n_frames(),
    };
    crate::mesh::io::pc2_check_counts(out, header.num_points, header.num_samples)?;
    write_staged(out, |w| {
        put(w, out, &header.to_bytes())?;
        let mut buf = Vec::new();
        for t in 0..header.num_samples {
            let frame = frames.read(t)?;
            crate::mesh::io::pc2_encode_sample(&frame, &mut buf)
                .map_err(|m| Error::mesh(m).at(Some(out.to_path_buf()), Some(t)))?;
            put(w, out, &buf)?;
        }
        Ok(())
    })
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::super::test_support::two_triangles;
    use super::super::{export, ExportFormat, ExportOptions};
    use crate::mesh::io::{read_pc2_header, read_pc2_sample_from};
    use crate::progress::NoProgress;

    #[test]
    fn reads_back_with_the_pc2_reader() {
        let seq = two_triangles(5);
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("a.pc2");
        export(
            &seq,
            ExportFormat::Pc2,
            &out,
            &ExportOptions::default(),
            &NoProgress,
        )
        .unwrap();
        let h = read_pc2_header(&out).unwrap();
        assert_eq!((h.num_points, h.num_samples, h.start_frame), (4, 5, 1.0));
        let mut f = std::fs::File::open(&out).unwrap();
        for t in 0..5 {
            let s = read_pc2_sample_from(&out, &mut f, &h, t).unwrap();
            for v in 0..4 {
                for c in 0..3 {
                    assert_eq!(s[v][c] as f32, seq.frames[t][v][c] as f32);
                }
            }
        }
    }
}
