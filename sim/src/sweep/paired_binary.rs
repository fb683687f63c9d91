//! Exact unconditional tests for paired yes/no outcomes (success, a run with a
//! collision) against a margin: non-inferiority and equivalence, with a size at
//! the margin that does not exceed the nominal level.
//!
//! Each of `n` pairs (the same route, density and seed driven by a and by b)
//! falls in one of three cells: b yes and a no (`plus`, the difference b - a is
//! +1), b no and a yes (`minus`, -1), or a tie (0). Their probabilities p+ and
//! p- are unknown; the mean difference is delta = p+ - p-. Shifting the 0/1
//! differences by the margin and sign-flipping them (the sweep's
//! [`super::exact::equivalence_p`]) assumes a symmetry 0/1 data cannot have:
//! at the margin it rejects too often (issue 50: 5.8 % at a nominal 5 % for 36
//! pairs and a margin of 1/6).
//!
//! Here (an exact unconditional test, as Berger and Sidik's for this design)
//! every outcome (plus, minus) is ranked by the score statistic of "delta >
//! -margin" (Nam's and Tango's: [`statistic`]), and the p-value of an
//! outcome is the largest probability, over every (p+, p-) of the null
//! hypothesis, of an outcome ranked at least as high. The null is searched on
//! [`BOUNDARY_POINTS`] points of its boundary delta = -margin and a grid of
//! its interior ([`INTERIOR_STEPS`] a side); the tests below show the size at
//! the margin is at most the nominal level on grids the test does not use.
//!
//! The interval beside such a verdict inverts the same test
//! ([`DifferenceIntervals`]): the differences on a grid of
//! [`INTERVAL_STEP`] that neither one-sided test rejects at half the
//! level, widened by a step each way. Its coverage is at least the level
//! for pairs drawn alike (computed exactly in the tests below, not
//! simulated), and the tests show it on the page's design of four routes
//! of nine pairs.

/// Points of the null's boundary (delta = -margin) the p-values are maximised over.
pub const BOUNDARY_POINTS: usize = 4001;
/// Steps a side of the grid over the null's interior.
pub const INTERIOR_STEPS: usize = 100;

/// ln(k!) for k in 0..=n.
fn ln_factorials(n: usize) -> Vec<f64> {
    let mut out = Vec::with_capacity(n + 1);
    let mut acc = 0.0f64;
    out.push(0.0);
    for k in 1..=n {
        acc += (k as f64).ln();
        out.push(acc);
    }
    out
}

/// (n - a - b) / (b + 1) at `a * (n + 1) + b`: [`Cells::fill`]'s step from
/// outcome (a, b) to (a, b + 1), less the cells' ratio.
struct Steps(Vec<f64>);

impl Steps {
    fn new(n: usize) -> Steps {
        let mut v = vec![0.0; (n + 1) * (n + 1)];
        for a in 0..=n {
            for b in 0..n - a {
                v[a * (n + 1) + b] = (n - a - b) as f64 / (b + 1) as f64;
            }
        }
        Steps(v)
    }
}

/// One point's cell probabilities with their logarithms, taken once for all
/// the outcomes weighed there.
struct Cells {
    ln_up: f64,
    ln_down: f64,
    ln_tie: f64,
    up: f64,
    down: f64,
    tie: f64,
}

impl Cells {
    fn new(up: f64, down: f64) -> Cells {
        let tie = (1.0 - up - down).max(0.0);
        Cells {
            ln_up: up.ln(),
            ln_down: down.ln(),
            ln_tie: tie.ln(),
            up,
            down,
            tie,
        }
    }

    /// The probability of `k_up` pairs at +1 and `k_down` at -1 of n (the rest
    /// ties), `coef` the log-multinomial coefficient ln(n!) - ln(k_up!) -
    /// ln(k_down!) - ln(k_tie!).
    fn probability(&self, n: usize, k_up: usize, k_down: usize, coef: f64) -> f64 {
        let term = |p: f64, ln_p: f64, k: usize| {
            if k == 0 {
                Some(0.0)
            } else if p <= 0.0 {
                None
            } else {
                Some(k as f64 * ln_p)
            }
        };
        let k_tie = n - k_up - k_down;
        match (
            term(self.up, self.ln_up, k_up),
            term(self.down, self.ln_down, k_down),
            term(self.tie, self.ln_tie, k_tie),
        ) {
            (Some(a), Some(b), Some(c)) => (coef + a + b + c).exp(),
            _ => 0.0,
        }
    }

    /// Every outcome's probability of n pairs, outcome (a, b) at `a * (n + 1) + b`:
    /// a row's first from its logarithm ([`Cells::probability`]), each next by
    /// the ratio of neighbours, `P(a, b + 1) = P(a, b) (n - a - b) / (b + 1) p- / p0`,
    /// a multiplication where the logarithm takes an exponential (the tables of
    /// the intervals weigh some 2 x 10^9 outcomes). A value too small for the
    /// ratio to carry (below 1e-200), or a cell of probability 0, is taken from
    /// its logarithm again.
    fn fill(&self, n: usize, lnf: &[f64], steps: &Steps, out: &mut [f64]) {
        let w = n + 1;
        let coef = |a: usize, b: usize| lnf[n] - lnf[a] - lnf[b] - lnf[n - a - b];
        let exact = self.down <= 0.0 || self.tie <= 0.0;
        let ratio = self.down / self.tie;
        for a in 0..=n {
            let mut pr = self.probability(n, a, 0, coef(a, 0));
            out[a * w] = pr;
            for b in 0..n - a {
                pr = if exact || pr < 1e-200 {
                    self.probability(n, a, b + 1, coef(a, b + 1))
                } else {
                    pr * steps.0[a * w + b] * ratio
                };
                out[a * w + b + 1] = pr;
            }
        }
    }
}

/// The score statistic of outcome (plus, minus) of n pairs for "delta >
/// -margin" (Nam 1997, Tango 1998): z = (d + margin) / sqrt(v / n), d = (plus -
/// minus) / n, with the variance v = p+ + p- - (p+ - p-)^2 at the cells'
/// maximum-likelihood probabilities under delta = -margin: p- the larger root
/// of 2n q^2 - (x + y + margin (x + 3y + 2t)) q + y margin (1 + margin) = 0
/// (x = plus, y = minus, t ties), p+ = p- - margin. Unlike the Wald statistic's
/// observed variance, it is never 0: all pairs alike is strong evidence only
/// as far as the null makes it unlikely.
fn statistic(plus: usize, minus: usize, n: usize, margin: f64) -> f64 {
    let nf = n as f64;
    let (x, y) = (plus as f64, minus as f64);
    let t = nf - x - y;
    let b = x + y + margin * (x + 3.0 * y + 2.0 * t);
    let c = y * margin * (1.0 + margin);
    let q = (b + (b * b - 8.0 * nf * c).max(0.0).sqrt()) / (4.0 * nf);
    let v = (2.0 * q - margin - margin * margin).max(1e-300);
    let d = (x - y) / nf;
    (d + margin) / (v / nf).sqrt()
}

/// The points (p+, p-) of the null "delta <= -margin" the p-values are
/// maximised over: its boundary p- = p+ + margin, and the grid of its interior.
/// A negative margin (the null "delta <= |margin|") starts the boundary at p+ = |margin|.
fn null_points(margin: f64) -> Vec<(f64, f64)> {
    let lo = (-margin).max(0.0);
    let hi = (1.0 - margin) / 2.0;
    let mut pts: Vec<(f64, f64)> = (0..BOUNDARY_POINTS)
        .map(|i| lo + (hi - lo) * i as f64 / (BOUNDARY_POINTS - 1) as f64)
        .map(|x| (x, x + margin))
        .collect();
    let down_lo = margin.max(0.0);
    for i in 0..=INTERIOR_STEPS {
        let down = down_lo + (1.0 - down_lo) * i as f64 / INTERIOR_STEPS as f64;
        let top = (down - margin).min(1.0 - down);
        for j in 0..INTERIOR_STEPS {
            pts.push((top * j as f64 / INTERIOR_STEPS as f64, down));
        }
    }
    pts
}

/// The p-values of every outcome of `n` pairs for non-inferiority at `margin`
/// where yes is better: H0 "delta <= -margin" (b is worse than a by the margin
/// or more) against "delta > -margin".
#[derive(Debug, Clone)]
pub struct NonInferiority {
    n: usize,
    /// p-value of outcome (plus, minus) at `plus * (n + 1) + minus`.
    p: Vec<f64>,
}

impl NonInferiority {
    /// The table for `n` pairs at `margin` (in (-1, 1): the page's margins are
    /// positive; the intervals invert the test at every difference, negative
    /// margins too).
    pub fn new(n: usize, margin: f64) -> Self {
        assert!(margin > -1.0 && margin < 1.0, "margin {margin}");
        let lnf = ln_factorials(n);
        // Outcomes from the strongest evidence down, grouped where the statistic ties.
        let mut outcomes: Vec<(usize, usize, f64)> = (0..=n)
            .flat_map(|a| (0..=n - a).map(move |b| (a, b)))
            .map(|(a, b)| (a, b, statistic(a, b, n, margin)))
            .collect();
        outcomes.sort_by(|x, y| y.2.total_cmp(&x.2));
        let mut group = Vec::with_capacity(outcomes.len());
        let mut g = 0;
        for k in 0..outcomes.len() {
            if k > 0 && outcomes[k].2 != outcomes[k - 1].2 {
                g += 1;
            }
            group.push(g);
        }
        let groups = g + 1;
        // For each group, the largest probability over the null of reaching it.
        let mut worst = vec![0.0f64; groups];
        let mut cum = vec![0.0f64; groups];
        let mut prob = vec![0.0f64; (n + 1) * (n + 1)];
        let steps = Steps::new(n);
        let at: Vec<(usize, usize)> = outcomes
            .iter()
            .enumerate()
            .map(|(k, &(a, b, _))| (a * (n + 1) + b, group[k]))
            .collect();
        for (up, down) in null_points(margin) {
            cum.iter_mut().for_each(|c| *c = 0.0);
            Cells::new(up, down).fill(n, &lnf, &steps, &mut prob);
            for &(i, g) in &at {
                cum[g] += prob[i];
            }
            let mut running = 0.0;
            for (c, w) in cum.iter().zip(worst.iter_mut()) {
                running += c;
                *w = w.max(running);
            }
        }
        let mut p = vec![1.0; (n + 1) * (n + 1)];
        for (k, &(a, b, _)) in outcomes.iter().enumerate() {
            p[a * (n + 1) + b] = worst[group[k]].min(1.0);
        }
        NonInferiority { n, p }
    }

    /// The p-value of `plus` pairs where only b said yes and `minus` where only a did.
    pub fn p(&self, plus: usize, minus: usize) -> f64 {
        assert!(
            plus + minus <= self.n,
            "{plus} + {minus} discordant pairs of {}",
            self.n
        );
        self.p[plus * (self.n + 1) + minus]
    }
}

/// The exact unconditional p-value of non-inferiority for paired yes/no
/// outcomes where yes is better ([`NonInferiority`]), from `plus` pairs where
/// only b said yes and `minus` where only a did, of `n` pairs; 1 without pairs.
/// Reject H0 at level alpha when the p-value is at most alpha.
pub fn noninferiority_p(plus: usize, minus: usize, n: usize, margin: f64) -> f64 {
    if n == 0 {
        return 1.0;
    }
    NonInferiority::new(n, margin).p(plus, minus)
}

/// The same where no is better (a run with a collision): H0 "delta >= margin"
/// (b says yes more often by the margin or more) against "delta < margin".
pub fn noninferiority_lower_p(plus: usize, minus: usize, n: usize, margin: f64) -> f64 {
    // b - a >= margin is a - b <= -margin: swap the cells.
    noninferiority_p(minus, plus, n, margin)
}

/// The exact equivalence test (two one-sided tests) of "delta lies within
/// ±margin" for paired yes/no outcomes: the larger of the two non-inferiority
/// p-values. Equivalence is shown at level alpha when it is at most alpha.
pub fn equivalence_p(plus: usize, minus: usize, n: usize, margin: f64) -> f64 {
    noninferiority_p(plus, minus, n, margin).max(noninferiority_lower_p(plus, minus, n, margin))
}

/// Grid step of [`DifferenceIntervals`]' ends (a difference of shares).
pub const INTERVAL_STEP: f64 = 0.01;

/// Confidence intervals for the mean difference delta = p+ - p- of `n` pairs,
/// each the inversion of the exact test ([`NonInferiority`]): for an outcome,
/// the differences d on the grid -0.99, -0.98, ..., 0.99 ([`INTERVAL_STEP`])
/// where neither "delta <= d" nor "delta >= d" is rejected at (1 - level) / 2;
/// the interval runs from a step below the lowest such d to a step above the
/// highest, clipped to [-1, 1], so that a true difference between two grid
/// points is not left out for the grid's sake. It treats the pairs as drawn
/// alike, as the test does.
#[derive(Debug, Clone)]
pub struct DifferenceIntervals {
    n: usize,
    /// (low, high) of outcome (plus, minus) at `plus * (n + 1) + minus`.
    ends: Vec<(f64, f64)>,
}

impl DifferenceIntervals {
    /// The intervals of every outcome of `n` pairs at `level` (in (0, 1)):
    /// 199 tables of the test, a few seconds for 36 pairs on two cores.
    pub fn new(n: usize, level: f64) -> Self {
        use rayon::prelude::*;
        assert!(level > 0.0 && level < 1.0, "level {level}");
        let half = (1.0 - level) / 2.0;
        let k_max = (1.0 / INTERVAL_STEP).round() as i64 - 1;
        let width = (n + 1) * (n + 1);
        // Table k tests "delta <= -k step" with p(plus, minus) and, mirrored,
        // "delta >= k step" with p(minus, plus).
        let tables: Vec<(i64, NonInferiority)> = (-k_max..=k_max)
            .into_par_iter()
            .map(|k| (k, NonInferiority::new(n, k as f64 * INTERVAL_STEP)))
            .collect();
        let grid = (2 * k_max + 1) as usize;
        let index = |d: i64| (d + k_max) as usize;
        let mut kept = vec![vec![true; grid]; width];
        for (k, table) in &tables {
            for plus in 0..=n {
                for minus in 0..=n - plus {
                    let row = &mut kept[plus * (n + 1) + minus];
                    if table.p(plus, minus) <= half {
                        row[index(-k)] = false;
                    }
                    if table.p(minus, plus) <= half {
                        row[index(*k)] = false;
                    }
                }
            }
        }
        let ends = kept
            .iter()
            .map(|row| {
                let first = row.iter().position(|&k| k);
                let last = row.iter().rposition(|&k| k);
                match (first, last) {
                    (Some(a), Some(b)) => {
                        let d = |j: usize| (j as i64 - k_max) as f64 * INTERVAL_STEP;
                        (
                            (d(a) - INTERVAL_STEP).max(-1.0),
                            (d(b) + INTERVAL_STEP).min(1.0),
                        )
                    }
                    _ => (-1.0, 1.0),
                }
            })
            .collect();
        DifferenceIntervals { n, ends }
    }

    /// The interval of `plus` pairs where only b said yes and `minus` where only a did.
    pub fn interval(&self, plus: usize, minus: usize) -> (f64, f64) {
        assert!(
            plus + minus <= self.n,
            "{plus} + {minus} discordant pairs of {}",
            self.n
        );
        self.ends[plus * (self.n + 1) + minus]
    }
}

impl DifferenceIntervals {
    /// The intervals of `n` pairs at `level`, made once a process (a caller
    /// that asks while they are being made waits for them).
    pub fn shared(n: usize, level: f64) -> std::sync::Arc<DifferenceIntervals> {
        use std::collections::HashMap;
        use std::sync::{Arc, Mutex, OnceLock};
        type Cache = Mutex<HashMap<(usize, u64), Arc<DifferenceIntervals>>>;
        static CACHE: OnceLock<Cache> = OnceLock::new();
        let cache = CACHE.get_or_init(|| Mutex::new(HashMap::new()));
        let mut map = cache
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        map.entry((n, level.to_bits()))
            .or_insert_with(|| Arc::new(DifferenceIntervals::new(n, level)))
            .clone()
    }
}

/// The exact test's interval ([`DifferenceIntervals`]) for the mean
/// difference b - a of `n` paired yes/no outcomes at `level`, from `plus`
/// pairs where only b said yes and `minus` where only a did. `None` without pairs.
pub fn difference_interval(plus: usize, minus: usize, n: usize, level: f64) -> Option<(f64, f64)> {
    (n > 0).then(|| DifferenceIntervals::shared(n, level).interval(plus, minus))
}

/// The share of `sims` simulated pages whose exact interval at `level`
/// ([`difference_interval`]) holds the true mean difference, the pages drawn
/// route by route at the page's own cells: each route (`clusters[i]` names the
/// route of the pair whose difference b - a is `diffs[i]`, each -1, 0 or +1)
/// keeps its number of pairs, each pair +1 and -1 with that route's observed
/// shares of them (plug-in). The truth is the pairs' mean of those shares'
/// differences, the observed mean difference: the claim is about the routes
/// driven. Where routes differ the pairs are not drawn alike, as the
/// interval assumes, and this shows what that costs. The same inputs and
/// `seed` give the same share. `None` without pairs or with lengths that differ.
pub fn interval_coverage_by_route(
    diffs: &[f64],
    clusters: &[usize],
    level: f64,
    sims: usize,
    seed: u64,
) -> Option<f64> {
    use rand::SeedableRng;
    if diffs.is_empty() || diffs.len() != clusters.len() {
        return None;
    }
    let ids = super::cluster::cluster_ids(clusters.iter());
    // (pairs, +1 share, -1 share) of each route.
    let mut routes = vec![(0usize, 0.0, 0.0); ids.iter().max().map_or(0, |m| m + 1)];
    for (&d, &i) in diffs.iter().zip(&ids) {
        routes[i].0 += 1;
        if d > 0.5 {
            routes[i].1 += 1.0;
        } else if d < -0.5 {
            routes[i].2 += 1.0;
        }
    }
    for r in &mut routes {
        r.1 /= r.0 as f64;
        r.2 /= r.0 as f64;
    }
    let n = diffs.len();
    let truth = routes
        .iter()
        .map(|&(k, up, down)| k as f64 * (up - down))
        .sum::<f64>()
        / n as f64;
    let intervals = DifferenceIntervals::shared(n, level);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    Some(covered_share(&routes, truth, &intervals, sims, &mut rng))
}

/// The share of `sims` pages drawn from `rng` whose interval from `intervals`
/// holds `truth`, each route's `k` pairs +1 with probability `up` and -1 with
/// probability `down`: (k, up, down) for each route.
fn covered_share(
    routes: &[(usize, f64, f64)],
    truth: f64,
    intervals: &DifferenceIntervals,
    sims: usize,
    rng: &mut impl rand::RngExt,
) -> f64 {
    let mut hits = 0;
    for _ in 0..sims {
        let (mut plus, mut minus) = (0, 0);
        for &(k, up, down) in routes {
            for _ in 0..k {
                let u: f64 = rng.random();
                if u < up {
                    plus += 1;
                } else if u < up + down {
                    minus += 1;
                }
            }
        }
        let (lo, hi) = intervals.interval(plus, minus);
        if lo <= truth + 1e-12 && truth - 1e-12 <= hi {
            hits += 1;
        }
    }
    hits as f64 / sims as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// The probability of `k_up` pairs at +1 and `k_down` at -1 of n, the cells'
    /// probabilities `up` and `down` (the rest ties).
    fn trinomial(n: usize, k_up: usize, k_down: usize, up: f64, down: f64, lnf: &[f64]) -> f64 {
        let coef = lnf[n] - lnf[k_up] - lnf[k_down] - lnf[n - k_up - k_down];
        Cells::new(up, down).probability(n, k_up, k_down, coef)
    }

    /// The probability, at cell probabilities (up, down), that the test whose
    /// p-values are `table` rejects at `alpha`.
    fn rejection_probability(
        n: usize,
        table: &NonInferiority,
        alpha: f64,
        up: f64,
        down: f64,
    ) -> f64 {
        probability_of(n, up, down, |a, b| table.p(a, b) <= alpha)
    }

    /// The probability, at cell probabilities (up, down), of the outcomes (plus,
    /// minus) of n pairs for which `holds` says yes.
    fn probability_of(n: usize, up: f64, down: f64, holds: impl Fn(usize, usize) -> bool) -> f64 {
        let lnf = ln_factorials(n);
        (0..=n)
            .flat_map(|a| (0..=n - a).map(move |b| (a, b)))
            .filter(|&(a, b)| holds(a, b))
            .map(|(a, b)| trinomial(n, a, b, up, down, &lnf))
            .sum()
    }

    /// The largest rejection probability over the null on grids the test does not
    /// use: 20001 points of the boundary and a 57 x 57 grid of the interior.
    fn size(n: usize, margin: f64, table: &NonInferiority, alpha: f64) -> f64 {
        let hi = (1.0 - margin) / 2.0;
        let boundary = (0..=20_000)
            .map(|i| hi * (i as f64 + 0.37) / 20_000.37)
            .map(|x| (x, x + margin));
        let interior = (0..57).flat_map(|i| {
            let down = margin + (1.0 - margin) * (i as f64 + 0.5) / 57.0;
            let top = (down - margin).min(1.0 - down);
            (0..57).map(move |j| (top * (j as f64 + 0.5) / 57.0, down))
        });
        boundary
            .chain(interior)
            .map(|(up, down)| rejection_probability(n, table, alpha, up, down))
            .fold(0.0, f64::max)
    }

    #[test]
    fn the_size_at_the_margin_is_at_most_nominal_for_the_pages_36_pairs() {
        // The page's margins, at 5 % and at the first step of Holm's method over
        // its family of 28 tests.
        let n = 36;
        for margin in [1.0 / 6.0, 1.0 / 12.0, 0.25] {
            let table = NonInferiority::new(n, margin);
            for alpha in [0.05, 0.05 / 28.0] {
                let size = size(n, margin, &table, alpha);
                eprintln!("36 pairs, margin {margin:.4}, alpha {alpha:.5}: size {size:.5}");
                assert!(size <= alpha, "margin {margin}, alpha {alpha}: size {size}");
                // And the test is not empty: it rejects with some probability.
                assert!(
                    size > 0.3 * alpha,
                    "margin {margin}, alpha {alpha}: size {size}"
                );
            }
        }
    }

    #[test]
    fn the_shifted_sign_flip_it_replaces_rejects_too_often_at_the_margin() {
        // Issue 50's finding, reproduced: 36 pairs, margin 1/6, nominal 5 %.
        let (n, margin) = (36, 1.0 / 6.0);
        let lnf = ln_factorials(n);
        let rejects: Vec<(usize, usize)> = (0..=n)
            .flat_map(|a| (0..=n - a).map(move |b| (a, b)))
            .filter(|&(a, b)| {
                let mut d = vec![1.0 + margin; a];
                d.extend(std::iter::repeat_n(-1.0 + margin, b));
                d.extend(std::iter::repeat_n(margin, n - a - b));
                super::super::exact::sign_flip_p(&d, super::super::exact::Alternative::Greater)
                    <= 0.05
            })
            .collect();
        let hi = (1.0 - margin) / 2.0;
        let worst = (0..=2000)
            .map(|i| hi * i as f64 / 2000.0)
            .map(|x| {
                rejects
                    .iter()
                    .map(|&(a, b)| trinomial(n, a, b, x, x + margin, &lnf))
                    .sum::<f64>()
            })
            .fold(0.0, f64::max);
        eprintln!("the shifted sign-flip test at margin 1/6, nominal 0.05: size {worst:.4}");
        assert!(worst > 0.055, "{worst}");
    }

    #[test]
    fn a_p_value_bounds_the_tail_at_every_null_point() {
        // 12 pairs at margin 0.2: for each outcome, the probability of an outcome
        // ranked at least as high is at most its p-value at points of the null the
        // test did not search (to 1e-6: the test searches a grid), and reaches it
        // within 1e-3 somewhere on the boundary.
        let (n, m) = (12, 0.2);
        let table = NonInferiority::new(n, m);
        let lnf = ln_factorials(n);
        let all: Vec<(usize, usize)> = (0..=n)
            .flat_map(|a| (0..=n - a).map(move |b| (a, b)))
            .collect();
        let hi = (1.0 - m) / 2.0;
        for &(a, b) in &all {
            let z = statistic(a, b, n, m);
            let tail = |up: f64, down: f64| -> f64 {
                all.iter()
                    .filter(|&&(c, d)| statistic(c, d, n, m) >= z)
                    .map(|&(c, d)| trinomial(n, c, d, up, down, &lnf))
                    .sum()
            };
            let p = table.p(a, b);
            let mut best = 0.0f64;
            for i in 0..=997 {
                let x = hi * (i as f64 + 0.5) / 998.0;
                best = best.max(tail(x, x + m));
            }
            for (up, down) in [(0.0, 0.9), (0.1, 0.5), (0.05, 0.3), (0.3, 0.6)] {
                assert!(tail(up, down) <= p + 1e-6, "({a}, {b}) at ({up}, {down})");
            }
            // The test's own grid of the boundary finds its largest point to 1e-6.
            assert!(
                best <= p + 1e-6 && p - best < 1e-3,
                "({a}, {b}): {p} {best}"
            );
        }
    }

    /// The exact coverage of `intervals` where each pair is +1 with probability
    /// `up` and -1 with `down`: the probability of the outcomes whose interval
    /// holds the true difference.
    fn coverage(intervals: &DifferenceIntervals, n: usize, up: f64, down: f64) -> f64 {
        let truth = up - down;
        probability_of(n, up, down, |a, b| {
            let (lo, hi) = intervals.interval(a, b);
            lo <= truth && truth <= hi
        })
    }

    #[test]
    fn the_exact_interval_covers_its_level_wherever_the_pairs_are_drawn_alike() {
        // Computed, not simulated: every outcome of n pairs weighed at cell
        // probabilities the grids of the test and of the interval do not use,
        // rare discordance (the old page's 0-3 discordant pairs of 36) included.
        for n in [12, 36] {
            let intervals = DifferenceIntervals::shared(n, 0.95);
            let mut worst = (1.0f64, 0.0, 0.0);
            for up in [0.0, 0.013, 0.05, 0.137, 0.31, 0.487] {
                for down in [0.0, 0.021, 0.05, 0.093, 0.26, 0.503] {
                    if up + down > 1.0 {
                        continue;
                    }
                    let c = coverage(&intervals, n, up, down);
                    if c < worst.0 {
                        worst = (c, up, down);
                    }
                }
            }
            eprintln!(
                "{n} pairs: the exact interval's lowest coverage {:.4} (up {}, down {})",
                worst.0, worst.1, worst.2
            );
            assert!(worst.0 >= 0.95, "{n} pairs: {worst:?}");
        }
    }

    #[test]
    fn the_exact_interval_covers_where_the_t_interval_over_routes_does_not() {
        // The page's design (4 routes x 9 pairs) and the registration's case of
        // rare discordance, b alone 5 % and a alone 2 %: the t interval over route
        // means covers 0.887 (`sweep::cluster`'s test of it). The exact interval,
        // here also with the cells differing by route (the claim is about the
        // routes driven: the truth is their mean difference).
        let intervals = DifferenceIntervals::shared(36, 0.95);
        let mut rng = ChaCha8Rng::seed_from_u64(51);
        for cells in [
            [(0.05, 0.02); 4],
            [(0.02, 0.03), (0.04, 0.01), (0.06, 0.02), (0.08, 0.02)],
            [(0.0, 0.0), (0.0, 0.0), (0.1, 0.0), (0.2, 0.1)],
        ] {
            let truth = cells.iter().map(|(u, d)| u - d).sum::<f64>() / 4.0;
            let routes = cells.map(|(up, down)| (9, up, down));
            let covered = covered_share(&routes, truth, &intervals, 5000, &mut rng);
            eprintln!(
                "4 routes x 9 pairs, cells {cells:?}: the exact interval covers {covered:.3}"
            );
            assert!(covered >= 0.95, "{cells:?}: {covered}");
        }
    }

    #[test]
    fn the_coverage_by_route_draws_each_route_at_its_own_cells() {
        // 4 routes x 9 pairs. All tied: every page is all tied, its interval
        // holds the true 0.
        let routes: Vec<usize> = (0..36).map(|i| i / 9).collect();
        let tied = vec![0.0; 36];
        assert_eq!(
            interval_coverage_by_route(&tied, &routes, 0.95, 200, 1),
            Some(1.0)
        );
        // Route 0 all +1, the rest tied: every page is the same (9 of 36 up),
        // and its interval holds the truth 0.25 (or no page would).
        let mut one = tied.clone();
        one[..9].fill(1.0);
        assert_eq!(
            interval_coverage_by_route(&one, &routes, 0.95, 200, 1),
            Some(1.0)
        );
        // Routes that differ: half up on two routes, half down on the others.
        // The pages vary; the figure is the test's own loop at those cells.
        let mut mixed = tied.clone();
        for r in 0..4 {
            for k in 0..4 {
                mixed[r * 9 + k] = if r < 2 { 1.0 } else { -1.0 };
            }
        }
        let covered = interval_coverage_by_route(&mixed, &routes, 0.95, 2000, 3).unwrap();
        let cells = [
            (9, 4.0 / 9.0, 0.0),
            (9, 4.0 / 9.0, 0.0),
            (9, 0.0, 4.0 / 9.0),
            (9, 0.0, 4.0 / 9.0),
        ];
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let want = covered_share(
            &cells,
            0.0,
            &DifferenceIntervals::shared(36, 0.95),
            2000,
            &mut rng,
        );
        assert_eq!(covered, want);
        eprintln!("routes half up and half down: the exact interval covers {covered:.3}");
        assert!(covered >= 0.95, "{covered}");
        assert_eq!(interval_coverage_by_route(&[], &[], 0.95, 10, 1), None);
        assert_eq!(
            interval_coverage_by_route(&[1.0], &[0, 1], 0.95, 10, 1),
            None
        );
    }

    #[test]
    fn the_exact_interval_holds_the_estimate_and_narrows_with_pairs() {
        let small = DifferenceIntervals::shared(12, 0.95);
        let large = DifferenceIntervals::shared(36, 0.95);
        for (a, b, n, t) in [
            (0, 0, 12, &*small),
            (3, 1, 12, &*small),
            (0, 0, 36, &*large),
            (9, 3, 36, &*large),
            (0, 36, 36, &*large),
        ] {
            let (lo, hi) = t.interval(a, b);
            let d = (a as f64 - b as f64) / n as f64;
            assert!(
                lo < d && d < hi || (d == -1.0 && lo == -1.0),
                "({a}, {b}) of {n}: [{lo}, {hi}]"
            );
            assert!((-1.0..=1.0).contains(&lo) && (-1.0..=1.0).contains(&hi));
        }
        // All alike: symmetric about 0, and narrower with three times the pairs.
        let (lo12, hi12) = small.interval(0, 0);
        let (lo36, hi36) = large.interval(0, 0);
        assert!((lo12 + hi12).abs() < 1e-9 && (lo36 + hi36).abs() < 1e-9);
        assert!(hi36 < hi12, "{hi36} against {hi12}");
        // The lookup that caches the tables gives the same.
        assert_eq!(
            difference_interval(9, 3, 36, 0.95),
            Some(large.interval(9, 3))
        );
        assert_eq!(difference_interval(0, 0, 0, 0.95), None);
    }

    #[test]
    fn the_neighbour_ratios_give_each_outcomes_probability() {
        // Against the logarithm, outcome by outcome, at cells with a zero, a
        // near-zero tie, and tiny cells whose rows underflow.
        let n = 36;
        let lnf = ln_factorials(n);
        let steps = Steps::new(n);
        let mut out = vec![0.0; (n + 1) * (n + 1)];
        for (up, down) in [
            (0.2, 0.3),
            (0.0, 0.5),
            (0.4, 0.0),
            (0.5, 0.5),
            (0.49, 0.5),
            (0.5 - 1e-13, 0.5),
            (1e-9, 0.7),
            (0.3, 1e-12),
        ] {
            Cells::new(up, down).fill(n, &lnf, &steps, &mut out);
            let mut total = 0.0;
            for a in 0..=n {
                for b in 0..=n - a {
                    let want = trinomial(n, a, b, up, down, &lnf);
                    let got = out[a * (n + 1) + b];
                    assert!(
                        (got - want).abs() <= 1e-12 * want.max(1e-300) + 1e-300,
                        "({a}, {b}) at ({up}, {down}): {got} against {want}"
                    );
                    total += got;
                }
            }
            assert!((total - 1.0).abs() < 1e-9, "({up}, {down}): {total}");
        }
    }

    #[test]
    fn all_pairs_alike_shows_equivalence_and_equivalence_needs_both_sides() {
        let n = 36;
        // 36 ties: equivalent within 1/6 at 1 % (the null's likeliest way to give
        // them, p- = 1/6 and p+ = 0, gives all 36 alike with probability 0.0014; the
        // outcomes ranked above them add the rest).
        let ties = equivalence_p(0, 0, n, 1.0 / 6.0);
        assert!(ties > (5.0f64 / 6.0).powi(36) && ties < 0.01, "{ties}");
        // b wins 12 more pairs than a: far from equivalent, though not inferior.
        assert!(equivalence_p(12, 0, n, 1.0 / 6.0) > 0.5);
        assert!(noninferiority_p(12, 0, n, 1.0 / 6.0) < 1e-3);
        assert_eq!(
            equivalence_p(3, 1, n, 0.25),
            noninferiority_p(3, 1, n, 0.25).max(noninferiority_p(1, 3, n, 0.25))
        );
        // More pairs, the same shares: a smaller p.
        assert!(noninferiority_p(2, 1, 72, 1.0 / 6.0) < noninferiority_p(1, 0, 36, 1.0 / 6.0));
        // The lower-is-better test is the mirror image.
        assert_eq!(
            noninferiority_lower_p(2, 5, n, 0.1),
            noninferiority_p(5, 2, n, 0.1)
        );
        assert_eq!(noninferiority_p(0, 0, 0, 0.1), 1.0);
    }
}
