//! Where long jobs keep what is too big or too fleeting for the repository:
//! the study's datasets and the training runs' state.
//!
//! A training run is a chain of time-limited jobs (docs/training.md, "A chain
//! of jobs"). Its data and state live outside the work tree so that a fresh
//! clone, a `git clean` or a checkout of another commit leaves them alone, and
//! a job that gets the same machine back finds them where the last one left
//! them. The folder is, in order of precedence:
//!
//! 1. `$MRDRIVE_CACHE`, when set and not empty;
//! 2. `$XDG_CACHE_HOME/mrdrive`, when that is set and not empty;
//! 3. `$HOME/.cache/mrdrive`;
//! 4. `.cache/mrdrive` under the working directory, when there is no home.

use std::path::PathBuf;

/// The environment variable that names the cache folder.
pub const ENV: &str = "MRDRIVE_CACHE";

/// The cache folder of this process's environment (see the module's list).
pub fn root() -> PathBuf {
    root_from(&|name| std::env::var_os(name).map(PathBuf::from))
}

/// The cache folder for an environment read through `var`.
pub fn root_from(var: &dyn Fn(&str) -> Option<PathBuf>) -> PathBuf {
    let set = |name: &str| var(name).filter(|p| !p.as_os_str().is_empty());
    if let Some(dir) = set(ENV) {
        return dir;
    }
    if let Some(dir) = set("XDG_CACHE_HOME") {
        return dir.join("mrdrive");
    }
    match set("HOME") {
        Some(home) => home.join(".cache/mrdrive"),
        None => PathBuf::from(".cache/mrdrive"),
    }
}

/// The study's dataset `name` (`original`, `retarget`, `original-quick`):
/// `<root>/data/<name>`.
pub fn dataset(name: &str) -> PathBuf {
    root().join("data").join(name)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env<'a>(pairs: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<PathBuf> + 'a {
        move |name| {
            pairs
                .iter()
                .find(|(k, _)| *k == name)
                .map(|(_, v)| PathBuf::from(v))
        }
    }

    #[test]
    fn the_cache_is_the_variable_then_xdg_then_home() {
        let all = [
            (ENV, "/scratch/c"),
            ("XDG_CACHE_HOME", "/x"),
            ("HOME", "/home/u"),
        ];
        assert_eq!(root_from(&env(&all)), PathBuf::from("/scratch/c"));
        let empty_var = [(ENV, ""), ("XDG_CACHE_HOME", "/x"), ("HOME", "/home/u")];
        assert_eq!(root_from(&env(&empty_var)), PathBuf::from("/x/mrdrive"));
        let home = [("HOME", "/home/u")];
        assert_eq!(
            root_from(&env(&home)),
            PathBuf::from("/home/u/.cache/mrdrive")
        );
        assert_eq!(root_from(&env(&[])), PathBuf::from(".cache/mrdrive"));
    }
}
