//! `mrdrive routes ...` end to end: planning route files, and drawing random
//! routes into a file that the study's held-out routes were written with.

mod common;

use common::{root, run, run_ok};

/// The route tables of a TOML route file, without its comments (the header
/// names the command, which differs by the output path).
fn tables(text: &str) -> String {
    text.lines()
        .filter(|l| !l.starts_with('#'))
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn random_routes_are_written_again_bit_for_bit_from_their_seeds() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("held01.toml");
    let printed = run_ok(&[
        "routes",
        "--map",
        "maps/held01.xodr",
        "--random",
        "0..4",
        "--write",
        out.to_str().unwrap(),
    ]);
    assert!(printed.contains("random-3"), "{printed}");
    assert!(printed.contains("wrote 4 route(s)"), "{printed}");
    let written = std::fs::read_to_string(&out).unwrap();
    assert!(
        written.starts_with("# Written by `mrdrive routes --map maps/held01.xodr --random 0..4"),
        "{written}"
    );
    // The shipped file is this command's output: same seeds, same routes.
    let shipped = std::fs::read_to_string(root().join("routes/held01.toml")).unwrap();
    assert_eq!(tables(&written), tables(&shipped));
    // And it plans again as a route file.
    let replanned = run_ok(&["routes", "--map", "maps/held01.xodr", out.to_str().unwrap()]);
    for id in ["random-0", "random-1", "random-2", "random-3"] {
        assert!(replanned.contains(id), "{replanned}");
    }
}

#[test]
fn a_bad_seed_list_is_named() {
    let out = run(&["routes", "--map", "maps/held01.xodr", "--random", "a..b"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("seeds") && err.contains("a..b"), "{err}");
}
