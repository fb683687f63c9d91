//! Exact unconditional tests for paired yes/no outcomes (success, a run with a
//! collision) against a margin: non-inferiority and equivalence, with a size at
//! the margin that never exceeds the nominal level.
//!
//! Each of `n` pairs (the same route, density and seed driven by a and by b)
//! falls in one of three cells: b yes and a no (`plus`, the difference b - a is
//! +1), b no and a yes (`minus`, -1), or a tie (0). Their probabilities p+ and
//! p- are unknown; the mean difference is delta = p+ - p-. Shifting the 0/1
//! differences by the margin and sign-flipping them (the sweep's
//! [`super::exact::equivalence_p`]) assumes a symmetry 0/1 data cannot have:
//! at the margin it rejects too often (issue 50: 5.8 % at a nominal 5 % for 36
//! pairs and a margin of 1/6). Here the p-value is the largest probability,
//! over every (p+, p-) on the null's boundary, of a statistic at least as
//! extreme as the one observed (an exact unconditional test, as Suissa and
//! Shuster's for McNemar's design): the statistic is `plus - minus`, whose
//! upper tail grows as mass moves from -1 to a tie or from a tie to +1, so the
//! largest probability over the whole null lies on its boundary
//! delta = -margin, a line of one free parameter. That line is searched on a
//! grid of [`GRID`] points, then around its best point by golden-section
//! search; the tests below show the size at the margin is at most the nominal
//! level at every point of a finer grid.

/// Points of the grid the null's boundary is searched on before refining.
pub const GRID: usize = 2001;

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

/// P(plus - minus >= t) for n pairs whose cells have probabilities `up` (+1)
/// and `down` (-1), the rest ties.
fn upper_tail(n: usize, up: f64, down: f64, t: i64, lnf: &[f64]) -> f64 {
    let tie = (1.0 - up - down).max(0.0);
    let ln = |p: f64, k: usize| if k == 0 { 0.0 } else { k as f64 * p.ln() };
    let mut total = 0.0;
    for k_up in 0..=n {
        if k_up > 0 && up <= 0.0 {
            break;
        }
        // plus - minus >= t: minus <= plus - t.
        let most_down = (k_up as i64 - t).min((n - k_up) as i64);
        if most_down < 0 {
            continue;
        }
        for k_down in 0..=most_down as usize {
            if k_down > 0 && down <= 0.0 {
                break;
            }
            let k_tie = n - k_up - k_down;
            if k_tie > 0 && tie <= 0.0 {
                continue;
            }
            let ln_p = lnf[n] - lnf[k_up] - lnf[k_down] - lnf[k_tie]
                + ln(up, k_up)
                + ln(down, k_down)
                + ln(tie, k_tie);
            total += ln_p.exp();
        }
    }
    total.min(1.0)
}

/// The largest of `f` over [lo, hi]: the best of [`GRID`] evenly spaced points,
/// then golden-section search between its neighbours.
fn sup_on(lo: f64, hi: f64, f: impl Fn(f64) -> f64) -> f64 {
    if hi <= lo {
        return f(lo);
    }
    let step = (hi - lo) / (GRID - 1) as f64;
    let (mut best_x, mut best) = (lo, f(lo));
    for i in 1..GRID {
        let x = lo + step * i as f64;
        let v = f(x);
        if v > best {
            (best_x, best) = (x, v);
        }
    }
    let (mut a, mut b) = ((best_x - step).max(lo), (best_x + step).min(hi));
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..60 {
        if fc > fd {
            (b, d, fd) = (d, c, fc);
            c = b - g * (b - a);
            fc = f(c);
        } else {
            (a, c, fc) = (c, d, fd);
            d = a + g * (b - a);
            fd = f(d);
        }
    }
    best.max(fc).max(fd)
}

/// The exact unconditional p-value of non-inferiority for paired yes/no
/// outcomes where yes is better: H0 "delta <= -margin" (b is worse than a by
/// the margin or more) against "delta > -margin", from `plus` pairs where only
/// b said yes and `minus` where only a did, of `n` pairs. `margin` in (0, 1).
/// Reject H0 at level alpha when the p-value is at most alpha.
pub fn noninferiority_p(plus: usize, minus: usize, n: usize, margin: f64) -> f64 {
    assert!(
        plus + minus <= n,
        "{plus} + {minus} discordant pairs of {n}"
    );
    assert!(margin > 0.0 && margin < 1.0, "margin {margin}");
    if n == 0 {
        return 1.0;
    }
    let lnf = ln_factorials(n);
    let t = plus as i64 - minus as i64;
    // The boundary delta = -margin: p+ = x, p- = x + margin, x in [0, (1 - margin) / 2].
    sup_on(0.0, (1.0 - margin) / 2.0, |x| {
        upper_tail(n, x, x + margin, t, &lnf)
    })
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Every (plus, minus) outcome of n pairs with its p-value from `p`, which
    /// depends on plus - minus only (computed once for each).
    fn outcomes(n: usize, p: impl Fn(usize, usize) -> f64) -> Vec<(usize, usize, f64)> {
        let mut by_t = std::collections::HashMap::new();
        (0..=n)
            .flat_map(|a| (0..=n - a).map(move |b| (a, b)))
            .map(|(a, b)| {
                let t = a as i64 - b as i64;
                let v = *by_t.entry(t).or_insert_with(|| p(a, b));
                (a, b, v)
            })
            .collect()
    }

    /// The probability, at cell probabilities (up, down), that the test rejects at `alpha`.
    fn rejection_probability(
        n: usize,
        table: &[(usize, usize, f64)],
        alpha: f64,
        up: f64,
        down: f64,
    ) -> f64 {
        let lnf = ln_factorials(n);
        let tie = 1.0 - up - down;
        let ln = |p: f64, k: usize| if k == 0 { 0.0 } else { k as f64 * p.ln() };
        table
            .iter()
            .filter(|(_, _, p)| *p <= alpha)
            .map(|&(a, b, _)| {
                (lnf[n] - lnf[a] - lnf[b] - lnf[n - a - b]
                    + ln(up, a)
                    + ln(down, b)
                    + ln(tie, n - a - b))
                .exp()
            })
            .sum()
    }

    /// The largest rejection probability at `alpha` on the null's boundary, on a
    /// grid of 20001 points that is not the test's own; `table` holds every
    /// outcome's p-value for n pairs at `margin`.
    fn size_at_margin(n: usize, margin: f64, table: &[(usize, usize, f64)], alpha: f64) -> f64 {
        let hi = (1.0 - margin) / 2.0;
        (0..=20_000)
            .map(|i| hi * (i as f64 + 0.37) / 20_000.37)
            .map(|x| rejection_probability(n, table, alpha, x, x + margin))
            .fold(0.0, f64::max)
    }

    #[test]
    fn the_size_at_the_margin_is_at_most_nominal_for_the_pages_36_pairs() {
        // The page's margins, at 5 % and at the first step of Holm's method over
        // its family of 28 tests.
        let n = 36;
        for margin in [1.0 / 6.0, 1.0 / 12.0, 0.25] {
            let table = outcomes(n, |a, b| noninferiority_p(a, b, n, margin));
            for alpha in [0.05, 0.05 / 28.0] {
                let size = size_at_margin(n, margin, &table, alpha);
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
        let n = 36;
        let margin = 1.0 / 6.0;
        // Its p-value depends on both cells, not on their difference only.
        let table: Vec<(usize, usize, f64)> = (0..=n)
            .flat_map(|a| (0..=n - a).map(move |b| (a, b)))
            .map(|(a, b)| (a, b, shifted_sign_flip(a, b)))
            .collect();
        let hi = (1.0 - margin) / 2.0;
        let worst = (0..=2000)
            .map(|i| hi * i as f64 / 2000.0)
            .map(|x| rejection_probability(n, &table, 0.05, x, x + margin))
            .fold(0.0, f64::max);
        eprintln!("the shifted sign-flip test at margin 1/6, nominal 0.05: size {worst:.4}");
        assert!(worst > 0.055, "{worst}");
    }

    /// The shifted sign-flip p-value of 36 pairs at margin 1/6 (issue 50).
    fn shifted_sign_flip(a: usize, b: usize) -> f64 {
        let (n, margin) = (36, 1.0 / 6.0);
        {
            let mut d = vec![1.0 + margin; a];
            d.extend(std::iter::repeat_n(-1.0 + margin, b));
            d.extend(std::iter::repeat_n(margin, n - a - b));
            super::super::exact::sign_flip_p(&d, super::super::exact::Alternative::Greater)
        }
    }

    #[test]
    fn the_p_value_is_the_largest_tail_on_the_boundary() {
        // 5 pairs, 3 for b, 0 for a, margin 0.2: the tail P(plus - minus >= 3) at
        // every boundary point of a fine grid is at most the p-value, and one comes
        // within 1e-9 of it.
        let (n, m) = (5, 0.2);
        let p = noninferiority_p(3, 0, n, m);
        let lnf = ln_factorials(n);
        let hi = (1.0 - m) / 2.0;
        let tails: Vec<f64> = (0..=100_000)
            .map(|i| hi * i as f64 / 100_000.0)
            .map(|x| upper_tail(n, x, x + m, 3, &lnf))
            .collect();
        let best = tails.iter().copied().fold(0.0, f64::max);
        assert!(best <= p + 1e-12 && p - best < 1e-9, "{p} {best}");
        // The tail by brute force over the 3^5 outcomes at one point.
        let (up, down) = (0.3, 0.5);
        let mut brute = 0.0;
        for code in 0..3usize.pow(5) {
            let (mut c, mut s, mut pr) = (code, 0i64, 1.0);
            for _ in 0..5 {
                match c % 3 {
                    0 => (s, pr) = (s + 1, pr * up),
                    1 => (s, pr) = (s - 1, pr * down),
                    _ => pr *= 1.0 - up - down,
                }
                c /= 3;
            }
            if s >= 3 {
                brute += pr;
            }
        }
        assert!((upper_tail(5, up, down, 3, &lnf) - brute).abs() < 1e-14);
    }

    #[test]
    fn equivalence_needs_both_sides_and_more_evidence_gives_smaller_p() {
        let n = 36;
        // All ties: no evidence of a difference either way.
        let p_ties = equivalence_p(0, 0, n, 1.0 / 6.0);
        // b wins 12 more pairs than a: far from equivalent.
        let p_apart = equivalence_p(12, 0, n, 1.0 / 6.0);
        assert!(p_ties < p_apart, "{p_ties} {p_apart}");
        assert!(p_apart > 0.5);
        assert_eq!(
            equivalence_p(3, 1, n, 0.25),
            noninferiority_p(3, 1, n, 0.25).max(noninferiority_p(1, 3, n, 0.25))
        );
        // More pairs, same shares: smaller p.
        assert!(noninferiority_p(0, 0, 72, 1.0 / 6.0) < noninferiority_p(0, 0, 36, 1.0 / 6.0));
        // The lower-is-better test is the mirror image.
        assert_eq!(
            noninferiority_lower_p(2, 5, n, 0.1),
            noninferiority_p(5, 2, n, 0.1)
        );
        assert_eq!(noninferiority_p(0, 0, 0, 0.1), 1.0);
    }
}
