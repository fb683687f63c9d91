use super::*;

/// Deterministic values in [-1, 1).
pub(crate) fn noise(len: usize, seed: u32) -> Vec<f32> {
    let mut state = seed;
    (0..len)
        .map(|_| {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 8) as f32 / (1u32 << 24) as f32 * 2.0 - 1.0
        })
        .collect()
}

/// The promise, written out: one fused multiply-add chain per output, in order.
fn definition(
    (m, k, n): (usize, usize, usize),
    lhs: &[f32],
    rhs: &[f32],
    start: Option<&[f32]>,
) -> Vec<f32> {
    let mut out = vec![0.0; m * n];
    for i in 0..m {
        for j in 0..n {
            let mut acc = start.map_or(0.0, |s| s[i * n + j]);
            for kk in 0..k {
                acc = lhs[i * k + kk].mul_add(rhs[kk * n + j], acc);
            }
            out[i * n + j] = acc;
        }
    }
    out
}

/// Shapes with every kind of edge: fewer rows than a panel, columns not a multiple of
/// 32, depths across several `KC` blocks, several `MC` and `NC` blocks, and the
/// network's own (a 3 x 3 layer of 256 channels at inference: 120 pixels, k = 2304).
const SHAPES: [(usize, usize, usize); 9] = [
    (1, 1, 1),
    (5, 27, 16),
    (8, 32, 32),
    (37, 1200, 40),
    (120, 2304, 256),
    (97, 257, 33),
    (200, 600, 300),
    (32, 3000, 288),
    (6, 480, 32),
];

/// Every kernel this CPU has gives the definition's bits, for every layout of the
/// operands (row-major or transposed views), overwriting or accumulating, packed
/// beforehand or not: the order of summation is the algorithm's, whatever the vector
/// width or the blocking. On an AVX-512 machine this compares AVX-512, AVX2 and the
/// scalar loop with each other, in one process.
#[test]
fn every_kernel_computes_the_definition_bit_for_bit() {
    for (case, (m, k, n)) in SHAPES.into_iter().enumerate() {
        let lhs = noise(m * k, 0x9e37_79b9 + case as u32);
        let rhs = noise(k * n, 0x85eb_ca6b + case as u32);
        let start = noise(m * n, 0xc2b2_ae35 + case as u32);
        let lhs_t: Vec<f32> = (0..k * m).map(|i| lhs[(i % m) * k + i / m]).collect();
        let rhs_t: Vec<f32> = (0..n * k).map(|i| rhs[(i % k) * n + i / k]).collect();
        for accumulate in [false, true] {
            let want = definition((m, k, n), &lhs, &rhs, accumulate.then_some(&start[..]));
            for isa in Isa::available() {
                for (lt, rt) in [(false, false), (false, true), (true, false), (true, true)] {
                    let l = match lt {
                        true => Mat::transposed(&lhs_t, m),
                        false => Mat::rows(&lhs, k),
                    };
                    let r = match rt {
                        true => Mat::transposed(&rhs_t, k),
                        false => Mat::rows(&rhs, n),
                    };
                    let mut out = match accumulate {
                        true => start.clone(),
                        false => vec![f32::NAN; m * n],
                    };
                    gemm_on(isa, &mut out, (m, k, n), l, r, accumulate);
                    let mut packed = match accumulate {
                        true => start.clone(),
                        false => vec![f32::NAN; m * n],
                    };
                    gemm_packed_on(isa, &mut packed, m, l, &PackedRhs::new(r, k, n), accumulate);
                    for (what, got) in [("strided", &out), ("packed", &packed)] {
                        if let Some(at) =
                            (0..m * n).find(|&i| got[i].to_bits() != want[i].to_bits())
                        {
                            panic!(
                                "{isa:?} {what}, m {m} k {k} n {n}, transposed ({lt}, {rt}), \
                                 accumulate {accumulate}: out[{}, {}] = {} but the chain gives {}",
                                at / n,
                                at % n,
                                got[at],
                                want[at]
                            );
                        }
                    }
                }
            }
        }
    }
}

/// Accumulating continues the chain: `0..a` then `a..k` is `0..k`, bit for bit (what
/// the weight gradient's sum over the batch relies on).
#[test]
fn two_accumulating_calls_are_one_chain() {
    let (m, k, n, a) = (19, 700, 45, 333);
    let lhs = noise(m * k, 1);
    let rhs = noise(k * n, 2);
    let mut whole = vec![0.0; m * n];
    gemm(
        &mut whole,
        (m, k, n),
        Mat::rows(&lhs, k),
        Mat::rows(&rhs, n),
        false,
    );
    let mut parts = vec![f32::NAN; m * n];
    let first = Mat {
        data: &lhs,
        row_stride: k,
        col_stride: 1,
    };
    gemm(&mut parts, (m, a, n), first, Mat::rows(&rhs, n), false);
    let second = Mat {
        data: &lhs[a..],
        row_stride: k,
        col_stride: 1,
    };
    gemm(
        &mut parts,
        (m, k - a, n),
        second,
        Mat::rows(&rhs[a * n..], n),
        true,
    );
    assert!(
        whole
            .iter()
            .zip(&parts)
            .all(|(x, y)| x.to_bits() == y.to_bits())
    );
}

/// Against the exact product (f64): each output within the forward error bound of a
/// recursive fused sum, `|err| <= gamma_k * sum_kk |lhs * rhs|` with
/// `gamma_k = k u / (1 - k u)` and `u = 2^-24` (Higham, *Accuracy and Stability of
/// Numerical Algorithms*, 2nd ed., eq. 3.5; a fused step rounds once, so the bound of
/// the unfused sum holds a fortiori). With k = 2304 that is 1.4e-4 of the absolute sum:
/// the tolerance is the arithmetic's own, not a guess.
#[test]
fn products_are_within_the_rounding_bound_of_the_exact_sum() {
    let u = f64::from(f32::EPSILON) / 2.0;
    for (case, (m, k, n)) in SHAPES.into_iter().enumerate() {
        let lhs = noise(m * k, 7 + case as u32);
        let rhs = noise(k * n, 11 + case as u32);
        let mut out = vec![0.0; m * n];
        gemm(
            &mut out,
            (m, k, n),
            Mat::rows(&lhs, k),
            Mat::rows(&rhs, n),
            false,
        );
        let gamma = k as f64 * u / (1.0 - k as f64 * u);
        for i in 0..m {
            for j in 0..n {
                let (mut exact, mut abs) = (0.0f64, 0.0f64);
                for kk in 0..k {
                    let p = f64::from(lhs[i * k + kk]) * f64::from(rhs[kk * n + j]);
                    exact += p;
                    abs += p.abs();
                }
                let err = (f64::from(out[i * n + j]) - exact).abs();
                assert!(
                    err <= gamma * abs,
                    "m {m} k {k} n {n} out[{i}, {j}]: error {err:e} > bound {:e}",
                    gamma * abs
                );
            }
        }
    }
}

#[test]
fn an_empty_inner_dimension_gives_zeros_or_leaves_the_sum() {
    let mut out = vec![f32::NAN; 6];
    gemm(
        &mut out,
        (2, 0, 3),
        Mat::rows(&[], 0),
        Mat::rows(&[], 3),
        false,
    );
    assert_eq!(out, vec![0.0; 6]);
    let mut out = vec![1.5; 6];
    gemm(
        &mut out,
        (2, 0, 3),
        Mat::rows(&[], 0),
        Mat::rows(&[], 3),
        true,
    );
    assert_eq!(out, vec![1.5; 6]);
}

#[test]
#[should_panic(expected = "leaves its data")]
fn a_view_outside_its_data_is_refused() {
    let mut out = vec![0.0; 4];
    gemm(
        &mut out,
        (2, 3, 2),
        Mat::rows(&[0.0; 5], 3),
        Mat::rows(&[0.0; 6], 2),
        false,
    );
}
