//! What tests need from outside the checkout, and how they skip without it.
//!
//! CARLA's maps and routes and Foxglove's schemas live in a `shared` folder
//! beside the checkout (`<workspace>/../shared`, or `MRDRIVE_SHARED_DIR`).
//! Some tests also need a Python with cross-checking packages, a renderer, or
//! an emulated CPU.
//! A test that cannot run calls [`skip`], which
//!
//! - panics instead when the variable that requires that thing is `1`
//!   (`MRDRIVE_REQUIRE_SHARED`, `MRDRIVE_REQUIRE_PYTHON`,
//!   `MRDRIVE_REQUIRE_GPU_API`, `MRDRIVE_REQUIRE_EMULATOR`,
//!   `MRDRIVE_REQUIRE_SLURM`; `cargo xtask ci` sets them all), so CI cannot skip silently;
//! - otherwise writes `SKIPPED: test: why` straight to stderr (past the test
//!   harness's capture) and appends it to the skip log, which `cargo xtask
//!   test` empties before the run and counts after it: a clone without
//!   `../shared` ends with "N tests skipped" and each reason, not with "ok"
//!   everywhere.

use std::io::Write;
use std::path::PathBuf;

/// The workspace root (the parent of the `world` crate).
pub fn workspace_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Where tests look for what they need, and what they must not skip.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TestEnv {
    /// The shared data folder: `MRDRIVE_SHARED_DIR` if set, else
    /// `<workspace>/../shared`. (Point the variable at an empty folder to
    /// see what a clone without it does.)
    pub shared_dir: PathBuf,
    /// The skip log: `MRDRIVE_SKIP_LOG` if set, else
    /// `<workspace>/target/skipped-tests.txt`.
    pub skip_log: PathBuf,
    /// What may not be skipped: each [`Needs`] whose
    /// [`Needs::require_var`] is `1`.
    pub required: Vec<Needs>,
}

/// Something a test needs that a machine may lack.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Needs {
    /// Files from the shared folder (CARLA's maps, Foxglove's schemas).
    Shared,
    /// A Python with the cross-checking packages.
    Python,
    /// A graphics adapter for the renderer (a GPU, or Mesa's lavapipe).
    Renderer,
    /// An emulated x86-64 CPU (`qemu-x86_64`, Debian's `qemu-user`) for the
    /// cross-CPU test (`tests/cross_cpu.rs`).
    Emulator,
    /// A local Slurm (Debian's `slurm-wlm` and `munge`, run as root) for the
    /// scale-out test (`tests/slurm.rs`).
    Slurm,
}

impl Needs {
    /// Every kind of need.
    pub const ALL: [Needs; 5] = [
        Needs::Shared,
        Needs::Python,
        Needs::Renderer,
        Needs::Emulator,
        Needs::Slurm,
    ];

    /// The variable that, set to `1`, turns a skip for this into a failure.
    pub fn require_var(self) -> &'static str {
        match self {
            Needs::Shared => "MRDRIVE_REQUIRE_SHARED",
            Needs::Python => "MRDRIVE_REQUIRE_PYTHON",
            Needs::Renderer => "MRDRIVE_REQUIRE_GPU_API",
            Needs::Emulator => "MRDRIVE_REQUIRE_EMULATOR",
            Needs::Slurm => "MRDRIVE_REQUIRE_SLURM",
        }
    }
}

impl TestEnv {
    /// The settings of this process, from its environment variables.
    pub fn from_env() -> Self {
        let var = |name: &str| std::env::var_os(name).map(PathBuf::from);
        TestEnv {
            shared_dir: var("MRDRIVE_SHARED_DIR")
                .unwrap_or_else(|| workspace_root().join("../shared")),
            skip_log: var("MRDRIVE_SKIP_LOG")
                .unwrap_or_else(|| workspace_root().join("target/skipped-tests.txt")),
            required: Needs::ALL
                .into_iter()
                .filter(|n| std::env::var(n.require_var()).as_deref() == Ok("1"))
                .collect(),
        }
    }

    /// Reports that `test` skips (all or part of it) because `why`: panics
    /// if `needs` is required, else prints the skip past the harness's
    /// capture and appends it to the skip log.
    pub fn skip(&self, test: &str, needs: Needs, why: &str) {
        if self.required.contains(&needs) {
            panic!(
                "{test}: {why}, and {}=1 forbids skipping",
                needs.require_var()
            );
        }
        self.log_line(&format!("SKIPPED: {test}: {why}\n"));
    }

    fn log_line(&self, line: &str) {
        // Straight to the handle: the test harness captures `eprintln!`.
        let _ = std::io::stderr().write_all(line.as_bytes());
        if let Some(dir) = self.skip_log.parent() {
            let _ = std::fs::create_dir_all(dir);
        }
        // One short append per line: lines from parallel tests do not interleave.
        if let Ok(mut f) = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&self.skip_log)
        {
            let _ = f.write_all(line.as_bytes());
        }
    }

    /// A folder of the shared data (`carla`, `foxglove-schemas`), or `None`
    /// after [`TestEnv::skip`]ping `test` when it lacks `probe` (a file it
    /// must hold).
    pub fn shared_subdir(&self, test: &str, name: &str, probe: &str) -> Option<PathBuf> {
        let dir = self.shared_dir.join(name);
        if dir.join(probe).is_file() {
            return Some(dir);
        }
        self.skip(
            test,
            Needs::Shared,
            &format!("{} not found", dir.join(probe).display()),
        );
        None
    }
}

/// [`TestEnv::skip`] with this process's settings.
pub fn skip(test: &str, needs: Needs, why: &str) {
    TestEnv::from_env().skip(test, needs, why);
}

/// The shared data folder of this process ([`TestEnv::shared_dir`]).
pub fn shared_dir() -> PathBuf {
    TestEnv::from_env().shared_dir
}

/// A folder of the shared data, or `None` after skipping `test`
/// ([`TestEnv::shared_subdir`] with this process's settings).
pub fn shared_subdir(test: &str, name: &str, probe: &str) -> Option<PathBuf> {
    TestEnv::from_env().shared_subdir(test, name, probe)
}

/// The CARLA data folder, or `None` after skipping `test` when it is
/// missing.
pub fn carla_dir(test: &str) -> Option<PathBuf> {
    shared_subdir(test, "carla", "Town01.xodr")
}

/// A Python that imports `modules` (e.g. `"safetensors.numpy, numpy"`):
/// `MRDRIVE_PYTHON` if set, else the workspace's `.venv`, else `python3`.
pub fn python_with(modules: &str) -> Option<PathBuf> {
    let candidates: Vec<PathBuf> = match std::env::var_os("MRDRIVE_PYTHON") {
        Some(p) => vec![p.into()],
        None => vec![workspace_root().join(".venv/bin/python"), "python3".into()],
    };
    candidates.into_iter().find(|p| {
        std::process::Command::new(p)
            .args(["-c", &format!("import {modules}")])
            .output()
            .is_ok_and(|o| o.status.success())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env(tmp: &std::path::Path, required: Vec<Needs>) -> TestEnv {
        TestEnv {
            shared_dir: tmp.join("shared"),
            skip_log: tmp.join("target/skips.txt"),
            required,
        }
    }

    #[test]
    fn a_missing_shared_folder_is_skipped_and_logged() {
        let tmp = tempfile::tempdir().unwrap();
        let e = env(tmp.path(), vec![Needs::Python]);
        assert_eq!(e.shared_subdir("t1", "carla", "Town01.xodr"), None);
        e.skip("t2", Needs::Renderer, "no adapter");
        let text = std::fs::read_to_string(&e.skip_log).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 2, "{text}");
        assert!(
            lines[0].starts_with("SKIPPED: t1: ") && lines[0].contains("Town01.xodr not found"),
            "{text}"
        );
        assert_eq!(lines[1], "SKIPPED: t2: no adapter");
    }

    #[test]
    fn a_required_need_fails_instead_of_skipping() {
        let tmp = tempfile::tempdir().unwrap();
        let e = env(tmp.path(), vec![Needs::Shared]);
        let result = std::panic::catch_unwind(|| e.shared_subdir("t", "carla", "Town01.xodr"));
        assert!(result.is_err(), "a required folder must not skip");
        assert!(!e.skip_log.exists(), "nothing was skipped");
    }

    #[test]
    fn a_present_folder_is_found() {
        let tmp = tempfile::tempdir().unwrap();
        let e = env(tmp.path(), Needs::ALL.to_vec());
        std::fs::create_dir_all(e.shared_dir.join("carla")).unwrap();
        std::fs::write(e.shared_dir.join("carla/Town01.xodr"), "").unwrap();
        assert_eq!(
            e.shared_subdir("t", "carla", "Town01.xodr"),
            Some(e.shared_dir.join("carla"))
        );
    }
}
