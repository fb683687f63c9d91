//! The loader's parts, each on a map small enough to know the answer: one
//! straight road written by hand (three driving lanes, a sidewalk, three
//! road marks, a traffic light, a building, a crosswalk), a generated grid
//! town for what needs junctions, and broken files for the errors.

use glam::Vec2;

use super::*;
use crate::map::generator::{GridTownParams, generate_grid_town};
use crate::map::{LightIdx, MapError, MarkColor, MarkKind};
use crate::road::geometry::{point_in_polygon, signed_area};

/// One road along +x from (0, 0), 100 m long, 50 km/h: lane 1 (driving,
/// against +x), lanes -1 and -2 (driving, along +x), 3.5 m each; a broken
/// yellow centre line, a broken white line between -1 and -2, a solid white
/// line on lane -2's outer edge; sidewalk -3 (3 m, 0.2 m high). A traffic
/// light for the +x traffic at s = 90, a building at (50, -15)
/// (10 m x 8 m x 12 m) and a crosswalk across lanes -1 and -2 at s = 50
/// (4 m x 7 m). `@WIDTH@` is lane -1's width.
const ROAD: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<OpenDRIVE>
    <header revMajor="1" revMinor="4" name="tiny" version="1"/>
    <road name="main" length="100" id="1" junction="-1">
        <type s="0" type="town"><speed max="50" unit="km/h"/></type>
        <planView>
            <geometry s="0" x="0" y="0" hdg="0" length="100"><line/></geometry>
        </planView>
        <lanes>
            <laneSection s="0">
                <left>
                    <lane id="1" type="driving" level="false">
                        <width sOffset="0" a="3.5" b="0" c="0" d="0"/>
                    </lane>
                </left>
                <center>
                    <lane id="0" type="none" level="false">
                        <roadMark sOffset="0" type="broken" weight="standard" color="yellow" width="0.15"/>
                    </lane>
                </center>
                <right>
                    <lane id="-1" type="driving" level="false">
                        <width sOffset="0" a="@WIDTH@" b="0" c="0" d="0"/>
                        <roadMark sOffset="0" type="broken" weight="standard" color="white" width="0.15"/>
                    </lane>
                    <lane id="-2" type="driving" level="false">
                        <width sOffset="0" a="3.5" b="0" c="0" d="0"/>
                        <roadMark sOffset="0" type="solid" weight="standard" color="white" width="0.15"/>
                    </lane>
                    <lane id="-3" type="sidewalk" level="false">
                        <width sOffset="0" a="3" b="0" c="0" d="0"/>
                        <height sOffset="0" inner="0.2" outer="0.2"/>
                    </lane>
                </right>
            </laneSection>
        </lanes>
        <objects>
            <object type="building" name="building" id="b1" s="50" t="-15" zOffset="0" orientation="none" length="10" width="8" height="12" hdg="0" pitch="0" roll="0"/>
            <object type="crosswalk" name="crosswalk" id="c1" s="50" t="-3.5" zOffset="0" orientation="none" length="4" width="7" height="0" hdg="0" pitch="0" roll="0"/>
        </objects>
        <signals>
            <signal s="90" t="-5" id="5000" name="TrafficLight" dynamic="yes" orientation="+" zOffset="0" country="OpenDRIVE" type="1000001" subtype="-1" value="-1" hOffset="3.141593" pitch="0" roll="0" height="3.0" width="0.5"/>
        </signals>
    </road>
</OpenDRIVE>
"#;

fn road_xml(width: &str) -> String {
    ROAD.replace("@WIDTH@", width)
}

fn road() -> (Town, LoadReport) {
    load_xodr_str(&road_xml("3.5"), "tiny", &LoadOptions::default()).unwrap()
}

fn close(a: Vec2, b: Vec2) -> bool {
    (a - b).length() < 1e-3
}

/// The lane whose OpenDRIVE id is `od`.
fn lane_od(town: &Town, od: i32) -> LaneIdx {
    LaneIdx(town.lanes.iter().position(|l| l.od_lane == od).unwrap() as u32)
}

#[test]
fn the_report_counts_what_the_file_holds() {
    let (town, report) = road();
    assert_eq!(town.name, "tiny");
    assert_eq!((report.roads, report.signals), (1, 1));
    // Lanes of every type: two driving lanes, the sidewalk and the centre lane's none.
    assert!(report.lanes >= 3, "{report:?}");
    assert!(!report.generated_lights);
    assert_eq!(report.file, PathBuf::from("<tiny>"));
    // `mrdrive map info`'s text: a line a figure, the counts above.
    let text = report.summary(&town, 1.5);
    assert!(
        text.starts_with("map: <tiny>\ntown: tiny\nroads: 1\n"),
        "{text}"
    );
    assert!(
        text.contains("\ndrivable lanes: 3 (0 in junctions)\n"),
        "{text}"
    );
    assert!(text.contains("\nload time: 1.5 ms\n"), "{text}");
}

#[test]
fn driving_lanes_run_their_way_with_width_speed_and_neighbours() {
    let (town, _) = road();
    assert_eq!(town.lanes.len(), 3, "the sidewalk is not a driving lane");
    let (inner, outer, back) = (lane_od(&town, -1), lane_od(&town, -2), lane_od(&town, 1));
    let f = town.lane(inner);
    // Along +x on the right of the reference line, resampled a metre apart.
    assert!(close(f.centerline[0].truncate(), Vec2::new(0.0, -1.75)));
    let last = f.centerline.len() - 1;
    assert!(close(
        f.centerline[last].truncate(),
        Vec2::new(100.0, -1.75)
    ));
    assert_eq!(last, (100.0 / CENTERLINE_SPACING_M) as usize);
    assert!((f.s[last] - 100.0).abs() < 1e-3);
    assert!(f.width.iter().all(|w| (w - 3.5).abs() < 1e-4));
    assert!((f.speed_limit_mps - 50.0 / 3.6).abs() < 1e-4);
    assert_eq!((f.road_id.as_str(), f.junction), ("1", None));
    assert!(close(
        town.lane(outer).centerline[0].truncate(),
        Vec2::new(0.0, -5.25)
    ));
    // Lane 1 drives against the reference line: it starts at x = 100.
    let b = town.lane(back);
    assert!(close(b.centerline[0].truncate(), Vec2::new(100.0, 1.75)));
    // Neighbours are the lanes one may change into, seen in the driving
    // direction: -2 is right of -1; lane 1 runs the other way, so it is
    // nobody's neighbour.
    assert_eq!((f.left, f.right), (None, Some(outer)));
    assert_eq!(
        (town.lane(outer).left, town.lane(outer).right),
        (Some(inner), None)
    );
    assert_eq!((b.left, b.right), (None, None));
}

#[test]
fn a_lane_without_a_speed_limit_gets_the_default() {
    let xml = road_xml("3.5").replace(r#"<speed max="50" unit="km/h"/>"#, "");
    let (town, _) = load_xodr_str(&xml, "tiny", &LoadOptions::default()).unwrap();
    assert!(
        town.lanes
            .iter()
            .all(|l| l.speed_limit_mps == DEFAULT_SPEED_LIMIT_MPS)
    );
}

#[test]
fn road_marks_follow_the_lane_edges_with_their_kind_and_colour() {
    let (town, _) = road();
    assert_eq!(town.markings.len(), 3, "{:?}", town.markings);
    // (kind, colour, dash pattern, y of the line)
    let expected = [
        (MarkKind::Broken, MarkColor::Yellow, Some((4.0, 8.0)), 0.0),
        (MarkKind::Broken, MarkColor::White, Some((4.0, 8.0)), -3.5),
        (MarkKind::Solid, MarkColor::White, None, -7.0),
    ];
    for (kind, color, dash, y) in expected {
        let m = town
            .markings
            .iter()
            .find(|m| m.kind == kind && m.color == color)
            .unwrap_or_else(|| panic!("no {kind:?} {color:?} line"));
        // No dash pattern in the file: the importer paints `broken` 4 m on, 8 m off.
        assert_eq!(m.dash_m, dash);
        assert!(
            m.points.iter().all(|p| (p.y - y).abs() < 1e-3),
            "{kind:?} {color:?}"
        );
        let (lo, hi) = m.points.iter().fold((f32::MAX, f32::MIN), |(lo, hi), p| {
            (lo.min(p.x), hi.max(p.x))
        });
        assert!(lo.abs() < 1e-3 && (hi - 100.0).abs() < 1e-3, "{lo}..{hi}");
        assert!((m.width_m - 0.15).abs() < 1e-6);
    }
}

#[test]
fn the_sidewalk_has_its_road_side_edge_inside_and_its_height() {
    let (town, _) = road();
    assert_eq!(town.sidewalks.len(), 1);
    let s = &town.sidewalks[0];
    assert!(
        s.inner.iter().all(|p| (p.y + 7.0).abs() < 1e-3),
        "{:?}",
        s.inner
    );
    assert!(
        s.outer.iter().all(|p| (p.y + 10.0).abs() < 1e-3),
        "{:?}",
        s.outer
    );
    assert!((s.height_m - 0.2).abs() < 1e-6);
    // Without a <height> record: the default.
    let xml = road_xml("3.5").replace(r#"<height sOffset="0" inner="0.2" outer="0.2"/>"#, "");
    let (town, _) = load_xodr_str(&xml, "tiny", &LoadOptions::default()).unwrap();
    assert_eq!(town.sidewalks[0].height_m, DEFAULT_SIDEWALK_HEIGHT_M);
}

#[test]
fn a_signal_stops_its_lanes_traffic_at_the_lane_end() {
    let (town, _) = road();
    assert_eq!(town.lights.len(), 1);
    let light = &town.lights[0];
    assert_eq!(light.od_id, "5000");
    assert_eq!((light.junction, light.group), (None, 0));
    assert_eq!(light.head_height_m, DEFAULT_LIGHT_HEAD_HEIGHT_M);
    // It stands where the file puts it: s = 90, t = -5.
    assert!(close(light.position.truncate(), Vec2::new(90.0, -5.0)));
    // Orientation "+": it stops the +x traffic (lanes -1 and -2), not lane
    // 1. The lanes lead into no junction, so each stop line is at its
    // lane's end, across its width.
    let mut lines: Vec<_> = light.stop_lines.iter().collect();
    let want = [
        (lane_od(&town, -1), 0.0, -3.5),
        (lane_od(&town, -2), -3.5, -7.0),
    ];
    assert_eq!(lines.len(), want.len());
    lines.sort_by_key(|sl| want.iter().position(|w| w.0 == sl.lane));
    for (sl, (lane, y_left, y_right)) in lines.iter().zip(want) {
        assert_eq!(sl.lane, lane);
        assert!((sl.s - town.lane(lane).length_m()).abs() < 1e-3);
        let mut ends = [sl.ends[0].truncate(), sl.ends[1].truncate()];
        ends.sort_by(|a, b| b.y.total_cmp(&a.y));
        assert!(close(ends[0], Vec2::new(100.0, y_left)), "{ends:?}");
        assert!(close(ends[1], Vec2::new(100.0, y_right)), "{ends:?}");
    }
}

#[test]
fn a_pole_before_the_lane_end_carries_the_stop_line_and_lamps_face_the_traffic() {
    // The same light 5 m before the end of its lanes: the lines move to the
    // pole, so a car waiting at them still has the light in view.
    let signal = r#"<signal s="90" t="-5""#;
    let xml = road_xml("3.5").replace(signal, r#"<signal s="95" t="-5""#);
    let (town, _) = load_xodr_str(&xml, "tiny", &LoadOptions::default()).unwrap();
    let light = &town.lights[0];
    assert_eq!(light.stop_lines.len(), 2);
    for sl in &light.stop_lines {
        assert!((sl.s - (town.lane(sl.lane).length_m() - 5.0)).abs() < 1e-3);
        assert!(
            sl.ends.iter().all(|e| (e.x - 95.0).abs() < 1e-3),
            "{:?}",
            sl.ends
        );
    }
    // The lamps face the traffic of the lanes they stop, whatever
    // orientation and hOffset say (CARLA's "-" signals would otherwise turn
    // their backs on it): "+" stops the +x lanes, "-" the -x lane.
    for (orientation, h_offset) in [("+", "3.141593"), ("+", "0"), ("-", "0")] {
        let xml = road_xml("3.5")
            .replace(
                r#"orientation="+""#,
                &format!(r#"orientation="{orientation}""#),
            )
            .replace(r#"hOffset="3.141593""#, &format!(r#"hOffset="{h_offset}""#));
        let (town, _) = load_xodr_str(&xml, "tiny", &LoadOptions::default()).unwrap();
        let light = &town.lights[0];
        let facing = Vec2::from_angle(light.heading);
        assert!(!light.stop_lines.is_empty());
        for sl in &light.stop_lines {
            let driving = Vec2::from_angle(town.lane(sl.lane).heading_at(sl.s));
            let want = if orientation == "+" { 1.0 } else { -1.0 };
            assert!(
                (driving.x - want).abs() < 1e-3,
                "{orientation}: {driving:?}"
            );
            assert!(
                facing.dot(driving) < -0.999,
                "{orientation} {h_offset}: {facing:?}"
            );
        }
    }
}

#[test]
fn unsignalled_junctions_get_one_light_per_approach_only_when_asked() {
    let p = GridTownParams {
        name: "g".into(),
        blocks_x: 2,
        blocks_y: 2,
        block_size_m: 60.0,
        seed: 3,
        features: Default::default(),
    };
    // The generator's lights, taken out: signals become plain road.
    let xml = generate_grid_town(&p).unwrap();
    let unlit = xml.replace(r#"dynamic="yes""#, r#"dynamic="no""#);
    let (plain, report) = load_xodr_str(&unlit, "g", &LoadOptions::default()).unwrap();
    assert!(plain.lights.is_empty() && !report.generated_lights);
    let opts = LoadOptions {
        unsignalled: UnsignalledJunctions::GenerateLights,
    };
    let (lit, report) = load_xodr_str(&unlit, "g", &opts).unwrap();
    assert!(report.generated_lights);
    assert!(!lit.lights.is_empty());
    // A generated light stays yellow as long as its fastest approach needs; a map's own
    // lights keep the controller's timing.
    for j in lit.junctions.iter().filter(|j| !j.lights.is_empty()) {
        let fastest = lit
            .lights
            .iter()
            .filter(|l| {
                j.lights
                    .iter()
                    .any(|i| lit.lights[i.0 as usize].od_id == l.od_id)
            })
            .flat_map(|l| &l.stop_lines)
            .map(|sl| lit.lanes[sl.lane.0 as usize].speed_limit_mps)
            .fold(0.0_f32, f32::max);
        assert!(fastest > 0.0);
        assert_eq!(
            j.yellow_s,
            Some(crate::rules::change_interval_s(fastest)),
            "{}",
            j.od_id
        );
    }
    assert!(lit.junctions.iter().any(|j| j.yellow_s.is_some()));
    // `map info` says where the lights came from.
    let n = lit.lights.len();
    assert!(
        report.summary(&lit, 0.0).contains(&format!(
            "traffic lights: {n} (0 from the map, {n} generated"
        )),
        "{}",
        report.summary(&lit, 0.0)
    );
    let (own, report) = load_xodr_str(&xml, "g", &opts).unwrap();
    assert!(own.junctions.iter().all(|j| j.yellow_s.is_none()));
    let n = own.lights.len();
    assert!(
        !report.generated_lights
            && report.summary(&own, 0.0).contains(&format!(
                "traffic lights: {n} ({n} from the map, 0 generated)"
            ))
    );
    for (i, l) in lit.lights.iter().enumerate() {
        // Each junction lists its lights, one group per approach road.
        let j = l.junction.expect("a generated light belongs to a junction");
        let listed = &lit.junctions[j.0 as usize].lights;
        assert!(listed.contains(&LightIdx(i as u32)));
        let groups: Vec<u32> = listed
            .iter()
            .map(|k| lit.lights[k.0 as usize].group)
            .collect();
        assert_eq!(groups, (0..listed.len() as u32).collect::<Vec<_>>());
        assert!(listed.len() >= 3, "only junctions with 3+ approaches");
        assert!(!l.stop_lines.is_empty());
    }
}

#[test]
fn generated_lights_leave_a_road_inside_one_box_unlit() {
    // Town04's road 2 runs 5.3 m from junction 317 into junction 386 (and back): a
    // car waiting at a light at its end stood in the first junction. Generated
    // lights leave both its ends unlit and light every road that is longer.
    let Some(dir) =
        crate::testdata::carla_dir("generated_lights_leave_a_road_inside_one_box_unlit")
    else {
        return;
    };
    let opts = LoadOptions {
        unsignalled: UnsignalledJunctions::GenerateLights,
    };
    let (town, _) = load_xodr_file(dir.join("Town04.xodr"), &opts).unwrap();
    let lit_roads: Vec<&str> = town
        .lights
        .iter()
        .flat_map(|l| &l.stop_lines)
        .map(|sl| town.lanes[sl.lane.0 as usize].road_id.as_str())
        .collect();
    assert!(!lit_roads.contains(&"2"), "{lit_roads:?}");
    assert!(lit_roads.contains(&"1"), "{lit_roads:?}");
    let road2: Vec<&crate::map::DriveLane> =
        town.lanes.iter().filter(|l| l.road_id == "2").collect();
    assert_eq!(road2.len(), 2);
    for l in road2 {
        assert!(l.length_m() < BOX_LINK_M, "{}", l.length_m());
        let into = l
            .successors
            .iter()
            .find_map(|s| town.lanes[s.0 as usize].junction);
        let from = l
            .predecessors
            .iter()
            .find_map(|p| town.lanes[p.0 as usize].junction);
        assert!(into.is_some() && from.is_some() && into != from);
        // The junction it leads into keeps its lights on its other roads.
        assert!(town.lights.iter().any(|x| x.junction == into), "{into:?}");
    }
    // Every lit road is at least `BOX_LINK_M` long or comes from no junction.
    for light in &town.lights {
        for sl in &light.stop_lines {
            let lane = &town.lanes[sl.lane.0 as usize];
            let from_junction = lane
                .predecessors
                .iter()
                .any(|p| town.lanes[p.0 as usize].junction.is_some());
            assert!(
                !from_junction || lane.length_m() >= BOX_LINK_M,
                "road {}",
                lane.road_id
            );
        }
    }
}

#[test]
fn buildings_and_the_maps_crosswalk_come_from_its_objects() {
    let (town, _) = road();
    assert_eq!(town.buildings.len(), 1);
    let b = &town.buildings[0];
    assert_eq!(b.height_m, 12.0);
    assert_eq!(b.footprint.len(), 4);
    assert!(signed_area(&b.footprint) > 0.0, "counter-clockwise");
    assert!((signed_area(&b.footprint) - 80.0).abs() < 1e-2);
    assert!(point_in_polygon(&b.footprint, Vec2::new(50.0, -15.0)));
    // The map's crosswalk is kept as it is, and none is generated.
    assert_eq!(town.crosswalks.len(), 1);
    let c = &town.crosswalks[0];
    assert!(c.from_map);
    let corners: Vec<Vec2> = c.corners.iter().map(|p| p.truncate()).collect();
    assert!((signed_area(&corners) - 28.0).abs() < 1e-2);
    assert!(point_in_polygon(&corners, Vec2::new(50.0, -3.5)));
}

#[test]
fn a_map_without_crosswalks_gets_one_at_each_junction_approach() {
    let p = GridTownParams {
        name: "g".into(),
        blocks_x: 2,
        blocks_y: 2,
        block_size_m: 60.0,
        seed: 3,
        features: Default::default(),
    };
    let xml = generate_grid_town(&p).unwrap();
    let (town, _) = load_xodr_str(&xml, "g", &LoadOptions::default()).unwrap();
    assert!(!town.crosswalks.is_empty());
    for c in &town.crosswalks {
        assert!(!c.from_map);
        let k: Vec<Vec2> = c.corners.iter().map(|p| p.truncate()).collect();
        // Depth along the road, width across both 3.5 m lanes.
        let (d1, d2) = ((k[1] - k[0]).length(), (k[2] - k[1]).length());
        let (depth, width) = (d1.min(d2), d1.max(d2));
        assert!((depth - CROSSWALK_DEPTH_M).abs() < 1e-3, "{k:?}");
        assert!((width - 7.0).abs() < 1e-2, "{k:?}");
        // Set back from the junction: its near edge is CROSSWALK_SETBACK_M
        // from the end of the lane that enters it.
        let gap = town
            .lanes
            .iter()
            .filter(|l| l.junction.is_none())
            .flat_map(|l| {
                [
                    l.centerline[0].truncate(),
                    l.centerline[l.centerline.len() - 1].truncate(),
                ]
            })
            .map(|e| {
                k.iter()
                    .zip(k.iter().cycle().skip(1))
                    .map(|(a, b)| crate::road::geometry::segment_point_distance(*a, *b, e))
                    .fold(f32::MAX, f32::min)
            })
            .fold(f32::MAX, f32::min);
        assert!((gap - CROSSWALK_SETBACK_M).abs() < 1e-2, "{gap}");
    }
}

#[test]
fn junction_outlines_hold_their_connecting_lanes() {
    let p = GridTownParams {
        name: "g".into(),
        blocks_x: 2,
        blocks_y: 2,
        block_size_m: 60.0,
        seed: 3,
        features: Default::default(),
    };
    let xml = generate_grid_town(&p).unwrap();
    let (town, _) = load_xodr_str(&xml, "g", &LoadOptions::default()).unwrap();
    assert!(!town.junctions.is_empty());
    for l in town.lanes.iter().filter(|l| l.junction.is_some()) {
        let outline = &town.junctions[l.junction.unwrap().0 as usize].outline;
        assert!(outline.len() >= 3);
        let mid = l.centerline[l.centerline.len() / 2].truncate();
        assert!(point_in_polygon(outline, mid), "{mid} outside {outline:?}");
    }
}

#[test]
fn the_surface_covers_the_driving_lanes_and_the_bounds_every_lane() {
    let (town, _) = road();
    let m = &town.road_surface;
    assert!(!m.indices.is_empty() && m.indices.len() % 3 == 0);
    let mut area = 0.0;
    for t in m.indices.chunks_exact(3) {
        let [a, b, c] = [0, 1, 2].map(|k| m.positions[t[k] as usize].truncate());
        let twice = (b - a).perp_dot(c - a);
        assert!(twice >= 0.0, "a triangle is wound clockwise");
        area += 0.5 * twice;
    }
    // Three 3.5 m lanes, 100 m long; the sidewalk is not road surface.
    assert!((area - 1050.0).abs() < 1.0, "{area} m^2");
    // Each lane's centre points, padded by half its width (the sidewalk's
    // centre is at y = -8.5, 3 m wide).
    let (lo, hi) = town.bounds;
    assert!(close(lo, Vec2::new(-1.75, -10.0)), "{lo}");
    assert!(close(hi, Vec2::new(101.75, 3.5)), "{hi}");
}

#[test]
fn a_lane_width_out_of_range_names_the_road_the_lane_and_the_record() {
    let err = load_xodr_str(&road_xml("150"), "tiny", &LoadOptions::default()).unwrap_err();
    let MapError::Invalid {
        file,
        what,
        location,
        fix,
    } = &err
    else {
        panic!("{err}");
    };
    assert_eq!(file, &PathBuf::from("<tiny>"));
    assert!(what.contains("lane width 150"), "{what}");
    assert_eq!(location, r#"road id="1" lane id="-1""#);
    assert!(fix.contains("<width>"), "{fix}");
}

#[test]
fn an_unreadable_width_is_an_error_not_a_lane_dropped() {
    // The importer drops the <width> (its `a` is not a number) and with it
    // the lane; the loader must not hand out a town without that lane.
    let err = load_xodr_str(&road_xml("nan"), "tiny", &LoadOptions::default()).unwrap_err();
    let MapError::Invalid { what, location, .. } = &err else {
        panic!("{err}");
    };
    assert!(what.contains("width"), "{what}");
    assert!(
        location.starts_with(r#"road id="1" lane id="-1""#),
        "{location}"
    );
}

#[test]
fn a_cut_short_or_foreign_file_is_refused_with_the_fix() {
    let xml = road_xml("3.5");
    let cut = &xml[..xml.find("<objects>").unwrap()];
    let err = load_xodr_str(cut, "cut", &LoadOptions::default()).unwrap_err();
    let text = err.to_string();
    assert!(matches!(err, MapError::Import { .. }), "{text}");
    assert!(text.contains("line") && text.contains("column"), "{text}");
    assert!(text.contains("copy the file again"), "{text}");
    let err = load_xodr_str("<html></html>", "page", &LoadOptions::default()).unwrap_err();
    assert!(
        err.to_string().contains("no <OpenDRIVE> root element"),
        "{err}"
    );
}

#[test]
fn a_missing_file_names_its_path() {
    let path = std::env::temp_dir().join("mrdrive-no-such-map.xodr");
    let err = load_xodr_file(&path, &LoadOptions::default()).unwrap_err();
    assert!(matches!(err, MapError::Read { .. }));
    assert!(
        err.to_string().contains("mrdrive-no-such-map.xodr"),
        "{err}"
    );
}

/// Two roads along +x, 0-100 m and 120-220 m, each with one driving lane a
/// way, both linked to junction 9 at the gap; `@CONNECTING@` is what fills
/// the gap (the junction's connecting road), `@CONNECTIONS@` the junction's
/// `<connection>`s.
const TWO_ROADS_AND_A_JUNCTION: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<OpenDRIVE>
    <header revMajor="1" revMinor="4" name="gap" version="1"/>
    <road name="west" length="100" id="1" junction="-1">
        <link><successor elementType="junction" elementId="9"/></link>
        <planView><geometry s="0" x="0" y="0" hdg="0" length="100"><line/></geometry></planView>
        <lanes><laneSection s="0">
            <left><lane id="1" type="driving" level="false"><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane></left>
            <center><lane id="0" type="none" level="false"/></center>
            <right><lane id="-1" type="driving" level="false"><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane></right>
        </laneSection></lanes>
    </road>
    <road name="east" length="100" id="2" junction="-1">
        <link><predecessor elementType="junction" elementId="9"/></link>
        <planView><geometry s="0" x="120" y="0" hdg="0" length="100"><line/></geometry></planView>
        <lanes><laneSection s="0">
            <left><lane id="1" type="driving" level="false"><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane></left>
            <center><lane id="0" type="none" level="false"/></center>
            <right><lane id="-1" type="driving" level="false"><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane></right>
        </laneSection></lanes>
    </road>
    @CONNECTING@
    <junction id="9" name="gap">@CONNECTIONS@</junction>
</OpenDRIVE>
"#;

const CONNECTING_ROAD: &str = r#"<road name="through" length="20" id="3" junction="9">
        <link>
            <predecessor elementType="road" elementId="1" contactPoint="end"/>
            <successor elementType="road" elementId="2" contactPoint="start"/>
        </link>
        <planView><geometry s="0" x="100" y="0" hdg="0" length="20"><line/></geometry></planView>
        <lanes><laneSection s="0">
            <left><lane id="1" type="driving" level="false"><width sOffset="0" a="3.5" b="0" c="0" d="0"/>
                <link><predecessor id="1"/><successor id="1"/></link></lane></left>
            <center><lane id="0" type="none" level="false"/></center>
            <right><lane id="-1" type="driving" level="false"><width sOffset="0" a="3.5" b="0" c="0" d="0"/>
                <link><predecessor id="-1"/><successor id="-1"/></link></lane></right>
        </laneSection></lanes>
    </road>"#;

const CONNECTIONS: &str = r#"
        <connection id="0" incomingRoad="1" connectingRoad="3" contactPoint="start"><laneLink from="-1" to="-1"/></connection>
        <connection id="1" incomingRoad="2" connectingRoad="3" contactPoint="end"><laneLink from="1" to="1"/></connection>
    "#;

#[test]
fn a_junction_without_connecting_lanes_is_refused_with_its_id_and_the_fix() {
    // Junction 9 is declared and both roads lead into it, but nothing
    // connects them: no lane into it could go on, and traffic would pile up
    // at the lane ends.
    let bad = TWO_ROADS_AND_A_JUNCTION
        .replace("@CONNECTING@", "")
        .replace("@CONNECTIONS@", "");
    let err = load_xodr_str(&bad, "gap", &LoadOptions::default()).unwrap_err();
    let MapError::Invalid {
        what,
        location,
        fix,
        ..
    } = &err
    else {
        panic!("{err}");
    };
    assert_eq!(location, r#"junction id="9""#);
    assert!(
        what.contains("junction 9 has no connecting driving lane"),
        "{what}"
    );
    assert!(what.contains("road 1, road 2"), "{what}");
    assert!(
        fix.contains("<connection") && fix.contains("<laneLink"),
        "{fix}"
    );
    // A road that links to a junction the file never declares: the same.
    let undeclared = bad.replace(r#"<junction id="9" name="gap"></junction>"#, "");
    let err = load_xodr_str(&undeclared, "gap", &LoadOptions::default()).unwrap_err();
    assert!(
        err.to_string().contains("junction 9 is not declared"),
        "{err}"
    );
    // With its connecting road and connections it loads, and the lanes go through.
    let good = TWO_ROADS_AND_A_JUNCTION
        .replace("@CONNECTING@", CONNECTING_ROAD)
        .replace("@CONNECTIONS@", CONNECTIONS);
    let (town, _) = load_xodr_str(&good, "gap", &LoadOptions::default()).unwrap();
    let through: Vec<&crate::map::DriveLane> =
        town.lanes.iter().filter(|l| l.junction.is_some()).collect();
    assert_eq!(through.len(), 2);
    for l in &town.lanes {
        let end_x = l.centerline.last().unwrap().x;
        let leads_into_gap =
            l.junction.is_none() && ((end_x - 100.0).abs() < 0.1 || (end_x - 120.0).abs() < 0.1);
        if leads_into_gap {
            assert!(!l.successors.is_empty(), "lane of road {} ends", l.road_id);
        }
    }
}

#[test]
fn a_connecting_lane_to_nowhere_is_named_and_driven_around() {
    // Junction 9 joins the two roads (road 3), but also holds road 4, a right
    // turn off road 1 that the file links to no road: a lane into it would
    // end inside the junction, holding it for good.
    let dangling = r#"<road name="nowhere" length="15" id="4" junction="9">
        <link><predecessor elementType="road" elementId="1" contactPoint="end"/></link>
        <planView><geometry s="0" x="100" y="0" hdg="0" length="15"><arc curvature="-0.1"/></geometry></planView>
        <lanes><laneSection s="0">
            <center><lane id="0" type="none" level="false"/></center>
            <right><lane id="-1" type="driving" level="false"><width sOffset="0" a="3.5" b="0" c="0" d="0"/>
                <link><predecessor id="-1"/></link></lane></right>
        </laneSection></lanes>
    </road>"#;
    let xml = TWO_ROADS_AND_A_JUNCTION
        .replace("@CONNECTING@", &format!("{CONNECTING_ROAD}\n    {dangling}"))
        .replace(
            "@CONNECTIONS@",
            &format!(
                r#"{CONNECTIONS}<connection id="2" incomingRoad="1" connectingRoad="4" contactPoint="start"><laneLink from="-1" to="-1"/></connection>"#
            ),
        );
    let (town, report) = load_xodr_str(&xml, "gap", &LoadOptions::default()).unwrap();
    let warning = report
        .warnings
        .iter()
        .find(|w| w.contains("junction 9: connecting road 4 lane -1 leads to no lane"))
        .unwrap_or_else(|| panic!("{:?}", report.warnings));
    assert!(warning.contains("fix:"), "{warning}");
    let lane_of = |road: &str, od: i32| {
        LaneIdx(
            town.lanes
                .iter()
                .position(|l| l.road_id == road && l.od_lane == od)
                .unwrap() as u32,
        )
    };
    let (west, through, nowhere) = (lane_of("1", -1), lane_of("3", -1), lane_of("4", -1));
    let succ = &town.lanes[west.0 as usize].successors;
    assert!(
        succ.contains(&through) && succ.contains(&nowhere),
        "{succ:?}"
    );
    // NPCs choose their way at random, but never the lane to nowhere.
    for seed in 0..50 {
        let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(seed);
        let mut path = crate::road::LanePath::new(west, 50.0);
        crate::agents::npc::extend_path(&town, &mut path, &mut rng, 80.0);
        assert_eq!(path.lanes.get(1), Some(&through), "seed {seed}");
    }
}

#[test]
fn junction_priorities_become_lane_pairs_and_a_bad_one_is_named() {
    let xml = generate_grid_town(&GridTownParams::gen03()).unwrap();
    let (town, report) = load_xodr_str(&xml, "gen03", &LoadOptions::default()).unwrap();
    assert!(report.warnings.is_empty(), "{:#?}", report.warnings);
    let with: Vec<&crate::map::Junction> = town
        .junctions
        .iter()
        .filter(|j| !j.priorities.is_empty())
        .collect();
    assert_eq!(with.len(), 4, "the roundabout's four junctions");
    for j in &with {
        let (high, low) = j.priorities[0];
        let idx = town.junctions.iter().position(|x| x.od_id == j.od_id);
        assert_eq!(town.lane(high).junction.map(|i| i.0 as usize), idx);
        assert_eq!(town.lane(low).junction.map(|i| i.0 as usize), idx);
    }
    // A priority naming a road the map does not have is dropped with a
    // warning that names the junction and the road; the map loads, first
    // come, first served at that junction.
    let first = xml.find("<priority high=\"").unwrap() + "<priority high=\"".len();
    let end = first + xml[first..].find('"').unwrap();
    let bad = format!("{}99999{}", &xml[..first], &xml[end..]);
    let (town, report) = load_xodr_str(&bad, "gen03", &LoadOptions::default()).unwrap();
    assert_eq!(report.warnings.len(), 1, "{:#?}", report.warnings);
    let w = &report.warnings[0];
    assert!(w.contains("priority") && w.contains("99999"), "{w}");
    let left = town
        .junctions
        .iter()
        .filter(|j| !j.priorities.is_empty())
        .count();
    assert_eq!(left, 3);
}

/// One 20 m road east from (0, 0). At s = 10 the `laneOffset` jumps from 0 to
/// 7 m and two lanes open on the inside, so lane -1 of the first section
/// (t = 0 .. -3.5) goes straight on as lane -3 of the second
/// (7 - 3.5 - 3.5 = 0 .. -3.5). Cause B of docs/maps.md ("Lane links far
/// apart"): xodr 0.8.0 applied the second offset record to the first
/// section's last station too (vendor/README.md).
const OFFSET_JUMP: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<OpenDRIVE>
  <header revMajor="1" revMinor="4" name="offset-jump"/>
  <road name="r1" length="20" id="1" junction="-1">
    <planView>
      <geometry s="0" x="0" y="0" hdg="0" length="20"><line/></geometry>
    </planView>
    <lanes>
      <laneOffset s="0" a="0" b="0" c="0" d="0"/>
      <laneOffset s="10" a="7" b="0" c="0" d="0"/>
      <laneSection s="0">
        <center><lane id="0" type="none"/></center>
        <right><lane id="-1" type="driving"><link><successor id="-3"/></link><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane></right>
      </laneSection>
      <laneSection s="10">
        <center><lane id="0" type="none"/></center>
        <right>
          <lane id="-1" type="driving"><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane>
          <lane id="-2" type="driving"><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane>
          <lane id="-3" type="driving"><link><predecessor id="-1"/></link><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane>
        </right>
      </laneSection>
    </lanes>
  </road>
</OpenDRIVE>
"#;

#[test]
fn a_lane_offset_starting_at_a_section_start_does_not_bend_the_section_before() {
    let (town, report) =
        load_xodr_str(OFFSET_JUMP, "offset-jump", &LoadOptions::default()).unwrap();
    assert!(report.warnings.is_empty(), "{:#?}", report.warnings);
    let first = town
        .lanes
        .iter()
        .position(|l| l.od_lane == -1 && l.centerline.first().is_some_and(|p| p.x < 1.0))
        .expect("the first section's lane -1");
    let lane = &town.lanes[first];
    // Straight along y = -1.75 to its end, as the file draws it (xodr 0.8.0 put
    // its last point at y = +5.25, swept by the next section's offset).
    for p in &lane.centerline {
        assert!((p.y + 1.75).abs() < 1e-3, "{:?}", lane.centerline);
    }
    assert!((lane.centerline.last().unwrap().x - 10.0).abs() < 1e-3);
    // It goes on into the second section's lane -3, which starts where it ends.
    let next = &town.lanes[lane.successors[0].0 as usize];
    assert_eq!((lane.successors.len(), next.od_lane), (1, -3));
    let (a, b) = (lane.centerline.last().unwrap(), next.centerline[0]);
    assert!(close(a.truncate(), b.truncate()), "{a} {b}");
}

/// Each lane's OpenDRIVE road and lane id.
fn road_lanes(town: &Town, ids: &[crate::map::LaneIdx]) -> Vec<(String, i32)> {
    ids.iter()
        .map(|l| {
            let l = &town.lanes[l.0 as usize];
            (l.road_id.clone(), l.od_lane)
        })
        .collect()
}

/// Road 4, between the junction's connecting road and road 2, is 5 um long:
/// too short to bake lanes (as roads 35 and 54 of CARLA's Town06 are, 6.4 um
/// and 19 um), so a link has to step through it with its own lane links.
const EMPTY_ROAD: &str = r#"<road name="stub" length="5e-6" id="4" junction="-1">
        <link>
            <predecessor elementType="junction" elementId="9"/>
            <successor elementType="road" elementId="2" contactPoint="start"/>
        </link>
        <planView><geometry s="0" x="120" y="0" hdg="0" length="5e-6"><line/></geometry></planView>
        <lanes><laneSection s="0">
            <left><lane id="1" type="driving" level="false"><width sOffset="0" a="3.5" b="0" c="0" d="0"/>
                <link><predecessor id="1"/><successor id="1"/></link></lane></left>
            <center><lane id="0" type="none" level="false"/></center>
            <right><lane id="-1" type="driving" level="false"><width sOffset="0" a="3.5" b="0" c="0" d="0"/>
                <link><predecessor id="-1"/><successor id="-1"/></link></lane></right>
        </laneSection></lanes>
    </road>"#;

#[test]
fn a_link_steps_through_a_road_too_short_to_have_lanes() {
    let xml = TWO_ROADS_AND_A_JUNCTION
        .replace(
            r#"<link><predecessor elementType="junction" elementId="9"/></link>"#,
            r#"<link><predecessor elementType="road" elementId="4" contactPoint="end"/></link>"#,
        )
        .replace(
            "@CONNECTING@",
            &(CONNECTING_ROAD.replace(
                r#"elementId="2" contactPoint="start""#,
                r#"elementId="4" contactPoint="start""#,
            ) + EMPTY_ROAD),
        )
        .replace(
            "@CONNECTIONS@",
            &CONNECTIONS.replace(r#"incomingRoad="2""#, r#"incomingRoad="4""#),
        );
    // Road 2's westbound lane leaves by its start into road 4's lane 1: a road link
    // needs the lane's own <link>.
    let (west, east) = xml.split_at(xml.find(r#"name="east""#).unwrap());
    let lane_1 = r#"<left><lane id="1" type="driving" level="false">"#;
    let xml = west.to_string()
        + &east.replacen(
            lane_1,
            &format!(r#"{lane_1}<link><predecessor id="1"/></link>"#),
            1,
        );
    let (town, report) = load_xodr_str(&xml, "stub", &LoadOptions::default()).unwrap();
    assert!(report.warnings.is_empty(), "{:#?}", report.warnings);
    let lane = |road: &str, od: i32| {
        town.lanes
            .iter()
            .position(|l| l.road_id == road && l.od_lane == od)
            .unwrap_or_else(|| panic!("road {road} lane {od}"))
    };
    // Eastbound: off the connecting road, through road 4, onto road 2.
    let east = &town.lanes[lane("3", -1)];
    assert_eq!(road_lanes(&town, &east.successors), [("2".to_string(), -1)]);
    // Westbound: off road 2's start, back through road 4, into the junction.
    let west = &town.lanes[lane("2", 1)];
    assert_eq!(road_lanes(&town, &west.successors), [("3".to_string(), 1)]);
    assert!(town.lanes.iter().all(|l| l.road_id != "4"));
}

/// Road 1 ends in a lane section 0.5 mm long, whose lane -1 links on to road 2's
/// lane -2; road 2 is drawn 3.5 m to the left (its laneOffset), so its lane -2 is
/// where road 1's lane -1 ends. Exporters write such sections (CARLA's Town04 holds
/// 18 links across them).
const SHORT_LAST_SECTION: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<OpenDRIVE>
  <header revMajor="1" revMinor="4" name="short-section"/>
  <road name="r1" length="20" id="1" junction="-1">
    <link><successor elementType="road" elementId="2" contactPoint="start"/></link>
    <planView><geometry s="0" x="0" y="0" hdg="0" length="20"><line/></geometry></planView>
    <lanes>
      <laneSection s="0">
        <center><lane id="0" type="none"/></center>
        <right><lane id="-1" type="driving"><link><successor id="-1"/></link><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane></right>
      </laneSection>
      <laneSection s="19.9995">
        <center><lane id="0" type="none"/></center>
        <right><lane id="-1" type="driving"><link><predecessor id="-1"/><successor id="-2"/></link><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane></right>
      </laneSection>
    </lanes>
  </road>
  <road name="r2" length="20" id="2" junction="-1">
    <link><predecessor elementType="road" elementId="1" contactPoint="end"/></link>
    <planView><geometry s="0" x="20" y="0" hdg="0" length="20"><line/></geometry></planView>
    <lanes>
      <laneOffset s="0" a="3.5" b="0" c="0" d="0"/>
      <laneSection s="0">
        <center><lane id="0" type="none"/></center>
        <right>
          <lane id="-1" type="driving"><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane>
          <lane id="-2" type="driving"><link><predecessor id="-1"/></link><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane>
        </right>
      </laneSection>
    </lanes>
  </road>
</OpenDRIVE>
"#;

#[test]
fn a_link_steps_through_a_section_too_short_to_have_lanes_by_its_own_links() {
    let (town, report) =
        load_xodr_str(SHORT_LAST_SECTION, "short-section", &LoadOptions::default()).unwrap();
    assert!(report.warnings.is_empty(), "{:#?}", report.warnings);
    let lane = town
        .lanes
        .iter()
        .find(|l| l.road_id == "1" && l.od_lane == -1)
        .expect("road 1's lane -1");
    let next = road_lanes(&town, &lane.successors);
    // Road 2's lane -2, where road 1's lane -1 ends (xodr 0.8.0 read the link as
    // naming road 2's lane -1, 3.5 m to the left).
    assert_eq!(next, [("2".to_string(), -2)]);
    let start = town.lanes[lane.successors[0].0 as usize].centerline[0];
    assert!(close(
        lane.centerline.last().unwrap().truncate(),
        start.truncate()
    ));
}

/// Road 1 of [`SHORT_LAST_SECTION`] drawn as CARLA's Town04 draws its connecting
/// road 581: a section 9.7 mm long (which bakes), then one of 0.1 um and, at the
/// road's end, one of 10 um (which do not), each lane linking to the next.
fn short_sections_in_a_row() -> String {
    let section = |s: &str, links: &str| {
        format!(
            r#"<laneSection s="{s}">
        <center><lane id="0" type="none"/></center>
        <right><lane id="-1" type="driving"><link>{links}</link><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane></right>
      </laneSection>"#
        )
    };
    let on = r#"<predecessor id="-1"/><successor id="-1"/>"#;
    let sections = [
        section("0", r#"<successor id="-1"/>"#),
        section("9.5", on),
        section("9.5097", on),
        section("9.5097001", on),
        section("19.99999", r#"<predecessor id="-1"/><successor id="-2"/>"#),
    ]
    .join("\n      ");
    let first = SHORT_LAST_SECTION.find("<laneSection").unwrap();
    let last = SHORT_LAST_SECTION.find("</lanes>").unwrap();
    format!(
        "{}{sections}\n    {}",
        &SHORT_LAST_SECTION[..first],
        &SHORT_LAST_SECTION[last..]
    )
}

#[test]
fn a_link_steps_over_sections_too_short_to_bake_but_not_over_one_that_bakes() {
    // Town04's road 581 (junction 569): its lane in the 9.7-mm section was reached
    // from no lane (the link from the section before stepped over it, to the dropped
    // section 9.7 mm on), and its last lane led nowhere (past the dropped last section
    // the link looked it up again, by the id it had just read from it).
    let (town, report) = load_xodr_str(
        &short_sections_in_a_row(),
        "short-sections",
        &LoadOptions::default(),
    )
    .unwrap();
    assert!(report.warnings.is_empty(), "{:#?}", report.warnings);
    let mut road1: Vec<usize> = (0..town.lanes.len())
        .filter(|&i| town.lanes[i].road_id == "1")
        .collect();
    road1.sort_by(|&a, &b| {
        town.lanes[a].centerline[0]
            .x
            .total_cmp(&town.lanes[b].centerline[0].x)
    });
    assert_eq!(road1.len(), 3, "the 9.5-m, 9.7-mm and 10.5-m sections bake");
    let idx = |i: usize| crate::map::LaneIdx(road1[i] as u32);
    assert_eq!(town.lanes[road1[0]].successors, [idx(1)]);
    assert_eq!(town.lanes[road1[1]].successors, [idx(2)]);
    assert_eq!(
        road_lanes(&town, &town.lanes[road1[2]].successors),
        [("2".to_string(), -2)]
    );
}

#[test]
fn a_junction_link_steps_through_a_connecting_roads_first_section_too_short_to_bake() {
    // Town04's road 688 (junction 669) and Town06's road 715 (junction 704) begin
    // with a section 1.7 um long, and the junction's <laneLink> names that section's
    // lane (here lane -2, which links on to lane -1): the connecting road was reached
    // from no lane.
    let right = r#"<right><lane id="-1" type="driving" level="false"><width sOffset="0" a="3.5" b="0" c="0" d="0"/>
                <link><predecessor id="-1"/><successor id="-1"/></link></lane></right>
        </laneSection></lanes>"#;
    let short_first = format!(
        r#"<laneSection s="0">
            <center><lane id="0" type="none" level="false"/></center>
            <right><lane id="-2" type="driving" level="false"><width sOffset="0" a="3.5" b="0" c="0" d="0"/>
                <link><predecessor id="-1"/><successor id="-1"/></link></lane></right>
        </laneSection><laneSection s="1.7e-6">
            <center><lane id="0" type="none" level="false"/></center>
            {right}"#
    );
    let connecting = CONNECTING_ROAD
        .replace(
            &CONNECTING_ROAD[CONNECTING_ROAD.find("<laneSection").unwrap()
                ..CONNECTING_ROAD.find("</lanes>").unwrap() + "</lanes>".len()],
            &short_first,
        )
        .replace(
            r#"<predecessor id="-1"/><successor id="-1"/></link></lane></right>
        </laneSection></lanes>"#,
            r#"<predecessor id="-2"/><successor id="-1"/></link></lane></right>
        </laneSection></lanes>"#,
        );
    let connections = r#"
        <connection id="0" incomingRoad="1" connectingRoad="3" contactPoint="start"><laneLink from="-1" to="-2"/></connection>
    "#;
    let xml = TWO_ROADS_AND_A_JUNCTION
        .replace("@CONNECTING@", &connecting)
        .replace("@CONNECTIONS@", connections);
    let (town, report) = load_xodr_str(&xml, "gap", &LoadOptions::default()).unwrap();
    let unreached: Vec<&String> = report
        .warnings
        .iter()
        .filter(|w| w.contains("reached from no lane"))
        .collect();
    assert!(unreached.is_empty(), "{unreached:#?}");
    let west = town
        .lanes
        .iter()
        .find(|l| l.road_id == "1" && l.od_lane == -1)
        .expect("road 1 lane -1");
    assert_eq!(road_lanes(&town, &west.successors), [("3".to_string(), -1)]);
}
