//! The OpenDRIVE elements the generator's roads share: a road's head (its
//! links, type and one geometry), a link, the town road type, a lane's
//! `<width>` and the right lanes of a junction road.

use std::fmt::Write;

use super::{SIDEWALK_HEIGHT_M, SPEED_LIMIT_KMH};

/// A lane's `<width>`: `a` metres, or, when it changes along the road, the
/// cubic from `a` to `b` over `len` metres with zero slope at both ends.
pub(super) fn width_element(a: f64, b: f64, len: f64) -> String {
    if a == b {
        format!("<width sOffset=\"0\" a=\"{a}\" b=\"0\" c=\"0\" d=\"0\"/>")
    } else {
        let d = b - a;
        format!(
            "<width sOffset=\"0\" a=\"{a}\" b=\"0\" c=\"{:.9}\" d=\"{:.9}\"/>",
            3.0 * d / (len * len),
            -2.0 * d / (len * len * len)
        )
    }
}

/// The start of a road element: named `name`, id `id`, in junction `jid`
/// (-1: none), `links` (its `<link>` children), `extra` (e.g. its type),
/// one geometry of `shape` from `start` at heading `hdg` (radians) over
/// `len` metres, a flat elevation and an empty lateral profile.
#[allow(clippy::too_many_arguments)]
pub(super) fn road_head(
    out: &mut String,
    name: &str,
    id: u32,
    jid: i64,
    links: &str,
    extra: &str,
    start: (f64, f64),
    hdg: f64,
    len: f64,
    shape: &str,
) {
    let (sx, sy) = start;
    let _ = writeln!(
        out,
        "    <road name=\"{name}\" length=\"{len:.6}\" id=\"{id}\" junction=\"{jid}\">\n        <link>\n{links}        </link>"
    );
    out.push_str(extra);
    let _ = writeln!(
        out,
        "        <planView>\n            <geometry s=\"0\" x=\"{sx:.6}\" y=\"{sy:.6}\" hdg=\"{hdg:.9}\" length=\"{len:.6}\">\n                {shape}\n            </geometry>\n        </planView>\n        <elevationProfile>\n            <elevation s=\"0\" a=\"0\" b=\"0\" c=\"0\" d=\"0\"/>\n        </elevationProfile>\n        <lateralProfile/>"
    );
}

/// A `<link>`'s predecessor or successor road element.
pub(super) fn road_link(kind: &str, road: u32, contact: &str) -> String {
    format!(
        "            <{kind} elementType=\"road\" elementId=\"{road}\" contactPoint=\"{contact}\"/>\n"
    )
}

/// The road type and speed limit of a town road.
pub(super) fn town_type() -> String {
    format!(
        "        <type s=\"0\" type=\"town\">\n            <speed max=\"{SPEED_LIMIT_KMH}\" unit=\"km/h\"/>\n        </type>\n"
    )
}

/// The right lanes of a junction road: when the lane (or sidewalk) it
/// carries does not start and end on the reference line, a spacer lane of
/// type none from `offsets_m.0` to `offsets_m.1` first; then the lane of
/// `kind` (`driving` or `sidewalk`) linked from `pred` to `succ`, `width_m`
/// wide and unmarked (a driving lane) or raised (a sidewalk).
pub(super) fn junction_lanes(
    kind: &str,
    offsets_m: (f64, f64),
    len: f64,
    width_m: f64,
    pred: i32,
    succ: i32,
) -> String {
    let mut lanes = String::new();
    let mut id = -1;
    if offsets_m != (0.0, 0.0) {
        let _ = write!(
            lanes,
            "                    <lane id=\"-1\" type=\"none\" level=\"false\">\n                        <link/>\n                        {}\n                    </lane>\n",
            width_element(offsets_m.0, offsets_m.1, len)
        );
        id = -2;
    }
    let finish = if kind == "sidewalk" {
        format!(
            "                        <height sOffset=\"0\" inner=\"{SIDEWALK_HEIGHT_M}\" outer=\"{SIDEWALK_HEIGHT_M}\"/>\n"
        )
    } else {
        "                        <roadMark sOffset=\"0\" type=\"none\" weight=\"standard\" color=\"white\" width=\"0\" laneChange=\"none\"/>\n".to_string()
    };
    let _ = write!(
        lanes,
        "                    <lane id=\"{id}\" type=\"{kind}\" level=\"false\">\n                        <link>\n                            <predecessor id=\"{pred}\"/>\n                            <successor id=\"{succ}\"/>\n                        </link>\n                        <width sOffset=\"0\" a=\"{width_m}\" b=\"0\" c=\"0\" d=\"0\"/>\n{finish}                    </lane>\n"
    );
    lanes
}
