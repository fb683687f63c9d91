//! Convolutions of channels-last images (`[h, w, c]`, batch 1): inference's layout.
//!
//! The product reads the input in place (an *indirect* or implicit im2col, as
//! XNNPACK's convolutions do; Dukhan, "The Indirect Convolution Algorithm", 2019):
//! the image is padded once with zeros, and output pixel `p`'s inner index
//! `kk = (ky * k + kx) * cin + ci` is `padded[window(p) + offset(kk)]`. No column
//! matrix is written. Each output is the chain over `kk` in that order, the same bits
//! as [`gemm`](crate::gemm) over an im2col matrix with the same column order (tested).

use crate::gemm::micro::{GatherLhs, Panel};
use crate::gemm::{Dest, KC, MR, NR, PackedRhs, tile_on};
use crate::isa::Isa;
use std::ops::Range;

/// A square convolution's shape on one channels-last image.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Conv2dNhwc {
    /// Input rows, columns and channels.
    pub h: usize,
    pub w: usize,
    pub cin: usize,
    /// Kernel size (k x k), stride and zero padding on every side.
    pub k: usize,
    pub stride: usize,
    pub pad: usize,
}

impl Conv2dNhwc {
    /// Output rows and columns.
    pub fn out_size(&self) -> (usize, usize) {
        let len = |n: usize| (n + 2 * self.pad - self.k) / self.stride + 1;
        (len(self.h), len(self.w))
    }

    /// The inner dimension `k * k * cin`.
    pub fn kdim(&self) -> usize {
        self.k * self.k * self.cin
    }

    /// Padded columns.
    fn wp(&self) -> usize {
        self.w + 2 * self.pad
    }
}

/// An input image ready for [`conv2d_nhwc`]: padded with zeros, with the table of
/// offsets of the inner index.
#[derive(Debug, Clone)]
pub struct Padded {
    shape: Conv2dNhwc,
    data: Vec<f32>,
    offsets: Vec<u32>,
}

impl Padded {
    /// Pads `x [h, w, cin]` for `shape`.
    ///
    /// # Panics
    /// If `x` does not hold `h * w * cin` values, the kernel is larger than the padded
    /// image, or the image is too large for 32-bit offsets.
    pub fn new(x: &[f32], shape: Conv2dNhwc) -> Padded {
        let Conv2dNhwc {
            h, w, cin, k, pad, ..
        } = shape;
        assert_eq!(x.len(), h * w * cin, "conv2d_nhwc: input size");
        assert!(shape.stride > 0 && k > 0 && h + 2 * pad >= k && w + 2 * pad >= k);
        let (hp, wp) = (h + 2 * pad, shape.wp());
        assert!(
            hp * wp * cin < u32::MAX as usize,
            "conv2d_nhwc: image too large"
        );
        let mut data = vec![0.0; hp * wp * cin];
        for y in 0..h {
            data[((y + pad) * wp + pad) * cin..][..w * cin]
                .copy_from_slice(&x[y * w * cin..][..w * cin]);
        }
        let offsets = (0..k)
            .flat_map(|ky| (0..k).flat_map(move |kx| (0..cin).map(move |ci| (ky, kx, ci))))
            .map(|(ky, kx, ci)| ((ky * wp + kx) * cin + ci) as u32)
            .collect();
        Padded {
            shape,
            data,
            offsets,
        }
    }

    /// Where output pixel `p`'s window starts in the padded image.
    fn window(&self, p: usize) -> usize {
        let s = &self.shape;
        let wo = s.out_size().1;
        let (oy, ox) = (p / wo, p % wo);
        (oy * s.stride * s.wp() + ox * s.stride) * s.cin
    }
}

/// Output pixels `pixels` (row-major over `[ho, wo]`) and channels `cols` of the
/// convolution of `x` with `weights` (`[kdim, cout]`, packed) into
/// `out [pixels.len(), cols.len()]`, row-major, on this thread.
///
/// # Panics
/// If the weights' inner dimension is not the shape's, `cols` does not start at a
/// multiple of [`NR`] or ends past the weights' columns, `pixels` ends past the
/// output, or `out` is too small.
pub fn conv2d_nhwc(
    out: &mut [f32],
    x: &Padded,
    weights: &PackedRhs,
    pixels: Range<usize>,
    cols: Range<usize>,
) {
    conv2d_nhwc_on(Isa::current(), out, x, weights, pixels, cols);
}

/// [`conv2d_nhwc`] on a given kernel.
pub fn conv2d_nhwc_on(
    isa: Isa,
    out: &mut [f32],
    x: &Padded,
    weights: &PackedRhs,
    pixels: Range<usize>,
    cols: Range<usize>,
) {
    let (ho, wo) = x.shape.out_size();
    let kdim = x.shape.kdim();
    assert_eq!(weights.k(), kdim, "conv2d_nhwc: weights' inner dimension");
    assert!(
        cols.start.is_multiple_of(NR) && cols.start <= cols.end && cols.end <= weights.n(),
        "conv2d_nhwc: columns {cols:?} of {}",
        weights.n()
    );
    assert!(pixels.start <= pixels.end && pixels.end <= ho * wo);
    let (m, n) = (pixels.len(), cols.len());
    assert!(
        out.len() >= m * n,
        "conv2d_nhwc: out holds {} < {m} x {n}",
        out.len()
    );
    if m == 0 || n == 0 {
        return;
    }
    let isa = isa.min(Isa::best());
    for pc in (0..kdim).step_by(KC) {
        let kc = KC.min(kdim - pc);
        let offsets = x.offsets[pc..].as_ptr();
        for j0 in (0..n).step_by(NR) {
            let width = NR.min(n - j0);
            let b = weights.panel(cols.start / NR + j0 / NR, pc);
            let panel = Panel {
                b: b.as_ptr(),
                ldb: NR,
            };
            for i0 in (0..m).step_by(MR) {
                let rows = MR.min(m - i0);
                // Rows past the last pixel repeat it (their outputs are dropped).
                let a = GatherLhs {
                    x: x.data.as_ptr(),
                    rows: std::array::from_fn(|i| x.window(pixels.start + i0 + i.min(rows - 1))),
                    offsets,
                };
                let dest = Dest {
                    out: &mut out[..m * n],
                    at: i0 * n + j0,
                    ldc: n,
                    rows,
                    width,
                };
                // SAFETY: every window plus every offset lies in the padded image (the
                // output size is derived from it); the panel holds kc rows of NR.
                unsafe { tile_on(isa, kc, &a, &panel, dest, pc > 0) };
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gemm::tests::noise;
    use crate::{Mat, gemm};

    /// im2col of a channels-last image, columns in the order `(ky, kx, ci)`.
    fn im2col(x: &[f32], s: &Conv2dNhwc) -> Vec<f32> {
        let (ho, wo) = s.out_size();
        let mut col = Vec::with_capacity(ho * wo * s.kdim());
        for oy in 0..ho {
            for ox in 0..wo {
                for ky in 0..s.k {
                    for kx in 0..s.k {
                        let iy = (oy * s.stride + ky) as isize - s.pad as isize;
                        let ix = (ox * s.stride + kx) as isize - s.pad as isize;
                        for ci in 0..s.cin {
                            let inside =
                                iy >= 0 && ix >= 0 && (iy as usize) < s.h && (ix as usize) < s.w;
                            col.push(match inside {
                                true => x[((iy as usize) * s.w + ix as usize) * s.cin + ci],
                                false => 0.0,
                            });
                        }
                    }
                }
            }
        }
        col
    }

    /// The network's layer shapes (the stem, 3x3 layers, strided 3x3 and 1x1
    /// downsamples) at both scales' sizes, and odd sizes.
    const SHAPES: [(usize, usize, usize, usize, usize, usize, usize); 8] = [
        // h, w, cin, cout, k, stride, pad
        (96, 240, 3, 32, 7, 2, 3),
        (24, 60, 32, 32, 3, 1, 1),
        (18, 45, 32, 64, 3, 2, 1),
        (18, 45, 32, 64, 1, 2, 0),
        (6, 15, 128, 128, 3, 1, 1),
        (3, 8, 256, 256, 3, 1, 1),
        (5, 7, 9, 40, 3, 1, 1),
        (4, 4, 16, 32, 1, 1, 0),
    ];

    /// The indirect convolution is the product over an im2col matrix, bit for bit, on
    /// every kernel this CPU has, for whole outputs and for shares of pixels and
    /// channels.
    #[test]
    fn the_indirect_convolution_is_the_product_over_im2col() {
        for (case, (h, w, cin, cout, k, stride, pad)) in SHAPES.into_iter().enumerate() {
            let s = Conv2dNhwc {
                h,
                w,
                cin,
                k,
                stride,
                pad,
            };
            let x = noise(h * w * cin, 5 + case as u32);
            let wt = noise(s.kdim() * cout, 9 + case as u32);
            let packed = PackedRhs::new(Mat::rows(&wt, cout), s.kdim(), cout);
            let (ho, wo) = s.out_size();
            let col = im2col(&x, &s);
            let mut want = vec![0.0; ho * wo * cout];
            gemm(
                &mut want,
                (ho * wo, s.kdim(), cout),
                Mat::rows(&col, s.kdim()),
                Mat::rows(&wt, cout),
                false,
            );
            let padded = Padded::new(&x, s);
            for isa in Isa::available() {
                let px = ho * wo;
                for (pixels, cols) in [(0..px, 0..cout), (px / 3..px, cout / 2 / NR * NR..cout)] {
                    let mut got = vec![f32::NAN; pixels.len() * cols.len()];
                    conv2d_nhwc_on(
                        isa,
                        &mut got,
                        &padded,
                        &packed,
                        pixels.clone(),
                        cols.clone(),
                    );
                    for (i, p) in pixels.clone().enumerate() {
                        for (j, c) in cols.clone().enumerate() {
                            let (g, e) = (got[i * cols.len() + j], want[p * cout + c]);
                            assert_eq!(
                                g.to_bits(),
                                e.to_bits(),
                                "{isa:?} shape {case}: pixel {p} channel {c}: {g} against {e}"
                            );
                        }
                    }
                }
            }
        }
    }
}
