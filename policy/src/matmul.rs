//! One matrix product for the CPU paths (fused inference and the training
//! convolutions): `gemm` cut along its inner dimension by our code, so every CPU
//! adds the same numbers in the same order.

/// A matrix operand read through strides: element `(i, j)` is
/// `data[i * row_stride + j * col_stride]`.
///
/// A row-major `[rows, cols]` array is `Mat::rows(data, cols)`; its transpose, read
/// without copying, is `Mat::transposed(data, cols)`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Mat<'a> {
    /// The stored values.
    pub data: &'a [f32],
    /// Distance between rows, in elements.
    pub row_stride: usize,
    /// Distance between columns, in elements.
    pub col_stride: usize,
}

impl<'a> Mat<'a> {
    /// A row-major array of `cols` columns.
    pub fn rows(data: &'a [f32], cols: usize) -> Self {
        Mat {
            data,
            row_stride: cols,
            col_stride: 1,
        }
    }

    /// The transpose of a row-major array of `cols` columns (its columns become rows).
    pub fn transposed(data: &'a [f32], cols: usize) -> Self {
        Mat {
            data,
            row_stride: 1,
            col_stride: cols,
        }
    }

    /// Whether a `rows x cols` view stays inside `data`.
    fn holds(&self, rows: usize, cols: usize) -> bool {
        rows == 0
            || cols == 0
            || (rows - 1) * self.row_stride + (cols - 1) * self.col_stride < self.data.len()
    }
}

/// The longest inner dimension handed to one `gemm` call.
///
/// gemm cuts a longer inner dimension into blocks whose size it derives from the CPU's
/// cache (cpuid), and each block's sum is added to the output in turn. So the order of the
/// sums, and with it the last bits of every logit, would change from one machine to the
/// next (an Intel Xeon and an AMD EPYC drove the same checkpoint to different golden
/// ticks). gemm never makes a block shorter than 512, so a call of at most 512 is one
/// sequential pass of fused multiply-adds on every x86-64 machine with FMA. [`matmul`]
/// cuts the inner dimension itself, into the same pieces everywhere.
pub(crate) const K_BLOCK: usize = 512;

/// The length of [`matmul`]'s pieces of an inner dimension `k`: `ceil(k / K_BLOCK)`
/// near-equal pieces, none longer than [`K_BLOCK`] (at least 1, a valid step).
pub(crate) fn piece_len(k: usize) -> usize {
    k.div_ceil(k.div_ceil(K_BLOCK).max(1)).max(1)
}

/// `out [m, n] (+)= lhs [m, k] x rhs [k, n]`, `out` row-major, on this thread.
///
/// With `accumulate` the product is added to `out`, otherwise it replaces it. The inner
/// dimension is cut into pieces of [`piece_len`], each one `gemm` call that adds its
/// product to `out`: the same arithmetic in the same order on any CPU (tested against a
/// scalar fused multiply-add loop, bit for bit).
pub(crate) fn matmul(
    out: &mut [f32],
    (m, k, n): (usize, usize, usize),
    lhs: Mat,
    rhs: Mat,
    accumulate: bool,
) {
    assert!(
        out.len() >= m * n,
        "matmul: out holds {} < {m} x {n}",
        out.len()
    );
    assert!(
        lhs.holds(m, k),
        "matmul: lhs view {m} x {k} leaves its data"
    );
    assert!(
        rhs.holds(k, n),
        "matmul: rhs view {k} x {n} leaves its data"
    );
    if k == 0 {
        if !accumulate {
            out[..m * n].fill(0.0);
        }
        return;
    }
    // Both operands contiguous along k (a row-major lhs and a transposed rhs, as in a
    // convolution's weight gradient) is the one layout gemm does not sum in one
    // sequential pass: it takes dot products in the CPU's vector width, so AVX-512 and
    // AVX2 round differently (tested below). Such a piece goes over with its smaller
    // operand copied to k-major order.
    let dot_products = lhs.col_stride == 1 && rhs.row_stride == 1 && k > 1;
    let piece = piece_len(k);
    KMAJOR.with_borrow_mut(|copy| {
        for k0 in (0..k).step_by(piece) {
            let kp = piece.min(k - k0);
            let lhs_at = &lhs.data[k0 * lhs.col_stride..];
            let rhs_at = &rhs.data[k0 * rhs.row_stride..];
            let (l, r) = match dot_products {
                false => (
                    Mat {
                        data: lhs_at,
                        ..lhs
                    },
                    Mat {
                        data: rhs_at,
                        ..rhs
                    },
                ),
                true if m <= n => {
                    copy.clear();
                    copy.extend(
                        (0..kp)
                            .flat_map(|kk| (0..m).map(move |i| (i, kk)))
                            .map(|(i, kk)| lhs_at[i * lhs.row_stride + kk]),
                    );
                    (
                        Mat::transposed(copy, m),
                        Mat {
                            data: rhs_at,
                            ..rhs
                        },
                    )
                }
                true => {
                    copy.clear();
                    copy.extend(
                        (0..kp)
                            .flat_map(|kk| (0..n).map(move |j| (kk, j)))
                            .map(|(kk, j)| rhs_at[kk + j * rhs.col_stride]),
                    );
                    (
                        Mat {
                            data: lhs_at,
                            ..lhs
                        },
                        Mat::rows(copy, n),
                    )
                }
            };
            product_piece(out, (m, kp, n), l, r, k0 == 0 && !accumulate);
        }
    });
}

thread_local! {
    /// One operand piece in k-major order, for the layout gemm would not sum in order.
    static KMAJOR: std::cell::RefCell<Vec<f32>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// One gemm call: `out (+)= lhs [m, kp] x rhs [kp, n]` (`overwrite`: `=`), in one
/// sequential pass of fused multiply-adds per output (kp <= [`K_BLOCK`], a layout that
/// is not two k-contiguous operands).
fn product_piece(
    out: &mut [f32],
    (m, kp, n): (usize, usize, usize),
    lhs: Mat,
    rhs: Mat,
    overwrite: bool,
) {
    debug_assert!(kp <= K_BLOCK && lhs.holds(m, kp) && rhs.holds(kp, n));
    // SAFETY: the caller's views hold m x kp and kp x n (checked by `matmul` for the
    // whole product, and each piece starts inside it and spans at most what is left),
    // and `out` holds m * n; `out` does not alias the inputs (it is a distinct `&mut`).
    unsafe {
        gemm::gemm(
            m,
            n,
            kp,
            out.as_mut_ptr(),
            1,
            n as isize,
            // The first piece overwrites `out` unless accumulating; the others add to
            // it (1 * out + 1 * product).
            !overwrite,
            lhs.data.as_ptr(),
            lhs.col_stride as isize,
            lhs.row_stride as isize,
            rhs.data.as_ptr(),
            rhs.col_stride as isize,
            rhs.row_stride as isize,
            if overwrite { 0.0 } else { 1.0 },
            1.0,
            false,
            false,
            false,
            gemm::Parallelism::None,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise(len: usize, seed: u32) -> Vec<f32> {
        let mut state = seed;
        (0..len)
            .map(|_| {
                state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                (state >> 8) as f32 / (1u32 << 24) as f32 * 2.0 - 1.0
            })
            .collect()
    }

    /// What [`matmul`] promises: each output is the pieces' sums added in turn, each piece
    /// one sequential run of fused multiply-adds from zero. A scalar loop fixes that order,
    /// so bit-for-bit equality here means no CPU-dependent blocking is left in the product
    /// (gemm would otherwise cut k = 2304 by the cache size that cpuid reports). Checked
    /// for plain and transposed operands, overwriting and accumulating.
    #[test]
    fn matmul_sums_in_one_fixed_order_whatever_the_cpu() {
        for (case, (m, k, n)) in [
            (128, 2304, 64),
            (37, 1200, 40),
            (5, 27, 16),
            (128, 512, 32),
            (6, 1440, 32),
            (6, 480, 32),
        ]
        .into_iter()
        .enumerate()
        {
            let lhs = noise(m * k, 0x9e37_79b9 + case as u32);
            let rhs = noise(k * n, 0x85eb_ca6b + case as u32);
            let start = noise(m * n, 0xc2b2_ae35 + case as u32);
            // lhs stored [m, k] or [k, m]; rhs stored [k, n] or [n, k].
            let lhs_t: Vec<f32> = (0..k * m).map(|i| lhs[(i % m) * k + i / m]).collect();
            let rhs_t: Vec<f32> = (0..n * k).map(|i| rhs[(i % k) * n + i / k]).collect();
            for (lhs_transposed, rhs_transposed) in
                [(false, false), (false, true), (true, false), (true, true)]
            {
                let transposed = (lhs_transposed, rhs_transposed);
                for accumulate in [false, true] {
                    let l = if lhs_transposed {
                        Mat::transposed(&lhs_t, m)
                    } else {
                        Mat::rows(&lhs, k)
                    };
                    let r = if rhs_transposed {
                        Mat::transposed(&rhs_t, k)
                    } else {
                        Mat::rows(&rhs, n)
                    };
                    let mut out = if accumulate {
                        start.clone()
                    } else {
                        vec![f32::NAN; m * n]
                    };
                    matmul(&mut out, (m, k, n), l, r, accumulate);

                    let piece = piece_len(k);
                    assert!(piece <= K_BLOCK);
                    for i in 0..m {
                        for j in 0..n {
                            let mut total = if accumulate { start[i * n + j] } else { 0.0 };
                            for (p, k0) in (0..k).step_by(piece).enumerate() {
                                let mut acc = 0.0f32;
                                for kk in k0..(k0 + piece).min(k) {
                                    acc = lhs[i * k + kk].mul_add(rhs[kk * n + j], acc);
                                }
                                total = if p == 0 && !accumulate {
                                    acc
                                } else {
                                    total + acc
                                };
                            }
                            assert_eq!(
                                out[i * n + j].to_bits(),
                                total.to_bits(),
                                "m {m} k {k} n {n} transposed {transposed:?} accumulate \
                                 {accumulate}: out[{i}, {j}] = {} but the fixed order gives \
                                 {total}",
                                out[i * n + j]
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn an_empty_inner_dimension_gives_zeros_or_leaves_the_sum() {
        let mut out = vec![f32::NAN; 6];
        matmul(
            &mut out,
            (2, 0, 3),
            Mat::rows(&[], 0),
            Mat::rows(&[], 3),
            false,
        );
        assert_eq!(out, vec![0.0; 6]);
        let mut out = vec![1.5; 6];
        matmul(
            &mut out,
            (2, 0, 3),
            Mat::rows(&[], 0),
            Mat::rows(&[], 3),
            true,
        );
        assert_eq!(out, vec![1.5; 6]);
    }
}
