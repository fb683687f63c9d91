//! Reading a log back: topics, message counts, time range, infractions and
//! the result record, in one streaming pass that names the file when it is
//! not a complete log.

use std::collections::BTreeMap;
use std::fs::File;
use std::path::{Path, PathBuf};

use serde_json::Value;

use super::NS;
use crate::monitors::Infraction;

/// A log could not be read back.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    /// The file could not be opened or read.
    #[error(
        "cannot read the log {path}: {message} (check the path; logs are written by `mrdrive run SCENARIO --record FILE`)"
    )]
    Io {
        /// The log file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// The file is not a complete MCAP log.
    #[error(
        "the log {path} is not a complete MCAP file: {message} (was the run interrupted before the log was closed? record it again with `mrdrive run SCENARIO --record FILE`)"
    )]
    Corrupt {
        /// The log file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
}

/// One topic of a log: its schema and how many messages it holds.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicSummary {
    /// The topic name.
    pub topic: String,
    /// The schema name (`foxglove.CompressedImage`, ...).
    pub schema: String,
    /// Messages on the topic.
    pub messages: u64,
}

/// What a log holds, read back in one streaming pass.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LogSummary {
    /// Every channel, sorted by topic.
    pub topics: Vec<TopicSummary>,
    /// Log time of the first and last message (nanoseconds of sim time).
    pub time_range_ns: Option<(u64, u64)>,
    /// The infractions, from `/infractions/events`, in log order.
    pub infractions: Vec<Infraction>,
    /// The metadata records by name (the run's result is `result`, key `json`).
    pub metadata: BTreeMap<String, BTreeMap<String, String>>,
}

impl LogSummary {
    /// Sim time from the first to the last message (seconds).
    pub fn duration_s(&self) -> f64 {
        self.time_range_ns
            .map_or(0.0, |(a, b)| (b - a) as f64 / NS as f64)
    }

    /// The result record written at the end of the run, if any.
    pub fn result(&self) -> Option<Value> {
        let text = self.metadata.get("result")?.get("json")?;
        serde_json::from_str(text).ok()
    }

    /// The summary as text, one topic a line (`mrdrive log summary`); `name`
    /// names the log in its first line.
    pub fn report(&self, name: &str) -> String {
        use std::fmt::Write;
        let mut out = String::new();
        let total: u64 = self.topics.iter().map(|t| t.messages).sum();
        let _ = writeln!(out, "log           {name}");
        let _ = writeln!(
            out,
            "duration      {:.3} s of sim time, {total} messages on {} topics",
            self.duration_s(),
            self.topics.len()
        );
        let _ = writeln!(out, "topics");
        for t in &self.topics {
            let _ = writeln!(out, "  {:<22} {:<26} {:>7}", t.topic, t.schema, t.messages);
        }
        let _ = writeln!(out, "infractions   {}", self.infractions.len());
        for i in &self.infractions {
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
        match self.result() {
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
}

/// The largest record (or decompressed chunk) a log may hold (bytes): far
/// above anything we write, and it keeps a corrupt length field from asking
/// for exabytes.
const MAX_RECORD_BYTES: usize = 256 << 20;

/// Reads a log file back (streaming: one chunk in memory at a time).
pub fn read_summary(path: &Path) -> Result<LogSummary, ReadError> {
    let file = File::open(path).map_err(|e| ReadError::Io {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    summarize(std::io::BufReader::new(file), path)
}

/// Reads a log from `source` (`path` is only used in messages).
pub fn summarize(mut source: impl std::io::Read, path: &Path) -> Result<LogSummary, ReadError> {
    use mcap::records::Record;
    use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};
    let corrupt = |e: &dyn std::fmt::Display| ReadError::Corrupt {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let mut schemas: BTreeMap<u16, String> = BTreeMap::new();
    // Channel id -> (topic, schema id, messages).
    let mut channels: BTreeMap<u16, (String, u16, u64)> = BTreeMap::new();
    let mut summary = LogSummary::default();
    let mut reader = LinearReader::new_with_options(
        LinearReaderOptions::default().with_record_length_limit(MAX_RECORD_BYTES),
    );
    while let Some(event) = reader.next_event() {
        match event.map_err(|e| corrupt(&e))? {
            LinearReadEvent::ReadRequest(need) => {
                let n = source
                    .read(reader.insert(need))
                    .map_err(|e| ReadError::Io {
                        path: path.to_path_buf(),
                        message: e.to_string(),
                    })?;
                reader.notify_read(n);
            }
            LinearReadEvent::Record { opcode, data } => {
                match mcap::parse_record(opcode, data).map_err(|e| corrupt(&e))? {
                    Record::Schema { header, .. } => {
                        schemas.insert(header.id, header.name);
                    }
                    Record::Channel(c) => {
                        channels.entry(c.id).or_insert((c.topic, c.schema_id, 0));
                    }
                    Record::Message { header, data } => {
                        let channel = channels.get_mut(&header.channel_id).ok_or_else(|| {
                            corrupt(&format!(
                                "message on channel {} before its channel record",
                                header.channel_id
                            ))
                        })?;
                        channel.2 += 1;
                        let t = header.log_time;
                        summary.time_range_ns = Some(
                            summary
                                .time_range_ns
                                .map_or((t, t), |(a, b)| (a.min(t), b.max(t))),
                        );
                        if channel.0 == "/infractions/events" {
                            let i: Infraction =
                                serde_json::from_slice(&data).map_err(|e| corrupt(&e))?;
                            summary.infractions.push(i);
                        }
                    }
                    Record::Metadata(m) => {
                        summary.metadata.insert(m.name, m.metadata);
                    }
                    _ => {}
                }
            }
        }
    }
    summary.topics = channels
        .into_values()
        .map(|(topic, schema_id, messages)| TopicSummary {
            topic,
            schema: schemas.get(&schema_id).cloned().unwrap_or_default(),
            messages,
        })
        .collect();
    summary.topics.sort_by(|a, b| a.topic.cmp(&b.topic));
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::monitors::InfractionKind;
    use crate::recorder::writer::tests::scripted_log;
    use std::io::Cursor;

    #[test]
    fn summary_counts_topics_time_infractions_and_result() {
        let bytes = scripted_log();
        let s = summarize(Cursor::new(&bytes), Path::new("mem.mcap")).unwrap();
        let count = |t: &str| s.topics.iter().find(|x| x.topic == t).map(|x| x.messages);
        assert_eq!(count("/tf"), Some(40));
        assert_eq!(count("/control"), Some(40));
        assert_eq!(count("/camera/image"), Some(20));
        assert_eq!(count("/scene/map"), Some(1));
        assert_eq!(count("/bev/image"), Some(0));
        let tf = s.topics.iter().find(|x| x.topic == "/tf").unwrap();
        assert_eq!(tf.schema, "foxglove.FrameTransform");
        assert_eq!(count("/contacts"), Some(1));
        assert_eq!(s.topics.len(), 11);
        // The map at t = 0, the last tick at 39 * 25 ms.
        assert!((s.duration_s() - 0.975).abs() < 1e-9, "{}", s.duration_s());
        assert_eq!(s.result().unwrap()["completion_pct"], 100.0);
        assert_eq!(s.infractions.len(), 1);
        assert_eq!(s.infractions[0].kind, InfractionKind::RedLight);
        assert_eq!(s.infractions[0].tick, 7);
        let report = s.report("mem.mcap");
        assert!(report.starts_with("log           mem.mcap\n"), "{report}");
        assert!(
            report.contains("duration      0.975 s of sim time"),
            "{report}"
        );
        assert!(report.contains("infractions   1\n"), "{report}");
        // The fixture's result has a completion but no success field.
        assert!(
            report.contains("result        (no success field)  completion 100.0 %"),
            "{report}"
        );
    }

    #[test]
    fn a_truncated_log_is_an_error_naming_the_file() {
        let bytes = scripted_log();
        let cut = &bytes[..bytes.len() / 2];
        let e = summarize(Cursor::new(cut), Path::new("half.mcap")).unwrap_err();
        let text = e.to_string();
        assert!(text.contains("half.mcap"), "{text}");
        assert!(text.contains("record it again"), "{text}");
        // A record length field of ~2^62 bytes.
        let mut bogus = bytes[..8].to_vec();
        bogus.push(0x01);
        bogus.extend_from_slice(&(1u64 << 62).to_le_bytes());
        let e = summarize(Cursor::new(&bogus), Path::new("bogus.mcap")).unwrap_err();
        assert!(e.to_string().contains("bogus.mcap"), "{e}");
        let e = read_summary(Path::new("/nonexistent/run.mcap")).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/run.mcap"), "{e}");
    }
}
