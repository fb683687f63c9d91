//! The SHA-256 of a dataset's files, written beside the plan in the repository
//! (`sha256sum`'s format), so that a dataset regenerated on another machine can be
//! checked bit for bit before a training run resumes on it.
//!
//! ```text
//! <64 hex digits>  original/episode-00000.safetensors
//! <64 hex digits>  original/labels-00000.safetensors
//! ```
//!
//! Paths are relative to the folder above the dataset (`<cache>/data`), so one
//! file lists both of the study's sets; `sha256sum -c` in that folder checks them.

use std::collections::BTreeMap;
use std::path::Path;

use crate::format::{DataError, Index};

/// The hash of every shard and label file of the dataset in `dir`, keyed by
/// `<dataset folder name>/<file>`, in index order.
pub fn of_dataset(dir: &Path) -> Result<BTreeMap<String, String>, DataError> {
    let index = Index::load(dir)?;
    of_episodes(dir, &index.episodes)
}

/// The hash of the shard and label files of `episodes` (entries of the index of
/// the dataset in `dir`), keyed as [`of_dataset`] keys them.
pub fn of_episodes(
    dir: &Path,
    episodes: &[crate::format::Episode],
) -> Result<BTreeMap<String, String>, DataError> {
    let name = dir
        .file_name()
        .map_or_else(|| ".".into(), |n| n.to_string_lossy().into_owned());
    let mut out = BTreeMap::new();
    for e in episodes {
        for file in std::iter::once(&e.shard).chain(e.labels.as_ref()) {
            let path = dir.join(file);
            let bytes = std::fs::read(&path).map_err(|source| DataError::Io {
                path: path.clone(),
                source,
            })?;
            out.insert(format!("{name}/{file}"), sim::record::sha256_hex(&bytes));
        }
    }
    Ok(out)
}

/// The hashes as `sha256sum` writes them, one line each.
pub fn to_text(hashes: &BTreeMap<String, String>) -> String {
    hashes
        .iter()
        .map(|(file, h)| format!("{h}  {file}\n"))
        .collect()
}

/// Reads a hash list (`sha256sum`'s format); a malformed line is an error naming it.
pub fn from_text(text: &str, source: &Path) -> Result<BTreeMap<String, String>, String> {
    let mut out = BTreeMap::new();
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let (h, file) = line.split_once("  ").ok_or_else(|| {
            format!(
                "{} line {}: expected `<sha256>  <file>`; write the file with `mrdrive data hashes`",
                source.display(),
                i + 1
            )
        })?;
        if h.len() != 64 || !h.bytes().all(|b| b.is_ascii_hexdigit()) {
            return Err(format!(
                "{} line {}: {h:?} is not a SHA-256 (64 hex digits)",
                source.display(),
                i + 1
            ));
        }
        out.insert(file.to_string(), h.to_ascii_lowercase());
    }
    Ok(out)
}

/// How a dataset stands against a hash list.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Check {
    /// Files whose bytes match.
    pub same: Vec<String>,
    /// Files listed that differ: the dataset is not the one the list was made from.
    pub differ: Vec<String>,
    /// Files listed but not (yet) in the dataset: to collect or label again.
    pub missing: Vec<String>,
    /// Files in the dataset the list does not know (collected after it was written).
    pub new: Vec<String>,
}

/// Compares the `found` hashes of a dataset with a `listed` hash list, over the
/// files of the datasets `found` covers.
pub fn check(found: &BTreeMap<String, String>, listed: &BTreeMap<String, String>) -> Check {
    let sets: Vec<&str> = found
        .keys()
        .filter_map(|k| k.split_once('/').map(|(set, _)| set))
        .collect();
    let mut c = Check::default();
    for (file, h) in listed {
        let set = file.split_once('/').map_or("", |(set, _)| set);
        if !sets.contains(&set) {
            continue;
        }
        match found.get(file) {
            Some(g) if g == h => c.same.push(file.clone()),
            Some(_) => c.differ.push(file.clone()),
            None => c.missing.push(file.clone()),
        }
    }
    c.new = found
        .keys()
        .filter(|k| !listed.contains_key(*k))
        .cloned()
        .collect();
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(pairs: &[(&str, char)]) -> BTreeMap<String, String> {
        pairs
            .iter()
            .map(|(f, c)| (f.to_string(), c.to_string().repeat(64)))
            .collect()
    }

    #[test]
    fn a_list_reads_back_and_a_check_sorts_every_file() {
        let listed = map(&[
            ("original/episode-00000.safetensors", 'a'),
            ("original/labels-00000.safetensors", 'b'),
            ("original/episode-00001.safetensors", 'c'),
            ("retarget/episode-00000.safetensors", 'd'),
        ]);
        let text = to_text(&listed);
        assert_eq!(from_text(&text, Path::new("h")).unwrap(), listed);
        let found = map(&[
            ("original/episode-00000.safetensors", 'a'),
            ("original/labels-00000.safetensors", 'e'),
            ("original/episode-00002.safetensors", 'f'),
        ]);
        let c = check(&found, &listed);
        assert_eq!(c.same, ["original/episode-00000.safetensors"]);
        assert_eq!(c.differ, ["original/labels-00000.safetensors"]);
        // The retargeting set is not checked: the found hashes do not cover it.
        assert_eq!(c.missing, ["original/episode-00001.safetensors"]);
        assert_eq!(c.new, ["original/episode-00002.safetensors"]);
        let e = from_text("abc  x\n", Path::new("h.sha256")).unwrap_err();
        assert!(e.contains("h.sha256 line 1") && e.contains("64 hex"), "{e}");
        assert!(from_text("no separator\n", Path::new("h")).is_err());
    }
}
