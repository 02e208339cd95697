//! The U-Net's two convolutions (kernel 4, stride 2, padding 1: the encoder's down-sampling and the decoder's
//! transposed up-sampling) written as one matrix product each.
//!
//! candle 0.11's CPU `conv_transpose2d` computes every output texel as its own short dot product, without the
//! blocking of a matrix product; at 256² the generator's decoder spent most of a forward pass there. The same
//! sum reorganised: `cols = xᵀ · W` gives, for every input texel, what it contributes through each of the 16
//! kernel taps (one GEMM), and with stride 2 each output parity (even/odd row × even/odd column) receives exactly
//! 4 of those taps, each from the input texel at a shift of −1, 0 or +1. Summing the shifted tap planes per
//! parity and interleaving the four parity planes is the transposed convolution. The down-sampling convolution
//! is the mirror image: the 16 taps of each output texel are gathered from the padded input split by parity
//! (views, no strided copy), stacked once (im2col) and multiplied by the kernel in one GEMM. Everything is a
//! candle tensor op, so training back-propagates through both unchanged; only the summation order differs from
//! candle's convolutions (f32 rounding, ~1e-6 relative).

use candle_core::{Result, Tensor};

/// The taps feeding one output parity along an axis, as (kernel index, input shift): with stride 2, kernel 4
/// and padding 1, output `2m + parity` sums `x[m + shift] · w[kernel index]` (derived from `o = 2i + k − 1`).
const TAPS: [[(usize, isize); 2]; 2] = [[(1, 0), (3, -1)], [(0, 1), (2, 0)]];

/// `x`: [b, c_in, h, w]; `weight`: [c_in, c_out, 4, 4] (candle's transposed-convolution layout); `bias`: [c_out].
/// Returns [b, c_out, 2h, 2w], equal to `x.conv_transpose2d(weight, 1, 0, 2, 1)` plus the bias.
pub fn conv_transpose_k4s2p1(x: &Tensor, weight: &Tensor, bias: Option<&Tensor>) -> Result<Tensor> {
    let (b, c_in, h, w) = x.dims4()?;
    let (wc_in, c_out, kh, kw) = weight.dims4()?;
    if wc_in != c_in || kh != 4 || kw != 4 {
        candle_core::bail!(
            "conv_transpose_k4s2p1: weight {:?} does not fit input {:?} with a 4×4 kernel",
            weight.dims(),
            x.dims()
        );
    }
    // [b, h·w, c_in] × [c_in, c_out·16] → [b, h·w, c_out·16]: every input texel's contribution through every
    // tap. The weight is used in its stored layout (no copy); the texels-major result keeps channels innermost
    // until the single permute at the end.
    let xt = x.reshape((b, c_in, h * w))?.transpose(1, 2)?;
    let cols = xt
        .broadcast_matmul(&weight.reshape((c_in, c_out * 16))?)?
        .reshape((b, h, w, c_out, 4, 4))?;
    let tap = |ky: usize, kx: usize| -> Result<Tensor> {
        cols.narrow(4, ky, 1)?
            .narrow(5, kx, 1)?
            .reshape((b, h, w, c_out))
    };
    let mut rows = Vec::with_capacity(2);
    for taps_y in &TAPS {
        let mut parities = Vec::with_capacity(2);
        for taps_x in &TAPS {
            let mut sum: Option<Tensor> = None;
            for &(ky, dy) in taps_y {
                for &(kx, dx) in taps_x {
                    let t = shift(&shift(&tap(ky, kx)?, 2, dx)?, 1, dy)?;
                    sum = Some(match sum {
                        None => t,
                        Some(s) => (s + t)?,
                    });
                }
            }
            parities.push(sum.expect("two taps per axis"));
        }
        // [b, h, w, 2, c] → [b, h, 2w, c]: even and odd columns interleaved.
        rows.push(Tensor::stack(&parities, 3)?.reshape((b, h, 2 * w, c_out))?);
    }
    // [b, h, 2, 2w, c] → [b, 2h, 2w, c] → [b, c, 2h, 2w].
    let out = Tensor::stack(&rows, 2)?
        .reshape((b, 2 * h, 2 * w, c_out))?
        .permute((0, 3, 1, 2))?
        .contiguous()?;
    match bias {
        Some(bias) => out.broadcast_add(&bias.reshape((1, c_out, 1, 1))?),
        None => Ok(out),
    }
}

/// `x`: [b, c_in, h, w] with h, w even; `weight`: [c_out, c_in, 4, 4] (candle's convolution layout); `bias`:
/// [c_out]. Returns [b, c_out, h/2, w/2], equal to `x.conv2d(weight, 1, 2, 1, 1)` plus the bias.
pub fn conv_k4s2p1(x: &Tensor, weight: &Tensor, bias: Option<&Tensor>) -> Result<Tensor> {
    let (b, c_in, h, w) = x.dims4()?;
    let (c_out, wc_in, kh, kw) = weight.dims4()?;
    if wc_in != c_in || kh != 4 || kw != 4 || h % 2 != 0 || w % 2 != 0 {
        candle_core::bail!(
            "conv_k4s2p1: weight {:?} does not fit input {:?} (4×4 kernel, even sides)",
            weight.dims(),
            x.dims()
        );
    }
    let (oh, ow) = (h / 2, w / 2);
    // Padded input split by parity: [b, c, oh + 1, 2, ow + 1, 2]; tap (ky, kx) of output (oy, ox) reads padded
    // texel (2·oy + ky, 2·ox + kx) = block (oy + ky/2, ox + kx/2), parity (ky % 2, kx % 2).
    let padded = x
        .pad_with_zeros(2, 1, 1)?
        .pad_with_zeros(3, 1, 1)?
        .reshape((b, c_in, oh + 1, 2, ow + 1, 2))?;
    let mut taps = Vec::with_capacity(16);
    for ky in 0..4 {
        for kx in 0..4 {
            taps.push(
                padded
                    .narrow(2, ky / 2, oh)?
                    .narrow(3, ky % 2, 1)?
                    .narrow(4, kx / 2, ow)?
                    .narrow(5, kx % 2, 1)?
                    .reshape((b, c_in, oh, ow))?,
            );
        }
    }
    // [b, c_in, 16, oh, ow] → [b, c_in·16, oh·ow]: rows in the kernel's (c_in, ky, kx) order.
    let cols = Tensor::stack(&taps, 2)?.reshape((b, c_in * 16, oh * ow))?;
    let out = weight
        .reshape((c_out, c_in * 16))?
        .broadcast_matmul(&cols)?
        .reshape((b, c_out, oh, ow))?;
    match bias {
        Some(bias) => out.broadcast_add(&bias.reshape((1, c_out, 1, 1))?),
        None => Ok(out),
    }
}

/// `z` moved along `dim` so that position m holds `z[m + d]` (zero where that falls outside), d ∈ {−1, 0, 1}.
fn shift(z: &Tensor, dim: usize, d: isize) -> Result<Tensor> {
    let n = z.dim(dim)?;
    match d {
        0 => Ok(z.clone()),
        _ if n == 1 => z.zeros_like(),
        -1 => z.pad_with_zeros(dim, 1, 0)?.narrow(dim, 0, n),
        1 => z.narrow(dim, 1, n - 1)?.pad_with_zeros(dim, 0, 1),
        _ => candle_core::bail!("shift by {d}: only −1, 0 and 1 occur"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nn::seed::Rng;
    use candle_core::{Device, Var};

    fn random(rng: &mut Rng, dims: &[usize]) -> Tensor {
        let n: usize = dims.iter().product();
        let v: Vec<f32> = (0..n).map(|_| rng.uniform() as f32 * 2.0 - 1.0).collect();
        Tensor::from_vec(v, dims, &Device::Cpu).unwrap()
    }

    fn max_abs_diff(a: &Tensor, b: &Tensor) -> f32 {
        (a - b)
            .unwrap()
            .abs()
            .unwrap()
            .flatten_all()
            .unwrap()
            .max(0)
            .unwrap()
            .to_scalar::<f32>()
            .unwrap()
    }

    type Ours = fn(&Tensor, &Tensor, Option<&Tensor>) -> Result<Tensor>;

    /// Ours and candle's convolution (`theirs`) on random input, kernel and bias of the given sizes agree
    /// within 1e-5.
    fn assert_same_output(
        rng: &mut Rng,
        ours: Ours,
        theirs: impl Fn(&Tensor, &Tensor) -> Result<Tensor>,
        x_dims: &[usize],
        w_dims: &[usize],
        c_out: usize,
    ) {
        let x = random(rng, x_dims);
        let wt = random(rng, w_dims);
        let bias = random(rng, &[c_out]);
        let ours = ours(&x, &wt, Some(&bias)).unwrap();
        let reference = theirs(&x, &wt)
            .unwrap()
            .broadcast_add(&bias.reshape((1, c_out, 1, 1)).unwrap())
            .unwrap();
        assert_eq!(ours.dims(), reference.dims());
        let diff = max_abs_diff(&ours, &reference);
        assert!(
            diff < 1e-5,
            "input {x_dims:?}, kernel {w_dims:?}: differs by {diff}"
        );
    }

    /// The gradients of a random linear functional of both outputs, with respect to the input and the kernel,
    /// agree within 1e-4: training back-propagates through ours as through candle's.
    fn assert_same_gradients(
        rng: &mut Rng,
        ours: Ours,
        theirs: impl Fn(&Tensor, &Tensor) -> Result<Tensor>,
        x_dims: &[usize],
        w_dims: &[usize],
    ) {
        let x = Var::from_tensor(&random(rng, x_dims)).unwrap();
        let wt = Var::from_tensor(&random(rng, w_dims)).unwrap();
        let out = theirs(x.as_tensor(), wt.as_tensor()).unwrap();
        let probe = random(rng, out.dims());
        let loss_of = |out: Tensor| (out * &probe).unwrap().sum_all().unwrap();
        let g1 = loss_of(ours(x.as_tensor(), wt.as_tensor(), None).unwrap())
            .backward()
            .unwrap();
        let g2 = loss_of(out).backward().unwrap();
        for (name, v) in [("input", &x), ("weight", &wt)] {
            let diff = max_abs_diff(
                g1.get(v.as_tensor()).unwrap(),
                g2.get(v.as_tensor()).unwrap(),
            );
            assert!(diff < 1e-4, "gradient wrt {name} differs by {diff}");
        }
    }

    fn candle_transposed(x: &Tensor, w: &Tensor) -> Result<Tensor> {
        x.conv_transpose2d(w, 1, 0, 2, 1)
    }

    fn candle_down(x: &Tensor, w: &Tensor) -> Result<Tensor> {
        x.conv2d(w, 1, 2, 1, 1)
    }

    #[test]
    fn equals_candles_transposed_convolution_at_every_size_the_unet_uses() {
        let mut rng = Rng::new(7);
        for &(b, c_in, c_out, h, w) in &[
            (1, 3, 2, 1, 1),
            (2, 4, 3, 2, 2),
            (1, 8, 5, 4, 3),
            (3, 6, 4, 8, 8),
        ] {
            let (x, k) = ([b, c_in, h, w], [c_in, c_out, 4, 4]);
            assert_same_output(
                &mut rng,
                conv_transpose_k4s2p1,
                candle_transposed,
                &x,
                &k,
                c_out,
            );
        }
        assert_same_gradients(
            &mut rng,
            conv_transpose_k4s2p1,
            candle_transposed,
            &[2, 5, 4, 6],
            &[5, 3, 4, 4],
        );
    }

    #[test]
    fn the_down_convolution_equals_candles() {
        let mut rng = Rng::new(5);
        for &(b, c_in, c_out, h, w) in &[(1, 4, 2, 2, 2), (2, 3, 5, 8, 6), (1, 6, 4, 16, 16)] {
            let (x, k) = ([b, c_in, h, w], [c_out, c_in, 4, 4]);
            assert_same_output(&mut rng, conv_k4s2p1, candle_down, &x, &k, c_out);
        }
        assert_same_gradients(
            &mut rng,
            conv_k4s2p1,
            candle_down,
            &[2, 3, 8, 8],
            &[4, 3, 4, 4],
        );
    }

    #[test]
    fn refuses_a_kernel_of_another_size() {
        let mut rng = Rng::new(3);
        let x = random(&mut rng, &[1, 2, 4, 4]);
        let wt = random(&mut rng, &[2, 3, 3, 3]);
        assert!(conv_transpose_k4s2p1(&x, &wt, None).is_err());
        assert!(conv_k4s2p1(&x, &wt, None).is_err());
        let odd = random(&mut rng, &[1, 2, 3, 4]);
        assert!(conv_k4s2p1(&odd, &random(&mut rng, &[3, 2, 4, 4]), None).is_err());
    }
}
