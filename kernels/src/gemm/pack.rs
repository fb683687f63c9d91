//! Packing: copying a block of an operand into the k-major panels the
//! micro-kernels read, zero-padded to whole panels.

use super::{MR, Mat, NR};
use std::ops::Range;

/// Rows `rows` (at most [`MR`]) and columns `ks` of `lhs` into `dst` as
/// `dst[kk * MR + i]`; rows past the matrix are zeros.
pub(super) fn lhs_panel(lhs: Mat, rows: Range<usize>, ks: Range<usize>, dst: &mut [f32]) {
    let kc = ks.len();
    let dst = &mut dst[..kc * MR];
    let n_rows = rows.len();
    if n_rows < MR {
        dst.fill(0.0);
    }
    if lhs.row_stride == 1 {
        // Columns of the panel are contiguous in the source.
        for (kk, k) in ks.enumerate() {
            let src = &lhs.data[rows.start + k * lhs.col_stride..][..n_rows];
            dst[kk * MR..][..n_rows].copy_from_slice(src);
        }
    } else if lhs.col_stride == 1 {
        // Rows of the panel are contiguous in the source: a transposing copy.
        for (i, r) in rows.enumerate() {
            let src = &lhs.data[r * lhs.row_stride + ks.start..][..kc];
            for (kk, &v) in src.iter().enumerate() {
                dst[kk * MR + i] = v;
            }
        }
    } else {
        for (i, r) in rows.enumerate() {
            for (kk, k) in ks.clone().enumerate() {
                dst[kk * MR + i] = lhs.at(r, k);
            }
        }
    }
}

/// Rows `ks` and columns `cols` (at most [`NR`]) of `rhs` into `dst` as
/// `dst[kk * NR + j]`; columns past the matrix are zeros.
pub(super) fn rhs_panel(rhs: Mat, ks: Range<usize>, cols: Range<usize>, dst: &mut [f32]) {
    let kc = ks.len();
    let dst = &mut dst[..kc * NR];
    let n_cols = cols.len();
    if n_cols < NR {
        dst.fill(0.0);
    }
    if rhs.col_stride == 1 {
        // Rows of the panel are contiguous in the source.
        for (kk, k) in ks.enumerate() {
            let src = &rhs.data[k * rhs.row_stride + cols.start..][..n_cols];
            dst[kk * NR..][..n_cols].copy_from_slice(src);
        }
    } else if rhs.row_stride == 1 {
        // Columns of the panel are contiguous in the source: a transposing copy.
        for (j, c) in cols.enumerate() {
            let src = &rhs.data[c * rhs.col_stride + ks.start..][..kc];
            for (kk, &v) in src.iter().enumerate() {
                dst[kk * NR + j] = v;
            }
        }
    } else {
        for (j, c) in cols.enumerate() {
            for (kk, k) in ks.clone().enumerate() {
                dst[kk * NR + j] = rhs.at(k, c);
            }
        }
    }
}
