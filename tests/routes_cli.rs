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
    // The held-out town's routes and gen03's (its arterials, unsignalled
    // junctions and roundabout).
    for (town, seeds, count) in [("held01", "0..4", 4), ("gen03", "0..8", 8)] {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join(format!("{town}.toml"));
        let map = format!("maps/{town}.xodr");
        let printed = run_ok(&[
            "routes",
            "--map",
            &map,
            "--random",
            seeds,
            "--write",
            out.to_str().unwrap(),
        ]);
        let last = format!("random-{}", count - 1);
        assert!(printed.contains(&last), "{printed}");
        assert!(
            printed.contains(&format!("wrote {count} route(s)")),
            "{printed}"
        );
        let written = std::fs::read_to_string(&out).unwrap();
        assert!(
            written.starts_with(&format!(
                "# Written by `mrdrive routes --map {map} --random {seeds}"
            )),
            "{written}"
        );
        // The shipped file is this command's output: same seeds, same routes.
        let shipped = std::fs::read_to_string(root().join(format!("routes/{town}.toml"))).unwrap();
        assert_eq!(tables(&written), tables(&shipped), "{town}");
        // And it plans again as a route file.
        let replanned = run_ok(&["routes", "--map", &map, out.to_str().unwrap()]);
        for k in 0..count {
            let id = format!("random-{k}");
            assert!(replanned.contains(&id), "{replanned}");
        }
    }
}

#[test]
fn a_bad_seed_list_is_named() {
    let out = run(&["routes", "--map", "maps/held01.xodr", "--random", "a..b"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("seeds") && err.contains("a..b"), "{err}");
}
