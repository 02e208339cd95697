//! The generator's decoder layers at a given resolution and filter count, timed with candle's
//! `conv_transpose2d` and with `gemm_conv::conv_transpose_k4s2p1`, interleaved in one process (medians of N).
//!
//! `cargo run --release -p crease-deep --example gemm_conv_bench -- [resolution 256] [filters 64] [repeats 3]`
//! (set RAYON_NUM_THREADS=1 for the one-core figure of issue 12).

use candle_core::{Device, Tensor};
use crease_deep::cgan::gemm_conv::{conv_k4s2p1, conv_transpose_k4s2p1};
use std::time::Instant;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() -> candle_core::Result<()> {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| a.parse().expect("numbers: resolution filters repeats"))
        .collect();
    let res = args.first().copied().unwrap_or(256);
    let f = args.get(1).copied().unwrap_or(64);
    let repeats = args.get(2).copied().unwrap_or(3);
    let depth = res.trailing_zeros() as usize;
    let ch: Vec<usize> = (0..depth).map(|i| (f << i.min(3)).min(8 * f)).collect();
    println!("{res}² maps, {f} filters, {depth} decoder layers, median of {repeats}");
    println!(
        "{:>6} {:>10} {:>12} {:>12} {:>8}",
        "layer", "in", "candle (ms)", "gemm (ms)", "ratio"
    );
    let (mut total_candle, mut total_gemm) = (0.0, 0.0);
    for i in 0..depth {
        let c_in = if i == 0 { 4 } else { ch[i - 1] };
        let side = res >> i;
        let x = Tensor::randn(0f32, 1f32, (1, c_in, side, side), &Device::Cpu)?;
        let w = Tensor::randn(0f32, 0.1f32, (ch[i], c_in, 4, 4), &Device::Cpu)?;
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for _ in 0..repeats {
            let t = Instant::now();
            let _ = x.conv2d(&w, 1, 2, 1, 1)?;
            a.push(t.elapsed().as_secs_f64() * 1e3);
            let t = Instant::now();
            let _ = conv_k4s2p1(&x, &w, None)?;
            b.push(t.elapsed().as_secs_f64() * 1e3);
        }
        let (ma, mb) = (median(a), median(b));
        total_candle += ma;
        total_gemm += mb;
        println!(
            "{:>6} {:>10} {ma:>12.2} {mb:>12.2} {:>7.1}x",
            format!("enc{i}"),
            format!("{c_in}×{side}²"),
            ma / mb
        );
    }
    for j in 0..depth {
        let c_in = if j == 0 {
            ch[depth - 1]
        } else {
            2 * ch[depth - 1 - j]
        };
        let c_out = if j == depth - 1 { 3 } else { ch[depth - 2 - j] };
        let side = 1usize << j;
        let x = Tensor::randn(0f32, 1f32, (1, c_in, side, side), &Device::Cpu)?;
        let w = Tensor::randn(0f32, 0.1f32, (c_in, c_out, 4, 4), &Device::Cpu)?;
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for _ in 0..repeats {
            let t = Instant::now();
            let _ = x.conv_transpose2d(&w, 1, 0, 2, 1)?;
            a.push(t.elapsed().as_secs_f64() * 1e3);
            let t = Instant::now();
            let _ = conv_transpose_k4s2p1(&x, &w, None)?;
            b.push(t.elapsed().as_secs_f64() * 1e3);
        }
        let (ma, mb) = (median(a), median(b));
        total_candle += ma;
        total_gemm += mb;
        println!(
            "dec{j:>3} {:>10} {ma:>12.2} {mb:>12.2} {:>7.1}x",
            format!("{c_in}×{side}²"),
            ma / mb
        );
    }
    println!(
        "{:>6} {:>10} {total_candle:>12.1} {total_gemm:>12.1} {:>7.1}x",
        "all",
        "",
        total_candle / total_gemm
    );
    // The whole generator (inference, as `crease deep apply` runs it), with both GEMM convolutions.
    let cfg = crease_deep::cgan::CganConfig {
        resolution: res,
        filters: f,
        ..Default::default()
    };
    let vars = candle_nn::VarMap::new();
    let vb = candle_nn::VarBuilder::from_varmap(&vars, candle_core::DType::F32, &Device::Cpu);
    let gen = crease_deep::cgan::Generator::new(&cfg, vb)?;
    let x = Tensor::randn(0f32, 1f32, (1, 4, res, res), &Device::Cpu)?;
    let mut t_gen = Vec::new();
    for _ in 0..repeats {
        let t = Instant::now();
        let _ = gen.forward(&x, false)?;
        t_gen.push(t.elapsed().as_secs_f64() * 1e3);
    }
    let g = median(t_gen);
    println!("generator forward: {g:.1} ms",);
    Ok(())
}
