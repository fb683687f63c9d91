//! Embeds the git commit the simulator was built from, for result records
//! (with `-dirty` where tracked files had uncommitted changes: such a build is
//! not one commit's, and a registered study refuses its records). The script
//! reruns only when HEAD or a branch moves, so an edit made after that rerun
//! goes unseen: `-dirty` is a lower bound. Build a study from a fresh worktree.

fn main() {
    let commit = std::process::Command::new("git")
        .args(["describe", "--always", "--dirty", "--abbrev=12"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_else(|| "unknown commit".into());
    println!("cargo:rustc-env=MRDRIVE_GIT_COMMIT={commit}");
    println!("cargo:rerun-if-changed=../.git/HEAD");
    println!("cargo:rerun-if-changed=../.git/refs/heads");
}
