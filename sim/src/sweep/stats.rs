//! Statistics the paper does not give: 95 % intervals for rates (Wilson) and means
//! (bootstrap, over runs or over blocks of runs that share a route), and a paired
//! comparison of two configurations that share seeds, with its exact p-value
//! ([`super::exact`]). Every resampling is seeded, so a table is the same each time
//! it is made.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// z for a two-sided 95 % interval.
pub const Z95: f64 = 1.959_963_984_540_054;

/// The Wilson score interval of `successes` out of `n` at normal quantile `z`, as
/// fractions in [0, 1]; (0, 1) when `n` is 0. Unlike the normal approximation it
/// stays inside [0, 1] and is honest at 0 % and 100 % (6 of 6 gives [0.61, 1]).
pub fn wilson(successes: usize, n: usize, z: f64) -> (f64, f64) {
    if n == 0 {
        return (0.0, 1.0);
    }
    let (k, n) = (successes as f64, n as f64);
    let p = k / n;
    let z2 = z * z;
    let centre = (p + z2 / (2.0 * n)) / (1.0 + z2 / n);
    let half = z / (1.0 + z2 / n) * (p * (1.0 - p) / n + z2 / (4.0 * n * n)).sqrt();
    ((centre - half).max(0.0), (centre + half).min(1.0))
}

/// How our estimate stands against a range the paper gives.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RangeCheck {
    /// The point estimate lies in the paper's range.
    Inside,
    /// The point estimate lies outside it, but the interval reaches it.
    Compatible,
    /// Neither the estimate nor its interval reaches the range.
    Outside,
}

impl RangeCheck {
    /// `point` with its interval `ci` against the paper's range `paper` (each
    /// (low, high), ends included).
    pub fn of(point: f64, ci: (f64, f64), paper: (f64, f64)) -> RangeCheck {
        if paper.0 <= point && point <= paper.1 {
            RangeCheck::Inside
        } else if ci.0 <= paper.1 && paper.0 <= ci.1 {
            RangeCheck::Compatible
        } else {
            RangeCheck::Outside
        }
    }

    /// "inside", "compatible", "outside".
    pub fn word(self) -> &'static str {
        match self {
            RangeCheck::Inside => "inside",
            RangeCheck::Compatible => "compatible",
            RangeCheck::Outside => "outside",
        }
    }
}

/// A percentile bootstrap 95 % interval of the mean of `values` from `resamples`
/// resamples drawn with a ChaCha8 generator seeded by `seed`; (mean, mean) for fewer
/// than two values.
pub fn bootstrap_mean(values: &[f64], resamples: usize, seed: u64) -> (f64, f64) {
    let n = values.len();
    let mean = values.iter().sum::<f64>() / n.max(1) as f64;
    if n < 2 || resamples == 0 {
        return (mean, mean);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut means: Vec<f64> = (0..resamples)
        .map(|_| (0..n).map(|_| values[rng.random_range(0..n)]).sum::<f64>() / n as f64)
        .collect();
    means.sort_by(f64::total_cmp);
    let at = |q: f64| means[((q * (resamples - 1) as f64).round() as usize).min(resamples - 1)];
    (at(0.025), at(0.975))
}

/// Numbers blocks 0, 1, 2, ... by their keys, in the order the keys first appear.
pub fn block_ids<K: PartialEq>(keys: impl Iterator<Item = K>) -> Vec<usize> {
    let mut seen: Vec<K> = Vec::new();
    keys.map(|k| {
        seen.iter().position(|s| *s == k).unwrap_or_else(|| {
            seen.push(k);
            seen.len() - 1
        })
    })
    .collect()
}

/// A percentile bootstrap 95 % interval of the mean of `values` that resamples
/// whole blocks: `blocks[i]` names the block of `values[i]` (runs on one route and
/// density, say), and each resample draws as many blocks as there are, with
/// replacement, and takes the mean over every value they hold. Runs in one block
/// are not independent (one route decides much of what happens on it), so this
/// interval is wider than [`bootstrap_mean`]'s when blocks differ, and equal to it
/// when every value is its own block. (mean, mean) for fewer than two blocks.
pub fn block_bootstrap_mean(
    values: &[f64],
    blocks: &[usize],
    resamples: usize,
    seed: u64,
) -> (f64, f64) {
    let n = values.len().min(blocks.len());
    let mean = values[..n].iter().sum::<f64>() / n.max(1) as f64;
    // (sum, count) per block, in the order blocks first appear.
    let ids = block_ids(blocks[..n].iter());
    let mut sums: Vec<(f64, usize)> = vec![(0.0, 0); ids.iter().max().map_or(0, |m| m + 1)];
    for (&v, &i) in values.iter().zip(&ids) {
        sums[i].0 += v;
        sums[i].1 += 1;
    }
    let k = sums.len();
    if k < 2 || resamples == 0 {
        return (mean, mean);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut means: Vec<f64> = (0..resamples)
        .map(|_| {
            let (s, c) = (0..k).fold((0.0, 0), |(s, c), _| {
                let (bs, bc) = sums[rng.random_range(0..k)];
                (s + bs, c + bc)
            });
            s / c as f64
        })
        .collect();
    means.sort_by(f64::total_cmp);
    let at = |q: f64| means[((q * (resamples - 1) as f64).round() as usize).min(resamples - 1)];
    (at(0.025), at(0.975))
}

/// Two configurations compared on the same seeds (run i of `a` and of `b` share
/// their seed, route and traffic).
#[derive(Debug, Clone, PartialEq)]
pub struct Paired {
    /// Pairs compared.
    pub n: usize,
    /// Mean of b - a.
    pub mean_diff: f64,
    /// Bootstrap 95 % interval of the mean difference, resampling whole blocks of
    /// pairs ([`block_bootstrap_mean`]; each pair its own block in [`paired`]).
    pub ci: (f64, f64),
    /// Pairs where b > a, b < a, b = a.
    pub better_worse_same: (usize, usize, usize),
    /// The exact two-sided p-value of "no difference": the sign-flip test of the
    /// differences, which for 0/1 outcomes is the exact McNemar test.
    pub p: f64,
    /// How many independent blocks the interval rests on.
    pub blocks: usize,
    /// The differences b - a, pair by pair.
    pub diffs: Vec<f64>,
    /// The cluster (route) of each pair, for intervals and tests over route
    /// means (`super::cluster`); the blocks until a caller names the routes.
    pub clusters: Vec<usize>,
}

impl Paired {
    /// Whether the exact test finds a difference at the 5 % level, before any
    /// correction for the other tests of its family.
    pub fn significant(&self) -> bool {
        self.p < 0.05
    }

    /// The exact p-value of "the mean difference lies within ±`margin`" (TOST):
    /// below 0.05, the two are shown alike within the margin.
    pub fn equivalence_p(&self, margin: f64) -> f64 {
        super::exact::equivalence_p(&self.diffs, margin)
    }

    /// How many routes (clusters) the pairs were driven on.
    pub fn routes(&self) -> usize {
        block_ids(self.clusters.iter())
            .into_iter()
            .max()
            .map_or(0, |m| m + 1)
    }
}

/// Compares `b` with `a` pair by pair (the shorter length is used), each pair
/// its own block.
pub fn paired(a: &[f64], b: &[f64], resamples: usize, seed: u64) -> Paired {
    let blocks: Vec<usize> = (0..a.len().min(b.len())).collect();
    paired_in_blocks(a, b, &blocks, resamples, seed)
}

/// Compares `b` with `a` pair by pair; `blocks[i]` names the block of pair i
/// (its route and density, say), and the interval resamples whole blocks.
pub fn paired_in_blocks(
    a: &[f64],
    b: &[f64],
    blocks: &[usize],
    resamples: usize,
    seed: u64,
) -> Paired {
    let d: Vec<f64> = a.iter().zip(b).map(|(x, y)| y - x).collect();
    let n = d.len().min(blocks.len());
    let d = d[..n].to_vec();
    let blocks = &blocks[..n];
    let mean_diff = d.iter().sum::<f64>() / n.max(1) as f64;
    let count = |f: &dyn Fn(f64) -> bool| d.iter().filter(|&&x| f(x)).count();
    Paired {
        n,
        mean_diff,
        ci: block_bootstrap_mean(&d, blocks, resamples, seed),
        better_worse_same: (
            count(&|x| x > 0.0),
            count(&|x| x < 0.0),
            count(&|x| x == 0.0),
        ),
        p: super::exact::sign_flip_p(&d, super::exact::Alternative::TwoSided),
        blocks: block_ids(blocks.iter())
            .into_iter()
            .max()
            .map_or(0, |m| m + 1),
        diffs: d,
        clusters: block_ids(blocks.iter()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_range_check_says_inside_only_for_the_point_estimate() {
        // The paper's range 80-100 % success.
        let paper = (0.8, 1.0);
        assert_eq!(RangeCheck::of(0.9, (0.7, 0.97), paper), RangeCheck::Inside);
        assert_eq!(RangeCheck::of(0.8, (0.6, 0.9), paper), RangeCheck::Inside);
        // The interval touches the range, the estimate does not: compatible, not inside.
        assert_eq!(
            RangeCheck::of(0.7, (0.55, 0.8), paper),
            RangeCheck::Compatible
        );
        assert_eq!(RangeCheck::of(0.7, (0.5, 0.79), paper), RangeCheck::Outside);
        // From above too.
        let low = (0.0, 0.1);
        assert_eq!(
            RangeCheck::of(0.2, (0.05, 0.4), low),
            RangeCheck::Compatible
        );
        assert_eq!(RangeCheck::of(0.2, (0.11, 0.4), low), RangeCheck::Outside);
        assert_eq!(RangeCheck::Compatible.word(), "compatible");
    }

    #[test]
    fn wilson_matches_known_values() {
        // 8 of 10: the textbook interval (0.490, 0.943).
        let (lo, hi) = wilson(8, 10, Z95);
        assert!(
            (lo - 0.4902).abs() < 5e-4 && (hi - 0.9433).abs() < 5e-4,
            "{lo} {hi}"
        );
        // 6 of 6 and 0 of 6 stay inside [0, 1] and are not degenerate.
        let (lo, hi) = wilson(6, 6, Z95);
        assert!((lo - 0.6097).abs() < 5e-4 && hi == 1.0, "{lo} {hi}");
        let (lo, hi) = wilson(0, 6, Z95);
        assert!(lo == 0.0 && (hi - 0.3903).abs() < 5e-4, "{lo} {hi}");
        assert_eq!(wilson(0, 0, Z95), (0.0, 1.0));
    }

    #[test]
    fn the_bootstrap_is_deterministic_for_a_seed_and_covers_the_mean() {
        let v: Vec<f64> = (0..40).map(|i| f64::from(i % 7) * 1.5).collect();
        let a = bootstrap_mean(&v, 2000, 7);
        assert_eq!(a, bootstrap_mean(&v, 2000, 7));
        assert_ne!(a, bootstrap_mean(&v, 2000, 8));
        let mean = v.iter().sum::<f64>() / 40.0;
        assert!(a.0 < mean && mean < a.1, "{a:?} {mean}");
        // Close to the t interval for a sample this size (sd / sqrt(n) * 1.96).
        let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / 39.0).sqrt();
        let half = 1.96 * sd / 40f64.sqrt();
        assert!(
            ((a.1 - a.0) / 2.0 - half).abs() < 0.25 * half,
            "{a:?} vs +-{half}"
        );
        assert_eq!(bootstrap_mean(&[3.0], 100, 1), (3.0, 3.0));
    }

    #[test]
    fn a_paired_comparison_sees_a_shift_that_seed_noise_hides() {
        // Per-seed outcomes vary a lot; b is a plus 1 on every seed.
        let a: Vec<f64> = (0..12).map(|i| f64::from((i * 37) % 11) * 3.0).collect();
        let b: Vec<f64> = a.iter().map(|x| x + 1.0).collect();
        let p = paired(&a, &b, 2000, 3);
        assert_eq!(p.n, 12);
        assert!((p.mean_diff - 1.0).abs() < 1e-12);
        assert!(p.significant() && p.better_worse_same == (12, 0, 0));
        // Unpaired, the two means' intervals overlap: the pairing is what tells.
        let (ia, ib) = (bootstrap_mean(&a, 2000, 3), bootstrap_mean(&b, 2000, 3));
        assert!(ib.0 < ia.1);
        let same = paired(&a, &a, 2000, 3);
        assert!(!same.significant());
        assert_eq!(same.p, 1.0);
        // 12 of 12 up: p = 2 / 2^12 exactly.
        assert_eq!(p.p, 2.0 / 4096.0);
    }

    #[test]
    fn blocks_of_one_give_the_plain_bootstrap_and_real_blocks_widen_it() {
        let v: Vec<f64> = (0..36).map(|i| f64::from((i * 7) % 5)).collect();
        let singletons: Vec<usize> = (0..36).collect();
        assert_eq!(
            block_bootstrap_mean(&v, &singletons, 2000, 9),
            bootstrap_mean(&v, 2000, 9)
        );
        // Four blocks whose runs agree inside and differ between: the interval is
        // that of four values, far wider than 36 independent runs would give.
        let blocks: Vec<usize> = (0..36).map(|i| i / 9).collect();
        let v: Vec<f64> = blocks.iter().map(|&b| [0.0, 1.0, 0.0, 3.0][b]).collect();
        let (lo, hi) = block_bootstrap_mean(&v, &blocks, 2000, 9);
        let (plo, phi) = bootstrap_mean(&v, 2000, 9);
        assert!(hi - lo > 1.8 * (phi - plo), "{lo} {hi} vs {plo} {phi}");
        assert!(lo <= 0.25 && hi >= 1.75, "{lo} {hi}");
        let p = paired_in_blocks(&vec![0.0; 36], &v, &blocks, 2000, 9);
        assert_eq!((p.blocks, p.n), (4, 36));
        assert_eq!(p.ci, (lo, hi));
        // One block: no interval to give.
        assert_eq!(
            block_bootstrap_mean(&[1.0, 2.0], &[5, 5], 100, 1),
            (1.5, 1.5)
        );
    }
}
