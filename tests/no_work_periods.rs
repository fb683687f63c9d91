//! No text of the repository names a work period ("session 18", "this session",
//! "the earlier sessions", ...): a reader cannot know what those were. Text names the
//! date and the commit instead ("2026-12-04, commit 9924a25"; `git log --format='%h %ad
//! %s' --date=short` lists them).
//!
//! The files looked at are the repository's text files (`git ls-files`, tracked and
//! untracked but not ignored; without git, a walk of the tree that skips `target/`,
//! `.git/`, `.venv/`, `data/` and `out/`) ending in `.md`, `.rs`, `.toml`, `.py`, `.txt`
//! or `.json`, except the paper pages' run records (`docs/paper*/sweeps/`), files over
//! 2 MB and this file. Plain string search, case-insensitive; no regex crate.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The extensions of the files looked at.
const EXTENSIONS: &[&str] = &["md", "rs", "toml", "py", "txt", "json"];
/// Files larger than this are not read.
const MAX_BYTES: u64 = 2 * 1024 * 1024;
/// Folders (relative to the repository root, `/`-separated) whose files are not read.
const SKIPPED_PREFIXES: &[&str] = &["docs/paper/sweeps/", "docs/paper-2026-12-05/sweeps/"];
/// Folders the fallback walk does not enter (git ignores them).
const SKIPPED_DIRS: &[&str] = &["target", ".git", ".venv", "data", "out"];
/// This file, which has to spell the patterns out.
const THIS_FILE: &str = "tests/no_work_periods.rs";

/// Words that, right before "session", name a work period ("last session").
const BEFORE: &[&str] = &["this ", "earlier ", "later ", "next ", "previous ", "last "];

/// Why `line` names a work period, or `None`. `line` is matched lower-cased:
/// - "session 4", "sessions 15-18", "session-17" (a number after the word);
/// - "session's", "session’s";
/// - "this session", "earlier sessions", "later session", "next session",
///   "previous session", "last session".
fn work_period(line: &str) -> Option<String> {
    let lower = line.to_lowercase();
    let word = "session";
    let mut from = 0;
    while let Some(at) = lower[from..].find(word) {
        let start = from + at;
        let end = start + word.len();
        let before = &lower[..start];
        let mut after = &lower[end..];
        if let Some(w) = BEFORE.iter().find(|w| before.ends_with(*w)) {
            return Some(format!("\"{w}{word}\""));
        }
        if after.starts_with("'s") || after.starts_with("’s") {
            return Some(format!("\"{word}'s\""));
        }
        if let Some(rest) = after.strip_prefix('s') {
            after = rest;
        }
        let numbered = after
            .strip_prefix(' ')
            .or_else(|| after.strip_prefix('-'))
            .is_some_and(|rest| rest.starts_with(|c: char| c.is_ascii_digit()));
        if numbered {
            return Some(format!("\"{word}\" with a number"));
        }
        from = end;
    }
    None
}

/// The repository's files (relative paths, `/`-separated) by `git ls-files`, or `None`
/// when git is missing or this is not a git checkout.
fn git_files(root: &Path) -> Option<Vec<String>> {
    let out = Command::new("git")
        .args([
            "ls-files",
            "-z",
            "--cached",
            "--others",
            "--exclude-standard",
        ])
        .current_dir(root)
        .output()
        .ok()?;
    if !out.status.success() {
        return None;
    }
    let text = String::from_utf8_lossy(&out.stdout);
    let mut files: Vec<String> = text
        .split('\0')
        .filter(|s| !s.is_empty())
        .map(str::to_string)
        .collect();
    files.sort();
    files.dedup();
    Some(files)
}

/// The files under `dir` (relative to `root`), without git: every folder but the
/// ignored ones of `SKIPPED_DIRS`.
fn walked_files(root: &Path, dir: &Path, out: &mut Vec<String>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let mut entries: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
    entries.sort();
    for path in entries {
        let Ok(rel) = path.strip_prefix(root) else {
            continue;
        };
        let rel = rel
            .components()
            .map(|c| c.as_os_str().to_string_lossy().into_owned())
            .collect::<Vec<_>>()
            .join("/");
        if path.is_dir() {
            let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
            if name.is_some_and(|n| SKIPPED_DIRS.contains(&n.as_str())) {
                continue;
            }
            walked_files(root, &path, out);
        } else {
            out.push(rel);
        }
    }
}

/// Whether `rel` is one of the text files this test reads.
fn looked_at(rel: &str) -> bool {
    let ext_ok = Path::new(rel)
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()));
    ext_ok && rel != THIS_FILE && !SKIPPED_PREFIXES.iter().any(|p| rel.starts_with(p))
}

#[test]
fn no_text_names_a_work_period() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let files = git_files(root).unwrap_or_else(|| {
        let mut files = Vec::new();
        walked_files(root, root, &mut files);
        files
    });
    let mut found = Vec::new();
    let mut read = 0usize;
    for rel in files.iter().filter(|r| looked_at(r)) {
        let path = root.join(rel);
        // Listed by git but deleted from the working tree, or too large: not read.
        let Ok(meta) = std::fs::metadata(&path) else {
            continue;
        };
        if !meta.is_file() || meta.len() > MAX_BYTES {
            continue;
        }
        let Ok(bytes) = std::fs::read(&path) else {
            continue;
        };
        read += 1;
        let text = String::from_utf8_lossy(&bytes);
        for (i, line) in text.lines().enumerate() {
            if let Some(what) = work_period(line) {
                found.push(format!("{rel}:{}: {what}: {}", i + 1, line.trim()));
            }
        }
    }
    assert!(
        read > 10,
        "only {read} text files found under {}",
        root.display()
    );
    assert!(
        found.is_empty(),
        "{} line(s) name a work period, which a reader of the repository cannot know:\n{}\n\
         Fix: name the date and the commit instead (e.g. \"2026-12-04, commit 9924a25\"; \
         `git log --format='%h %ad %s' --date=short` lists them). In a .rs file change only \
         the comment or string text.",
        found.len(),
        found.join("\n")
    );
}

#[test]
fn the_patterns_catch_work_periods_and_leave_other_words_alone() {
    for hit in [
        "Lamps at CARLA's height (2026-12-04, session 18).",
        "sessions 15-18 and 19",
        "Record the Session-17 gen-town experiment",
        "With session 4's recipe (300 steps of 32",
        "found at the end of this session.",
        "the 2-core Intel Xeon VM of the earlier sessions",
        "(Done the next session: below.)",
        "as the previous session did",
        "what the last session left",
        "a later session will",
        "a GPU session's work",
    ] {
        assert!(work_period(hit).is_some(), "not caught: {hit}");
    }
    for clean in [
        "Training wall time so far (seconds, over every run).",
        "A training session of the optimiser (a process that resumes).",
        "sessions of Adam",
        "2026-12-04, commit 9924a25",
        "the sessionless client",
    ] {
        assert_eq!(work_period(clean), None, "caught: {clean}");
    }
}
