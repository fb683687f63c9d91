//! `mrdrive traffic ...` end to end on the built-in fixture town.

mod common;

use common::{run, run_ok};

fn field(out: &str, name: &str) -> f64 {
    let line = out
        .lines()
        .find(|l| l.starts_with(name))
        .unwrap_or_else(|| panic!("no {name:?} in:\n{out}"));
    line[name.len()..]
        .split_whitespace()
        .next()
        .unwrap()
        .parse()
        .unwrap()
}

#[test]
fn soak_on_the_fixture_prints_its_figures() {
    let out = run_ok(&[
        "traffic",
        "soak",
        "--fixture",
        "3x3",
        "--block-m",
        "60",
        "--vehicles",
        "10",
        "--pedestrians",
        "10",
        "--minutes",
        "0.5",
        "--seed",
        "3",
    ]);
    assert!(out.contains("FIXTURE town"));
    assert_eq!(field(&out, "simulated"), 30.0);
    assert_eq!(field(&out, "realised vehicles"), 10.0);
    assert_eq!(field(&out, "NPC-NPC collisions"), 0.0);
    assert_eq!(field(&out, "red lights run by NPCs"), 0.0);
    assert!(field(&out, "ticks/s") > 0.0);
}

#[test]
fn table_prints_three_densities() {
    let out = run_ok(&[
        "traffic",
        "table",
        "--fixture",
        "3x3",
        "--block-m",
        "60",
        "--resets",
        "2",
    ]);
    for d in ["(0, 0)", "(5, 10)", "(20, 40)"] {
        assert!(out.contains(d), "{d} missing:\n{out}");
    }
}

#[test]
fn bad_town_arguments_name_the_problem() {
    let o = run(&["traffic", "soak", "--map", "/nonexistent/Town01.xodr"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("/nonexistent/Town01.xodr") && err.contains("--fixture"),
        "{err}"
    );
    let o = run(&["traffic", "soak", "--fixture", "3by3"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("NXxNY"));
}
