//! How well the page's intervals cover at the page's own variance components
//! (issue 50, item 3): for each test of the shapes' family, the interval
//! printed beside it is simulated on pages drawn as this page's own pairs
//! were, and the share of them whose interval holds the truth is printed.
//!
//! Counts (red lights, lane crossings) use the t interval over route means;
//! their pages are drawn by a two-stage bootstrap at the estimated between-
//! and within-route standard deviations ([`t_interval_coverage`]). Yes/no
//! outcomes use the exact test's interval; their pages are drawn route by
//! route at each route's own shares of pairs that went each way
//! ([`interval_coverage_by_route`]). The verdicts rest on the tests, not on
//! these intervals; a coverage short of [`SHORT_OF`] is marked, and says the
//! interval beside that test is narrower than it claims.

use crate::report::Table;
use sim::sweep::cluster::{components, t_interval_coverage};
use sim::sweep::paired_binary::interval_coverage_by_route;
use sim::sweep::stats::Paired;

/// Simulated pages per test: a binomial sd of 0.3 % at 95 %.
pub const SIMS: usize = 5000;
/// The nominal level of every interval on the page.
pub const LEVEL: f64 = 0.95;
/// A coverage below this is marked as short (more than 6 binomial sds of
/// [`SIMS`] pages below the nominal 95 %).
pub const SHORT_OF: f64 = 0.93;

/// One test's interval, as the page prints it beside the test.
pub struct Interval<'a> {
    /// The test's name on the page.
    pub what: &'a str,
    /// Its paired differences and their routes.
    pub pair: &'a Paired,
    /// Yes/no outcome (the exact interval) or a count (the t interval).
    pub yes_no: bool,
    /// For a count's margin test: how often it says the margin holds at
    /// 5 % where the truth lies on the margin's edge, simulated as the
    /// coverage is (`shapes`, where one over its limit does not pass).
    pub size: Option<f64>,
}

/// The page's section: one row per test, its components and its coverage; a
/// margin test's size above `size_limit` is marked over (the caller's rule:
/// `shapes::SIZE_LIMIT`, where such a margin does not pass).
pub fn section(intervals: &[Interval], size_limit: f64) -> String {
    let mut t = Table::new(&[
        "test (b - a)",
        "pairs (routes)",
        "between-route sd",
        "within-route sd",
        "pairs b alone / a alone",
        "coverage of its 95 % interval",
        "its margin test's size at 5 %",
    ]);
    for (i, iv) in intervals.iter().enumerate() {
        let p = iv.pair;
        let c = components(&p.diffs, &p.clusters);
        let sd = |f: fn(&sim::sweep::cluster::Components) -> f64| {
            c.as_ref().map_or("–".into(), |c| format!("{:.3}", f(c)))
        };
        let seed = 50 + i as u64;
        let covered = if iv.yes_no {
            interval_coverage_by_route(&p.diffs, &p.clusters, LEVEL, SIMS, seed)
        } else {
            t_interval_coverage(&p.diffs, &p.clusters, LEVEL, SIMS, seed)
        };
        let (plus, minus, _) = p.better_worse_same;
        t.push(vec![
            iv.what.to_string(),
            format!("{} ({})", p.n, p.routes()),
            sd(|c| c.between_sd),
            sd(|c| c.within_sd),
            if iv.yes_no {
                format!("{plus} / {minus}")
            } else {
                "–".into()
            },
            covered.map_or("–".into(), |c| {
                format!(
                    "{:.1} %{}",
                    100.0 * c,
                    if c < SHORT_OF { " (short)" } else { "" }
                )
            }),
            iv.size.map_or("–".into(), |s| {
                format!(
                    "{:.1} %{}",
                    100.0 * s,
                    if s > size_limit { " (over)" } else { "" }
                )
            }),
        ]);
    }
    format!(
        "### The intervals' coverage at this page's own variance components\n\n\
         Each interval above is simulated on {SIMS} pages drawn as this page's own pairs were, \
         and the share whose interval holds the truth is given (nominal {:.0} %). Counts: the \
         t interval over route means, its pages drawn by a two-stage bootstrap (each route's \
         effect from the routes' centred means, each run's deviation from the runs' own, scaled \
         to the estimated between- and within-route sd; truth 0). Yes/no outcomes: the exact \
         test's interval, each route's pairs drawn at that route's own shares of pairs that \
         went each way (truth: the mean difference over the routes driven). Below {:.0} % a \
         coverage is marked short: that interval is narrower than it claims. The verdicts rest \
         on the tests, not on these intervals. A count's margin test (equivalence, no worse) \
         is simulated on the same pages moved to the margin's edge (each edge of an \
         equivalence, the larger share given): how often it says the margin holds at 5 % \
         where it does not, marked over above {:.1} %, and then its margin does not pass (a \
         count's mean admits no test valid for every shape of counts: the page's own is the \
         one it must hold for); a yes/no outcome's is exact (at most nominal for pairs drawn \
         alike). \"–\": fewer than two routes, no route with two \
         pairs, or no margin.\n\n{}\n",
        100.0 * LEVEL,
        100.0 * SHORT_OF,
        100.0 * size_limit,
        t.markdown()
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_test_gets_its_components_and_its_coverage() {
        let routes = ["a", "b", "c", "d"];
        let keys: Vec<&str> = (0..36).map(|i| routes[i / 9]).collect();
        // A count that only route a gives, and a yes/no outcome with every pair tied.
        let mut b = vec![0.0; 36];
        b[0] = 3.0;
        b[1] = 3.0;
        let count = Paired::by_route(&[0.0; 36], &b, &keys);
        let tied = Paired::by_route(&[1.0; 36], &[1.0; 36], &keys);
        let one_route = Paired::by_route(&[0.0; 9], &[1.0; 9], &keys[..9]);
        let s = section(
            &[
                Interval {
                    what: "red lights",
                    pair: &count,
                    yes_no: false,
                    size: Some(0.0612),
                },
                Interval {
                    what: "success",
                    pair: &tied,
                    yes_no: true,
                    size: None,
                },
                Interval {
                    what: "one route",
                    pair: &one_route,
                    yes_no: false,
                    size: Some(0.05),
                },
            ],
            0.059,
        );
        let rows: Vec<&str> = s
            .lines()
            .filter(|l| l.starts_with("| ") && !l.starts_with("| ---"))
            .collect();
        assert_eq!(rows.len(), 4, "{s}");
        // The count: sds by the analysis of variance (between 0.25, within
        // sqrt(14 / 32)), and the two-stage bootstrap's share, which the route
        // holding every red light makes short.
        let want = t_interval_coverage(&count.diffs, &count.clusters, LEVEL, SIMS, 50).unwrap();
        assert!(want < SHORT_OF, "{want}");
        assert_eq!(
            rows[1],
            format!(
                "| red lights | 36 (4) | 0.250 | 0.661 | – | {:.1} % (short) | 6.1 % (over) |",
                100.0 * want
            )
        );
        assert_eq!(
            rows[2],
            "| success | 36 (4) | 0.000 | 0.000 | 0 / 0 | 100.0 % | – |"
        );
        assert_eq!(rows[3], "| one route | 9 (1) | – | – | – | – | 5.0 % |");
    }
}
