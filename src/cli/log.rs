//! `mrdrive log summary RUN.mcap`: what a recorded run log holds;
//! `mrdrive log picture RUN.mcap|RUN.json`: the run's picture.

use std::path::PathBuf;

use clap::{Args, Subcommand};
use serde_json::Value;
use sim::recorder::{LogSummary, read_summary};

/// Log subcommands.
#[derive(Subcommand)]
pub enum LogCommand {
    /// Print a log's topics (with schemas), message counts, sim-time duration,
    /// infractions and result record.
    Summary(SummaryArgs),
    /// Draw a run's picture (the route on the map, the path driven coloured by input
    /// scale, each infraction) from its MCAP log or its JSON record.
    Picture(PictureArgs),
}

/// `log picture` arguments.
#[derive(Args)]
pub struct PictureArgs {
    /// The run's MCAP log (`mrdrive run --record`) or JSON record (`--json`, a sweep's `runs/*.json`).
    pub run: PathBuf,
    /// The PNG to write [default: beside the run's file, with the extension .png].
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// `log summary` arguments.
#[derive(Args)]
pub struct SummaryArgs {
    /// The MCAP log (written by `mrdrive run SCENARIO --record FILE`).
    pub log: PathBuf,
}

/// Runs a `log` subcommand.
pub fn run(c: LogCommand) -> anyhow::Result<()> {
    match c {
        LogCommand::Summary(a) => {
            let summary = read_summary(&a.log)?;
            print!("{}", format_summary(&a.log.display().to_string(), &summary));
            Ok(())
        }
        LogCommand::Picture(a) => {
            let result = sim::picture::read_result(&a.run)?;
            let img = sim::picture::picture_of(&result)?;
            let out = a.out.unwrap_or_else(|| a.run.with_extension("png"));
            sim::picture::save(&img, &out)?;
            println!("picture: {}", out.display());
            Ok(())
        }
    }
}

/// The summary as text, one topic a line.
fn format_summary(name: &str, s: &LogSummary) -> String {
    use std::fmt::Write;
    let mut out = String::new();
    let total: u64 = s.topics.iter().map(|t| t.messages).sum();
    let _ = writeln!(out, "log           {name}");
    let _ = writeln!(
        out,
        "duration      {:.3} s of sim time, {total} messages on {} topics",
        s.duration_s(),
        s.topics.len()
    );
    let _ = writeln!(out, "topics");
    for t in &s.topics {
        let _ = writeln!(out, "  {:<22} {:<26} {:>7}", t.topic, t.schema, t.messages);
    }
    let _ = writeln!(out, "infractions   {}", s.infractions.len());
    for i in &s.infractions {
        let _ = writeln!(
            out,
            "  {:>8.2} s  {:<22} at ({:.1}, {:.1})  {}",
            i.time_s,
            i.kind.name(),
            i.position[0],
            i.position[1],
            i.detail
        );
    }
    match s.result() {
        Some(r) => {
            let number = |k: &str| r.get(k).and_then(Value::as_f64);
            let _ = writeln!(
                out,
                "result        {}  completion {}  driving score {}  ended by {}",
                match r.get("success").and_then(Value::as_bool) {
                    Some(true) => "SUCCESS",
                    Some(false) => "FAILURE",
                    None => "(no success field)",
                },
                number("completion_pct").map_or("?".into(), |c| format!("{c:.1} %")),
                number("driving_score").map_or("?".into(), |c| format!("{c:.1}")),
                r.get("termination")
                    .and_then(Value::as_str)
                    .unwrap_or("the route's end or the tick limit"),
            );
            if let Some(Value::Object(counts)) = r.get("counts") {
                let counts: Vec<String> = counts
                    .iter()
                    .filter(|(_, v)| v.as_u64() != Some(0))
                    .map(|(k, v)| format!("{k} {v}"))
                    .collect();
                let counts = if counts.is_empty() {
                    "none".to_string()
                } else {
                    counts.join(", ")
                };
                let _ = writeln!(out, "counts        {counts}");
            }
        }
        None => {
            let _ = writeln!(out, "result        (no result metadata)");
        }
    }
    out
}
