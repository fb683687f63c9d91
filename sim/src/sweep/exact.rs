//! Exact tests for paired runs: the sign-flip permutation test for per-run
//! counts, the exact McNemar test for 0/1 outcomes, the two one-sided tests
//! (TOST) for equivalence within a margin, and Holm's step-down correction
//! for a family of tests.
//!
//! "Exact" means no resampling and no normal approximation: the p-value is
//! the share of the 2^n equally likely sign patterns at least as extreme as
//! the one observed, counted by a subset-sum table over the differences
//! (scaled to integers). Every function gives the same number each time, and
//! the tests below check them against SciPy and statsmodels.

/// Which way a test looks for a difference.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Alternative {
    /// The mean difference is not 0.
    TwoSided,
    /// The mean difference is above 0.
    Greater,
    /// The mean difference is below 0.
    Less,
}

/// The largest integer a difference may be scaled to before the table gets
/// too big (the table has one entry per integer up to the scaled sum).
const MAX_SCALED_SUM: u64 = 4_000_000;

/// The exact p-value of the paired sign-flip test of "the differences `d` are
/// symmetric about 0" against `alt`. Under that null each non-zero difference
/// is as likely to carry the opposite sign, so the 2^n sign patterns are
/// equally likely; p is the share whose sum is at least as extreme as the
/// observed one (two-sided: |sum| at least as large). Zeros change nothing and
/// drop out. Returns 1 when every difference is 0.
///
/// The count is exact when the differences are multiples of 1/k for some
/// k <= 1000 (counts, 0/1 outcomes and such counts shifted by a margin like
/// 1/6 all are) and otherwise exact by enumeration for up to 22 non-zero
/// differences; beyond both, the differences are rounded to multiples of
/// 1/1000 (documented, and never the case for the page's counts).
pub fn sign_flip_p(d: &[f64], alt: Alternative) -> f64 {
    let nz: Vec<f64> = d.iter().copied().filter(|&x| x != 0.0).collect();
    if nz.is_empty() {
        return 1.0;
    }
    match integer_scale(&nz) {
        Some(k) => sign_flip_by_table(&nz, k, alt),
        None if nz.len() <= 22 => sign_flip_by_enumeration(&nz, alt),
        None => sign_flip_by_table(&nz, 1000, alt),
    }
}

/// The smallest k in 1..=1000 that makes every |x| k an integer (to 1e-9
/// relative) with a total under [`MAX_SCALED_SUM`].
fn integer_scale(values: &[f64]) -> Option<u64> {
    (1..=1000u64).find(|&k| {
        let kf = k as f64;
        let mut total = 0.0;
        values.iter().all(|&x| {
            let s = x.abs() * kf;
            total += s.round();
            (s - s.round()).abs() <= 1e-9 * s.max(1.0)
        }) && total <= MAX_SCALED_SUM as f64
    })
}

/// The sign-flip p-value by a subset-sum table over the differences scaled by
/// `k` to integers a_i: with A = sum a_i and W the sum of the a_i that carry a
/// minus sign, the signed sum is A - 2W, and the table holds P(W = w).
fn sign_flip_by_table(nz: &[f64], k: u64, alt: Alternative) -> f64 {
    let a: Vec<usize> = nz
        .iter()
        .map(|x| (x.abs() * k as f64).round() as usize)
        .collect();
    let total: usize = a.iter().sum();
    let observed_w: usize = nz
        .iter()
        .zip(&a)
        .filter(|(x, _)| **x < 0.0)
        .map(|(_, a)| a)
        .sum();
    // prob[w] = P(W = w) over the 2^n patterns, built one difference at a time.
    let mut prob = vec![0.0f64; total + 1];
    prob[0] = 1.0;
    let mut reach = 0;
    for &ai in &a {
        for w in (0..=reach).rev() {
            let p = prob[w] * 0.5;
            prob[w] = p;
            prob[w + ai] += p;
        }
        reach += ai;
    }
    let signed = |w: usize| total as i64 - 2 * w as i64;
    let t = signed(observed_w);
    let p: f64 = prob
        .iter()
        .enumerate()
        .filter(|&(w, _)| match alt {
            Alternative::Greater => signed(w) >= t,
            Alternative::Less => signed(w) <= t,
            Alternative::TwoSided => signed(w).abs() >= t.abs(),
        })
        .map(|(_, p)| p)
        .sum();
    p.min(1.0)
}

/// The sign-flip p-value by listing all 2^n patterns (n <= 22).
fn sign_flip_by_enumeration(nz: &[f64], alt: Alternative) -> f64 {
    let n = nz.len();
    let observed: f64 = nz.iter().sum();
    // Sums equal to the observed one up to rounding count as at least as extreme.
    let tol = 1e-9 * nz.iter().map(|x| x.abs()).sum::<f64>().max(1.0);
    let mut hits = 0u64;
    for mask in 0u64..(1 << n) {
        let s: f64 = nz
            .iter()
            .enumerate()
            .map(|(i, &x)| {
                if mask >> i & 1 == 1 {
                    -x.abs()
                } else {
                    x.abs()
                }
            })
            .sum();
        let extreme = match alt {
            Alternative::Greater => s >= observed - tol,
            Alternative::Less => s <= observed + tol,
            Alternative::TwoSided => s.abs() >= observed.abs() - tol,
        };
        hits += u64::from(extreme);
    }
    (hits as f64 / (1u64 << n) as f64).min(1.0)
}

/// The exact (binomial) McNemar test for paired 0/1 outcomes: `b` pairs went
/// one way, `c` the other, the concordant pairs drop out. Two-sided, as SciPy's
/// `binomtest(min(b, c), b + c, 0.5)`; 1 when there is no discordant pair. It is
/// the sign-flip test of the 0/1 differences.
pub fn mcnemar_exact_p(b: usize, c: usize) -> f64 {
    let n = b + c;
    if n == 0 {
        return 1.0;
    }
    let k = b.min(c);
    // P(X <= k) for X ~ Binomial(n, 1/2), summed in logs so large n stays finite.
    let ln_half_n = n as f64 * 0.5f64.ln();
    let mut ln_choose = 0.0f64; // ln C(n, 0)
    let mut tail = 0.0;
    for i in 0..=k {
        if i > 0 {
            ln_choose += ((n - i + 1) as f64).ln() - (i as f64).ln();
        }
        tail += (ln_choose + ln_half_n).exp();
    }
    (2.0 * tail).min(1.0)
}

/// The equivalence test (two one-sided tests, TOST) of "the mean difference
/// lies within ±`margin`", by exact sign flips of the shifted differences:
/// H0 "mean <= -margin" is rejected when d + margin is shown above 0, H0
/// "mean >= margin" when d - margin is shown below 0. Returns the larger of the
/// two one-sided p-values: equivalence is shown at level a when it is below a.
pub fn equivalence_p(d: &[f64], margin: f64) -> f64 {
    let up: Vec<f64> = d.iter().map(|x| x + margin).collect();
    let down: Vec<f64> = d.iter().map(|x| x - margin).collect();
    sign_flip_p(&up, Alternative::Greater).max(sign_flip_p(&down, Alternative::Less))
}

/// Holm's step-down adjustment of a family of p-values, in their order: the
/// i-th smallest is multiplied by (m - i + 1), kept at least as large as the
/// adjusted ones before it, and capped at 1 (as statsmodels'
/// `multipletests(p, method="holm")`). Controls the family-wise error rate
/// under any dependence between the tests.
pub fn holm(p: &[f64]) -> Vec<f64> {
    let m = p.len();
    let mut order: Vec<usize> = (0..m).collect();
    order.sort_by(|&i, &j| p[i].total_cmp(&p[j]).then(i.cmp(&j)));
    let mut adjusted = vec![0.0; m];
    let mut running: f64 = 0.0;
    for (rank, &i) in order.iter().enumerate() {
        running = running.max(((m - rank) as f64 * p[i]).min(1.0));
        adjusted[i] = running;
    }
    adjusted
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Within 1e-12 of the reference (both exact).
    fn close(got: f64, want: f64) {
        assert!((got - want).abs() < 1e-12, "got {got}, want {want}");
    }

    /// The reference values were computed once with SciPy 1.17.1 and
    /// statsmodels 0.15.0 (Python 3.11) and are written here:
    ///   scipy.stats.permutation_test((d,), np.mean, permutation_type="samples",
    ///                                n_resamples=np.inf, alternative=...).pvalue
    #[test]
    fn sign_flip_matches_scipy() {
        // 36 pairs shaped like a Fig. 3 cell: 10 up (by 1, 2 or 3 red lights), 4 down,
        // 22 the same. Zeros drop out of a sign flip, so SciPy was given the 14 others
        // (its exact enumeration of 2^36 patterns does not fit in memory).
        let fig3: Vec<f64> = [1., 1., 1., 1., 1., 2., 2., 2., 3., 1., -1., -1., -1., -1.]
            .into_iter()
            .chain(std::iter::repeat_n(0.0, 22))
            .collect();
        close(sign_flip_p(&fig3, Alternative::TwoSided), SCIPY_FIG3_TWO);
        close(sign_flip_p(&fig3, Alternative::Greater), SCIPY_FIG3_GREATER);
        close(sign_flip_p(&fig3, Alternative::Less), SCIPY_FIG3_LESS);
        // Non-integer differences take the enumeration.
        let frac = [0.3, -1.7, 2.25, 0.9, 1.1, -0.4, 3.3, 0.05];
        close(sign_flip_p(&frac, Alternative::TwoSided), SCIPY_FRAC_TWO);
        close(sign_flip_p(&frac, Alternative::Greater), SCIPY_FRAC_GREATER);
        assert_eq!(sign_flip_p(&[0.0, 0.0], Alternative::TwoSided), 1.0);
    }

    #[test]
    fn the_table_and_the_enumeration_agree() {
        let d = [
            2.0, -1.0, 3.0, 1.0, 1.0, -2.0, 4.0, 0.0, 1.0, 5.0, -1.0, 2.0,
        ];
        for alt in [
            Alternative::TwoSided,
            Alternative::Greater,
            Alternative::Less,
        ] {
            let nz: Vec<f64> = d.iter().copied().filter(|&x| x != 0.0).collect();
            close(
                sign_flip_by_table(&nz, 1, alt),
                sign_flip_by_enumeration(&nz, alt),
            );
        }
        // A sixth, as a margin of one run in six shifts 0/1 differences.
        let shifted: Vec<f64> = [1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0]
            .iter()
            .map(|x| x + 1.0 / 6.0)
            .collect();
        assert_eq!(integer_scale(&shifted), Some(6));
        close(
            sign_flip_p(&shifted, Alternative::Greater),
            sign_flip_by_enumeration(&shifted, Alternative::Greater),
        );
    }

    /// scipy.stats.binomtest(min(b, c), b + c, 0.5).pvalue
    #[test]
    fn mcnemar_matches_scipy_and_the_sign_flip() {
        close(mcnemar_exact_p(10, 0), SCIPY_BINOM_10_0);
        close(mcnemar_exact_p(4, 1), SCIPY_BINOM_4_1);
        close(mcnemar_exact_p(15, 0), SCIPY_BINOM_15_0);
        close(mcnemar_exact_p(6, 2), SCIPY_BINOM_6_2);
        assert_eq!(mcnemar_exact_p(3, 3), 1.0);
        assert_eq!(mcnemar_exact_p(0, 0), 1.0);
        // Large n stays finite and symmetric.
        close(mcnemar_exact_p(700, 640), mcnemar_exact_p(640, 700));
        assert!(mcnemar_exact_p(700, 640) > 0.0);
        // The sign-flip test of 0/1 differences is McNemar's.
        let d: Vec<f64> = [1.0; 6]
            .into_iter()
            .chain([-1.0; 2])
            .chain([0.0; 9])
            .collect();
        close(
            sign_flip_p(&d, Alternative::TwoSided),
            mcnemar_exact_p(6, 2),
        );
    }

    /// max of the two one-sided scipy permutation_test p-values of d + m
    /// (alternative="greater") and d - m (alternative="less").
    #[test]
    fn equivalence_matches_scipy() {
        // 18 pairs of 0/1 outcomes, 1 up and 1 down: alike within one run in six.
        let d: Vec<f64> = [1.0, -1.0].into_iter().chain([0.0; 16]).collect();
        close(equivalence_p(&d, 1.0 / 6.0), SCIPY_TOST_ALIKE);
        assert!(equivalence_p(&d, 1.0 / 6.0) < 0.05);
        // 8 up, 0 down of 12: not equivalent within a sixth.
        let d: Vec<f64> = [1.0; 8].into_iter().chain([0.0; 4]).collect();
        close(equivalence_p(&d, 1.0 / 6.0), SCIPY_TOST_SHIFTED);
        assert!(equivalence_p(&d, 1.0 / 6.0) > 0.5);
        // Red lights per run, margin 0.5.
        let d = [0.0, 1.0, -1.0, 0.0, 2.0, 0.0, -1.0, 0.0, 0.0, 1.0, 0.0, 0.0];
        close(equivalence_p(&d, 0.5), SCIPY_TOST_COUNTS);
    }

    /// statsmodels.stats.multitest.multipletests(p, method="holm")[1]
    #[test]
    fn holm_matches_statsmodels() {
        let p = [0.01, 0.04, 0.03, 0.005, 0.2, 0.04];
        for (got, want) in holm(&p).into_iter().zip(STATSMODELS_HOLM) {
            close(got, want);
        }
        assert_eq!(holm(&[]), Vec::<f64>::new());
        assert_eq!(holm(&[0.7]), vec![0.7]);
    }

    const SCIPY_FIG3_TWO: f64 = 0.0693359375;
    const SCIPY_FIG3_GREATER: f64 = 0.03466796875;
    const SCIPY_FIG3_LESS: f64 = 0.9871826171875;
    const SCIPY_FRAC_TWO: f64 = 0.2421875;
    const SCIPY_FRAC_GREATER: f64 = 0.12109375;
    const SCIPY_BINOM_10_0: f64 = 0.001953125;
    const SCIPY_BINOM_4_1: f64 = 0.375;
    const SCIPY_BINOM_15_0: f64 = 6.103515625e-05;
    const SCIPY_BINOM_6_2: f64 = 0.2890625;
    const SCIPY_TOST_ALIKE: f64 = 0.02626800537109375;
    const SCIPY_TOST_SHIFTED: f64 = 0.996337890625;
    const SCIPY_TOST_COUNTS: f64 = 0.126953125;
    const STATSMODELS_HOLM: [f64; 6] = [0.05, 0.12, 0.12, 0.03, 0.2, 0.12];
}
