//! A tracing chunk's result in the binary anchors form ([`crate::folds::anchors::binary`]): what one tracing
//! task hands to the merge. Values are stored as their bits, so the merge reconciles exactly the frames the
//! task traced, and the bytes are a pure function of the chunk (a rerun writes the same file).

use super::{ChunkFrame, TracedChunk};
use crate::error::{Error, Result};
use crate::folds::anchors::binary::{
    read_anchor_list, read_frames, write_anchor_list, write_frames, Kind, Reader, Writer,
};
use std::path::Path;

impl TracedChunk {
    /// The chunk as bytes: first frame, entry seeds, the frames' anchors (as [`write_frames`]), then per frame
    /// its seed memory and, for overlay frames, the anchors on the traced mesh and the fold count.
    pub fn to_binary(&self) -> Vec<u8> {
        let mut w = Writer::new(Kind::TracedChunk);
        w.size(self.first);
        w.u32s(&self.entry_seeds);
        let anchors: Vec<_> = self.frames.iter().map(|f| f.anchors.clone()).collect();
        write_frames(&mut w, &anchors);
        for f in &self.frames {
            w.u32s(&f.seeds);
            match &f.overlay {
                None => w.u64(0),
                Some((anchors, folds)) => {
                    w.u64(1);
                    w.size(*folds);
                    write_anchor_list(&mut w, anchors);
                }
            }
        }
        w.finish()
    }

    /// Reads [`TracedChunk::to_binary`]'s bytes; `path` names the file in errors.
    pub fn from_binary(bytes: &[u8], path: &Path) -> Result<Self> {
        let mut r = Reader::open(path, bytes, Kind::TracedChunk)?;
        let first = r.u64("first frame")? as usize;
        let entry_seeds = r.u32s("entry seeds")?;
        let anchors = read_frames(&mut r)?;
        let mut frames = Vec::with_capacity(anchors.len());
        for (k, a) in anchors.into_iter().enumerate() {
            let what = format!("frame {} (entry {k})", a.frame);
            let seeds = r.u32s(&format!("{what}: seeds"))?;
            let overlay = match r.u64(&format!("{what}: overlay flag"))? {
                0 => None,
                1 => {
                    let folds = r.u64(&format!("{what}: overlay folds"))? as usize;
                    Some((
                        read_anchor_list(&mut r, &format!("{what}: overlay anchors"))?,
                        folds,
                    ))
                }
                v => {
                    return Err(Error::format(
                        path,
                        None,
                        format!("{what}: overlay flag {v} (0 or 1 expected)"),
                    ))
                }
            };
            frames.push(ChunkFrame {
                anchors: a,
                seeds,
                overlay,
            });
        }
        r.end()?;
        Ok(TracedChunk {
            first,
            entry_seeds,
            frames,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::folds::{Anchor, FrameAnchors, FrameDetection};

    fn chunk() -> TracedChunk {
        let a = |t: u32, angle: f64| Anchor {
            triangle: t,
            axis: [0.0, 0.6, 0.8],
            angle,
        };
        TracedChunk {
            first: 4,
            entry_seeds: vec![1, 5, 9],
            frames: vec![
                ChunkFrame {
                    anchors: FrameAnchors {
                        frame: 4,
                        anchors: vec![a(2, 0.1), a(3, -0.3)],
                        control_lines: vec![vec![[0.5, 0.25, 1.0 / 3.0]; 3]],
                        detection: Some(FrameDetection {
                            folds: 1,
                            seeds_tried: Some(17),
                        }),
                    },
                    seeds: vec![5],
                    overlay: Some((vec![a(1, 0.2)], 1)),
                },
                ChunkFrame {
                    anchors: FrameAnchors {
                        frame: 5,
                        detection: Some(FrameDetection {
                            folds: 0,
                            seeds_tried: None,
                        }),
                        ..Default::default()
                    },
                    seeds: vec![],
                    overlay: None,
                },
            ],
        }
    }

    #[test]
    fn round_trips_exactly() {
        let c = chunk();
        let bytes = c.to_binary();
        let back = TracedChunk::from_binary(&bytes, Path::new("c.bin")).unwrap();
        // Every field, compared through the JSON form the chunks used to travel in (floats exact there too).
        assert_eq!(
            serde_json::to_string(&back).unwrap(),
            serde_json::to_string(&c).unwrap()
        );
        assert_eq!(back.to_binary(), bytes, "rewriting gives the same bytes");
    }

    #[test]
    fn truncation_and_a_wrong_kind_name_the_file() {
        let bytes = chunk().to_binary();
        for cut in [0, 10, 24, bytes.len() / 2, bytes.len() - 1] {
            let e = TracedChunk::from_binary(&bytes[..cut], Path::new("trace/f000004.bin"))
                .unwrap_err()
                .to_string();
            assert!(e.contains("trace/f000004.bin"), "cut at {cut}: {e}");
        }
        let set = crate::folds::AnchorSet::empty(2).to_binary();
        let e = TracedChunk::from_binary(&set, Path::new("x.bin")).unwrap_err();
        assert!(e.to_string().contains("holds an anchor set"), "{e}");
    }
}
