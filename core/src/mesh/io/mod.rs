//! Readers and writers for sequence layouts.
//!
//! Captured sequences arrive as a directory of numbered OBJ or PLY frames, or as an OBJ plus a PC2 point cache.
//! [`open_sequence`] detects the layout and returns a lazy [`FrameSource`](crate::mesh::FrameSource) (one file
//! or one cache sample per read, so memory is bounded by what the caller holds); [`create_sink`] writes results
//! back in the same layout with the same file names and vertex order. The parsers are hand-written so that
//! every error names the file and the line, element or index at fault, and so that a frame parses in
//! milliseconds.

mod faces;
mod frame_dir;
mod layout;
mod numbering;
mod obj;
mod obj_blame;
mod obj_frames;
mod pc2;
mod ply;
mod point_cache;
mod tokens;

#[cfg(test)]
mod tests;

pub use frame_dir::{FrameFormat, FrameReference};
pub use layout::{
    create_sink, detect_layout, open_layout, open_sequence, OpenedSequence, SequenceLayout,
};
pub use numbering::{frame_number, sort_numbered, NumberedFile};
pub use obj::{write_obj, write_obj_sequence};
pub use obj_frames::ObjFramesSink;
pub(crate) use pc2::{check_counts as pc2_check_counts, encode_sample as pc2_encode_sample};
pub use pc2::{read_pc2_header, read_pc2_header_from, read_pc2_sample_from, write_pc2, Pc2Header};
pub use ply::write_ply_frame;
pub use point_cache::Pc2Reference;
