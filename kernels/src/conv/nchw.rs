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

use crate::gemm::micro::{GatherLhs, GatherRhs, PackedLhs, Panel};
use crate::gemm::{Dest, KC, MR, NR, tile_on};
use crate::isa::Isa;
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

    /// Whether [`forward`] and [`weight_grad`] read the (padded) input in place instead
    /// of building a column matrix: strides of 1 or 2, and output rows at least half a
    /// 32-pixel panel wide.
    fn in_place(&self) -> bool {
        let strides = (1..=2).contains(&self.stride[0]) && (1..=2).contains(&self.stride[1]);
        strides && !self.direct() && self.ow >= NR / 2
    }

    /// The padded input's columns per phase: with stride `s` along a row, the padded
    /// planes are split into `s` phases of every `s`-th column, so a tap's input under
    /// neighbouring output pixels is contiguous ([`pad_sample`]).
    fn phase_width(&self) -> usize {
        (self.w + 2 * self.pad[1]).div_ceil(self.stride[1])
    }

    /// Where output pixel `(oy, ox)`'s window starts in [`pad_sample`]'s phase planes.
    fn window(&self, oy: usize, ox: usize) -> usize {
        oy * self.stride[0] * self.phase_width() + ox
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
    if g.in_place() {
        let weights = pack_rows(w, g.cout, k);
        out.par_chunks_mut(g.cout * p)
            .enumerate()
            .for_each(|(b, chunk)| {
                SCRATCH.with_borrow_mut(|(padded, _)| {
                    let offsets = pad_sample(x, g, b, padded);
                    forward_in_place(padded, &offsets, &weights, g, chunk);
                });
            });
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

/// `w [rows, k]` (row-major) packed in panels of [`MR`] rows, each `k` deep:
/// `packed[(panel * k + kk) * MR + i]`, rows past the last zero.
fn pack_rows(w: &[f32], rows: usize, k: usize) -> Vec<f32> {
    let mut packed = vec![0.0; rows.div_ceil(MR) * MR * k];
    for r in 0..rows {
        let (panel, i) = (r / MR, r % MR);
        for (kk, &v) in w[r * k..][..k].iter().enumerate() {
            packed[(panel * k + kk) * MR + i] = v;
        }
    }
    packed
}

/// Sample `b` of `x`, zero-padded by the geometry's padding into `buf`, its columns
/// split into `stride` phases (phase `q` holds padded columns `q, q + s, ...`; one phase
/// at stride 1): planes `[phase][c][h + 2 ph][phase width]`, then [`NR`] floats of slack
/// (a panel row near the end of the last row reads past it, into lanes that are
/// dropped). Returns the offset of each inner index `(c, ky, kx)` from an output pixel's
/// window ([`Geometry::window`]).
fn pad_sample(x: &[f32], g: &Geometry, b: usize, buf: &mut Vec<f32>) -> Vec<u32> {
    let (hp, sw, wq) = (g.h + 2 * g.pad[0], g.stride[1], g.phase_width());
    let plane = hp * wq;
    let phase = g.cin * plane;
    buf.clear();
    buf.resize(sw * phase + NR, 0.0);
    for c in 0..g.cin {
        let src = &x[(b * g.cin + c) * g.h * g.w..][..g.h * g.w];
        for y in 0..g.h {
            let row = c * plane + (y + g.pad[0]) * wq;
            if sw == 1 {
                buf[row + g.pad[1]..][..g.w].copy_from_slice(&src[y * g.w..][..g.w]);
            } else {
                for (ix, &v) in src[y * g.w..][..g.w].iter().enumerate() {
                    let xp = ix + g.pad[1];
                    buf[(xp % sw) * phase + row + xp / sw] = v;
                }
            }
        }
    }
    (0..g.cin)
        .flat_map(|c| (0..g.kh).flat_map(move |ky| (0..g.kw).map(move |kx| (c, ky, kx))))
        .map(|(c, ky, kx)| ((kx % sw) * phase + c * plane + ky * wq + kx / sw) as u32)
        .collect()
}

/// One sample of [`forward`] reading its padded input in place: each output row is cut
/// into runs of [`NR`] pixels, and tap `(c, ky, kx)` of a run is [`NR`] consecutive
/// floats of a padded phase plane. Each output is the chain over
/// the inner index in the order of the column matrix's rows, so the bits are those of
/// im2col and [`gemm`](crate::gemm) (tested).
fn forward_in_place(
    padded: &[f32],
    offsets: &[u32],
    weights: &[f32],
    g: &Geometry,
    out: &mut [f32],
) {
    let (k, p) = (g.k(), g.p());
    let isa = Isa::current();
    for pc in (0..k).step_by(KC) {
        let kc = KC.min(k - pc);
        let load = pc > 0;
        for oy in 0..g.oh {
            for ox0 in (0..g.ow).step_by(NR) {
                let width = NR.min(g.ow - ox0);
                let b = GatherRhs {
                    x: padded.as_ptr(),
                    base: g.window(oy, ox0),
                    offsets: offsets[pc..].as_ptr(),
                };
                for panel in 0..g.cout.div_ceil(MR) {
                    let (r0, rows) = (panel * MR, MR.min(g.cout - panel * MR));
                    let a = PackedLhs(weights[(panel * k + pc) * MR..][..kc * MR].as_ptr());
                    let dest = Dest {
                        out: &mut *out,
                        at: r0 * p + oy * g.ow + ox0,
                        ldc: p,
                        rows,
                        width,
                    };
                    // SAFETY: the panel holds kc * MR packed floats; every gathered row is
                    // NR floats inside `padded` (its slack covers the last row's overrun).
                    unsafe { tile_on(isa, kc, &a, &b, dest, load) };
                }
            }
        }
    }
}

/// Samples `samples` of [`weight_grad`], added to
/// `dwt [K, cout]`, reading the padded input in place: row `(c, ky, kx)` of the column
/// matrix at pixel `px` is the padded plane at the tap's offset plus the pixel's window.
/// The chain runs over the samples and their pixels in order, as over the column
/// matrix's columns, so the bits are the column matrix's (tested).
fn weight_grad_in_place(
    x: &[f32],
    dy: &[f32],
    g: &Geometry,
    samples: std::ops::Range<usize>,
    dwt: &mut [f32],
    padded: &mut Vec<f32>,
    packed: &mut Vec<f32>,
) {
    let (k, p) = (g.k(), g.p());
    let windows: Vec<u32> = (0..p)
        .map(|px| g.window(px / g.ow, px % g.ow) as u32)
        .collect();
    let isa = Isa::current();
    packed.resize(KC * NR, 0.0);
    for b in samples {
        let offsets = pad_sample(x, g, b, padded);
        let dyb = Mat::transposed(&dy[b * g.cout * p..][..g.cout * p], p);
        for pc in (0..p).step_by(KC) {
            let kc = KC.min(p - pc);
            for c0 in (0..g.cout).step_by(NR) {
                let width = NR.min(g.cout - c0);
                crate::gemm::pack::rhs_panel(dyb, pc..pc + kc, c0..c0 + width, packed);
                let panel = Panel {
                    b: packed.as_ptr(),
                    ldb: NR,
                };
                for r0 in (0..k).step_by(MR) {
                    let rows = MR.min(k - r0);
                    let a = GatherLhs {
                        x: padded.as_ptr(),
                        rows: std::array::from_fn(|i| offsets[r0 + i.min(rows - 1)] as usize),
                        offsets: windows[pc..].as_ptr(),
                    };
                    let dest = Dest {
                        out: &mut *dwt,
                        at: r0 * g.cout + c0,
                        ldc: g.cout,
                        rows,
                        width,
                    };
                    // SAFETY: every tap offset plus every window lies in the padded planes;
                    // the packed panel holds kc rows of NR.
                    unsafe { tile_on(isa, kc, &a, &panel, dest, true) };
                }
            }
        }
    }
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
                if g.in_place() {
                    weight_grad_in_place(x, dy, g, first..last, &mut dwt, col, tmp);
                    return;
                }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gemm::tests::noise;

    /// The column-matrix forward of one sample: im2col, then the product.
    fn through_columns(x: &[f32], w: &[f32], g: &Geometry, b: usize) -> Vec<f32> {
        let (k, p) = (g.k(), g.p());
        let mut col = vec![0.0; k * p];
        im2col(x, g, b, 1, &mut col);
        let mut y = vec![f32::NAN; g.cout * p];
        matmul(
            &mut y,
            (g.cout, k, p),
            Mat::rows(w, k),
            Mat::rows(&col, p),
            false,
        );
        y
    }

    /// The weight gradient read in place gives the column matrix's bits: the sum over
    /// the batch of `col_b x dy_b^T`, one chain over samples and pixels.
    #[test]
    fn the_weight_gradient_read_in_place_gives_the_column_matrix_bits() {
        for (case, (batch, cin, h, w, cout, k, pad)) in [
            (1, 32, 12, 30, 32, 3, 1),
            (2, 9, 7, 20, 40, 3, 1),
            (1, 3, 6, 18, 8, 3, 0),
            (1, 3, 24, 60, 32, 7, 3),
        ]
        .into_iter()
        .enumerate()
        {
            // The last case has stride 2 (the stem's shape).
            let s = if case == 3 { 2 } else { 1 };
            let g =
                Geometry::new([batch, cin, h, w], [cout, cin, k, k], [s, s], [pad, pad]).unwrap();
            assert!(g.in_place());
            let x = noise(batch * cin * h * w, 41 + case as u32);
            let dy = noise(batch * cout * g.p(), 51 + case as u32);
            let got = weight_grad(&x, &dy, &g);
            // The column matrix's way, one sample after another in one lane.
            let (kd, p) = (g.k(), g.p());
            let mut dwt = vec![0.0; kd * cout];
            for b in 0..batch {
                let mut col = vec![0.0; kd * p];
                im2col(&x, &g, b, 1, &mut col);
                let dyb = &dy[b * cout * p..][..cout * p];
                matmul(
                    &mut dwt,
                    (kd, p, cout),
                    Mat::rows(&col, p),
                    Mat::transposed(dyb, p),
                    true,
                );
            }
            // One lane here (the batch is one group); with several, lanes add their
            // parts at the end (the policy fingerprint covers that).
            assert_eq!(LANES.min(batch.div_ceil(g.group())), 1, "case {case}");
            for q in 0..kd {
                for o in 0..cout {
                    assert_eq!(
                        got[o * kd + q].to_bits(),
                        dwt[q * cout + o].to_bits(),
                        "case {case}: dW[{o}, {q}]"
                    );
                }
            }
        }
    }

    /// A stride-1 convolution read in place gives the column matrix's bits: the
    /// network's 3x3 layers at both scales' widths, a row of exactly one panel, rows cut
    /// short, more than one depth block, channels not a multiple of a panel, a 5x5 kernel.
    #[test]
    fn reading_the_input_in_place_gives_the_column_matrix_bits() {
        // batch, cin, h, w, cout, k, pad
        let cases = [
            (2, 32, 24, 60, 32, 3, 1),
            (1, 32, 18, 45, 32, 3, 1),
            (1, 64, 12, 30, 64, 3, 1),
            (1, 9, 7, 32, 40, 3, 1),
            (2, 16, 10, 33, 12, 5, 2),
            (1, 3, 6, 18, 8, 3, 0),
            // Stride 2: the stem (7x7, 3 channels) and a 3x3 downsample.
            (1, 3, 24, 60, 32, 7, 3),
            (2, 32, 12, 33, 64, 3, 1),
        ];
        for (case, (batch, cin, h, w, cout, k, pad)) in cases.into_iter().enumerate() {
            let s = if case >= 6 { 2 } else { 1 };
            let g =
                Geometry::new([batch, cin, h, w], [cout, cin, k, k], [s, s], [pad, pad]).unwrap();
            assert!(g.in_place(), "case {case} should read in place");
            let x = noise(batch * cin * h * w, 21 + case as u32);
            let wt = noise(cout * g.k(), 31 + case as u32);
            let y = forward(&x, &wt, &g);
            for b in 0..batch {
                let want = through_columns(&x, &wt, &g, b);
                let got = &y[b * cout * g.p()..][..cout * g.p()];
                if let Some(i) = (0..want.len()).find(|&i| got[i].to_bits() != want[i].to_bits()) {
                    panic!(
                        "case {case}, sample {b}, value {i}: {} against {}",
                        got[i], want[i]
                    );
                }
            }
        }
    }
}
