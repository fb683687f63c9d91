//! The paper's tables and figures, and the sweeps each one reads.

use sim::scenario::SelectorKind;

use crate::PaperError;
use crate::config::PaperConfig;
use crate::units::{Driver, Unit};

/// One table or figure of the paper (or past it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Experiment {
    /// Table I: realised traffic per route and density.
    Table1,
    /// Table II: success and collisions per town, D = 0, with the expert.
    Table2,
    /// Fig. 3: red-light infractions against scale at D = 0 and 50 ms.
    Fig3,
    /// Fig. 4: lane crossings against scale at D = 0 and 50 ms.
    Fig4,
    /// Fig. 5: success and collisions against D.
    Fig5,
    /// Table III: the oracle and map-lookahead switchers against fixed scales
    /// under each latency envelope.
    Table3,
    /// Beyond the paper: success, collisions and red lights against the
    /// worst-case latency, one point per fixed scale and per switcher.
    Frontier,
    /// Beyond the paper: fixed scales and switchers as the execution
    /// latency spreads (log-normal jitter) under the first envelope.
    Jitter,
    /// Beyond the paper: one RA network with more scales, each scale alone
    /// at the latency each envelope gives it.
    Scales,
}

impl Experiment {
    /// Every experiment, in the order the page shows them.
    pub const ALL: [Experiment; 9] = [
        Experiment::Table1,
        Experiment::Table2,
        Experiment::Fig3,
        Experiment::Fig4,
        Experiment::Fig5,
        Experiment::Table3,
        Experiment::Frontier,
        Experiment::Jitter,
        Experiment::Scales,
    ];

    /// Its name on the command line and in file names.
    pub fn id(self) -> &'static str {
        match self {
            Experiment::Table1 => "table1",
            Experiment::Table2 => "table2",
            Experiment::Fig3 => "fig3",
            Experiment::Fig4 => "fig4",
            Experiment::Fig5 => "fig5",
            Experiment::Table3 => "table3",
            Experiment::Frontier => "frontier",
            Experiment::Jitter => "jitter",
            Experiment::Scales => "scales",
        }
    }

    /// Its name on the page: "Table II", "Fig. 3", "Beyond the paper: latency jitter".
    pub fn title(self) -> &'static str {
        match self {
            Experiment::Table1 => "Table I",
            Experiment::Table2 => "Table II",
            Experiment::Fig3 => "Fig. 3",
            Experiment::Fig4 => "Fig. 4",
            Experiment::Fig5 => "Fig. 5",
            Experiment::Table3 => "Table III",
            Experiment::Frontier => "Beyond the paper: the latency/safety frontier",
            Experiment::Jitter => "Beyond the paper: latency jitter",
            Experiment::Scales => "Beyond the paper: more scales in one network",
        }
    }

    /// The names of `list`, as `--only` takes them ("fig3, table3").
    pub fn joined(list: &[Experiment]) -> String {
        list.iter().map(|e| e.id()).collect::<Vec<_>>().join(", ")
    }

    /// Every name.
    pub fn ids() -> Vec<&'static str> {
        Self::ALL.iter().map(|e| e.id()).collect()
    }

    /// Parses a comma-separated `--only` list (empty: all).
    pub fn parse_list(text: &str) -> Result<Vec<Experiment>, PaperError> {
        let mut out = Vec::new();
        for name in text.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            let e = Self::ALL
                .into_iter()
                .find(|e| e.id() == name)
                .ok_or_else(|| PaperError::UnknownExperiment { name: name.into() })?;
            if !out.contains(&e) {
                out.push(e);
            }
        }
        if out.is_empty() {
            out = Self::ALL.to_vec();
        }
        out.sort();
        Ok(out)
    }

    /// The sweeps it reads (Table I reads none: it only spawns traffic).
    pub fn units(self, cfg: &PaperConfig) -> Vec<Unit> {
        let first_two: Vec<f64> = cfg.delays_ms.iter().copied().take(2).collect();
        let d0 = cfg.delays_ms.first().copied().unwrap_or(0.0);
        let compared = [Driver::NraLow, Driver::NraHigh, Driver::Ra];
        let at = |drivers: &[Driver], delays: &[f64]| -> Vec<Unit> {
            delays
                .iter()
                .flat_map(|&d| drivers.iter().map(move |&drv| Unit::fixed(drv, d)))
                .collect()
        };
        match self {
            Experiment::Table1 => Vec::new(),
            Experiment::Table2 => at(&Driver::ALL, &[d0]),
            Experiment::Fig3 | Experiment::Fig4 => at(&compared, &first_two),
            Experiment::Fig5 => {
                let mut u = at(&compared, &cfg.delays_ms);
                u.extend(at(&[Driver::Expert], &cfg.delays_ms));
                u
            }
            Experiment::Table3 | Experiment::Frontier => {
                let mut u = Vec::new();
                for e in &cfg.envelopes {
                    for d in [e.low_ms, e.high_ms] {
                        let fixed = Unit::fixed(Driver::Ra, d);
                        if !u.contains(&fixed) {
                            u.push(fixed);
                        }
                    }
                }
                for e in &cfg.envelopes {
                    for s in cfg.selectors() {
                        u.push(Unit::switch(s, *e));
                    }
                }
                if self == Experiment::Frontier {
                    for &d in &cfg.delays_ms {
                        let fixed = Unit::fixed(Driver::Ra, d);
                        if !u.contains(&fixed) {
                            u.push(fixed);
                        }
                    }
                }
                u
            }
            Experiment::Jitter => {
                let mut u = Vec::new();
                if let Some(e) = cfg.envelopes.first() {
                    // Sigma 0 is Table III's own rows for this envelope.
                    u.extend([
                        Unit::fixed(Driver::Ra, e.low_ms),
                        Unit::fixed(Driver::Ra, e.high_ms),
                        Unit::switch(SelectorKind::Oracle, *e),
                        Unit::switch(SelectorKind::Lookahead, *e),
                    ]);
                    for &j in &cfg.jitters {
                        for s in [
                            SelectorKind::Fixed,
                            SelectorKind::Oracle,
                            SelectorKind::Lookahead,
                        ] {
                            u.push(Unit::jittered(s, *e, j));
                        }
                    }
                }
                u
            }
            Experiment::Scales => {
                if cfg.models.ladder.is_none() {
                    return Vec::new();
                }
                // The two-scale RA at the same latencies, to pair with.
                let mut u: Vec<Unit> = Vec::new();
                for e in &cfg.envelopes {
                    for d in [e.low_ms, e.high_ms] {
                        let fixed = Unit::fixed(Driver::Ra, d);
                        if !u.contains(&fixed) {
                            u.push(fixed);
                        }
                    }
                }
                // The widest envelope first: the 150 ms cliff is where the
                // scales part ways. Each envelope's ladder, then the map's
                // switchers between the ladder's two ends.
                for e in cfg.envelopes.iter().rev() {
                    u.push(Unit::ladder(*e));
                    if let Some(ends) = cfg.ladder_envelope(*e) {
                        for s in [
                            SelectorKind::Oracle,
                            SelectorKind::Lookahead,
                            SelectorKind::Braking,
                        ] {
                            u.push(Unit::ladder_switch(s, ends));
                        }
                    }
                }
                u
            }
        }
    }
}

impl Experiment {
    /// The order a run fills experiments in: the paper's main tables first,
    /// the figures that reuse their sweeps next, the extensions last.
    pub fn priority(self) -> u8 {
        match self {
            Experiment::Table1 => 0,
            Experiment::Table2 => 1,
            Experiment::Table3 => 2,
            Experiment::Fig3 => 3,
            Experiment::Fig4 => 4,
            Experiment::Fig5 => 5,
            Experiment::Frontier => 6,
            Experiment::Jitter => 7,
            Experiment::Scales => 8,
        }
    }
}

/// The units of several experiments, each once, in the experiments'
/// [`Experiment::priority`] order (so the main tables fill first).
pub fn units_of(experiments: &[Experiment], cfg: &PaperConfig) -> Vec<Unit> {
    let mut experiments = experiments.to_vec();
    experiments.sort_by_key(|e| e.priority());
    let mut out: Vec<Unit> = Vec::new();
    for e in &experiments {
        for u in e.units(cfg) {
            if !out.contains(&u) {
                out.push(u);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn experiments_share_their_sweeps() {
        let cfg = PaperConfig::full();
        let ids = |units: Vec<Unit>| -> Vec<String> { units.iter().map(|u| u.id(&cfg)).collect() };
        assert_eq!(
            ids(Experiment::Table2.units(&cfg)),
            [
                "expert-d000",
                "original-d000",
                "nra-0.75-d000",
                "nra-1.0-d000",
                "ra-d000"
            ]
        );
        assert_eq!(
            ids(Experiment::Table3.units(&cfg)),
            [
                "ra-d050",
                "ra-d100",
                "ra-d150",
                "ra-oracle-100-50",
                "ra-lookahead-100-50",
                "ra-learned-100-50",
                "ra-braking-100-50",
                "ra-oracle-150-100",
                "ra-lookahead-150-100",
                "ra-learned-150-100",
                "ra-braking-150-100"
            ]
        );
        let all = units_of(&Experiment::ALL, &cfg);
        // 5 at D = 0, 3 policies x 4 more delays, the expert at 4 more, 8 switchers,
        // 2 jitters x (fixed, oracle, lookahead), a ladder and 3 switchers per envelope.
        assert_eq!(all.len(), 5 + 12 + 4 + 8 + 6 + 8);
        assert_eq!(
            ids(Experiment::Scales.units(&cfg)),
            [
                "ra-d050",
                "ra-d100",
                "ra-d150",
                "ra5-ladder-150-100",
                "ra5-oracle-150-50",
                "ra5-lookahead-150-50",
                "ra5-braking-150-50",
                "ra5-ladder-100-50",
                "ra5-oracle-100-0",
                "ra5-lookahead-100-0",
                "ra5-braking-100-0"
            ]
        );
        // Without a trigger the learned rows are left out.
        let mut bare = cfg.clone();
        bare.models.trigger = None;
        assert_eq!(Experiment::Table3.units(&bare).len(), 9);
        // Without a ladder network the more-scales study has no runs.
        bare.models.ladder = None;
        assert!(Experiment::Scales.units(&bare).is_empty());
        assert_eq!(
            ids(Experiment::Jitter.units(&cfg))[3..],
            [
                "ra-lookahead-100-50",
                "ra-fixed-100-50-j0.25",
                "ra-oracle-100-50-j0.25",
                "ra-lookahead-100-50-j0.25",
                "ra-fixed-100-50-j0.5",
                "ra-oracle-100-50-j0.5",
                "ra-lookahead-100-50-j0.5"
            ]
        );
        assert_eq!(
            Experiment::parse_list("fig5, table2,fig5").unwrap(),
            [Experiment::Table2, Experiment::Fig5]
        );
        assert_eq!(Experiment::parse_list("").unwrap().len(), 9);
        let e = Experiment::parse_list("fig9").unwrap_err().to_string();
        assert!(e.contains("--only fig9") && e.contains("table3"), "{e}");
    }
}
