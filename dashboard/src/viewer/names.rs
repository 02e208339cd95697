//! The names the viewer serves. A name is matched against this fixed list (or parsed as a frame number),
//! never joined into a path, so no URL can reach another file.

/// One thing the viewer serves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ViewFile {
    /// `meta.json`: sizes, camera, overlays available, notes.
    Meta,
    /// `index.bin`: the shared triangle list as little-endian `u32` triples.
    Index,
    /// `frame-N.bin`: frame N (0-based) in the [`crate::viewer::frame_buffer`] layout.
    Frame(usize),
    /// `report.json` of the output, as written.
    Report,
    /// `eval.json` of the output (`crease eval`'s figures), as written.
    Eval,
}

/// The longest frame number accepted (nine digits: more than any sequence, and no overflow).
const MAX_DIGITS: usize = 9;

impl ViewFile {
    pub fn parse(name: &str) -> Option<ViewFile> {
        match name {
            "meta.json" => return Some(ViewFile::Meta),
            "index.bin" => return Some(ViewFile::Index),
            "report.json" => return Some(ViewFile::Report),
            "eval.json" => return Some(ViewFile::Eval),
            _ => {}
        }
        let digits = name.strip_prefix("frame-")?.strip_suffix(".bin")?;
        if digits.is_empty()
            || digits.len() > MAX_DIGITS
            || !digits.bytes().all(|b| b.is_ascii_digit())
        {
            return None;
        }
        digits.parse().ok().map(ViewFile::Frame)
    }

    /// The file in the output folder a JSON name is read from.
    pub fn output_key(self) -> Option<&'static str> {
        match self {
            ViewFile::Report => Some("report.json"),
            ViewFile::Eval => Some("eval.json"),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_fixed_names_and_numbered_frames_are_served() {
        assert_eq!(ViewFile::parse("meta.json"), Some(ViewFile::Meta));
        assert_eq!(ViewFile::parse("index.bin"), Some(ViewFile::Index));
        assert_eq!(ViewFile::parse("frame-0.bin"), Some(ViewFile::Frame(0)));
        assert_eq!(ViewFile::parse("frame-047.bin"), Some(ViewFile::Frame(47)));
        assert_eq!(ViewFile::parse("eval.json"), Some(ViewFile::Eval));
        for bad in [
            "",
            "../report.json",
            "..%2freport.json",
            "frame-.bin",
            "frame--1.bin",
            "frame-1.bin/",
            "frame-1/../x.bin",
            "frame-1234567890.bin",
            "frame-+1.bin",
            "Meta.json",
            "anchors.json",
            ".crease-work/folds/anchors.bin",
            "preview.png",
        ] {
            assert_eq!(ViewFile::parse(bad), None, "{bad}");
        }
    }
}
