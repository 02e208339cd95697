//! Minimal NumPy `.npy` (format 1.0) writer for little-endian numeric arrays, so that intermediate arrays and
//! exported matrices open directly in NumPy/SciPy.

use crate::error::Result;
use crate::fsutil::write_atomic_with;
use std::io::Write;
use std::path::Path;

/// Element types the writer supports.
pub trait NpyElement: Copy {
    const DESCR: &'static str;
    fn write_le(self, out: &mut impl Write) -> std::io::Result<()>;
}

macro_rules! npy_element {
    ($t:ty, $d:expr) => {
        impl NpyElement for $t {
            const DESCR: &'static str = $d;
            fn write_le(self, out: &mut impl Write) -> std::io::Result<()> {
                out.write_all(&self.to_le_bytes())
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
    write_atomic_with(path, |w| {
        w.write_all(b"\x93NUMPY\x01\x00")?;
        w.write_all(&(header.len() as u16).to_le_bytes())?;
        w.write_all(header.as_bytes())?;
        for &x in data {
            x.write_le(w)?;
        }
        Ok(())
    })
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
}
