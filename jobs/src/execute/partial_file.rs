//! One anchor block's result as one stored object: its partial blend and its CG statistics.
//!
//! Why one object and not an `.npy` plus a JSON sidecar: a per-anchor window has tens of blocks and each block
//! is a short task, so every put and get is a fixed cost paid hundreds of times per job (two objects per block
//! were 15 % of a block task's time on a loaded machine), and the reduce parsed a JSON file per block. The
//! statistics go in a fixed header, the nodes as `u32` (not `f64` as in the `.npy` rows), the values as `f64`
//! bit for bit, so the reduce sums exactly what the block computed.
//!
//! Layout, little-endian: magic `CREASEPB`, format version (u32, 1), reserved (u32, 0), columns, CG iterations,
//! max relative residual (f64), node updates, seconds (f64), node count n (u64 each where not said); then n
//! node indices (u32), zero padding to a multiple of 8 bytes, and n × 3 values (f64). `seconds` is the block's
//! solve time, the only bytes that differ between two runs of the same block.

use crease_core::spacetime::weights::fused::CgStats;
use crease_core::spacetime::weights::per_anchor::PartialBlend;
use crease_core::vec3::V3;

const MAGIC: &[u8; 8] = b"CREASEPB";
const VERSION: u32 = 1;
const HEADER: usize = 8 + 4 + 4 + 6 * 8;

/// What a block reports beside its partial blend.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlockStats {
    pub columns: usize,
    pub iterations: usize,
    pub max_relative_residual: f64,
    pub node_updates: u64,
    pub seconds: f64,
}

fn padded(n: usize) -> usize {
    (n * 4).div_ceil(8) * 8
}

/// The stored bytes of a block's result.
pub fn encode(p: &PartialBlend, stats: &BlockStats) -> Vec<u8> {
    let n = p.nodes.len();
    let mut out = Vec::with_capacity(HEADER + padded(n) + n * 24);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    for w in [
        stats.columns as u64,
        stats.iterations as u64,
        stats.max_relative_residual.to_bits(),
        stats.node_updates,
        stats.seconds.to_bits(),
        n as u64,
    ] {
        out.extend_from_slice(&w.to_le_bytes());
    }
    for &g in &p.nodes {
        out.extend_from_slice(&g.to_le_bytes());
    }
    out.resize(HEADER + padded(n), 0);
    for v in &p.values {
        for x in v {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }
    out
}

/// Checks a stored result's header and length; returns its node count and statistics.
fn header(bytes: &[u8]) -> Result<(usize, BlockStats), String> {
    if bytes.len() < HEADER || &bytes[..8] != MAGIC {
        return Err("not an anchor block result (no CREASEPB header)".into());
    }
    let u32_at = |o: usize| u32::from_le_bytes(bytes[o..o + 4].try_into().expect("4 bytes"));
    let u64_at = |o: usize| u64::from_le_bytes(bytes[o..o + 8].try_into().expect("8 bytes"));
    let version = u32_at(8);
    if version != VERSION {
        return Err(format!(
            "format version {version}, this crease reads version {VERSION}"
        ));
    }
    let word = |i: usize| u64_at(16 + 8 * i);
    let n = word(5);
    // In u128, so that no announced count can overflow the arithmetic.
    let len = HEADER as u128 + (n as u128 * 4).div_ceil(8) * 8 + n as u128 * 24;
    if len != bytes.len() as u128 {
        return Err(format!(
            "{} bytes do not hold the {n} nodes the header announces",
            bytes.len()
        ));
    }
    let stats = BlockStats {
        columns: word(0) as usize,
        iterations: word(1) as usize,
        max_relative_residual: f64::from_bits(word(2)),
        node_updates: word(3),
        seconds: f64::from_bits(word(4)),
    };
    Ok((n as usize, stats))
}

/// Reads a block's result back; `n_nodes` is the window's node count (every node index must be below it).
/// Errors say what is wrong with the bytes (the caller names the object). The reduce uses [`add_into`]; this is
/// the reference it is tested against.
#[cfg(test)]
pub fn decode(bytes: &[u8], n_nodes: usize) -> Result<(PartialBlend, BlockStats), String> {
    let (n, stats) = header(bytes)?;
    let nodes: Vec<u32> = bytes[HEADER..HEADER + 4 * n]
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes(c.try_into().expect("4 bytes")))
        .collect();
    if let Some(g) = nodes.iter().find(|&&g| g as usize >= n_nodes) {
        return Err(format!(
            "node {g} is not one of the window's {n_nodes} nodes"
        ));
    }
    let start = HEADER + padded(n);
    let values = bytes[start..]
        .chunks_exact(24)
        .map(|c| {
            let f = |k: usize| f64::from_le_bytes(c[8 * k..8 * k + 8].try_into().expect("8 bytes"));
            [f(0), f(1), f(2)]
        })
        .collect();
    Ok((
        PartialBlend {
            nodes,
            values,
            iterations: stats.iterations,
            max_relative_residual: stats.max_relative_residual,
            node_updates: stats.node_updates,
        },
        stats,
    ))
}

/// Adds a block's stored result straight into a window field and its statistics, as [`decode`] followed by
/// [`weights::reduce_into`] would, bit for bit, but without building the block's node and value lists: the reduce
/// sums tens of blocks of a few MB each, and decoding each into fresh vectors first was most of its time.
/// Every node index is checked before anything is added, so a malformed result leaves `field` untouched.
pub fn add_into(
    bytes: &[u8],
    field: &mut [V3],
    cg: &mut CgStats,
    updates: &mut u64,
) -> Result<BlockStats, String> {
    let (n, stats) = header(bytes)?;
    let nodes = &bytes[HEADER..HEADER + 4 * n];
    let node_at = |c: &[u8]| u32::from_le_bytes(c.try_into().expect("4 bytes")) as usize;
    if let Some(g) = nodes
        .chunks_exact(4)
        .map(node_at)
        .find(|&g| g >= field.len())
    {
        return Err(format!(
            "node {g} is not one of the window's {} nodes",
            field.len()
        ));
    }
    let values = &bytes[HEADER + padded(n)..];
    let f =
        |c: &[u8], k: usize| f64::from_le_bytes(c[8 * k..8 * k + 8].try_into().expect("8 bytes"));
    for (g, v) in nodes
        .chunks_exact(4)
        .map(node_at)
        .zip(values.chunks_exact(24))
    {
        // The same additions, in the same order per node, as `per_anchor::accumulate`.
        let x = &mut field[g];
        x[0] += f(v, 0);
        x[1] += f(v, 1);
        x[2] += f(v, 2);
    }
    // As `per_anchor::merge_stats` and `weights::reduce_into`.
    cg.iterations += stats.iterations;
    cg.relative_residual = cg.relative_residual.max(stats.max_relative_residual);
    *updates += stats.node_updates;
    Ok(stats)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(n: usize) -> (PartialBlend, BlockStats) {
        let p = PartialBlend {
            nodes: (0..n as u32).map(|i| i * 7 + 3).collect(),
            values: (0..n)
                .map(|i| {
                    [
                        i as f64 * 0.1 + 1e-300,
                        -(i as f64) / 3.0,
                        f64::MIN_POSITIVE,
                    ]
                })
                .collect(),
            iterations: 17 * n,
            max_relative_residual: 1.0 / 3.0e9,
            node_updates: 123_456_789_012,
        };
        let s = BlockStats {
            columns: 256,
            iterations: p.iterations,
            max_relative_residual: p.max_relative_residual,
            node_updates: p.node_updates,
            seconds: 0.1234,
        };
        (p, s)
    }

    /// Every value comes back bit for bit, for node counts with and without padding.
    #[test]
    fn round_trips_bit_for_bit() {
        for n in [0, 1, 2, 3, 1000] {
            let (p, s) = sample(n);
            let bytes = encode(&p, &s);
            let (q, t) = decode(&bytes, 7 * n + 3).unwrap();
            assert_eq!(q.nodes, p.nodes);
            let bits =
                |v: &[[f64; 3]]| -> Vec<u64> { v.iter().flatten().map(|x| x.to_bits()).collect() };
            assert_eq!(bits(&q.values), bits(&p.values));
            assert_eq!(t, s);
            assert_eq!(
                (
                    q.iterations,
                    q.max_relative_residual.to_bits(),
                    q.node_updates
                ),
                (
                    p.iterations,
                    p.max_relative_residual.to_bits(),
                    p.node_updates
                )
            );
        }
    }

    /// Adding a stored result in place gives the bits of decoding it and reducing it with the core's stage,
    /// statistics included; a bad node index is refused before the field is touched.
    #[test]
    fn add_into_matches_decode_and_reduce() {
        use crease_core::spacetime::weights;
        let n_nodes = 7 * 1000 + 3;
        let start: Vec<V3> = (0..n_nodes)
            .map(|i| [i as f64 / 7.0, -1.0 / (i as f64 + 1.0), 1e-17 * i as f64])
            .collect();
        let (mut a, mut b) = (start.clone(), start.clone());
        let (mut cg_a, mut cg_b) = (CgStats::default(), CgStats::default());
        let (mut up_a, mut up_b) = (5u64, 5u64);
        for n in [1000, 0, 3, 999] {
            let (mut p, mut s) = sample(n);
            // Nodes out of order and a residual that changes the maximum.
            p.nodes.reverse();
            p.max_relative_residual = 1e-3 / (n as f64 + 1.0);
            s.max_relative_residual = p.max_relative_residual;
            let bytes = encode(&p, &s);
            let (q, _) = decode(&bytes, n_nodes).unwrap();
            weights::reduce_into(&mut a, &mut cg_a, &mut up_a, &q);
            let t = add_into(&bytes, &mut b, &mut cg_b, &mut up_b).unwrap();
            assert_eq!(t, s);
        }
        let bits = |v: &[V3]| -> Vec<u64> { v.iter().flatten().map(|x| x.to_bits()).collect() };
        assert_eq!(bits(&a), bits(&b));
        assert_ne!(bits(&a), bits(&start), "the sums changed the field");
        assert_eq!(cg_a.iterations, cg_b.iterations);
        assert_eq!(
            cg_a.relative_residual.to_bits(),
            cg_b.relative_residual.to_bits()
        );
        assert_eq!(up_a, up_b);
        let (p, s) = sample(5);
        let mut small = vec![[1.0; 3]; 31];
        let err = add_into(&encode(&p, &s), &mut small, &mut cg_b, &mut up_b).unwrap_err();
        assert!(err.contains("node 31"), "{err}");
        assert!(small.iter().all(|v| *v == [1.0; 3]), "field untouched");
        assert!(add_into(&encode(&p, &s)[..40], &mut small, &mut cg_b, &mut up_b).is_err());
    }

    /// Truncated, padded, foreign or out-of-range data is refused with a reason, never read past its end.
    #[test]
    fn malformed_results_are_refused() {
        let (p, s) = sample(5);
        let bytes = encode(&p, &s);
        for cut in [0, 8, HEADER - 1, HEADER, bytes.len() - 1] {
            assert!(decode(&bytes[..cut], 1000).is_err(), "cut at {cut}");
        }
        let mut longer = bytes.clone();
        longer.push(0);
        assert!(decode(&longer, 1000).unwrap_err().contains("do not hold"));
        let mut foreign = bytes.clone();
        foreign[0] = b'X';
        assert!(decode(&foreign, 1000).unwrap_err().contains("CREASEPB"));
        let mut newer = bytes.clone();
        newer[8] = 2;
        assert!(decode(&newer, 1000).unwrap_err().contains("version 2"));
        let mut huge = bytes.clone();
        huge[56..64].copy_from_slice(&u64::MAX.to_le_bytes());
        assert!(decode(&huge, 1000).is_err());
        // The largest node is 7·4 + 3 = 31.
        assert!(decode(&bytes, 31).unwrap_err().contains("node 31"));
        assert!(decode(&bytes, 32).is_ok());
    }
}
