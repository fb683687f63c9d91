//! Statistics the paper does not give: the Wilson interval of a rate, how an
//! estimate stands against a range the paper gives ([`RangeCheck`]), and a paired
//! comparison of two configurations that share seeds ([`Paired`]), with its exact
//! p-value ([`super::exact`]) and an interval clustered at the route
//! ([`super::cluster`]).

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

/// Two configurations compared on the same seeds (run i of `a` and of `b` share
/// their seed, route and traffic).
#[derive(Debug, Clone, PartialEq)]
pub struct Paired {
    /// Pairs compared.
    pub n: usize,
    /// Mean of b - a over the pairs.
    pub mean_diff: f64,
    /// The 95 % interval of the mean difference, clustered at the route: a
    /// Student t interval over the routes' mean differences with G - 1 degrees
    /// of freedom (`super::cluster::cluster_t_interval`; each route weighs the
    /// same, and its centre is the mean of the route means). `None` with fewer
    /// than two routes.
    pub ci: Option<(f64, f64)>,
    /// Pairs where b > a, b < a, b = a.
    pub better_worse_same: (usize, usize, usize),
    /// The exact two-sided p-value of "no difference": the sign-flip test of the
    /// differences, which for 0/1 outcomes is the exact McNemar test.
    pub p: f64,
    /// The differences b - a, pair by pair.
    pub diffs: Vec<f64>,
    /// The cluster (route) of each pair, numbered 0, 1, ... in the order they
    /// first appear, for intervals and tests over route means (`super::cluster`).
    pub clusters: Vec<usize>,
}

impl Paired {
    /// Compares `b` with `a` pair by pair (the shortest of the three lengths is
    /// used); `routes[i]` names the route, the cluster, of pair i.
    pub fn by_route<K: PartialEq>(a: &[f64], b: &[f64], routes: &[K]) -> Paired {
        let d: Vec<f64> = a.iter().zip(b).map(|(x, y)| y - x).collect();
        let n = d.len().min(routes.len());
        let d = d[..n].to_vec();
        let clusters = super::cluster::cluster_ids(routes[..n].iter());
        let count = |f: &dyn Fn(f64) -> bool| d.iter().filter(|&&x| f(x)).count();
        Paired {
            n,
            mean_diff: d.iter().sum::<f64>() / n.max(1) as f64,
            ci: super::cluster::cluster_t_interval(&d, &clusters, 0.95).map(|(_, lo, hi)| (lo, hi)),
            better_worse_same: (
                count(&|x| x > 0.0),
                count(&|x| x < 0.0),
                count(&|x| x == 0.0),
            ),
            p: super::exact::sign_flip_p(&d, super::exact::Alternative::TwoSided),
            diffs: d,
            clusters,
        }
    }

    /// Whether the exact test finds a difference at the 5 % level, before any
    /// correction for the other tests of its family.
    pub fn significant(&self) -> bool {
        self.p < 0.05
    }

    /// How many routes (clusters) the pairs were driven on.
    pub fn routes(&self) -> usize {
        self.clusters.iter().max().map_or(0, |m| m + 1)
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
    fn a_paired_comparison_sees_a_shift_that_seed_noise_hides() {
        // Per-seed outcomes vary a lot; b is a plus 1 on every seed, each pair on
        // a route of its own.
        let a: Vec<f64> = (0..12).map(|i| f64::from((i * 37) % 11) * 3.0).collect();
        let b: Vec<f64> = a.iter().map(|x| x + 1.0).collect();
        let routes: Vec<usize> = (0..12).collect();
        let p = Paired::by_route(&a, &b, &routes);
        assert_eq!((p.n, p.routes()), (12, 12));
        assert!((p.mean_diff - 1.0).abs() < 1e-12);
        assert!(p.significant() && p.better_worse_same == (12, 0, 0));
        // Every difference is 1: the interval has no width.
        assert_eq!(p.ci, Some((1.0, 1.0)));
        // Unpaired, the runs of a and b overlap: the pairing is what tells.
        let max_a = a.iter().copied().fold(f64::MIN, f64::max);
        let min_b = b.iter().copied().fold(f64::MAX, f64::min);
        assert!(min_b < max_a);
        let same = Paired::by_route(&a, &a, &routes);
        assert!(!same.significant());
        assert_eq!(same.p, 1.0);
        // 12 of 12 up: p = 2 / 2^12 exactly.
        assert_eq!(p.p, 2.0 / 4096.0);
    }

    #[test]
    fn the_interval_is_clustered_at_the_route() {
        // Four routes of nine pairs whose differences agree inside a route and
        // differ between: the interval is that of four route means, t with 3
        // degrees of freedom, not of 36 independent pairs.
        let routes: Vec<&str> = (0..36).map(|i| ["r0", "r1", "r2", "r3"][i / 9]).collect();
        let d: Vec<f64> = (0..36).map(|i| [0.0, 1.0, 0.0, 3.0][i / 9]).collect();
        let p = Paired::by_route(&vec![0.0; 36], &d, &routes);
        assert_eq!((p.n, p.routes()), (36, 4));
        assert_eq!(p.clusters[9], 1);
        let (lo, hi) = p.ci.unwrap();
        // Route means 0, 1, 0, 3: mean 1, sd sqrt(2), half = t(0.975, 3) sd / 2.
        let half = 3.182_446_305_284_263 * 2f64.sqrt() / 2.0;
        assert!((hi - 1.0 - half).abs() < 1e-9 && (1.0 - lo - half).abs() < 1e-9);
        // One route: no interval to give.
        let one = Paired::by_route(&[0.0, 0.0], &[1.0, 2.0], &["r0", "r0"]);
        assert_eq!((one.n, one.routes(), one.ci), (2, 1, None));
    }
}
