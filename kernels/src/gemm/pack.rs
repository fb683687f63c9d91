//! Packing: copying a block of an operand into the k-major panels the
//! micro-kernels read, zero-padded to whole panels.

use super::{MR, Mat, NR};
use std::ops::Range;

/// Rows `rows` (at most [`MR`]) and columns `ks` of `lhs` into `dst` as
/// `dst[kk * MR + i]`; rows past the matrix are zeros.
pub(super) fn lhs_panel(lhs: Mat, rows: Range<usize>, ks: Range<usize>, dst: &mut [f32]) {
    panel::<MR>(lhs, rows, ks, dst);
}

/// Rows `ks` and columns `cols` (at most [`NR`]) of `rhs` into `dst` as
/// `dst[kk * NR + j]`; columns past the matrix are zeros: the left operand's packing
/// applied to the transposed view.
pub(crate) fn rhs_panel(rhs: Mat, ks: Range<usize>, cols: Range<usize>, dst: &mut [f32]) {
    let transposed = Mat {
        data: rhs.data,
        row_stride: rhs.col_stride,
        col_stride: rhs.row_stride,
    };
    panel::<NR>(transposed, cols, ks, dst);
}

/// Lanes `lanes` (at most `W`: the panel's width) and columns `ks` of `m` into `dst`
/// as `dst[kk * W + lane]`; lanes past the matrix are zeros.
fn panel<const W: usize>(m: Mat, lanes: Range<usize>, ks: Range<usize>, dst: &mut [f32]) {
    let kc = ks.len();
    let dst = &mut dst[..kc * W];
    let n = lanes.len();
    if n < W {
        dst.fill(0.0);
    }
    if m.row_stride == 1 {
        // A column of the panel is contiguous in the source.
        for (kk, k) in ks.enumerate() {
            let src = &m.data[lanes.start + k * m.col_stride..][..n];
            dst[kk * W..][..n].copy_from_slice(src);
        }
    } else if m.col_stride == 1 {
        // A lane of the panel is contiguous in the source: a transposing copy.
        for (i, lane) in lanes.enumerate() {
            let src = &m.data[lane * m.row_stride + ks.start..][..kc];
            for (kk, &v) in src.iter().enumerate() {
                dst[kk * W + i] = v;
            }
        }
    } else {
        for (i, lane) in lanes.enumerate() {
            for (kk, k) in ks.clone().enumerate() {
                dst[kk * W + i] = m.at(lane, k);
            }
        }
    }
}
