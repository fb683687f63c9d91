//! The sweeps a paper run is made of. A [`Unit`] is one driver at one
//! injected delay (or one scale switcher under one latency envelope) over
//! every route, density and seed; each is a resumable sweep folder
//! `OUT/sweeps/ID/`. Tables and figures read the units they need, so a unit
//! shared by two figures runs once.

use std::path::{Path, PathBuf};

use sim::scenario::{DriverKind, DriverSpec, SelectorKind};
use sim::sweep::{SweepDir, SweepPlan};

use crate::PaperError;
use crate::config::{Envelope, PaperConfig};

/// Who drives a unit's runs, and at which fixed scales.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Driver {
    /// The privileged expert (no camera): the reference row.
    Expert,
    /// The single-resolution network at the high scale.
    Original,
    /// NRA retargeted to the low scale, driven at the low scale.
    NraLow,
    /// NRA retargeted to the high scale, driven at the high scale.
    NraHigh,
    /// The multi-resolution network, at both scales.
    Ra,
    /// The multi-resolution network with a BN branch for every scale of the
    /// ladder (the more-scales study; not one of Table II's columns).
    Ladder,
}

impl Driver {
    /// Table II's drivers, in table order.
    pub const ALL: [Driver; 5] = [
        Driver::Expert,
        Driver::Original,
        Driver::NraLow,
        Driver::NraHigh,
        Driver::Ra,
    ];

    /// Its name in folders and tables ("nra-0.75").
    pub fn id(self, cfg: &PaperConfig) -> String {
        match self {
            Driver::Expert => "expert".into(),
            Driver::Original => "original".into(),
            Driver::NraLow => format!("nra-{}", scale_label(cfg.low)),
            Driver::NraHigh => format!("nra-{}", scale_label(cfg.high)),
            Driver::Ra => "ra".into(),
            Driver::Ladder => cfg
                .models
                .ladder
                .as_deref()
                .and_then(Path::file_stem)
                .map_or_else(|| "ra-ladder".into(), |s| s.to_string_lossy().into_owned()),
        }
    }

    /// The driver of its runs (a policy names its checkpoint).
    pub fn spec(self, cfg: &PaperConfig) -> DriverSpec {
        let policy = |p: &PathBuf| DriverSpec {
            kind: DriverKind::Policy,
            checkpoint: Some(p.clone()),
            device: None,
            trigger: None,
        };
        match self {
            Driver::Expert => DriverSpec::default(),
            Driver::Original => policy(&cfg.models.original),
            Driver::NraLow => policy(&cfg.models.nra_low),
            Driver::NraHigh => policy(&cfg.models.nra_high),
            Driver::Ra => policy(&cfg.models.ra),
            // Never planned without its own checkpoint: the more-scales
            // study has no units then.
            Driver::Ladder => policy(cfg.models.ladder.as_ref().unwrap_or(&cfg.models.ra)),
        }
    }

    /// The fixed scales it is driven at (`None`: the expert, who sees no image).
    pub fn scales(self, cfg: &PaperConfig) -> Vec<Option<f64>> {
        match self {
            Driver::Expert => vec![None],
            Driver::Original | Driver::NraHigh => vec![Some(cfg.high)],
            Driver::NraLow => vec![Some(cfg.low)],
            Driver::Ra => vec![Some(cfg.low), Some(cfg.high)],
            Driver::Ladder => cfg.ladder.iter().copied().map(Some).collect(),
        }
    }

    /// The two scales a switcher driving this network moves between: the
    /// paper's low and high for RA, the ladder's ends for the ladder network.
    pub fn switch_scales(self, cfg: &PaperConfig) -> (f64, f64) {
        match (self, cfg.ladder.first(), cfg.ladder.last()) {
            (Driver::Ladder, Some(&lo), Some(&hi)) => (lo, hi),
            _ => (cfg.low, cfg.high),
        }
    }
}

/// "0.75", "1.0": a scale as the scenario files and model names write it.
pub fn scale_label(scale: f64) -> String {
    if scale.fract() == 0.0 {
        format!("{scale:.1}")
    } else {
        format!("{scale}")
    }
}

/// How a unit picks its input scale.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Selection {
    /// The driver's fixed scales at an injected delay D (milliseconds).
    Fixed {
        /// D (milliseconds).
        delay_ms: f64,
    },
    /// The RA policy with a scale selector whose two scales cost the
    /// envelope's latencies (no injected delay beyond them).
    Switch {
        /// `oracle` (the paper's), `lookahead` (map-based), or `fixed`
        /// (each scale alone at its own latency).
        selector: SelectorKind,
        /// Latency at each scale.
        envelope: Envelope,
        /// The latencies' log-normal spread (`timing.latency_jitter`; 0: none).
        jitter: f64,
    },
    /// Each of the driver's fixed scales alone, at the latency the envelope
    /// gives it ([`Envelope::latency_ms_at`]) as the injected delay.
    Ladder {
        /// The envelope the latencies are drawn from.
        envelope: Envelope,
    },
}

/// One sweep of a paper run.
#[derive(Debug, Clone, PartialEq)]
pub struct Unit {
    /// Who drives.
    pub driver: Driver,
    /// How the scale is chosen.
    pub selection: Selection,
}

impl Unit {
    /// A fixed-scale unit.
    pub fn fixed(driver: Driver, delay_ms: f64) -> Self {
        Unit {
            driver,
            selection: Selection::Fixed { delay_ms },
        }
    }

    /// A switcher unit (always the RA policy).
    pub fn switch(selector: SelectorKind, envelope: Envelope) -> Self {
        Self::jittered(selector, envelope, 0.0)
    }

    /// A selector unit whose latencies spread by `jitter` (log-normal sigma);
    /// `SelectorKind::Fixed` runs both scales, each at its own latency.
    pub fn jittered(selector: SelectorKind, envelope: Envelope, jitter: f64) -> Self {
        Unit {
            driver: Driver::Ra,
            selection: Selection::Switch {
                selector,
                envelope,
                jitter,
            },
        }
    }

    /// The ladder network switching between its lowest and highest scale,
    /// which cost `envelope`'s latencies.
    pub fn ladder_switch(selector: SelectorKind, envelope: Envelope) -> Self {
        Unit {
            driver: Driver::Ladder,
            selection: Selection::Switch {
                selector,
                envelope,
                jitter: 0.0,
            },
        }
    }

    /// The ladder network's scales, each at its latency under `envelope`.
    pub fn ladder(envelope: Envelope) -> Self {
        Unit {
            driver: Driver::Ladder,
            selection: Selection::Ladder { envelope },
        }
    }

    /// Whether its selector is the policy's learned trigger.
    fn learned(&self) -> bool {
        matches!(
            self.selection,
            Selection::Switch {
                selector: SelectorKind::Learned,
                ..
            }
        )
    }

    /// Its folder name: "ra-d050", "ra-oracle-100-50".
    pub fn id(&self, cfg: &PaperConfig) -> String {
        match self.selection {
            Selection::Fixed { delay_ms } => {
                format!("{}-d{:03}", self.driver.id(cfg), delay_ms.round() as u64)
            }
            Selection::Switch {
                selector,
                envelope,
                jitter,
            } => format!(
                "{}-{}",
                self.driver.id(cfg),
                switch_tag(selector, envelope, jitter)
            ),
            Selection::Ladder { envelope } => format!(
                "{}-ladder-{}-{}",
                self.driver.id(cfg),
                envelope.high_ms.round() as u64,
                envelope.low_ms.round() as u64
            ),
        }
    }

    /// Its sweep folder under `out`.
    pub fn dir(&self, cfg: &PaperConfig, out: &Path) -> SweepDir {
        SweepDir {
            root: out.join("sweeps").join(self.id(cfg)),
        }
    }

    /// Its runs: every route x density x seed (x the driver's scales), the
    /// scenario files derived where the unit or the configuration needs
    /// other settings than the route's own (written under `OUT/scenarios/`).
    pub fn plan(&self, cfg: &PaperConfig, out: &Path) -> Result<SweepPlan, PaperError> {
        let mut scenarios = Vec::new();
        for r in &cfg.routes {
            scenarios.push(self.scenario_for(&r.scenario, cfg, out)?);
        }
        let densities: Vec<Option<(u32, u32)>> = cfg.densities.iter().copied().map(Some).collect();
        let cross = |delays: &[Option<f64>], scales: &[Option<f64>]| {
            SweepPlan::cross(&scenarios, delays, scales, &densities, &cfg.seeds).runs
        };
        let runs = match self.selection {
            Selection::Fixed { delay_ms } => cross(&[Some(delay_ms)], &self.driver.scales(cfg)),
            Selection::Switch {
                selector: SelectorKind::Fixed,
                ..
            } => cross(&[Some(0.0)], &self.driver.scales(cfg)),
            Selection::Switch { .. } => cross(&[Some(0.0)], &[None]),
            // One cross per scale, each at its own delay, scales outermost.
            Selection::Ladder { envelope } => self
                .driver
                .scales(cfg)
                .into_iter()
                .flatten()
                .flat_map(|s| {
                    cross(
                        &[Some(envelope.latency_ms_at(s, cfg.low, cfg.high))],
                        &[Some(s)],
                    )
                })
                .collect(),
        };
        let mut plan = SweepPlan { runs };
        let mut driver = self.driver.spec(cfg);
        if self.learned() {
            driver.trigger = cfg.models.trigger.clone();
        }
        for r in &mut plan.runs {
            r.driver = Some(driver.clone());
        }
        Ok(plan)
    }

    /// The scenario file this unit drives for `base`: `base` itself, or a
    /// derived copy with the switcher's settings and the run cap.
    fn scenario_for(
        &self,
        base: &Path,
        cfg: &PaperConfig,
        out: &Path,
    ) -> Result<PathBuf, PaperError> {
        let switch = match self.selection {
            Selection::Switch {
                selector,
                envelope,
                jitter,
            } => Some((selector, envelope, jitter)),
            Selection::Fixed { .. } | Selection::Ladder { .. } => None,
        };
        if switch.is_none() && cfg.timeout_s.is_none() {
            return Ok(base.to_path_buf());
        }
        let stem = base
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let mut tag = match switch {
            Some((s, e, j)) => switch_tag(s, e, j),
            None => "fixed".into(),
        };
        if self.driver == Driver::Ladder {
            // Its switchers move between other scales than RA's.
            tag = format!("{}-{tag}", self.driver.id(cfg));
        }
        if let Some(t) = cfg.timeout_s {
            tag += &format!("-cap{}s", t.round() as u64);
        }
        let name = format!("{stem}__{tag}");
        let dir = out.join("scenarios");
        let driver = if self.learned() {
            // The scenario names its driver and trigger too: a learned
            // selector without a trigger is refused when the file is read.
            let trigger = cfg
                .models
                .trigger
                .as_ref()
                .ok_or_else(|| PaperError::Scenario {
                    path: base.to_path_buf(),
                    problem: "the learned selector needs models.trigger".into(),
                })?;
            let rel = |p: &Path| {
                relative_to(&dir, p)
                    .map(|r| r.display().to_string())
                    .map_err(|e| PaperError::io("resolve", p, e))
            };
            let mut d = toml::Table::new();
            d.insert("kind".into(), "policy".into());
            d.insert("checkpoint".into(), rel(&cfg.models.ra)?.into());
            d.insert("trigger".into(), rel(trigger)?.into());
            Some(d)
        } else {
            None
        };
        let scales = self.driver.switch_scales(cfg);
        let text = derived_scenario(base, &dir, &name, cfg, scales, switch, driver)?;
        std::fs::create_dir_all(&dir).map_err(|e| PaperError::io("create", &dir, e))?;
        let path = dir.join(format!("{name}.toml"));
        std::fs::write(&path, text).map_err(|e| PaperError::io("write", &path, e))?;
        Ok(path)
    }
}

/// "oracle-100-50", "fixed-100-50-j0.25": a selector, its envelope and jitter.
fn switch_tag(selector: SelectorKind, e: Envelope, jitter: f64) -> String {
    let mut tag = format!(
        "{}-{}-{}",
        selector_name(selector),
        e.high_ms.round() as u64,
        e.low_ms.round() as u64
    );
    if jitter > 0.0 {
        tag += &format!("-j{jitter}");
    }
    tag
}

/// The selector's name in scenario files.
pub fn selector_name(s: SelectorKind) -> &'static str {
    match s {
        SelectorKind::Fixed => "fixed",
        SelectorKind::Oracle => "oracle",
        SelectorKind::Lookahead => "lookahead",
        SelectorKind::Braking => "braking",
        SelectorKind::Budget => "budget",
        SelectorKind::Learned => "learned",
    }
}

/// The components of an absolute path with `.` and `..` resolved lexically.
fn lexical(p: &Path) -> Vec<std::path::Component<'_>> {
    use std::path::Component;
    let mut out = Vec::new();
    for c in p.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir if matches!(out.last(), Some(Component::Normal(_))) => {
                out.pop();
            }
            c => out.push(c),
        }
    }
    out
}

/// `target` written relative to the folder `from` (both made absolute first),
/// so a derived scenario in a committed folder names its map the same way on
/// every machine.
fn relative_to(from: &Path, target: &Path) -> std::io::Result<PathBuf> {
    let (from, target) = (std::path::absolute(from)?, std::path::absolute(target)?);
    let (f, t) = (lexical(&from), lexical(&target));
    let common = f.iter().zip(&t).take_while(|(a, b)| a == b).count();
    let mut rel = PathBuf::new();
    for _ in common..f.len() {
        rel.push("..");
    }
    for c in &t[common..] {
        rel.push(c.as_os_str());
    }
    Ok(rel)
}

/// The text of a scenario derived from `base`, to be written into `dir`:
/// its map and route files rewritten relative to `dir`, renamed `name`, with
/// a selector between the configuration's scales at the envelope's
/// latencies (and their jitter), the configuration's run cap, and `driver`
/// as its `[driver]` section when given.
fn derived_scenario(
    base: &Path,
    dir: &Path,
    name: &str,
    cfg: &PaperConfig,
    (low, high): (f64, f64),
    switch: Option<(SelectorKind, Envelope, f64)>,
    driver: Option<toml::Table>,
) -> Result<String, PaperError> {
    let text = std::fs::read_to_string(base).map_err(|e| PaperError::io("read", base, e))?;
    let mut doc: toml::Table = text
        .parse()
        .map_err(|e: toml::de::Error| PaperError::Scenario {
            path: base.to_path_buf(),
            problem: e.to_string(),
        })?;
    let here = base.parent().unwrap_or(Path::new("."));
    for section in ["map", "route"] {
        let table = doc
            .get_mut(section)
            .and_then(toml::Value::as_table_mut)
            .ok_or_else(|| PaperError::Scenario {
                path: base.to_path_buf(),
                problem: format!("no [{section}] section with a `file`"),
            })?;
        if let Some(toml::Value::String(f)) = table.get("file") {
            let target = here.join(f);
            let rel =
                relative_to(dir, &target).map_err(|e| PaperError::io("resolve", &target, e))?;
            table.insert("file".into(), rel.display().to_string().into());
        }
    }
    doc.insert("name".into(), name.into());
    let section = |doc: &mut toml::Table, key: &str| -> toml::Table {
        doc.remove(key)
            .and_then(|v| v.as_table().cloned())
            .unwrap_or_default()
    };
    if let Some((selector, envelope, jitter)) = switch {
        let mut timing = section(&mut doc, "timing");
        let mut latency = toml::Table::new();
        latency.insert(scale_label(low), envelope.low_ms.into());
        latency.insert(scale_label(high), envelope.high_ms.into());
        timing.insert("latency_ms".into(), latency.into());
        if jitter > 0.0 {
            timing.insert("latency_jitter".into(), jitter.into());
        }
        doc.insert("timing".into(), timing.into());
        let mut resolution = section(&mut doc, "resolution");
        resolution.insert("selector".into(), selector_name(selector).into());
        resolution.insert("low".into(), low.into());
        resolution.insert("high".into(), high.into());
        doc.insert("resolution".into(), resolution.into());
    }
    if let Some(d) = driver {
        doc.insert("driver".into(), d.into());
    }
    if let Some(t) = cfg.timeout_s {
        let mut termination = section(&mut doc, "termination");
        termination.insert("timeout_s".into(), t.into());
        doc.insert("termination".into(), termination.into());
    }
    Ok(format!(
        "# Derived by `mrdrive paper` from {}: do not edit, it is rewritten.\n{}",
        base.display(),
        toml::to_string(&doc).expect("a TOML table serialises")
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn root() -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
    }

    #[test]
    fn paths_are_made_relative_to_a_folder() {
        assert_eq!(
            relative_to(Path::new("/a/b/c"), Path::new("/a/x/../d/e.toml")).unwrap(),
            PathBuf::from("../../d/e.toml")
        );
        assert_eq!(
            relative_to(Path::new("/a"), Path::new("/a/b.toml")).unwrap(),
            PathBuf::from("b.toml")
        );
    }

    #[test]
    fn fixed_units_of_the_full_run_drive_the_route_files_themselves() {
        let cfg = PaperConfig::full();
        let tmp = tempfile::tempdir().unwrap();
        let u = Unit::fixed(Driver::Ra, 50.0);
        assert_eq!(u.id(&cfg), "ra-d050");
        let plan = u.plan(&cfg, tmp.path()).unwrap();
        // 4 routes x 2 scales x 3 densities x 3 seeds.
        assert_eq!(plan.runs.len(), 72);
        assert_eq!(
            plan.runs[0].scenario,
            PathBuf::from("scenarios/paper/town01_route0.toml")
        );
        assert!(plan.runs.iter().all(|r| r.delay_ms == Some(50.0)));
        assert_eq!(
            plan.runs[0].driver.as_ref().unwrap().checkpoint,
            Some(PathBuf::from("models/ra.safetensors"))
        );
        assert!(!tmp.path().join("scenarios").exists());
        let e = Unit::fixed(Driver::Expert, 0.0)
            .plan(&cfg, tmp.path())
            .unwrap();
        assert_eq!(e.runs.len(), 36);
        assert_eq!(e.runs[0].driver.as_ref().unwrap().kind, DriverKind::Expert);
    }

    #[test]
    fn a_ladder_unit_drives_each_scale_at_the_latency_its_envelope_gives_it() {
        let cfg = PaperConfig::full();
        let tmp = tempfile::tempdir().unwrap();
        let u = Unit::ladder(cfg.envelopes[1]);
        assert_eq!(u.id(&cfg), "ra5-ladder-150-100");
        let plan = u.plan(&cfg, tmp.path()).unwrap();
        // 5 scales x 4 routes x 3 densities x 3 seeds, each scale at one delay.
        assert_eq!(plan.runs.len(), 5 * 36);
        let mut seen: Vec<(f64, f64)> = plan
            .runs
            .iter()
            .map(|r| (r.scale.unwrap(), r.delay_ms.unwrap()))
            .collect();
        seen.dedup();
        assert_eq!(
            seen,
            [
                (0.5, 50.0),
                (0.625, 75.0),
                (0.75, 100.0),
                (0.875, 125.0),
                (1.0, 150.0)
            ]
        );
        assert!(
            plan.runs
                .iter()
                .all(|r| r.driver.as_ref().unwrap().checkpoint
                    == Some(PathBuf::from("models/ra5.safetensors")))
        );
        // Every run has its own record.
        let mut keys: Vec<String> = plan.runs.iter().map(|r| r.key()).collect();
        keys.sort();
        keys.dedup();
        assert_eq!(keys.len(), plan.runs.len());
        // Under 100->50 ms the cheapest scale costs nothing, never less.
        let e = cfg.envelopes[0];
        assert_eq!(e.latency_ms_at(0.5, cfg.low, cfg.high), 0.0);
        assert_eq!(e.latency_ms_at(0.25, cfg.low, cfg.high), 0.0);
        assert_eq!(e.latency_ms_at(0.875, cfg.low, cfg.high), 75.0);
    }

    #[test]
    fn a_ladder_switcher_moves_between_the_ladders_ends_at_their_latencies() {
        let mut cfg = PaperConfig::full();
        cfg.routes = vec![crate::config::Route {
            scenario: root().join("scenarios/default.toml"),
            town: "gen01".into(),
            route: "route 0".into(),
        }];
        let tmp = tempfile::tempdir().unwrap();
        let ends = cfg.ladder_envelope(cfg.envelopes[1]).unwrap();
        assert_eq!((ends.high_ms, ends.low_ms), (150.0, 50.0));
        let u = Unit::ladder_switch(SelectorKind::Lookahead, ends);
        assert_eq!(u.id(&cfg), "ra5-lookahead-150-50");
        let plan = u.plan(&cfg, tmp.path()).unwrap();
        assert_eq!(plan.runs.len(), 9);
        assert!(plan.runs.iter().all(|r| r.scale.is_none()
            && r.driver.as_ref().unwrap().checkpoint
                == Some(PathBuf::from("models/ra5.safetensors"))));
        let path = &plan.runs[0].scenario;
        assert!(
            path.ends_with("scenarios/default__ra5-lookahead-150-50.toml"),
            "{path:?}"
        );
        let s = sim::scenario::Scenario::from_file(path).unwrap();
        assert_eq!(s.resolution.selector, SelectorKind::Lookahead);
        assert_eq!((s.resolution.low, s.resolution.high), (0.5, 1.0));
        assert_eq!((s.latency_ms_at(0.5), s.latency_ms_at(1.0)), (50.0, 150.0));
    }

    #[test]
    fn a_switcher_unit_derives_a_scenario_with_its_envelope() {
        let mut cfg = PaperConfig::full();
        cfg.routes = vec![crate::config::Route {
            scenario: root().join("scenarios/default.toml"),
            town: "gen01".into(),
            route: "route 0".into(),
        }];
        cfg.timeout_s = Some(8.0);
        let tmp = tempfile::tempdir().unwrap();
        let u = Unit::switch(SelectorKind::Oracle, cfg.envelopes[1]);
        assert_eq!(u.id(&cfg), "ra-oracle-150-100");
        let plan = u.plan(&cfg, tmp.path()).unwrap();
        assert_eq!(plan.runs.len(), 9);
        let path = &plan.runs[0].scenario;
        assert!(
            path.ends_with("scenarios/default__oracle-150-100-cap8s.toml"),
            "{path:?}"
        );
        let s = sim::scenario::Scenario::from_file(path).unwrap();
        assert_eq!(s.name, "default__oracle-150-100-cap8s");
        assert_eq!(s.resolution.selector, SelectorKind::Oracle);
        assert_eq!(
            (s.latency_ms_at(0.75), s.latency_ms_at(1.0)),
            (100.0, 150.0)
        );
        assert_eq!(s.termination.timeout_s, Some(8.0));
        // The map and route are the base scenario's, wherever the copy lives.
        let base =
            sim::scenario::Scenario::from_file(&root().join("scenarios/default.toml")).unwrap();
        assert_eq!(
            std::fs::canonicalize(&s.map.file).unwrap(),
            std::fs::canonicalize(&base.map.file).unwrap()
        );
        assert_eq!(cfg.route_of(path).unwrap().town, "gen01");
        let text = std::fs::read_to_string(path).unwrap();
        assert!(
            text.contains("file = \"../"),
            "paths must be relative:\n{text}"
        );
        // Fixed scales under jitter: both scales, each at its own jittered latency.
        let j = Unit::jittered(SelectorKind::Fixed, cfg.envelopes[0], 0.25);
        assert_eq!(j.id(&cfg), "ra-fixed-100-50-j0.25");
        let plan = j.plan(&cfg, tmp.path()).unwrap();
        assert_eq!(plan.runs.len(), 18);
        assert_eq!(plan.runs[0].scale, Some(0.75));
        let s = sim::scenario::Scenario::from_file(&plan.runs[0].scenario).unwrap();
        assert_eq!(s.timing.latency_jitter, 0.25);
        assert_eq!(s.resolution.selector, SelectorKind::Fixed);
        assert_eq!(s.latency_ms_at(0.75), 50.0);
        // The learned trigger: the scenario names the RA policy and its trigger,
        // so the file is valid on its own; the runs carry the trigger too.
        let l = Unit::switch(SelectorKind::Learned, cfg.envelopes[0]);
        assert_eq!(l.id(&cfg), "ra-learned-100-50");
        let plan = l.plan(&cfg, tmp.path()).unwrap();
        let s = sim::scenario::Scenario::from_file(&plan.runs[0].scenario).unwrap();
        assert_eq!(s.resolution.selector, SelectorKind::Learned);
        // (Relative to the working folder, as the run resolves it.)
        assert!(
            s.driver
                .trigger
                .as_ref()
                .unwrap()
                .ends_with("models/ra.trigger.json"),
            "{:?}",
            s.driver.trigger
        );
        assert_eq!(s.driver.kind, DriverKind::Policy);
        assert_eq!(
            plan.runs[0].driver.as_ref().unwrap().trigger,
            Some(PathBuf::from("models/ra.trigger.json"))
        );
    }
}
