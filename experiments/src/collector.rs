//! The build that makes the study's data (issue 48).
//!
//! The training chain collects and labels its datasets a slice at a time over
//! many sessions, and a machine whose cache was lost regenerates them bit for
//! bit (`models/train-state/data.sha256` lists every file's SHA-256). A change
//! to the simulator after the first slice (an NPC rule, a lane under a point)
//! would make a later build's episodes and labels differ from those hashes, so
//! the data have a build of their own: the file [`FILE`] beside the chain's
//! snapshot names its commit, and `mrdrive train --all` runs every `collect`
//! and `label` step with that commit's binary ([`crate::pipeline::data_by`]).
//! The binary lives in the cache (`bin/mrdrive-<7 hex>`); where it is missing
//! it is built once from a worktree of that commit ([`build`]: a cold release
//! build, minutes). Training and the closed-loop drives use the running build.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The file, beside the chain's snapshot, that names the data's commit.
pub const FILE: &str = "collector";

/// Why the data's build could not be found or made.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {problem}")]
pub struct CollectorError {
    /// The file or folder concerned.
    pub path: PathBuf,
    /// What is wrong and how to mend it.
    pub problem: String,
}

fn problem(path: &Path, problem: impl Into<String>) -> CollectorError {
    CollectorError {
        path: path.to_path_buf(),
        problem: problem.into(),
    }
}

/// The commit named by `dir/`[`FILE`]: its one line that is not blank or a `#`
/// comment, 7 to 40 hex digits; `None` where the file does not exist.
pub fn pinned(dir: &Path) -> Result<Option<String>, CollectorError> {
    pinned_in(
        &dir.join(FILE),
        "the data's commit",
        "whose build made the data",
    )
}

/// The commit a pin file names: its one line that is not blank or a `#` comment,
/// 7 to 40 hex digits; `None` where the file does not exist. `what` names the
/// commit ("the data's commit") and `whose` says what it is ("whose build made the
/// data") in the error.
pub fn pinned_in(path: &Path, what: &str, whose: &str) -> Result<Option<String>, CollectorError> {
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(problem(path, format!("cannot read it: {e}"))),
    };
    let lines: Vec<&str> = text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .collect();
    match lines.as_slice() {
        [commit]
            if (7..=40).contains(&commit.len())
                && commit.bytes().all(|b| b.is_ascii_hexdigit()) =>
        {
            Ok(Some(commit.to_ascii_lowercase()))
        }
        _ => Err(problem(
            path,
            format!(
                "{what} must be its one line besides `#` comments, 7 to 40 hex digits (found \
                 {} such lines: {:?}); write the commit {whose}, as `git rev-parse HEAD` \
                 prints it",
                lines.len(),
                lines
            ),
        )),
    }
}

/// The binary that runs the data's steps for the pinned `commit`: `None` when
/// this build is that commit (clean: `this_commit` as `git describe --dirty`
/// printed it, see `registration::build_commit`), else `cache/bin/mrdrive-<7
/// hex>`, which may not exist yet ([`build`]).
pub fn binary(commit: &str, this_commit: Option<&str>, cache: &Path) -> Option<PathBuf> {
    let same = this_commit.is_some_and(|c| {
        !c.ends_with("-dirty") && c.len() >= 7 && (commit.starts_with(c) || c.starts_with(commit))
    });
    if same {
        None
    } else {
        Some(
            cache
                .join("bin")
                .join(format!("mrdrive-{}", commit.get(..7).unwrap_or(commit))),
        )
    }
}

/// The binary that must collect and label the data whose commit `dir/`[`FILE`]
/// pins, built from a worktree of the repository around `repo` where missing;
/// `None` where nothing is pinned or this build is the pinned commit. `note`
/// hears what it does.
pub fn data_build(
    dir: &Path,
    repo: &Path,
    cache: &Path,
    note: &dyn Fn(&str),
) -> Result<Option<PathBuf>, CollectorError> {
    let Some(commit) = pinned(dir)? else {
        return Ok(None);
    };
    let this = sim::output::provenance::build_id();
    let this_commit = crate::registration::build_commit(&this);
    let Some(bin) = binary(&commit, this_commit, cache) else {
        return Ok(None);
    };
    if !bin.exists() {
        let base = cache.join("collector");
        let target = base.join("target");
        build(
            repo,
            &commit,
            &base,
            &target,
            &bin,
            "the data's build",
            note,
        )?;
    }
    note(&format!(
        "the data are collected and labelled by {} (commit {commit}, pinned in {})",
        bin.display(),
        dir.join(FILE).display()
    ));
    Ok(Some(bin))
}

/// Builds `commit` of the repository around `repo` into `binary`: a detached
/// worktree at `base/<commit>` (kept: the study runs in it), `cargo build --release
/// --bin mrdrive` there into the target folder `target`, and a copy of the result.
/// `label` names the build in what `note` hears ("the data's build").
pub fn build(
    repo: &Path,
    commit: &str,
    base: &Path,
    target: &Path,
    binary: &Path,
    label: &str,
    note: &dyn Fn(&str),
) -> Result<(), CollectorError> {
    let tree = base.join(commit);
    let run = |cmd: &mut Command, what: &str| -> Result<(), CollectorError> {
        let status = cmd
            .status()
            .map_err(|e| problem(repo, format!("could not run {what}: {e}")))?;
        if status.success() {
            Ok(())
        } else {
            Err(problem(
                repo,
                format!(
                    "{what} failed ({status}); commit {commit} must be in this checkout's \
                     history (fetch it), or put its binary at {}",
                    binary.display()
                ),
            ))
        }
    };
    if !tree.join("Cargo.toml").exists() {
        note(&format!(
            "{label}: a worktree of {commit} at {}",
            tree.display()
        ));
        std::fs::create_dir_all(base)
            .map_err(|e| problem(base, format!("cannot create it: {e}")))?;
        run(
            Command::new("git").arg("-C").arg(repo).args([
                "worktree",
                "add",
                "--force",
                "--detach",
                &tree.display().to_string(),
                commit,
            ]),
            "git worktree add",
        )?;
    }
    note(&format!(
        "{label}: cargo build --release in {} (a cold build: minutes)",
        tree.display()
    ));
    run(
        Command::new("cargo")
            .args(["build", "--release", "--bin", "mrdrive"])
            .current_dir(&tree)
            .env("CARGO_TARGET_DIR", target),
        "cargo build",
    )?;
    if let Some(parent) = binary.parent() {
        std::fs::create_dir_all(parent)
            .map_err(|e| problem(parent, format!("cannot create it: {e}")))?;
    }
    let built = target.join("release").join("mrdrive");
    std::fs::copy(&built, binary)
        .map_err(|e| problem(binary, format!("cannot copy {} here: {e}", built.display())))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pinned_commit_is_the_files_one_line() {
        let dir = tempfile::tempdir().unwrap();
        assert!(pinned(dir.path()).unwrap().is_none());
        let file = dir.path().join(FILE);
        std::fs::write(&file, "# the data's build\n\n540F94D1ab2c\n").unwrap();
        assert_eq!(pinned(dir.path()).unwrap().as_deref(), Some("540f94d1ab2c"));
        for bad in [
            "540f9\n",
            "540f94d\n2df71be\n",
            "not-a-commit\n",
            "# only a comment\n",
        ] {
            std::fs::write(&file, bad).unwrap();
            let e = pinned(dir.path()).unwrap_err().to_string();
            assert!(
                e.contains(FILE) && e.contains("git rev-parse HEAD"),
                "{bad:?}: {e}"
            );
        }
    }

    #[test]
    fn the_data_steps_run_this_build_only_when_it_is_the_pinned_commit() {
        let cache = Path::new("/c");
        let commit = "540f94d1ab2c0000000000000000000000000000";
        assert_eq!(binary(commit, Some("540f94d1ab2c"), cache), None);
        let other = Some(PathBuf::from("/c/bin/mrdrive-540f94d"));
        // Another commit, a dirty build of this one, or an unknown one: the pinned binary.
        assert_eq!(binary(commit, Some("2df71be0aaaa"), cache), other);
        assert_eq!(binary(commit, Some("540f94d1ab2c-dirty"), cache), other);
        assert_eq!(binary(commit, None, cache), other);
    }
}
