//! The output contract (docs/formats.md, docs/deepwrinkles.md): per frame N, `OUT/mesh/frame_NNNN.obj` (the coarse mesh with `vt`, faces
//! `f v/vt`) and `OUT/normals/frame_NNNN.png` (the normal map in that layout). Every file is written atomically
//! (temporary name, then rename), so a reader never sees half a frame; `OUT/done.json` is written last, after
//! all frames, and is what says the output is complete.
//!
//! Durability: [`FrameWriter`] does not sync each file as it goes (two device flushes per frame were a large
//! share of an apply's wall time); whoever writes frames calls [`sync_frames`] once they are all written and
//! before anything that vouches for them (`done.json`, a task's success), so a crash can still lose only a
//! run that has not claimed to be complete.

pub mod obj_text;

use crate::contract::obj_text::ObjText;
use crate::normal_maps::uv::UvLayout;
use crate::normal_maps::{NormalMap, PngScratch, PngSettings, Space};
use crease_core::mesh::Topology;
use crease_core::vec3::V3;
use crease_core::{Error, Result};
use std::io::Write;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// File name stem of output frame `t` (0-based): frames are numbered from 1, four digits.
pub fn frame_stem(t: usize) -> String {
    format!("frame_{:04}", t + 1)
}

pub fn mesh_path(out: &Path, t: usize) -> PathBuf {
    out.join("mesh").join(format!("{}.obj", frame_stem(t)))
}

pub fn normals_path(out: &Path, t: usize) -> PathBuf {
    out.join("normals").join(format!("{}.png", frame_stem(t)))
}

/// Creates `OUT/mesh` and `OUT/normals`, and removes a stale completion marker (a rerun into the same folder is
/// incomplete until it finishes).
pub fn prepare(out: &Path) -> Result<()> {
    crease_core::fsutil::create_dir_all(&out.join("mesh"))?;
    crease_core::fsutil::create_dir_all(&out.join("normals"))?;
    let done = out.join("done.json");
    if done.exists() {
        std::fs::remove_file(&done).map_err(|e| crease_core::Error::io(&done, e))?;
    }
    Ok(())
}

/// Writes one frame's two files and syncs them (for callers that write a frame now and then; a sequence goes
/// through [`FrameWriter`] and [`sync_frames`]).
pub fn write_frame(
    out: &Path,
    t: usize,
    topo: &Topology,
    positions: &[V3],
    layout: &UvLayout,
    map: &NormalMap,
    note: &str,
) -> Result<()> {
    FrameWriter::new(topo, layout).write(
        out,
        t,
        positions,
        map,
        note,
        &mut FrameScratch::default(),
    )?;
    sync_frames(out, t..t + 1)
}

/// Writes frames of one model's layout: the OBJ lines that never change are formatted once, the buffers are
/// the caller's [`FrameScratch`] (one per thread), and the files are renamed into place unsynced.
#[derive(Debug, Clone)]
pub struct FrameWriter {
    obj: ObjText,
    png: PngSettings,
}

/// Per-thread buffers of [`FrameWriter::write`], reused from frame to frame.
#[derive(Debug, Clone, Default)]
pub struct FrameScratch {
    obj_head: Vec<u8>,
    png: PngScratch,
}

impl FrameWriter {
    pub fn new(topo: &Topology, layout: &UvLayout) -> Self {
        FrameWriter {
            obj: ObjText::new(topo, &layout.uv, &layout.corners),
            png: PngSettings::default(),
        }
    }

    /// Bytes of the OBJ lines every frame shares (`vt` and `f`), formatted once.
    pub fn constant_obj_bytes(&self) -> usize {
        self.obj.tail().len()
    }

    /// The frame's OBJ (`head` of `scratch` then the constant lines) and PNG bytes, without touching the disk
    /// (what [`FrameWriter::write`] writes; the benchmark times the two halves apart).
    pub fn encode<'s>(
        &self,
        out: &Path,
        t: usize,
        positions: &[V3],
        map: &NormalMap,
        note: &str,
        scratch: &'s mut FrameScratch,
    ) -> Result<(&'s [u8], &'s [u8])> {
        self.obj.head(positions, note, &mut scratch.obj_head);
        let png = map.encode_png(&normals_path(out, t), self.png, &mut scratch.png)?;
        Ok((&scratch.obj_head, png))
    }

    /// Writes frame `t` (0-based) into `out` (prepared by [`prepare`]); each file appears whole or not at all,
    /// durable once [`sync_frames`] has run.
    pub fn write(
        &self,
        out: &Path,
        t: usize,
        positions: &[V3],
        map: &NormalMap,
        note: &str,
        scratch: &mut FrameScratch,
    ) -> Result<()> {
        let (head, png) = self.encode(out, t, positions, map, note, scratch)?;
        write_renamed(&mesh_path(out, t), &[head, self.obj.tail()])?;
        write_renamed(&normals_path(out, t), &[png])
    }
}

/// `parts` written to a temporary name beside `path`, then renamed to it (no sync: see the module docs).
fn write_renamed(path: &Path, parts: &[&[u8]]) -> Result<()> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = path.with_file_name(format!(".{name}.tmp-{}", std::process::id()));
    let result = (|| {
        let mut file = std::fs::File::create(&tmp)?;
        for part in parts {
            file.write_all(part)?;
        }
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(Error::io(path, e));
    }
    Ok(())
}

/// Flushes the files of `frames` to the device (both of each frame), in parallel: written by a
/// [`FrameWriter`], they are durable only after this.
pub fn sync_frames(out: &Path, frames: Range<usize>) -> Result<()> {
    use rayon::prelude::*;
    frames
        .into_par_iter()
        .flat_map_iter(|t| [mesh_path(out, t), normals_path(out, t)])
        .try_for_each(|path| {
            std::fs::File::open(&path)
                .and_then(|f| f.sync_data())
                .map_err(|e| Error::io(&path, e))
        })
}

/// Marks the output complete: frame count, map space and resolution, for people and tools.
pub fn finish(
    out: &Path,
    n_frames: usize,
    space: Space,
    resolution: usize,
    what: &str,
) -> Result<()> {
    let doc = serde_json::json!({
        "complete": true,
        "frames": n_frames,
        "space": space,
        "resolution": resolution,
        "produced_by": what,
    });
    crease_core::fsutil::write_atomic(&out.join("done.json"), doc.to_string().as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::normal_maps::bake_coarse;
    use crate::normal_maps::raster::TexelMap;
    use crate::normal_maps::uv::auto_atlas;

    /// A wavy open tube; `phase` moves every vertex.
    fn tube(phase: f64) -> (Topology, Vec<V3>) {
        let (na, nr) = (20usize, 9usize);
        let mut tris = Vec::new();
        for j in 0..nr - 1 {
            for i in 0..na {
                let i1 = (i + 1) % na;
                let (a, b, c, d) = (j * na + i, j * na + i1, (j + 1) * na + i1, (j + 1) * na + i);
                tris.push([a as u32, b as u32, c as u32]);
                tris.push([a as u32, c as u32, d as u32]);
            }
        }
        let mut p = Vec::new();
        for j in 0..nr {
            for i in 0..na {
                let phi = std::f64::consts::TAU * i as f64 / na as f64;
                let x = 0.6 * j as f64 / (nr - 1) as f64;
                let r = 0.07 + 0.004 * (5.0 * phi + phase).sin() * (9.0 * x).cos();
                p.push([x, r * phi.cos(), r * phi.sin()]);
            }
        }
        // Numbers std writes in unusual ways: tiny (an exponent in ryu's notation), negative zero, an integer.
        p[1][0] = 3.0e-7;
        p[2][0] = -0.0;
        p[3][2] = 2.0;
        (Topology::new(na * nr, tris).unwrap(), p)
    }

    /// The OBJ exactly as the contract's first writer made it (`format!` per number).
    fn obj_as_first_written(topo: &Topology, positions: &[V3], layout: &UvLayout) -> Vec<u8> {
        use std::fmt::Write as _;
        let mut s = String::new();
        s.push_str("# crease deep: coarse mesh with the normal map's UV layout\n");
        s.push_str("# normals: a test\n");
        for p in positions {
            let _ = writeln!(s, "v {} {} {}", p[0], p[1], p[2]);
        }
        for t in &layout.uv {
            let _ = writeln!(s, "vt {} {}", t[0], t[1]);
        }
        for (tri, c) in topo.triangles().iter().zip(&layout.corners) {
            let _ = writeln!(
                s,
                "f {}/{} {}/{} {}/{}",
                tri[0] + 1,
                c[0] + 1,
                tri[1] + 1,
                c[1] + 1,
                tri[2] + 1,
                c[2] + 1
            );
        }
        s.into_bytes()
    }

    /// The gutter fill as first written: the whole map cloned and scanned once per ring.
    fn dilated_as_first_written(m: &NormalMap, rings: usize) -> NormalMap {
        let mut out = m.clone();
        let (w, h) = (m.width as i64, m.height as i64);
        for _ in 0..rings {
            let prev = out.clone();
            for y in 0..h {
                for x in 0..w {
                    let k = (y * w + x) as usize;
                    if prev.covered[k] {
                        continue;
                    }
                    let mut acc = [0.0f32; 3];
                    let mut any = false;
                    for (dx, dy) in [
                        (-1, 0),
                        (1, 0),
                        (0, -1),
                        (0, 1),
                        (-1, -1),
                        (1, 1),
                        (-1, 1),
                        (1, -1),
                    ] {
                        let (xx, yy) = (x + dx, y + dy);
                        if xx >= 0 && yy >= 0 && xx < w && yy < h {
                            let j = (yy * w + xx) as usize;
                            if prev.covered[j] {
                                for (a, v) in acc.iter_mut().zip(prev.n[j]) {
                                    *a += v;
                                }
                                any = true;
                            }
                        }
                    }
                    if any {
                        let n = (acc[0] * acc[0] + acc[1] * acc[1] + acc[2] * acc[2]).sqrt();
                        out.n[k] = if n > 0.0 {
                            [acc[0] / n, acc[1] / n, acc[2] / n]
                        } else {
                            [0.0, 0.0, 1.0]
                        };
                        out.covered[k] = true;
                    }
                }
            }
        }
        out
    }

    /// The PNG as first written: `image`'s buffer of the dilated map, encoded with the crate's defaults.
    fn png_as_first_written(m: &NormalMap) -> Vec<u8> {
        let dilated = dilated_as_first_written(m, 3);
        let mut img =
            image::ImageBuffer::<image::Rgba<u16>, Vec<u16>>::new(m.width as u32, m.height as u32);
        for (k, px) in img.pixels_mut().enumerate() {
            let n = dilated.n[k];
            let enc = |x: f32| (((x.clamp(-1.0, 1.0) + 1.0) * 0.5) * 65535.0).round() as u16;
            let a = if m.covered[k] { 65535 } else { 0 };
            *px = image::Rgba([enc(n[0]), enc(n[1]), enc(n[2]), a]);
        }
        let mut bytes = Vec::new();
        img.write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .unwrap();
        bytes
    }

    #[test]
    fn frames_are_the_bytes_the_first_writer_wrote_and_nothing_else_is_left() {
        let (topo, p0) = tube(0.0);
        let layout = auto_atlas(&topo, &p0, 0.01).unwrap();
        let texels = TexelMap::new(&layout, 48, 48);
        let dir = tempfile::tempdir().unwrap();
        prepare(dir.path()).unwrap();
        let writer = FrameWriter::new(&topo, &layout);
        let mut scratch = FrameScratch::default();
        for (t, phase) in [(0usize, 0.0), (1, 1.7), (2, -0.4)] {
            let (_, p) = tube(phase);
            let map = bake_coarse(&texels, &topo, &p);
            // The gutter fill has work to do, and the old and new fills agree texel for texel.
            let old = dilated_as_first_written(&map, 3);
            assert!(
                old.covered.iter().filter(|&&c| c).count()
                    > map.covered.iter().filter(|&&c| c).count()
            );
            assert_eq!(map.dilated(3), old);
            // The same scratch across frames: nothing of the previous frame may leak into this one.
            writer
                .write(dir.path(), t, &p, &map, "a test", &mut scratch)
                .unwrap();
            assert_eq!(
                std::fs::read(mesh_path(dir.path(), t)).unwrap(),
                obj_as_first_written(&topo, &p, &layout),
                "frame {t} OBJ"
            );
            assert_eq!(
                std::fs::read(normals_path(dir.path(), t)).unwrap(),
                png_as_first_written(&map),
                "frame {t} PNG"
            );
        }
        sync_frames(dir.path(), 0..3).unwrap();
        for sub in ["mesh", "normals"] {
            let names: Vec<String> = std::fs::read_dir(dir.path().join(sub))
                .unwrap()
                .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .collect();
            assert_eq!(names.len(), 3, "{sub}: {names:?} (no temporary files left)");
        }
        // A frame that was never written cannot be vouched for: the error names its file.
        let err = sync_frames(dir.path(), 2..4).unwrap_err().to_string();
        assert!(err.contains("frame_0004"), "{err}");
        // write_frame (one frame, synced) writes the same bytes.
        let other = tempfile::tempdir().unwrap();
        prepare(other.path()).unwrap();
        let (_, p) = tube(-0.4);
        let map = bake_coarse(&texels, &topo, &p);
        write_frame(other.path(), 2, &topo, &p, &layout, &map, "a test").unwrap();
        for path in [mesh_path, normals_path] {
            assert_eq!(
                std::fs::read(path(other.path(), 2)).unwrap(),
                std::fs::read(path(dir.path(), 2)).unwrap()
            );
        }
    }

    #[test]
    fn every_png_setting_decodes_to_the_same_16_bit_pixels() {
        use image::codecs::png::{CompressionType as C, FilterType as F};
        let (topo, p) = tube(0.3);
        let layout = auto_atlas(&topo, &p, 0.01).unwrap();
        let map = bake_coarse(&TexelMap::new(&layout, 40, 40), &topo, &p);
        let decode = |bytes: &[u8]| {
            let img = image::load_from_memory_with_format(bytes, image::ImageFormat::Png).unwrap();
            assert_eq!(img.color(), image::ColorType::Rgba16);
            img.to_rgba16().into_raw()
        };
        let mut scratch = PngScratch::default();
        let reference = decode(&png_as_first_written(&map));
        let mut sizes = Vec::new();
        for (c, f) in [
            (C::Fast, F::Adaptive),
            (C::Default, F::Adaptive),
            (C::Fast, F::Up),
            (C::Uncompressed, F::NoFilter),
        ] {
            let settings = PngSettings {
                compression: c,
                filter: f,
            };
            let bytes = map
                .encode_png(Path::new("m.png"), settings, &mut scratch)
                .unwrap()
                .to_vec();
            assert_eq!(decode(&bytes), reference, "{c:?} {f:?}");
            sizes.push(bytes.len());
        }
        // The settings really differ (else this test would compare one encoding with itself).
        assert!(sizes[3] > sizes[0], "{sizes:?}");
    }
}
