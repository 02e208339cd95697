//! Frame numbers from file names, and numeric ordering of frame files.
//!
//! Capture tools pad inconsistently (`f1.obj … f10.obj`, `frame_0001.obj`), so files are ordered by the number
//! in their name, not by the name itself: lexical order would put `f10` before `f2`.

use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

/// A frame file and the number found in its name.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NumberedFile {
    pub number: u64,
    pub path: PathBuf,
}

/// The frame number of a file: the last run of ASCII digits in its stem (`take2_frame0010.obj` → 10), with any
/// zero padding. `None` when the stem has no digits or the number does not fit in 64 bits.
pub fn frame_number(path: &Path) -> Option<u64> {
    let stem = path.file_stem()?.to_string_lossy();
    let bytes = stem.as_bytes();
    let end = bytes.iter().rposition(|b| b.is_ascii_digit())? + 1;
    let start = bytes[..end]
        .iter()
        .rposition(|b| !b.is_ascii_digit())
        .map_or(0, |p| p + 1);
    std::str::from_utf8(bytes.get(start..end)?)
        .ok()?
        .parse()
        .ok()
}

/// Sorts frame files by their number. Two files with the same number, or a file without a number, make the
/// sequence ambiguous and are an error naming the files involved.
pub fn sort_numbered(files: Vec<PathBuf>) -> Result<Vec<NumberedFile>> {
    let mut numbered = Vec::with_capacity(files.len());
    for path in files {
        match frame_number(&path) {
            Some(number) => numbered.push(NumberedFile { number, path }),
            None => {
                let example = numbered
                    .first()
                    .map(|f: &NumberedFile| format!(" (e.g. {})", file_name(&f.path)))
                    .unwrap_or_default();
                return Err(Error::format(
                    &path,
                    None,
                    format!(
                        "has no frame number in its name; every frame file must end in a number{example}, or be \
                         moved out of the sequence directory"
                    ),
                ));
            }
        }
    }
    // Ties broken by name so the error below is deterministic.
    numbered.sort_by(|a, b| a.number.cmp(&b.number).then_with(|| a.path.cmp(&b.path)));
    for pair in numbered.windows(2) {
        if let [a, b] = pair {
            if a.number == b.number {
                return Err(Error::format(
                    &b.path,
                    None,
                    format!(
                        "has frame number {} like {}; frame numbers must be unique",
                        b.number,
                        a.path.display()
                    ),
                ));
            }
        }
    }
    Ok(numbered)
}

/// The final component of a path as text, for messages.
pub(crate) fn file_name(path: &Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.display().to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_from_names() {
        let n = |s: &str| frame_number(Path::new(s));
        assert_eq!(n("frame_0001.obj"), Some(1));
        assert_eq!(n("f1.obj"), Some(1));
        assert_eq!(n("12.obj"), Some(12));
        assert_eq!(n("take2_frame0010.ply"), Some(10));
        assert_eq!(n("dir7/mesh.obj"), None);
        assert_eq!(n("shirt.obj"), None);
        assert_eq!(n("f99999999999999999999999.obj"), None);
    }

    #[test]
    fn sorted_numerically() {
        let files = ["f10.obj", "f2.obj", "f1.obj"].map(PathBuf::from).to_vec();
        let sorted: Vec<u64> = sort_numbered(files)
            .unwrap()
            .iter()
            .map(|f| f.number)
            .collect();
        assert_eq!(sorted, vec![1, 2, 10]);
    }
}
