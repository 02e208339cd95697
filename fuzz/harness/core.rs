//! What each crease-core fuzz target does with one input, shared (through `#[path]`) by the libFuzzer targets
//! in `fuzz/fuzz_targets/` and the corpus replay test `core/tests/fuzz_corpus.rs`, so that the committed
//! corpus is replayed through exactly the code that was fuzzed.
//!
//! Every function goes through the public entry point a user's file reaches, continues into the validation
//! that follows parsing (topology, later frames, samples), and checks that a rejection names the file.

// Each fuzz target uses one function of this file; the replay test uses all of them.
#![allow(dead_code)]

use crease_core::folds::video::CameraRig;
use crease_core::folds::AnchorSet;
use crease_core::mesh::io::{read_pc2_header_from, FrameFormat, FrameReference, Pc2Reference};
use crease_core::Error;
use std::io::Cursor;
use std::path::Path;

/// Splits an input into a first and a second frame file at the first `SEPARATOR`, so one input can describe a
/// sequence (and exercise the checks of later frames against the first); without one, both are the input.
pub const SEPARATOR: &[u8] = b"\n#--next-frame--\n";

fn split_frames(data: &[u8]) -> (&[u8], &[u8]) {
    match data.windows(SEPARATOR.len()).position(|w| w == SEPARATOR) {
        Some(p) => (&data[..p], &data[p + SEPARATOR.len()..]),
        None => (data, data),
    }
}

/// A rejection of a user's file must say which file it is about.
fn assert_names(e: &Error, name: &str) {
    let text = e.to_string();
    assert!(text.contains(name), "error does not name {name}: {text}");
}

fn frames(format: FrameFormat, ext: &str, data: &[u8]) {
    let (first, second) = split_frames(data);
    let (p0, p1) = (format!("frame_0001.{ext}"), format!("frame_0002.{ext}"));
    let reference = match FrameReference::from_first_frame(format, Path::new(&p0), first) {
        Ok(r) => r,
        Err(e) => return assert_names(&e, &p0),
    };
    match reference.check_frame(1, Path::new(&p1), second) {
        Ok(frame) => assert_eq!(frame.len(), reference.topology().n_vertices()),
        Err(e) => assert_names(&e, &p1),
    }
}

/// An OBJ frame sequence: the first frame builds the topology, the second is checked against it.
pub fn obj(data: &[u8]) {
    frames(FrameFormat::Obj, "obj", data);
}

/// A PLY frame sequence (ASCII or binary), as [`obj`].
pub fn ply(data: &[u8]) {
    frames(FrameFormat::Ply, "ply", data);
}

/// Topology of [`pc2`] inputs that carry no OBJ of their own: a unit quad (4 points).
pub const QUAD_OBJ: &[u8] = b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";

/// Most samples of one cache that are read and validated.
const MAX_SAMPLES: usize = 16;

/// An OBJ + PC2 pair: the input is `OBJ bytes` followed by the cache (from its `POINTCACHE2` magic on), or the
/// cache alone with [`QUAD_OBJ`] as its topology. Header, point count against the OBJ, and the first samples.
pub fn pc2(data: &[u8]) {
    const MAGIC: &[u8] = b"POINTCACHE2\0";
    let (obj, cache) = match data.windows(MAGIC.len()).position(|w| w == MAGIC) {
        Some(p) if p > 0 => (&data[..p], &data[p..]),
        _ => (QUAD_OBJ, data),
    };
    let (obj_path, pc2_path) = (Path::new("take.obj"), Path::new("take.pc2"));
    let mut reader = Cursor::new(cache);
    let header = match read_pc2_header_from(pc2_path, &mut reader) {
        Ok(h) => h,
        Err(e) => return assert_names(&e, "take.pc2"),
    };
    assert_eq!(header.file_len(), Some(cache.len() as u64));
    let reference = match Pc2Reference::new(obj_path, obj, pc2_path, header) {
        Ok(r) => r,
        Err(e) => return assert_names(&e, "take."),
    };
    for t in 0..header.num_samples.min(MAX_SAMPLES) {
        match reference.read_sample(&mut reader, t) {
            Ok(frame) => assert_eq!(frame.len(), header.num_points),
            Err(e) => assert_names(&e, "take.pc2"),
        }
    }
}

/// Sequence size the anchors are checked against.
pub const ANCHOR_FRAMES: usize = 8;
pub const ANCHOR_TRIANGLES: usize = 64;

/// An anchors file (read as UTF-8 text, as `AnchorSet::read` does) for an 8-frame, 64-triangle sequence.
pub fn anchors(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let path = Path::new("anchors.json");
    match AnchorSet::parse(text, Some(path), ANCHOR_FRAMES, ANCHOR_TRIANGLES) {
        Ok(set) => {
            assert_eq!(set.n_frames(), ANCHOR_FRAMES);
            // What the tools do next with a loaded set: write it back and draw its control lines.
            let back =
                AnchorSet::parse(&set.to_json(), Some(path), ANCHOR_FRAMES, ANCHOR_TRIANGLES)
                    .expect("a validated anchor set reads back");
            assert_eq!(back.total(), set.total());
            let _ = set.control_lines_obj();
        }
        Err(e) => assert_names(&e, "anchors.json"),
    }
}

/// A `cameras.json` (UTF-8 text, as `CameraRig::read` does), with and without an images directory override,
/// then the image paths of each camera for a few frame numbers (the pattern comes from the file).
pub fn cameras(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let path = Path::new("capture/cameras.json");
    for images in [None, Some(Path::new("/images"))] {
        match CameraRig::parse(text, path, images) {
            Ok(rig) => {
                for cam in 0..rig.cameras.len().min(4) {
                    for number in [0, 1, 42, u64::MAX] {
                        let _ = rig.image_path(cam, number);
                    }
                }
            }
            Err(e) => assert_names(&e, "cameras.json"),
        }
    }
}
