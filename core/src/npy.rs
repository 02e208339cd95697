//! Minimal NumPy `.npy` (format 1.0) writer and reader for little-endian numeric arrays, so that intermediate
//! arrays and exported matrices open directly in NumPy/SciPy. The reader accepts exactly what the writer
//! produces (C order, the element type asked for), which is what the cluster's intermediates need; the bytes
//! of an array are a pure function of its shape and values, so rewriting an intermediate writes the same bytes.

use crate::error::{Error, Result};
use crate::fsutil::write_atomic_with;
use std::io::Write;
use std::path::Path;

/// Element types the writer supports.
pub trait NpyElement: Copy {
    const DESCR: &'static str;
    const SIZE: usize;
    fn write_le(self, out: &mut impl Write) -> std::io::Result<()>;
    /// Decodes one element from exactly `SIZE` little-endian bytes.
    fn read_le(bytes: &[u8]) -> Self;
}

macro_rules! npy_element {
    ($t:ty, $d:expr) => {
        impl NpyElement for $t {
            const DESCR: &'static str = $d;
            const SIZE: usize = std::mem::size_of::<$t>();
            fn write_le(self, out: &mut impl Write) -> std::io::Result<()> {
                out.write_all(&self.to_le_bytes())
            }
            fn read_le(bytes: &[u8]) -> Self {
                let mut b = [0u8; std::mem::size_of::<$t>()];
                b.copy_from_slice(bytes);
                <$t>::from_le_bytes(b)
            }
        }
    };
}
npy_element!(f64, "<f8");
npy_element!(f32, "<f4");
npy_element!(u32, "<u4");
npy_element!(i32, "<i4");
npy_element!(u64, "<u8");
npy_element!(i64, "<i8");

/// Writes `data` (row-major, C order) with `shape` to `path` atomically.
pub fn write<T: NpyElement>(path: &Path, shape: &[usize], data: &[T]) -> Result<()> {
    write_atomic_with(path, |w| w.write_all(&to_bytes(shape, data)))
}

/// The `.npy` encoding of `data` (row-major, C order) with `shape`.
pub fn to_bytes<T: NpyElement>(shape: &[usize], data: &[T]) -> Vec<u8> {
    debug_assert_eq!(shape.iter().product::<usize>(), data.len());
    let shape_str = match shape {
        [n] => format!("({n},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(|s| s.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    };
    let mut header = format!(
        "{{'descr': '{}', 'fortran_order': False, 'shape': {}, }}",
        T::DESCR,
        shape_str
    );
    // Magic (6) + version (2) + header length (2) + header + '\n' must be a multiple of 64.
    let total = 10 + header.len() + 1;
    header.push_str(&" ".repeat((64 - total % 64) % 64));
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len() + data.len() * T::SIZE);
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for &x in data {
        // Writing into a Vec cannot fail.
        let _ = x.write_le(&mut out);
    }
    out
}

/// Decodes an `.npy` array of element type `T` in C order, as written by [`to_bytes`]; returns (shape, data).
/// `what` names the array (file or key) in errors.
pub fn from_bytes<T: NpyElement>(what: &Path, bytes: &[u8]) -> Result<(Vec<usize>, Vec<T>)> {
    let bad = |msg: String| Error::format(what, None, format!("not a readable .npy array: {msg}"));
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err(bad("missing the \\x93NUMPY magic".into()));
    }
    let (hlen, start) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 if bytes.len() >= 12 => (
            u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
            12,
        ),
        v => return Err(bad(format!("unsupported format version {v}"))),
    };
    let header = bytes
        .get(start..start + hlen)
        .and_then(|h| std::str::from_utf8(h).ok())
        .ok_or_else(|| bad("truncated or non-UTF-8 header".into()))?;
    let field = |name: &str| -> Option<&str> {
        let i = header.find(&format!("'{name}':"))? + name.len() + 3;
        Some(header[i..].trim_start())
    };
    let descr = field("descr").ok_or_else(|| bad("no 'descr' in the header".into()))?;
    if !descr.starts_with(&format!("'{}'", T::DESCR)) {
        return Err(bad(format!(
            "element type {} where {} was expected",
            descr.split(',').next().unwrap_or(""),
            T::DESCR
        )));
    }
    if !field("fortran_order").is_some_and(|f| f.starts_with("False")) {
        return Err(bad("only C-order arrays are supported".into()));
    }
    let shape_txt = field("shape")
        .and_then(|f| f.strip_prefix('('))
        .and_then(|f| f.split_once(')'))
        .map(|(inner, _)| inner)
        .ok_or_else(|| bad("no 'shape' tuple in the header".into()))?;
    let shape = shape_txt
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse::<usize>())
        .collect::<std::result::Result<Vec<_>, _>>()
        .map_err(|e| bad(format!("shape ({shape_txt}): {e}")))?;
    let n = shape
        .iter()
        .try_fold(1usize, |a, &b| a.checked_mul(b))
        .ok_or_else(|| bad("shape overflows".into()))?;
    let body = &bytes[start + hlen..];
    if Some(body.len()) != n.checked_mul(T::SIZE) {
        return Err(bad(format!(
            "{} data bytes for shape {shape:?} of {} ({} expected)",
            body.len(),
            T::DESCR,
            n * T::SIZE
        )));
    }
    Ok((shape, body.chunks_exact(T::SIZE).map(T::read_le).collect()))
}

/// Writes rows of 3-vectors as an (n, 3) array.
pub fn write_v3(path: &Path, rows: &[[f64; 3]]) -> Result<()> {
    let flat: Vec<f64> = rows.iter().flatten().copied().collect();
    write(path, &[rows.len(), 3], &flat)
}

#[cfg(test)]
mod tests {
    #[test]
    fn header_is_aligned() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.npy");
        super::write(&p, &[2, 3], &[1.0f64, 2.0, 3.0, 4.0, 5.0, 6.0]).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        let hlen = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
        assert_eq!((10 + hlen) % 64, 0);
        assert_eq!(bytes.len(), 10 + hlen + 48);
        assert!(std::str::from_utf8(&bytes[10..10 + hlen])
            .unwrap()
            .contains("'shape': (2, 3)"));
    }

    #[test]
    fn round_trips_and_rejects_other_types() {
        let data = [1.5f64, -0.0, f64::MIN_POSITIVE, 1e300, 2.0, 3.0];
        let bytes = super::to_bytes(&[3, 2], &data);
        let (shape, back) =
            super::from_bytes::<f64>(std::path::Path::new("a.npy"), &bytes).unwrap();
        assert_eq!(shape, vec![3, 2]);
        assert_eq!(
            back.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            data.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
        );
        let (shape, back) = super::from_bytes::<u64>(
            std::path::Path::new("b.npy"),
            &super::to_bytes(&[2], &[7u64, 9]),
        )
        .unwrap();
        assert_eq!((shape, back), (vec![2], vec![7, 9]));
        let err = super::from_bytes::<u32>(std::path::Path::new("a.npy"), &bytes).unwrap_err();
        assert!(
            err.to_string().contains("a.npy") && err.to_string().contains("<f8"),
            "{err}"
        );
        let err =
            super::from_bytes::<f64>(std::path::Path::new("a.npy"), &bytes[..bytes.len() - 1])
                .unwrap_err();
        assert!(err.to_string().contains("data bytes"), "{err}");
    }
}
