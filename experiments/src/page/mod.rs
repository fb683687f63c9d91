//! The page (`docs/paper/README.md`) and every table and figure file beside
//! it: our numbers next to the paper's, with the checks of the paper's
//! shapes written out from the numbers.
//!
//! One file per table or figure: [`table1`], [`table2`], [`fig34`] (Figs. 3
//! and 4), [`fig5`], [`table3`], and beyond the paper [`frontier`], [`jitter`]
//! and [`scales`] (sharing [`beyond`]); [`shapes`] checks the paper's claims,
//! [`reference`] holds the paper's own numbers, [`configs`] the configurations
//! compared and [`writer`] the files written. This file writes the page's
//! header and assembles it.

mod beyond;
mod configs;
mod coverage;
mod fig34;
mod fig5;
mod frontier;
mod jitter;
pub mod reference;
mod scales;
mod shapes;
mod table1;
mod table2;
mod table3;
mod writer;

use std::path::PathBuf;

use self::configs::x;
use self::writer::Writer;
use crate::PaperError;
use crate::config::PaperConfig;
use crate::experiment::Experiment;
use crate::options::{RunOptions, WallLog};
use crate::report::{Table, resolve_holm};
use crate::results::Results;

/// Writes every table, figure and the page; returns the files written.
pub fn write_all(
    cfg: &PaperConfig,
    opts: &RunOptions,
    results: &Results,
    registration: Option<&crate::registration::Registration>,
) -> Result<Vec<PathBuf>, PaperError> {
    let mut w = Writer {
        docs: opts.out.clone(),
        written: Vec::new(),
    };
    let asked = &opts.experiments;
    let shown: Vec<Experiment> = Experiment::ALL
        .into_iter()
        .filter(|&e| drawn(cfg, results, asked, e))
        .collect();
    let mut sections = Vec::new();
    for e in Experiment::ALL {
        if !shown.contains(&e) {
            sections.push(not_run_here(cfg, results, asked, e));
            continue;
        }
        sections.push(match e {
            Experiment::Table1 => table1::table1(cfg, &mut w)?,
            Experiment::Table2 => table2::table2(cfg, results, &mut w)?,
            Experiment::Fig3 => fig34::fig34(cfg, results, &mut w, true)?,
            Experiment::Fig4 => fig34::fig34(cfg, results, &mut w, false)?,
            Experiment::Fig5 => fig5::fig5(cfg, results, &mut w)?,
            Experiment::Table3 => table3::table3(cfg, results, &mut w)?,
            Experiment::Frontier => frontier::frontier(cfg, results, &mut w)?,
            Experiment::Jitter => jitter::jitter(cfg, results, &mut w)?,
            Experiment::Scales => scales::scales(cfg, results, &mut w)?,
        });
    }
    // The sections' paired tests form one family for Holm's correction; the
    // shapes' tests, which decide the verdicts, form their own (see `shapes`).
    let (sections, family) = resolve_holm(&sections.join("\n"));
    let registered = registration.map_or_else(
        || {
            "Not registered: this folder has no `registered.toml`, so its verdicts are not a \
             registered study's (`mrdrive paper --register`, issue 50).\n\n"
                .to_string()
        },
        |r| r.line() + "\n\n",
    );
    let page = header(cfg, opts, results, family, &shown)
        + &registered
        + &shapes::shapes(cfg, results, asked)
        + &sections;
    w.text("README.md", &page)?;
    Ok(w.written)
}

/// Whether the page draws `e`: it was asked of this folder (`--only`, all by
/// default), or every run it reads is here (runs it shares with those asked
/// for: Fig. 4's are Fig. 3's), or it reads no runs (Table I). A folder run
/// for some experiments does not show half of another (registration, section
/// 1: a stage not run is reported as not rerun, none of its records used).
fn drawn(cfg: &PaperConfig, results: &Results, asked: &[Experiment], e: Experiment) -> bool {
    let (done, planned) = results.progress(cfg, &e.units(cfg));
    e == Experiment::Table1 || asked.contains(&e) || done == planned
}

/// The section of an experiment the page does not draw ([`drawn`]).
fn not_run_here(
    cfg: &PaperConfig,
    results: &Results,
    asked: &[Experiment],
    e: Experiment,
) -> String {
    let (done, planned) = results.progress(cfg, &e.units(cfg));
    format!(
        "## {}: not run in this folder\n\nThis folder's runs were made for {} (`--only`). {done} \
         of the {planned} runs {} reads are here (runs it shares with those), so it is not \
         drawn and none of its records is used here; `--only {}` runs the rest.\n",
        e.title(),
        Experiment::joined(asked),
        e.title(),
        e.id()
    )
}

/// The page's header: how it was made, from which builds, and how far each
/// experiment is (`shown`: those the page draws, [`drawn`]).
fn header(
    cfg: &PaperConfig,
    opts: &RunOptions,
    results: &Results,
    family: usize,
    shown: &[Experiment],
) -> String {
    let wall = WallLog::read(&opts.out);
    let builds = results.provenance(|p| &p.build);
    let backends = results.backends();
    let mut s =
        format!(
        "# The paper's evidence, regenerated\n\n\
         Made by `cargo xtask paper{}` (`mrdrive paper`), the {} configuration: {} routes \
         ({}), densities {}, seeds {:?} per (route, density), D in {:?} ms, scales {} and {}, \
         checkpoints `{}`, `{}`, `{}`, `{}`{}.{} Every table and figure below is rewritten from \
         the run records in `sweeps/` beside this page each time the command runs; a killed \
         run resumes where it stopped.\n\n",
        match opts.label.as_str() {
            "quick" => " --quick",
            "held-out" => " --held-out",
            _ => "",
        },
        opts.label,
        cfg.routes.len(),
        cfg.routes
            .iter()
            .map(|r| format!("{} {}", r.town, r.route))
            .collect::<Vec<_>>()
            .join(", "),
        cfg.densities
            .iter()
            .map(|(v, p)| format!("({v}, {p})"))
            .collect::<Vec<_>>()
            .join(", "),
        cfg.seeds,
        cfg.delays_ms,
        x(cfg.low),
        x(cfg.high),
        cfg.models.original.display(),
        cfg.models.nra_low.display(),
        cfg.models.nra_high.display(),
        cfg.models.ra.display(),
        cfg.models.ladder.as_ref().map_or(String::new(), |p| format!(
            " and `{}` (scales {}) for the more-scales study",
            p.display(),
            cfg.ladder.iter().map(|&s| x(s)).collect::<Vec<_>>().join(", ")
        )),
        cfg.timeout_s.map_or(String::new(), |t| format!(
            " Runs are capped at {t} simulated seconds (a smoke test: no run can finish its route)."
        )),
    );
    if backends.len() > 1 {
        s += "**Warning**: these runs were rendered by more than one backend. Software \
              rasterisers differ pixel by pixel and a policy can act on that, so rows made on \
              different backends are not run-for-run comparable; rerun one backend's runs into a \
              fresh folder.\n\n";
    }
    let checkpoints = results.checkpoints();
    if !checkpoints.is_empty() {
        s += &format!(
            "Checkpoints and learned triggers (file, first digits of its SHA-256, from the run \
             records; a resumed run refuses a folder whose files have changed since): {}.\n\n",
            checkpoints
                .into_iter()
                .map(|c| format!("`{c}`"))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    s += &format!(
        "Builds: {} (the records'); this page was written by {}. Render backend: {}.\n\n",
        if builds.is_empty() {
            "none yet".into()
        } else {
            builds.iter().cloned().collect::<Vec<_>>().join(", ")
        },
        sim::output::provenance::build_id(),
        if backends.is_empty() {
            "none yet".into()
        } else {
            backends.into_iter().collect::<Vec<_>>().join(", ")
        },
    );
    let cpus = results.cpus();
    if !cpus.is_empty() {
        s += &format!(
            "CPUs (runs made on each): {}. Runs made since commit 1f7033c (2026-12-05) are the \
             same on every x86-64 CPU with AVX2 and FMA; before it, llvmpipe's sRGB encode made a \
             policy's run on an Intel Xeon and on an AMD EPYC differ by a few ticks (README, \
             \"Determinism\"); the seeds are independent samples either way.\n\n",
            cpus.into_iter()
                .map(|(cpu, n)| format!("{cpu} ({n})"))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    let records: usize = results.units.values().map(|u| u.runs.len()).sum();
    let unnamed = results.cpus().get("not recorded").copied().unwrap_or(0);
    if builds.len() > 1 || unnamed > 0 {
        s += &format!(
            "**Provenance**: the study's rules ask for one build for every record and a CPU \
             named by every record; these records come from {} build(s), and {unnamed} name no \
             CPU. Rerun into a fresh folder with one build to meet them.\n\n",
            builds.len()
        );
    }
    let record_wall_s: f64 = results
        .units
        .values()
        .flat_map(|u| &u.runs)
        .map(|r| r.record.perf.wall_s)
        .sum();
    s += &format!(
        "**Wall time**: {:.2} h in sweeps over {} invocation(s), which timed {} runs for the {} \
         recorded here ({} at a time; runs of an invocation stopped by hand were never timed, \
         and a run made again was timed again), on the machines that made them (the CPUs \
         above; `docs/bench.md` names the one it was measured on). The records' own wall \
         times, one per run, sum to {:.2} h over all {records} runs (run time only, one run at \
         a time).\n\n",
        wall.sweep_s / 3600.0,
        wall.invocations,
        wall.runs,
        records,
        wall.jobs,
        record_wall_s / 3600.0,
    );
    s += &format!(
        "**Statistics**: every interval `[low, high]` is a 95 % interval clustered at the \
         route (runs on one route are not independent draws; the route is the unit): a \
         Student t interval over the routes' means with G - 1 degrees of freedom, clipped to \
         the values the outcome can take, \"(1 route)\" where there is only one (with two \
         routes, as in one town of Table II, 1 degree of freedom: wide, and honest). Rates are \
         in percent; `paired` cells compare two configurations run by run on the same route, \
         density and seed: the mean difference b - a, its interval over the routes' mean \
         differences, how many pairs on how many routes, how many pairs went up or down, the \
         exact two-sided p-value (a sign-flip permutation test of the differences, which for \
         0/1 outcomes is the exact McNemar test) and that p adjusted by Holm's method across \
         all {family} paired tests in the tables below, `*` where the adjusted p is below \
         0.05. The tables give no verdicts of their own: the paper's claims are judged in \
         the next section by the registered rules, with their own family of tests.\n\n"
    );
    let mut t = Table::new(&["experiment", "runs finished / planned"]);
    for e in Experiment::ALL {
        let (done, planned) = results.progress(cfg, &e.units(cfg));
        t.push(vec![
            e.id().into(),
            if e == Experiment::Table1 {
                "(spawns only)".into()
            } else if shown.contains(&e) {
                format!("{done} / {planned}")
            } else {
                format!("{done} / {planned} (not run in this folder)")
            },
        ]);
    }
    s += "## Progress\n\n";
    s += &t.markdown();
    s += "\nThe discussion of where our shapes differ from the paper's, and why, is in \
          [`discussion.md`](discussion.md) (written by hand from these tables).\n\n";
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::tests::run;
    use crate::results::UnitRuns;
    use crate::units::Unit;

    /// A folder whose runs were all made for `run_for`: every unit those read
    /// has its two planned runs, every other unit none.
    fn folder(cfg: &PaperConfig, run_for: &[Experiment]) -> Results {
        let made: Vec<Unit> = run_for.iter().flat_map(|e| e.units(cfg)).collect();
        let mut r = Results::default();
        for u in Experiment::ALL.iter().flat_map(|e| e.units(cfg)) {
            let runs = if made.contains(&u) {
                (0..2).map(|s| run("a", s, true, 0, 0, 0, 100.0)).collect()
            } else {
                Vec::new()
            };
            r.units.insert(u.id(cfg), UnitRuns { planned: 2, runs });
        }
        r
    }

    fn drawn_of(cfg: &PaperConfig, r: &Results, asked: &[Experiment]) -> Vec<Experiment> {
        Experiment::ALL
            .into_iter()
            .filter(|&e| drawn(cfg, r, asked, e))
            .collect()
    }

    #[test]
    fn a_folder_run_for_some_experiments_draws_those_and_what_their_runs_complete() {
        use Experiment::*;
        let cfg = PaperConfig::full();
        // The held-out stage (`--held-out`: fig3, table3): Fig. 4 reads Fig. 3's runs
        // and is drawn; Table II lacks the Original's and the expert's, Fig. 5 the
        // delays past 50 ms.
        let asked = [Fig3, Table3];
        let r = folder(&cfg, &asked);
        assert_eq!(drawn_of(&cfg, &r, &asked), [Table1, Fig3, Fig4, Table3]);
        let table2 = not_run_here(&cfg, &r, &asked, Table2);
        assert!(
            table2.starts_with("## Table II: not run in this folder\n\nThis folder's runs were made for fig3, table3 (`--only`). 6 of the 10 runs Table II reads are here"),
            "{table2}"
        );
        // Stage 1 without stage 3: the frontier is all stage 1's runs, jitter and
        // the more scales are not.
        let stage1 = [Table2, Fig3, Fig4, Fig5, Table3];
        let r = folder(&cfg, &stage1);
        assert_eq!(
            drawn_of(&cfg, &r, &stage1),
            [Table1, Table2, Fig3, Fig4, Fig5, Table3, Frontier]
        );
        // Asked for, an experiment is drawn however few of its runs are here.
        assert_eq!(
            drawn_of(&cfg, &folder(&cfg, &[]), &Experiment::ALL),
            Experiment::ALL
        );
    }
}
