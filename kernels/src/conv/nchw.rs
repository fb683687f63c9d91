//! Convolutions of batches in burn's layout (`[batch, channels, h, w]`, row-major): what
//! training runs through, forward and both backward products, as a few large matrix
//! products in the way PyTorch's CPU path does them:
//! - forward: per group of samples, one im2col copy `col [C*KH*KW, n*OH*OW]` and one
//!   product `y = W [O, C*KH*KW] x col`;
//! - weight gradient: `dW^T += col [C*KH*KW, n*OH*OW] x dY^T`, summed over the batch;
//! - input gradient: `dcol = W^T x dY`, scattered back onto `dX` (col2im).
//!
//! Every product is [`gemm`](crate::gemm) (each output one fused multiply-add chain in a
//! fixed order), and the batch is cut into groups and lanes whose sizes follow the shapes
//! alone, so results are bit-identical for any thread count and on any x86-64 CPU.
//! `policy::conv` registers these with burn (its backend extension) and tests them against
//! burn's own convolutions.

use crate::{Mat, gemm as matmul};
use rayon::prelude::*;
use std::cell::RefCell;

/// The shapes of one convolution: input `[batch, cin, h, w]`, weights
/// `[cout, cin, kh, kw]`, output `[batch, cout, oh, ow]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Geometry {
    pub batch: usize,
    pub cin: usize,
    pub h: usize,
    pub w: usize,
    pub cout: usize,
    pub kh: usize,
    pub kw: usize,
    /// Rows, columns.
    pub stride: [usize; 2],
    /// Zeros added above and below, left and right.
    pub pad: [usize; 2],
    pub oh: usize,
    pub ow: usize,
}

/// The fewest output columns (samples x output pixels) one product gets: the late
/// layers' few pixels per sample are grouped until a product is this wide.
const MIN_COLS: usize = 256;

/// The most lanes a backward pass splits the batch into, each summing its own weight
/// gradient (then added in lane order): enough for the cores of a laptop, few enough
/// that the partial sums stay small.
const LANES: usize = 8;

impl Geometry {
    /// The geometry of `x` convolved with `weight`; `None` where they do not fit
    /// (channel counts differ, or the kernel is larger than the padded input).
    pub fn new(
        x: [usize; 4],
        weight: [usize; 4],
        stride: [usize; 2],
        pad: [usize; 2],
    ) -> Option<Self> {
        let [batch, cin, h, w] = x;
        let [cout, wcin, kh, kw] = weight;
        let out = |len: usize, k: usize, s: usize, p: usize| {
            (s > 0 && k > 0 && len + 2 * p >= k).then(|| (len + 2 * p - k) / s + 1)
        };
        let oh = out(h, kh, stride[0], pad[0])?;
        let ow = out(w, kw, stride[1], pad[1])?;
        (wcin == cin).then_some(Geometry {
            batch,
            cin,
            h,
            w,
            cout,
            kh,
            kw,
            stride,
            pad,
            oh,
            ow,
        })
    }

    /// The products' inner dimension, `cin * kh * kw`.
    fn k(&self) -> usize {
        self.cin * self.kh * self.kw
    }

    /// Output pixels per sample and channel.
    fn p(&self) -> usize {
        self.oh * self.ow
    }

    /// Samples per product.
    fn group(&self) -> usize {
        MIN_COLS
            .div_ceil(self.p().max(1))
            .clamp(1, self.batch.max(1))
    }

    /// Whether the input itself is the column matrix (a 1x1 kernel, stride 1, no padding).
    fn direct(&self) -> bool {
        self.kh == 1 && self.kw == 1 && self.stride == [1, 1] && self.pad == [0, 0]
    }

    /// The output columns `lo..hi` whose input column `ox * stride + kx - pad` lies
    /// inside the image.
    fn valid_cols(&self, kx: usize) -> (usize, usize) {
        let (s, p) = (self.stride[1], self.pad[1]);
        let lo = p.saturating_sub(kx).div_ceil(s).min(self.ow);
        // ox * s + kx - p <= w - 1  <=>  ox <= (w - 1 + p - kx) / s
        let hi = match (self.w + p).checked_sub(kx + 1) {
            Some(last) => (last / s + 1).min(self.ow),
            None => 0,
        };
        (lo, hi.max(lo))
    }

    /// The input row under output row `oy` and kernel row `ky`, if inside the image.
    fn input_row(&self, oy: usize, ky: usize) -> Option<usize> {
        (oy * self.stride[0] + ky)
            .checked_sub(self.pad[0])
            .filter(|&iy| iy < self.h)
    }
}

thread_local! {
    /// Per-thread scratch for column matrices and gathered gradients, kept between calls.
    static SCRATCH: RefCell<(Vec<f32>, Vec<f32>)> = const { RefCell::new((Vec::new(), Vec::new())) };
}

/// `buf` grown to at least `len` elements (values left as they were).
fn sized(buf: &mut Vec<f32>, len: usize) -> &mut [f32] {
    if buf.len() < len {
        buf.resize(len, 0.0);
    }
    &mut buf[..len]
}

/// One output row of one tap, as [`walk`] hands it over.
struct TapRow {
    /// Row of the column matrix: `(c, ky, kx)`.
    row: usize,
    /// Offset of this sample's channel `c` in the images (`(s * cin + c) * h * w`).
    image: usize,
    /// Offset of this sample's output row `oy` in a column-matrix row (`s * P + oy * ow`).
    at: usize,
    /// The input row read, if inside the image.
    iy: Option<usize>,
    /// Output columns `lo..hi` whose input column lies inside the image.
    lo: usize,
    hi: usize,
    /// The input column of output column `lo`.
    first: usize,
}

/// Visits every tap `(c, ky, kx)`, sample `0..n` and output row of a convolution, in one
/// fixed order: the loop shared by [`im2col`] and its transpose [`col2im_add`].
fn walk(g: &Geometry, n: usize, mut visit: impl FnMut(TapRow)) {
    let (p, hw) = (g.p(), g.h * g.w);
    for c in 0..g.cin {
        for ky in 0..g.kh {
            for kx in 0..g.kw {
                let row = (c * g.kh + ky) * g.kw + kx;
                let (lo, hi) = g.valid_cols(kx);
                // Read only where lo < hi, which makes it non-negative; saturated for empty rows.
                let first = (lo * g.stride[1] + kx).saturating_sub(g.pad[1]);
                for s in 0..n {
                    for oy in 0..g.oh {
                        visit(TapRow {
                            row,
                            image: (s * g.cin + c) * hw,
                            at: s * p + oy * g.ow,
                            iy: g.input_row(oy, ky),
                            lo,
                            hi,
                            first,
                        });
                    }
                }
            }
        }
    }
}

/// Writes `col [K, n * P]` for samples `b0..b0 + n` of `x`: row `(c, ky, kx)`, column
/// `(sample, oy, ox)` holds `x[b0 + sample, c, oy * sh + ky - ph, ox * sw + kx - pw]`,
/// or 0 in the padding.
fn im2col(x: &[f32], g: &Geometry, b0: usize, n: usize, col: &mut [f32]) {
    let (cols, sw) = (n * g.p(), g.stride[1]);
    let x = &x[b0 * g.cin * g.h * g.w..];
    walk(g, n, |t| {
        let dst = &mut col[t.row * cols + t.at..][..g.ow];
        let Some(iy) = t.iy else {
            dst.fill(0.0);
            return;
        };
        let src = &x[t.image + iy * g.w..][..g.w];
        dst[..t.lo].fill(0.0);
        dst[t.hi..].fill(0.0);
        if t.lo == t.hi {
            // No input column under this row (`first` may lie past the image).
        } else if sw == 1 {
            dst[t.lo..t.hi].copy_from_slice(&src[t.first..t.first + t.hi - t.lo]);
        } else {
            for (o, v) in dst[t.lo..t.hi].iter_mut().enumerate() {
                *v = src[t.first + o * sw];
            }
        }
    });
}

/// Adds `dcol [K, n * P]` back onto `dx` (the `n` samples' `[n, cin, h, w]`): the
/// transpose of [`im2col`], in one fixed order.
fn col2im_add(dcol: &[f32], g: &Geometry, n: usize, dx: &mut [f32]) {
    let (cols, sw) = (n * g.p(), g.stride[1]);
    walk(g, n, |t| {
        let Some(iy) = t.iy else {
            return;
        };
        let src = &dcol[t.row * cols + t.at..][..g.ow];
        let dst = &mut dx[t.image + iy * g.w..][..g.w];
        for (o, v) in src[t.lo..t.hi].iter().enumerate() {
            dst[t.first + o * sw] += v;
        }
    });
}

/// The convolution of `x [batch, cin, h, w]` with `w [cout, cin, kh, kw]` (no bias):
/// `[batch, cout, oh, ow]`, row-major.
pub fn forward(x: &[f32], w: &[f32], g: &Geometry) -> Vec<f32> {
    let (k, p, per) = (g.k(), g.p(), g.group());
    assert_eq!(
        x.len(),
        g.batch * g.cin * g.h * g.w,
        "conv forward: input size"
    );
    assert_eq!(w.len(), g.cout * k, "conv forward: weight size");
    let mut out = vec![0.0; g.batch * g.cout * p];
    if out.is_empty() {
        return out;
    }
    out.par_chunks_mut(per * g.cout * p)
        .enumerate()
        .for_each(|(i, chunk)| {
            let (b0, n) = (i * per, chunk.len() / (g.cout * p));
            SCRATCH.with_borrow_mut(|(col, tmp)| {
                let cols = n * p;
                let col: &[f32] = if g.direct() && n == 1 {
                    &x[b0 * k * p..][..k * p]
                } else {
                    let col = sized(col, k * cols);
                    im2col(x, g, b0, n, col);
                    col
                };
                let lhs = Mat::rows(w, k);
                if n == 1 {
                    matmul(chunk, (g.cout, k, p), lhs, Mat::rows(col, p), false);
                    return;
                }
                // One product for the group, then each sample's rows to their place.
                let tmp = sized(tmp, g.cout * cols);
                matmul(tmp, (g.cout, k, cols), lhs, Mat::rows(col, cols), false);
                for s in 0..n {
                    for c in 0..g.cout {
                        chunk[(s * g.cout + c) * p..][..p]
                            .copy_from_slice(&tmp[c * cols + s * p..][..p]);
                    }
                }
            });
        });
    out
}

/// This group's slice of `dy` as `[cout, n * P]`: a view when the group is one sample,
/// else gathered into `buf`.
fn group_rows<'a>(
    dy: &'a [f32],
    g: &Geometry,
    b0: usize,
    n: usize,
    buf: &'a mut Vec<f32>,
) -> &'a [f32] {
    let (p, cols) = (g.p(), n * g.p());
    if n == 1 {
        return &dy[b0 * g.cout * p..][..g.cout * p];
    }
    let t = sized(buf, g.cout * cols);
    for s in 0..n {
        for c in 0..g.cout {
            t[c * cols + s * p..][..p].copy_from_slice(&dy[((b0 + s) * g.cout + c) * p..][..p]);
        }
    }
    t
}

/// The gradient of [`forward`] with respect to its input, given the output's gradient
/// `dy [batch, cout, oh, ow]`: `[batch, cin, h, w]`. Per group of samples,
/// `dcol = W^T x dy`, added back onto the group's own images (so groups run in
/// parallel without sharing a value).
pub fn input_grad(w: &[f32], dy: &[f32], g: &Geometry) -> Vec<f32> {
    let (k, p, per) = (g.k(), g.p(), g.group());
    let image = g.cin * g.h * g.w;
    assert_eq!(w.len(), g.cout * k, "conv input gradient: weight size");
    assert_eq!(
        dy.len(),
        g.batch * g.cout * p,
        "conv input gradient: gradient size"
    );
    let mut dx = vec![0.0; g.batch * image];
    if dx.is_empty() {
        return dx;
    }
    dx.par_chunks_mut(per * image)
        .enumerate()
        .for_each(|(i, chunk)| {
            let (b0, n) = (i * per, chunk.len() / image);
            SCRATCH.with_borrow_mut(|(col, tmp)| {
                let cols = n * p;
                let dyg = group_rows(dy, g, b0, n, tmp);
                let dcol = sized(col, k * cols);
                matmul(
                    dcol,
                    (k, g.cout, cols),
                    Mat::transposed(w, k),
                    Mat::rows(dyg, cols),
                    false,
                );
                col2im_add(dcol, g, n, chunk);
            });
        });
    dx
}

/// The gradient of [`forward`] with respect to its weights, given the output's gradient
/// `dy`: `[cout, cin, kh, kw]`, the sum over the batch of `dy_b x col_b^T`. It is computed
/// transposed, `dW^T [K, cout] += col_b [K, P] x dy_b^T`, so the large operand (the
/// column matrix) is read in place and only `dy_b` is repacked. The batch is cut into at
/// most `LANES` (8) lanes of whole groups, each summing its own part; the parts are then
/// added in lane order, so the result does not depend on the thread count.
pub fn weight_grad(x: &[f32], dy: &[f32], g: &Geometry) -> Vec<f32> {
    let (k, p, per) = (g.k(), g.p(), g.group());
    assert_eq!(
        x.len(),
        g.batch * g.cin * g.h * g.w,
        "conv weight gradient: input size"
    );
    assert_eq!(
        dy.len(),
        g.batch * g.cout * p,
        "conv weight gradient: gradient size"
    );
    let groups = g.batch.div_ceil(per);
    let lanes = LANES.min(groups);
    if lanes == 0 {
        return vec![0.0; g.cout * k];
    }
    let parts: Vec<Vec<f32>> = (0..lanes)
        .into_par_iter()
        .map(|l| {
            let first = l * groups / lanes * per;
            let last = ((l + 1) * groups / lanes * per).min(g.batch);
            let mut dwt = vec![0.0; k * g.cout];
            SCRATCH.with_borrow_mut(|(col, tmp)| {
                for b0 in (first..last).step_by(per) {
                    let n = per.min(last - b0);
                    let cols = n * p;
                    let dyg = group_rows(dy, g, b0, n, tmp);
                    let cm: &[f32] = if g.direct() && n == 1 {
                        &x[b0 * k * p..][..k * p]
                    } else {
                        let c = sized(col, k * cols);
                        im2col(x, g, b0, n, c);
                        c
                    };
                    let (lhs, rhs) = (Mat::rows(cm, cols), Mat::transposed(dyg, cols));
                    matmul(&mut dwt, (k, cols, g.cout), lhs, rhs, true);
                }
            });
            dwt
        })
        .collect();
    let mut parts = parts.into_iter();
    let mut total = parts.next().expect("one lane at least");
    for part in parts {
        total.iter_mut().zip(&part).for_each(|(t, v)| *t += v);
    }
    let mut dw = vec![0.0; g.cout * k];
    for (q, row) in total.chunks_exact(g.cout).enumerate() {
        for (o, v) in row.iter().enumerate() {
            dw[o * k + q] = *v;
        }
    }
    dw
}

/// Both gradients of [`forward`], each computed only where asked for: `(dx, dw)`.
pub fn backward(
    x: &[f32],
    w: &[f32],
    dy: &[f32],
    g: &Geometry,
    want_dx: bool,
    want_dw: bool,
) -> (Option<Vec<f32>>, Option<Vec<f32>>) {
    (
        want_dx.then(|| input_grad(w, dy, g)),
        want_dw.then(|| weight_grad(x, dy, g)),
    )
}
