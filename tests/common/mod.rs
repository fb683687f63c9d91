//! What the command-line tests share: running `mrdrive` from the workspace
//! root and checking that it succeeded.

// Each test file uses its own part of this module.
#![allow(dead_code)]

use std::ffi::OsStr;
use std::path::PathBuf;
use std::process::{Command, Output};

/// The workspace root (where `scenarios/`, `maps/` and `routes/` are).
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A `mrdrive` command run from the workspace root.
pub fn mrdrive() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_mrdrive"));
    c.current_dir(root());
    // As a user's shell has it: .cargo/config.toml sets it for test processes,
    // and the binary must set it for itself (tests/first_run.rs checks that it does).
    c.env_remove("NODEVICE_SELECT");
    c
}

/// Runs `mrdrive ARGS` and returns what it did, whatever the outcome.
pub fn run<S: AsRef<OsStr>>(args: &[S]) -> Output {
    mrdrive().args(args).output().expect("mrdrive starts")
}

/// Runs `mrdrive ARGS`, asserts that it succeeded (else panics with the
/// arguments, its output and its errors) and returns its standard output.
pub fn run_ok<S: AsRef<OsStr>>(args: &[S]) -> String {
    succeeded(args, &run(args))
}

/// Asserts that `out`, from `mrdrive ARGS`, succeeded and returns its
/// standard output.
pub fn succeeded<S: AsRef<OsStr>>(args: &[S], out: &Output) -> String {
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let shown: Vec<_> = args.iter().map(|a| a.as_ref().to_string_lossy()).collect();
    assert!(
        out.status.success(),
        "mrdrive {} failed ({}):\n{stdout}\n{}",
        shown.join(" "),
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

/// `file`, a scenario on CARLA's maps (`../../../shared/carla/...`), rewritten into
/// `tmp` to read them from the CARLA folder the tests use; `None` (`test` skipped)
/// without one.
pub fn with_tests_carla(
    test: &str,
    file: &std::path::Path,
    tmp: &std::path::Path,
) -> Option<PathBuf> {
    let carla = world::testdata::carla_dir(test)?;
    let text = std::fs::read_to_string(file).unwrap();
    let copy = tmp.join(file.file_name().unwrap());
    std::fs::write(
        &copy,
        text.replace("../../../shared/carla", &carla.display().to_string()),
    )
    .unwrap();
    Some(copy)
}
