//! `mrdrive paper --quick` end to end: every table and figure of the paper at
//! toy size from the shipped checkpoints, resumed without redoing a run.
//! Needs CARLA's Town01 (`../shared/carla/`); skips without it.

mod common;

use common::run_ok;

#[test]
fn the_quick_paper_writes_every_table_and_figure_and_resumes() {
    if world::testdata::carla_dir("the_quick_paper_writes_every_table_and_figure_and_resumes")
        .is_none()
    {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("paper");
    let out_s = out.to_str().unwrap();
    let first = run_ok(&["paper", "--quick", "--out", out_s]);
    // 2 densities x 1 seed on one route: the expert and the three compared
    // policies at 3 delays (RA at 2 scales), the Original at D = 0, 4 switchers
    // (oracle, lookahead, the learned trigger, the braking lookahead), under
    // jitter the 2 fixed scales and 2 switchers, and the more-scales network
    // at its 2 quick scales and with 3 switchers between them.
    let planned = 2 * (3 + 3 + 3 + 3 * 2 + 1 + 4 + 4 + 2 + 3);
    assert!(
        first.contains(&format!("{planned} runs finished now, 0 failed")),
        "{first}"
    );
    let docs = out.clone();
    let page = std::fs::read_to_string(docs.join("README.md")).unwrap();
    for section in [
        "## The paper's shapes, checked",
        "## Table I",
        "## Table II",
        "## Fig. 3",
        "## Fig. 4",
        "## Fig. 5",
        "## Table III",
        "## Beyond the paper: the latency/safety frontier",
        "| table2 | 12 / 12 |",
        "RA learned switcher (50/100 ms) | 2 |",
        "RA braking switcher (50/100 ms) | 2 |",
        "## Beyond the paper: latency jitter",
        "## Beyond the paper: more scales in one network",
        "| scales | 18 / 18 |",
    ] {
        assert!(page.contains(section), "no {section:?} in:\n{page}");
    }
    for stem in ["fig3", "fig4", "fig5", "frontier", "jitter", "scales"] {
        let png = image::open(docs.join(format!("{stem}.png"))).unwrap();
        assert!(png.width() >= 800, "{stem}");
        let svg = std::fs::read_to_string(docs.join(format!("{stem}.svg"))).unwrap();
        assert!(svg.starts_with("<svg"), "{stem}");
    }
    for csv in [
        "table1", "table2", "fig3", "fig4", "fig5", "table3", "frontier", "jitter", "scales",
    ] {
        let text = std::fs::read_to_string(docs.join(format!("{csv}.csv"))).unwrap();
        assert!(text.lines().count() >= 2, "{csv}.csv has no rows:\n{text}");
    }
    // Table II's expert column has its two runs; the switcher rows name their latencies.
    let t2 = std::fs::read_to_string(docs.join("table2.csv")).unwrap();
    assert!(
        t2.lines().any(|l| l.starts_with("Expert,Town01,0,,2,")),
        "{t2}"
    );
    let t3 = std::fs::read_to_string(docs.join("table3.csv")).unwrap();
    assert!(t3.contains("RA oracle switcher (50/100 ms)"), "{t3}");
    // The wall-time log counted every finished run, in one invocation.
    let wall: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(docs.join("wall.json")).unwrap()).unwrap();
    assert_eq!(wall["runs"], planned, "{wall}");
    assert_eq!(wall["invocations"], 1, "{wall}");
    // The learned switcher's records name the trigger file and its digest.
    let learned = std::fs::read_dir(out.join("sweeps/ra-learned-100-50/runs"))
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path();
    let rec: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&learned).unwrap()).unwrap();
    let trigger = &rec["result"]["provenance"]["trigger"];
    assert_eq!(trigger["file"], "models/ra.trigger.json", "{rec}");
    assert_eq!(
        trigger["sha256"],
        sim::record::sha256_hex(&std::fs::read("models/ra.trigger.json").unwrap()),
        "{rec}"
    );
    // A second run finds every run done and writes the same page.
    let again = run_ok(&["paper", "--quick", "--out", out_s]);
    assert!(again.contains("0 runs finished now, 0 failed"), "{again}");
    assert_eq!(
        std::fs::read_to_string(docs.join("README.md")).unwrap(),
        page
    );
    // Runs from another renderer are not mixed in: a record "made" on GL is refused.
    let one = std::fs::read_dir(out.join("sweeps/ra-d000/runs"))
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path();
    let text = std::fs::read_to_string(&one).unwrap();
    let backend = text
        .lines()
        .find(|l| l.contains("\"render_backend\""))
        .unwrap()
        .to_string();
    let comma = if backend.ends_with(',') { "," } else { "" };
    std::fs::write(
        &one,
        text.replace(
            &backend,
            &format!("      \"render_backend\": \"Gl elsewhere\"{comma}"),
        ),
    )
    .unwrap();
    let mixed = common::run(&["paper", "--quick", "--out", out_s]);
    let err = String::from_utf8_lossy(&mixed.stderr);
    assert!(
        !mixed.status.success() && err.contains("rendered by `Gl elsewhere`"),
        "{err}"
    );
    // Nor runs of another checkpoint saved under the same name: a record
    // whose digest is not the file's is refused, naming the file.
    let digest = text
        .lines()
        .find(|l| l.contains("\"sha256\""))
        .expect("a policy's record carries its checkpoint's digest")
        .to_string();
    std::fs::write(&one, text.replace(&digest, "        \"sha256\": \"0000\"")).unwrap();
    let retrained = common::run(&["paper", "--quick", "--out", out_s]);
    let err = String::from_utf8_lossy(&retrained.stderr);
    assert!(
        !retrained.status.success()
            && err.contains("ra.safetensors")
            && err.contains("move the folder aside"),
        "{err}"
    );
    std::fs::write(&one, &text).unwrap();
    // The page says it is not a registered study's; once the folder is registered,
    // a record whose build does not descend from the registering commit is refused
    // (here the commit 000...0, which nothing descends from).
    assert!(page.contains("Not registered: this folder has no `registered.toml`"));
    let rules = "# Registration\nthe rules\n";
    std::fs::write(out.join("registration.md"), rules).unwrap();
    register_at_no_commit(&out, rules);
    let registered = common::run(&["paper", "--quick", "--out", out_s, "--report-only"]);
    let err = String::from_utf8_lossy(&registered.stderr);
    assert!(
        !registered.status.success() && err.contains("registration,"),
        "{err}"
    );
    // And a registration whose rules changed afterwards is refused before anything runs.
    std::fs::write(out.join("registration.md"), "# Registration\nother rules\n").unwrap();
    let changed = common::run(&["paper", "--quick", "--out", out_s]);
    let err = String::from_utf8_lossy(&changed.stderr);
    assert!(
        !changed.status.success() && err.contains("changed after registration"),
        "{err}"
    );
    std::fs::remove_file(out.join("registered.toml")).unwrap();
    // A name that is not an experiment is refused with the list.
    let bad = common::run(&["paper", "--quick", "--out", out_s, "--only", "fig9"]);
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        !bad.status.success() && err.contains("--only fig9") && err.contains("frontier"),
        "{err}"
    );
}

#[test]
fn the_held_out_routes_are_bound_by_the_papers_registration() {
    // A checkout whose docs/paper is registered, with rules changed since: the
    // held-out study (its own folder) is refused too, and registering from it
    // registers the paper's folder, never a second registration.
    let tmp = tempfile::tempdir().unwrap();
    let paper = tmp.path().join("docs/paper");
    std::fs::create_dir_all(&paper).unwrap();
    std::fs::write(
        paper.join("registration.md"),
        "# Registration\nother rules\n",
    )
    .unwrap();
    register_at_no_commit(&paper, "# Registration\nthe rules\n");
    let held_out = tmp.path().join("held-out");
    let out = common::mrdrive()
        .current_dir(tmp.path())
        .args(["paper", "--held-out", "--report-only", "--out"])
        .arg(&held_out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success()
            && err.contains("changed after registration")
            && err.contains("docs/paper/registration.md"),
        "{err}"
    );
    let again = common::mrdrive()
        .current_dir(tmp.path())
        .args(["paper", "--held-out", "--register"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&again.stderr);
    assert!(
        !again.status.success() && err.contains("docs/paper/registered.toml"),
        "{err}"
    );
}

/// Writes `dir/registered.toml` registering `rules` at the commit 000...0,
/// which nothing descends from.
fn register_at_no_commit(dir: &std::path::Path, rules: &str) {
    std::fs::write(
        dir.join("registered.toml"),
        format!(
            "commit = \"{}\"\nsha256 = \"{}\"\n",
            "0".repeat(40),
            sim::record::sha256_hex(rules.as_bytes())
        ),
    )
    .unwrap();
}
