//! Traffic lights: at the junctions the town's [`LightRule`] names (every
//! junction with three or more arms, or only where arterials cross), a
//! signal beside each approach, 1 m before the junction, right of its
//! incoming lanes, with one controller per approach; the approaches take
//! their turns in arm order (`sequence`).

use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::fmt::Write;

use super::layout::{Arm, Grid, Node};
use super::{LANE_WIDTH_M, LightRule, SIGNAL_Z_OFFSET_M};

/// The town's lights as OpenDRIVE elements.
#[derive(Debug, Default)]
pub(super) struct Lights {
    /// The `<signal>` elements on each street, by street id.
    pub(super) signals: BTreeMap<u32, String>,
    /// The `<controller>` elements, one per signal.
    pub(super) controllers: String,
    /// Each junction's `<controller>` references.
    pub(super) junction_controllers: BTreeMap<Node, String>,
}

/// The lights of the junctions the grid's [`LightRule`] names among those
/// with three or more `arms` (never a roundabout): signals from id 5000,
/// controllers from 7000, junction by junction.
pub(super) fn lights(grid: &Grid, arms: &BTreeMap<Node, Vec<Arm<'_>>>) -> Lights {
    let mut lights = Lights::default();
    let mut next_signal = 5000u32;
    let mut next_ctrl = 7000u32;
    for (node, list) in arms {
        let lit = match grid.features.lights {
            LightRule::ThreeOrMoreArms => true,
            LightRule::WhereArterialsCross => grid.arterials_cross(*node),
        };
        if list.len() < 3 || !lit || grid.roundabout(*node) {
            continue;
        }
        for (seq, arm) in list.iter().enumerate() {
            // At the street's end that meets this junction, right of its incoming lanes.
            let len = grid.street_length(arm.street);
            let side = f64::from(arm.street.lanes) * LANE_WIDTH_M + 1.5;
            let (s, t, orient, hoff) = if arm.at_b {
                (len - 1.0, -side, "+", PI)
            } else {
                (1.0, side, "-", 0.0)
            };
            let sid = next_signal;
            next_signal += 1;
            let cid = next_ctrl;
            next_ctrl += 1;
            let _ = writeln!(
                lights.signals.entry(arm.street.id).or_default(),
                "            <signal s=\"{s:.3}\" t=\"{t:.3}\" id=\"{sid}\" name=\"TrafficLight\" dynamic=\"yes\" orientation=\"{orient}\" zOffset=\"{SIGNAL_Z_OFFSET_M:.3}\" country=\"OpenDRIVE\" type=\"1000001\" subtype=\"-1\" value=\"-1\" text=\"\" hOffset=\"{hoff:.6}\" pitch=\"0\" roll=\"0\" height=\"3.0\" width=\"0.5\"/>"
            );
            let _ = writeln!(
                lights.controllers,
                "    <controller id=\"{cid}\" name=\"ctrl{cid}\" sequence=\"{seq}\">\n        <control signalId=\"{sid}\" type=\"0\"/>\n    </controller>"
            );
            let _ = writeln!(
                lights.junction_controllers.entry(*node).or_default(),
                "        <controller id=\"{cid}\" type=\"0\" sequence=\"{seq}\"/>"
            );
        }
    }
    lights
}
