//! Integration tests: CARLA's maps and routes, our generated towns, bad input.

use world::map::generator::{GridTownParams, generate_grid_town};
use world::testdata::{carla_dir, workspace_root};
use world::{
    Command, LoadOptions, PlannerConfig, RouteFile, Town, load_xodr_file, load_xodr_str, plan_route,
};

#[test]
fn carla_towns_load_with_all_their_lights() {
    let Some(dir) = carla_dir("carla_towns_load_with_all_their_lights") else {
        return;
    };
    for (name, lights, junctions) in [("Town01", 36, 12), ("Town02", 24, 8)] {
        let (town, report) =
            load_xodr_file(dir.join(format!("{name}.xodr")), &LoadOptions::default()).unwrap();
        assert_eq!(town.lights.len(), lights, "{name}");
        assert_eq!(town.junctions.len(), junctions, "{name}");
        // Every light belongs to a junction and has a stop line on a lane
        // entering it, at the light's pole (or at the junction's entry where
        // the pole stands beside it), and its lamps face that lane's traffic.
        for l in &town.lights {
            assert!(
                l.junction.is_some(),
                "{name} light {} without junction",
                l.od_id
            );
            assert!(
                !l.stop_lines.is_empty(),
                "{name} light {} without stop line",
                l.od_id
            );
            for sl in &l.stop_lines {
                let lane = town.lane(sl.lane);
                assert!(lane.junction.is_none());
                assert!(
                    lane.successors
                        .iter()
                        .any(|s| town.lane(*s).junction == l.junction),
                    "{name}: stop line not at its junction's entry"
                );
                let setback = lane.length_m() - sl.s;
                assert!(
                    (-1e-3..world::map::opendrive::MAX_POLE_SETBACK_M).contains(&setback),
                    "{name} light {}: stop line {setback} m before the junction",
                    l.od_id
                );
                let driving = glam::Vec2::from_angle(lane.heading_at(sl.s));
                let centre = (sl.ends[0] + sl.ends[1]).truncate() * 0.5;
                let pole_ahead = (l.position.truncate() - centre).dot(driving);
                assert!(
                    setback < 1e-3 || pole_ahead.abs() < 0.05,
                    "{name} light {}: pole {pole_ahead} m from its stop line",
                    l.od_id
                );
                assert!(
                    glam::Vec2::from_angle(l.heading).dot(driving) < -0.99,
                    "{name} light {} faces away from its lane",
                    l.od_id
                );
                // The stop line spans the lane: its ends are a lane width apart.
                let w = sl.ends[0].distance(sl.ends[1]);
                assert!((w - lane.width_at(sl.s)).abs() < 0.05, "{w}");
            }
        }
        // Each junction's lights are in group order with distinct groups.
        for j in &town.junctions {
            let groups: Vec<u32> = j
                .lights
                .iter()
                .map(|l| town.lights[l.0 as usize].group)
                .collect();
            assert!(groups.windows(2).all(|w| w[0] < w[1]), "{name} {groups:?}");
        }
        // The controllers: at most one group of a junction is not red at once,
        // and every light is green at some time in a cycle.
        let mut ctl = world::LightController::new(&town, world::LightTiming::default(), 5);
        let mut was_green = vec![false; town.lights.len()];
        for _ in 0..(60.0 / 0.05) as usize {
            ctl.step(0.05);
            for j in &town.junctions {
                let live = j
                    .lights
                    .iter()
                    .filter(|l| ctl.state(**l) != world::LightState::Red)
                    .map(|l| town.lights[l.0 as usize].group)
                    .collect::<std::collections::BTreeSet<_>>();
                assert!(
                    live.len() <= 1,
                    "{name}: junction {} has groups {live:?} live",
                    j.od_id
                );
            }
            for (i, g) in was_green.iter_mut().enumerate() {
                *g |= ctl.state(world::LightIdx(i as u32)) == world::LightState::Green;
            }
        }
        assert!(
            was_green.iter().all(|g| *g),
            "{name}: a light never turned green in 60 s"
        );
        assert!(town.is_strongly_connected(), "{name}");
        assert!(report.roads > 0 && town.lanes.len() > 50);
        assert!(
            town.markings
                .iter()
                .any(|m| m.kind == world::MarkKind::Broken && m.color == world::MarkColor::Yellow)
        );
        assert!(
            !town.sidewalks.is_empty()
                && !town.crosswalks.is_empty()
                && !town.road_surface.indices.is_empty()
        );
        // Centrelines are ~1 m apart.
        for l in &town.lanes {
            for w in l.centerline.windows(2) {
                assert!(w[0].distance(w[1]) < 1.3);
            }
        }
    }
}

#[test]
fn paper_routes_plan_continuously() {
    let Some(dir) = carla_dir("paper_routes_plan_continuously") else {
        return;
    };
    for (map, routes) in [
        ("Town01.xodr", "routes_town01.xml"),
        ("Town02.xodr", "routes_town02.xml"),
    ] {
        let town = Town::from_xodr_file(dir.join(map)).unwrap();
        let file = RouteFile::load(dir.join(routes)).unwrap();
        for id in ["0", "1"] {
            let r = file.route(id).unwrap();
            let d = plan_route(&town, r, &PlannerConfig::default()).unwrap();
            println!(
                "{map} route {id}: {} waypoints, {} points, {:.1} m, {:?}",
                r.waypoints.len(),
                d.points.len(),
                d.length_m,
                d.command_counts()
            );
            assert!(d.max_gap_m() <= 1.5, "{map} {id}: gap {}", d.max_gap_m());
            assert!(d.length_m > 300.0);
            assert!(d.points.iter().any(|p| matches!(
                p.command,
                Command::Left | Command::Right | Command::Straight
            )));
            // Each waypoint lies within 1 m of its dense point.
            for (w, &i) in r.waypoints.iter().zip(&d.waypoint_points) {
                assert!(
                    w.position
                        .truncate()
                        .distance(d.points[i].position.truncate())
                        < 1.0,
                    "{map} {id}"
                );
            }
        }
    }
}

fn generated(name: &str) -> (GridTownParams, String) {
    let p = if name == "gen01" {
        GridTownParams::gen01()
    } else {
        GridTownParams::gen02()
    };
    let xml = generate_grid_town(&p).unwrap();
    (p, xml)
}

#[test]
fn shipped_generated_towns_are_reproducible_clean_and_connected() {
    for name in ["gen01", "gen02"] {
        let (_, xml) = generated(name);
        let path = workspace_root().join("maps").join(format!("{name}.xodr"));
        let shipped = std::fs::read_to_string(&path).unwrap();
        assert!(
            shipped == xml,
            "{} differs from the generator's output; regenerate with `mrdrive map generate`",
            path.display()
        );
        let (town, report) = load_xodr_file(&path, &LoadOptions::default()).unwrap();
        assert!(report.warnings.is_empty(), "{name}: {:#?}", report.warnings);
        assert!(town.is_strongly_connected(), "{name}");
        assert!(!town.lights.is_empty() && !town.buildings.is_empty());
        // Both 4-way and T junctions.
        let arms = |j: usize| {
            town.lanes
                .iter()
                .filter(|l| {
                    l.junction.is_none()
                        && l.successors
                            .iter()
                            .any(|s| town.lane(*s).junction == Some(world::JunctionIdx(j as u32)))
                })
                .count()
        };
        let counts: Vec<usize> = (0..town.junctions.len()).map(arms).collect();
        assert!(
            counts.contains(&4) && counts.contains(&3),
            "{name}: {counts:?}"
        );
        let routes =
            RouteFile::load(workspace_root().join("routes").join(format!("{name}.toml"))).unwrap();
        let mut seen = std::collections::BTreeSet::new();
        for r in &routes.routes {
            let d = plan_route(&town, r, &PlannerConfig::default()).unwrap();
            assert!(d.max_gap_m() <= 1.5);
            for p in &d.points {
                seen.insert(format!("{:?}", p.command));
            }
        }
        assert!(
            seen.contains("Left") && seen.contains("Right") && seen.contains("Straight"),
            "{name}: {seen:?}"
        );
    }
}

#[test]
fn bad_maps_get_errors_naming_file_and_problem() {
    let dir = tempfile::tempdir().unwrap();
    let (_, good) = generated("gen02");
    let cases: Vec<(&str, String, &str)> = vec![
        ("truncated.xodr", good[..good.len() / 2].to_string(), "XML"),
        (
            "malformed.xodr",
            "<OpenDRIVE><header/><road id=\"1\" length=\"10\"><planView></OpenDRIVE>".into(),
            "XML",
        ),
        (
            "notodr.xodr",
            "<html><body>hello</body></html>".into(),
            "OpenDRIVE",
        ),
        ("empty.xodr", String::new(), "OpenDRIVE"),
        (
            "nan.xodr",
            good.replacen(
                "<geometry s=\"0\" x=\"",
                "<geometry s=\"0\" x=\"NaN\" data-x=\"",
                1,
            ),
            "finite",
        ),
        (
            "huge.xodr",
            good.replacen(
                "<geometry s=\"0\" x=\"",
                "<geometry s=\"0\" x=\"1e30\" data-x=\"",
                1,
            ),
            "finite",
        ),
    ];
    for (file, text, needle) in cases {
        let path = dir.path().join(file);
        std::fs::write(&path, &text).unwrap();
        let e = load_xodr_file(&path, &LoadOptions::default())
            .map(|_| ())
            .unwrap_err()
            .to_string();
        assert!(e.contains(file), "{file}: {e}");
        assert!(e.contains(needle), "{file}: {e}");
        assert!(e.contains("Fix:"), "{file}: {e}");
    }
    let binary: Vec<u8> = (0..=255u8).cycle().take(4096).collect();
    let path = dir.path().join("binary.xodr");
    std::fs::write(&path, &binary).unwrap();
    let e = load_xodr_file(&path, &LoadOptions::default())
        .map(|_| ())
        .unwrap_err()
        .to_string();
    assert!(e.contains("binary.xodr"), "{e}");
    let e = load_xodr_file(dir.path().join("missing.xodr"), &LoadOptions::default())
        .map(|_| ())
        .unwrap_err()
        .to_string();
    assert!(e.contains("missing.xodr"), "{e}");
}

#[test]
fn negative_lengths_are_rejected() {
    let (_, good) = generated("gen02");
    // The first street's length (road and geometry) made negative.
    let bad = good.replacen("length=\"47.000000\"", "length=\"-47.000000\"", 2);
    assert_ne!(bad, good);
    let e = load_xodr_str(&bad, "neg", &LoadOptions::default())
        .map(|_| ())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("<neg>") && (e.contains("length") || e.contains("not a usable")),
        "{e}"
    );
}

#[test]
fn bad_routes_get_errors_naming_file_and_problem() {
    let town = load_xodr_str(&generated("gen02").1, "gen02", &LoadOptions::default())
        .unwrap()
        .0;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("off.toml");
    std::fs::write(&path, "[[route]]\nid = \"a\"\nwaypoints = [[20.0, 65.25], [30.0, 30.0]]\n[[route]]\nid = \"b\"\nwaypoints = [[20.0, 65.25], [40.0, 65.25]]\n").unwrap();
    let file = RouteFile::load(&path).unwrap();
    let e = plan_route(&town, file.route("a").unwrap(), &PlannerConfig::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("off.toml")
            && e.contains("waypoint 1")
            && e.contains("m from the nearest driving lane"),
        "{e}"
    );
    let e = file.route("zz").unwrap_err().to_string();
    assert!(
        e.contains("off.toml") && e.contains("\"zz\"") && e.contains("a, b"),
        "{e}"
    );
    assert!(plan_route(&town, file.route("b").unwrap(), &PlannerConfig::default()).is_ok());
}

#[test]
fn unsignalled_maps_get_lights_only_when_asked() {
    let (_, good) = generated("gen02");
    // Strip every signal and controller.
    let mut stripped = String::new();
    let mut skip = false;
    for line in good.lines() {
        let t = line.trim_start();
        if t.starts_with("<signal ") || (t.starts_with("<controller ") && t.ends_with("/>")) {
            continue;
        }
        if t.starts_with("<controller ") {
            skip = true;
        }
        if !skip {
            stripped.push_str(line);
            stripped.push('\n');
        }
        if t.starts_with("</controller>") {
            skip = false;
        }
    }
    let stripped = stripped.replace("        <signals>\n        </signals>\n", "");
    let (none, _) = load_xodr_str(&stripped, "bare", &LoadOptions::default()).unwrap();
    assert!(none.lights.is_empty());
    let opts = LoadOptions {
        unsignalled: world::UnsignalledJunctions::GenerateLights,
    };
    let (lit, report) = load_xodr_str(&stripped, "bare", &opts).unwrap();
    let (orig, _) = load_xodr_str(&good, "orig", &LoadOptions::default()).unwrap();
    assert!(report.generated_lights);
    assert_eq!(
        lit.lights.len(),
        orig.lights.len(),
        "one per approach at every junction with 3+ arms"
    );
    assert!(lit.lights.iter().all(|l| l.stop_lines.len() == 1));
}
