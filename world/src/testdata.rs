//! Where tests find CARLA's maps and routes (`<workspace>/../shared/carla/`).

use std::path::PathBuf;

/// The workspace root (the parent of the `world` crate).
pub fn workspace_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The CARLA data folder, or `None` (after printing a visible
/// "SKIPPED: ... not found" line) when it is missing. With
/// `MRDRIVE_REQUIRE_SHARED=1` a missing folder panics instead, so CI that
/// has the files cannot skip silently.
pub fn carla_dir(test: &str) -> Option<PathBuf> {
    let dir = workspace_root().join("../shared/carla");
    if dir.join("Town01.xodr").is_file() {
        return Some(dir);
    }
    if std::env::var("MRDRIVE_REQUIRE_SHARED").as_deref() == Ok("1") {
        panic!(
            "{test}: {} not found and MRDRIVE_REQUIRE_SHARED=1",
            dir.display()
        );
    }
    println!("SKIPPED: {test}: CARLA data {} not found", dir.display());
    None
}
