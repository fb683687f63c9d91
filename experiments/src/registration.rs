//! The study's registration: `registration.md` beside the page holds every
//! rule the verdicts follow, and `registered.toml` names the commit that
//! registered it and the file's SHA-256. Both are committed before the
//! rerun's first run; after that the file never changes (what one would
//! change goes into `discussion.md`), and the page refuses records of a build
//! that does not descend from the registered commit.
//!
//! `mrdrive paper --register` writes `registered.toml` from the checkout's
//! `HEAD` once `registration.md` is final (no "DRAFT" status line) and
//! committed as it is; the file is then committed by hand. A folder without
//! `registered.toml` (a quick run, a toy folder) builds its page as before and
//! says it is not registered.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::PaperError;

/// The rules' file, beside the page.
pub const RULES_FILE: &str = "registration.md";
/// The registration's record, beside the page.
pub const RECORD_FILE: &str = "registered.toml";

/// A registration: the commit whose `registration.md` binds the study.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Registration {
    /// The registering commit (40 hex digits).
    pub commit: String,
    /// SHA-256 of `registration.md` at that commit (64 hex digits).
    pub sha256: String,
}

impl Registration {
    /// Reads `dir/registered.toml`; `None` where there is none.
    pub fn load(dir: &Path) -> Result<Option<Registration>, PaperError> {
        let path = dir.join(RECORD_FILE);
        let text = match std::fs::read_to_string(&path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(PaperError::io("read", &path, e)),
        };
        let r: Registration = toml::from_str(&text).map_err(|e| problem(&path, e.to_string()))?;
        let hex = |s: &str, n: usize| s.len() == n && s.bytes().all(|b| b.is_ascii_hexdigit());
        if !hex(&r.commit, 40) {
            return Err(problem(
                &path,
                format!(
                    "field `commit`: {:?} is not a full commit hash (40 hex digits); write it \
                     again with `mrdrive paper --register`",
                    r.commit
                ),
            ));
        }
        if !hex(&r.sha256, 64) {
            return Err(problem(
                &path,
                format!(
                    "field `sha256`: {:?} is not a SHA-256 (64 hex digits); write it again \
                     with `mrdrive paper --register`",
                    r.sha256
                ),
            ));
        }
        Ok(Some(r))
    }

    /// Checks that `dir/registration.md` is the file registered.
    pub fn check_rules(&self, dir: &Path) -> Result<(), PaperError> {
        let path = dir.join(RULES_FILE);
        let bytes = std::fs::read(&path).map_err(|e| PaperError::io("read", &path, e))?;
        let here = sim::output::record::sha256_hex(&bytes);
        if here != self.sha256 {
            return Err(problem(
                &path,
                format!(
                    "its SHA-256 is {here}, not the {} registered at commit {}: the rules \
                     changed after registration. Restore it (`git checkout {} -- {}`); what \
                     you would change goes into a dated section of discussion.md",
                    self.sha256,
                    self.commit,
                    self.commit,
                    path.display()
                ),
            ));
        }
        Ok(())
    }

    /// Checks that every build in `builds` (`mrdrive VERSION (COMMIT)`, as
    /// records hold them) was made from a clean checkout of a commit that
    /// descends from the registered one, asking git in `dir`'s repository.
    pub fn check_builds<'a>(
        &self,
        dir: &Path,
        builds: impl IntoIterator<Item = &'a String>,
    ) -> Result<(), PaperError> {
        for build in builds {
            let Some(commit) = build_commit(build) else {
                return Err(problem(
                    dir,
                    format!(
                        "a record's build `{build}` names no commit (built outside a git \
                         checkout); the registered study takes records of builds of commit \
                         {} or a descendant of it",
                        self.commit
                    ),
                ));
            };
            if commit.ends_with("-dirty") {
                return Err(problem(
                    dir,
                    format!(
                        "a record's build `{build}` was made from a checkout with uncommitted \
                         changes; the registered study takes records of one clean build: commit, \
                         build again and rerun those runs"
                    ),
                ));
            }
            if !descends(dir, &self.commit, commit)? {
                return Err(problem(
                    dir,
                    format!(
                        "a record's build `{build}` does not descend from the registered commit \
                         {}: its runs were made before the rules were registered (or on another \
                         branch). Move them out of the folder and rerun them with this build",
                        self.commit
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The page's line about it.
    pub fn line(&self) -> String {
        format!(
            "Registered at commit `{}`: `{RULES_FILE}` SHA-256 `{}`; every record below was made \
             by a build that descends from it.",
            self.commit, self.sha256
        )
    }
}

/// Registers `dir/registration.md` at the checkout's `HEAD`: checks that the
/// file has no draft status line and is committed as it is, and that nothing
/// is registered yet, then writes `dir/registered.toml` (to be committed).
pub fn register(dir: &Path) -> Result<Registration, PaperError> {
    let rules = dir.join(RULES_FILE);
    let record = dir.join(RECORD_FILE);
    if let Some(r) = Registration::load(dir)? {
        return Err(problem(
            &record,
            format!(
                "already registered at commit {}; a registration never changes (what you would \
                 change goes into discussion.md)",
                r.commit
            ),
        ));
    }
    let text = std::fs::read_to_string(&rules).map_err(|e| PaperError::io("read", &rules, e))?;
    if text.lines().take(5).any(|l| l.contains("DRAFT")) {
        return Err(problem(
            &rules,
            "still a draft (a status line in its first lines says DRAFT): settle what is open, \
             remove the status line, commit, then register"
                .into(),
        ));
    }
    let changed = git(dir, &["status", "--porcelain", "--", RULES_FILE])?;
    if !changed.trim().is_empty() {
        return Err(problem(
            &rules,
            "has changes that are not committed; commit it as it is to be registered, then \
             register"
                .into(),
        ));
    }
    let r = Registration {
        commit: git(dir, &["rev-parse", "HEAD"])?.trim().to_string(),
        sha256: sim::output::record::sha256_hex(text.as_bytes()),
    };
    let body = format!(
        "# Written by `mrdrive paper --register`: the commit whose {RULES_FILE} binds the\n\
         # study, and that file's SHA-256. Commit this file next; never edit it.\n{}",
        toml::to_string(&r).expect("two strings serialise")
    );
    std::fs::write(&record, body).map_err(|e| PaperError::io("write", &record, e))?;
    Ok(r)
}

/// The commit of a build id `mrdrive VERSION (COMMIT)`: what `git describe
/// --always --dirty` printed (a hash, perhaps after a tag and `-g`, perhaps
/// with `-dirty`); `None` for "unknown commit".
pub fn build_commit(build: &str) -> Option<&str> {
    let inner = build.rsplit_once('(')?.1.strip_suffix(')')?;
    if inner.is_empty() || inner.contains(' ') {
        return None;
    }
    // `v1.0-3-gabc123`: the hash after the last `-g`.
    let dirty = inner.ends_with("-dirty");
    let base = inner.strip_suffix("-dirty").unwrap_or(inner);
    match base.rsplit_once("-g") {
        Some((_, hash)) if !dirty && hash.bytes().all(|b| b.is_ascii_hexdigit()) => Some(hash),
        _ => Some(inner),
    }
}

/// Whether commit `later` descends from (or is) `earlier`, in `dir`'s repository.
pub(crate) fn descends(dir: &Path, earlier: &str, later: &str) -> Result<bool, PaperError> {
    let out = Command::new("git")
        .arg("-C")
        .arg(dir)
        .args(["merge-base", "--is-ancestor", earlier, later])
        .output()
        .map_err(|e| git_missing(dir, e))?;
    match out.status.code() {
        Some(0) => Ok(true),
        Some(1) => Ok(false),
        _ => Err(problem(
            dir,
            format!(
                "git could not compare commits {earlier} and {later} ({}); fetch the \
                 repository's full history (a shallow clone lacks them)",
                String::from_utf8_lossy(&out.stderr).trim()
            ),
        )),
    }
}

/// Runs git in `dir` and returns what it printed.
pub(crate) fn git(dir: &Path, args: &[&str]) -> Result<String, PaperError> {
    let out = Command::new("git")
        .arg("-C")
        .arg(dir)
        .args(args)
        .output()
        .map_err(|e| git_missing(dir, e))?;
    if !out.status.success() {
        return Err(problem(
            dir,
            format!(
                "`git {}` failed: {}; registering needs the folder inside a git checkout",
                args.join(" "),
                String::from_utf8_lossy(&out.stderr).trim()
            ),
        ));
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

fn git_missing(dir: &Path, e: std::io::Error) -> PaperError {
    problem(
        dir,
        format!("could not run git ({e}); the registration is checked with git: install it"),
    )
}

fn problem(path: &Path, problem: String) -> PaperError {
    PaperError::Registration {
        path: PathBuf::from(path),
        problem,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A git repository in a temporary folder with one commit of `files`.
    fn repo(files: &[(&str, &str)]) -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        let run = |args: &[&str]| {
            let ok = Command::new("git")
                .arg("-C")
                .arg(dir.path())
                .args(args)
                .output()
                .unwrap()
                .status
                .success();
            assert!(ok, "git {args:?}");
        };
        run(&["init", "-q"]);
        run(&["config", "user.email", "t@example.com"]);
        run(&["config", "user.name", "t"]);
        for (name, text) in files {
            std::fs::write(dir.path().join(name), text).unwrap();
        }
        run(&["add", "-A"]);
        run(&["commit", "-q", "-m", "first"]);
        dir
    }

    fn commit_all(dir: &Path, message: &str) -> String {
        for args in [
            &["add", "-A"][..],
            &["commit", "-q", "--allow-empty", "-m", message],
        ] {
            assert!(
                Command::new("git")
                    .arg("-C")
                    .arg(dir)
                    .args(args)
                    .status()
                    .unwrap()
                    .success()
            );
        }
        git(dir, &["rev-parse", "HEAD"]).unwrap().trim().to_string()
    }

    #[test]
    fn a_build_id_names_its_commit() {
        assert_eq!(
            build_commit("mrdrive 0.1.0 (df4ab9c300dd)"),
            Some("df4ab9c300dd")
        );
        assert_eq!(
            build_commit("mrdrive 0.1.0 (v0.1-3-gdf4ab9c300dd)"),
            Some("df4ab9c300dd")
        );
        assert_eq!(
            build_commit("mrdrive 0.1.0 (df4ab9c300dd-dirty)"),
            Some("df4ab9c300dd-dirty")
        );
        assert_eq!(build_commit("mrdrive 0.1.0 (unknown commit)"), None);
    }

    #[test]
    fn a_draft_is_not_registered_and_a_final_file_is_once() {
        let dir = repo(&[(RULES_FILE, "# Registration — DRAFT, not yet registered\n")]);
        let e = register(dir.path()).unwrap_err().to_string();
        assert!(e.contains("still a draft"), "{e}");
        std::fs::write(dir.path().join(RULES_FILE), "# Registration\nrules\n").unwrap();
        let e = register(dir.path()).unwrap_err().to_string();
        assert!(e.contains("not committed"), "{e}");
        let head = commit_all(dir.path(), "final rules");
        let r = register(dir.path()).unwrap();
        assert_eq!(r.commit, head);
        assert_eq!(Registration::load(dir.path()).unwrap(), Some(r.clone()));
        r.check_rules(dir.path()).unwrap();
        let e = register(dir.path()).unwrap_err().to_string();
        assert!(e.contains("already registered"), "{e}");
        // The rules changed afterwards: refused, with the way back.
        std::fs::write(dir.path().join(RULES_FILE), "# Registration\nother rules\n").unwrap();
        let e = r.check_rules(dir.path()).unwrap_err().to_string();
        assert!(
            e.contains("changed after registration") && e.contains("git checkout"),
            "{e}"
        );
    }

    #[test]
    fn records_of_builds_before_the_registration_or_dirty_are_refused() {
        let dir = repo(&[(RULES_FILE, "# Registration\nrules\n")]);
        let before = git(dir.path(), &["rev-parse", "HEAD"]).unwrap();
        let registered = commit_all(dir.path(), "registered");
        let after = commit_all(dir.path(), "later work");
        let r = Registration {
            commit: registered.clone(),
            sha256: "0".repeat(64),
        };
        let id = |c: &str| format!("mrdrive 0.1.0 ({})", &c.trim()[..12]);
        r.check_builds(dir.path(), &[id(&registered), id(&after)])
            .unwrap();
        let e = r
            .check_builds(dir.path(), &[id(&after), id(&before)])
            .unwrap_err()
            .to_string();
        assert!(e.contains("does not descend"), "{e}");
        let e = r
            .check_builds(
                dir.path(),
                &[format!("mrdrive 0.1.0 ({}-dirty)", &after[..12])],
            )
            .unwrap_err()
            .to_string();
        assert!(e.contains("uncommitted changes"), "{e}");
        let e = r
            .check_builds(dir.path(), &["mrdrive 0.1.0 (unknown commit)".to_string()])
            .unwrap_err()
            .to_string();
        assert!(e.contains("names no commit"), "{e}");
    }

    #[test]
    fn a_malformed_record_names_its_field_and_the_fix() {
        let dir = tempfile::tempdir().unwrap();
        assert_eq!(Registration::load(dir.path()).unwrap(), None);
        std::fs::write(
            dir.path().join(RECORD_FILE),
            "commit = \"abc\"\nsha256 = \"00\"\n",
        )
        .unwrap();
        let e = Registration::load(dir.path()).unwrap_err().to_string();
        assert!(
            e.contains("registered.toml") && e.contains("field `commit`"),
            "{e}"
        );
        assert!(e.contains("mrdrive paper --register"), "{e}");
    }
}
