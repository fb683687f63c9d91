//! NPC vehicles: CARLA-autopilot-like drivers on the lane graph.
//!
//! Each NPC follows a [`LanePath`] through the lane graph, choosing a random
//! successor (its own `ChaCha8Rng`) whenever the path ahead runs short, so a
//! new random choice is made at each junction. On a road of several lanes
//! each way the choice also takes the turns of the lanes beside it; such a
//! turn is a [`PlannedChange`], made where the lane beside has room (the
//! rule book's gap check, as the expert's) or given up for a way from its
//! own lane. Per tick it decides a
//! [`VehicleControl`] for the shared vehicle model:
//!
//! - longitudinal: the Intelligent Driver Model toward the lane's speed limit
//!   (lowered on curves to keep lateral acceleration below 2.5 m/s^2), with
//!   obstacles at (a) the nearest actor in its corridor ahead
//!   ([`crate::rules::ahead::nearest_ahead`]), minimum gap 3.0 m, (b) the stop line
//!   of a light it must stop for ([`rules::must_stop`]: red, or a yellow
//!   one it can still stop for at its comfortable deceleration),
//!   (c) the entry of a junction it holds no reservation for;
//! - lateral: pure pursuit on the path from the rear axle
//!   ([`pursuit_steer`], lookahead [`rules::pursuit_lookahead_m`]).
//!
//! Junction yielding: connecting lanes of one junction conflict as
//! [`rules::conflicts`] says. Before entering a junction an
//! NPC requests its connecting lane; [`crate::traffic::Reservations`] grants requests in
//! order of waiting time (then id) when no other vehicle holds a conflicting
//! lane and the exit lane has room for it ("don't block the box"), and,
//! where the map gives another lane priority (a roundabout's ring), no
//! vehicle is about to take that lane. The reservation is released once the
//! vehicle has left the junction.

use crate::agents::vehicle::{VehicleControl, VehicleParams, VehicleState};
use crate::map::town::{LaneIdx, LightIdx, LightState, Town};
use crate::road::geometry::curvature;
use crate::road::lane_path::LanePath;
use crate::rules::ahead::{ActorView, nearest_ahead, walker_horizon_s};
use crate::rules::{self, JunctionConflicts, RuleBook};
use glam::Vec2;
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

/// Parameters of the NPC driver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NpcParams {
    /// Minimum bumper-to-bumper gap to a leader at standstill (metres; docs/protocol.md §2: 3.0).
    pub min_gap_m: f32,
    /// Desired time headway to a leader (seconds).
    pub time_headway_s: f32,
    /// IDM maximum acceleration (metres per second squared).
    pub max_accel_mps2: f32,
    /// IDM comfortable deceleration (metres per second squared); also the yellow-light decision.
    pub comfort_decel_mps2: f32,
    /// Standstill gap before a stop line or junction entry (metres).
    pub stop_gap_m: f32,
    /// Standstill gap to a pedestrian (metres).
    pub pedestrian_gap_m: f32,
    /// Largest lateral acceleration on curves (metres per second squared).
    pub max_lateral_accel_mps2: f32,
    /// Fraction of the speed limit driven (1.0 = at the limit).
    pub speed_factor: f32,
    /// Extra half-width of the corridor in which actors count as ahead (metres).
    pub corridor_margin_m: f32,
}

impl Default for NpcParams {
    fn default() -> Self {
        NpcParams {
            min_gap_m: 3.0,
            time_headway_s: 1.0,
            max_accel_mps2: 2.0,
            comfort_decel_mps2: 3.0,
            stop_gap_m: 0.5,
            pedestrian_gap_m: 4.0,
            max_lateral_accel_mps2: rules::pursuit::CURVE_LATERAL_ACCEL_MPS2,
            speed_factor: 1.0,
            corridor_margin_m: 0.4,
        }
    }
}

/// One NPC vehicle.
#[derive(Debug, Clone)]
pub struct Npc {
    /// Actor id.
    pub id: u32,
    /// Pose, speed and actuators.
    pub state: VehicleState,
    /// Ground height (metres).
    pub ground_z: f32,
    /// Where it is on the lane graph and where it goes next.
    pub path: LanePath,
    /// The connecting lane it may enter, if granted.
    pub reservation: Option<LaneIdx>,
    /// The connecting lane it still holds while its rear leaves it, once the
    /// next one was granted: two junctions less than a car length apart
    /// (Town03's road 14), where it stands at the second's entry with its rear
    /// still in the first ([`crate::traffic::Reservations`]).
    pub leaving: Option<LaneIdx>,
    /// The connecting lane it is asking for and the tick it started asking.
    pub request: Option<(LaneIdx, u64)>,
    /// The lane change it has planned for its next turn, if any.
    pub change: Option<PlannedChange>,
    /// Consecutive ticks below the Traffic Manager's idle speed
    /// (`traffic::removal::STOPPED_MPS`): how long it has stood, for its removal.
    pub idle_ticks: u32,
    /// Consecutive ticks below 0.1 m/s for any reason.
    pub stopped_ticks: u32,
    /// The control decided this tick.
    pub control: VehicleControl,
    /// Paint index.
    pub color: u8,
    /// Its own random stream (route choices, respawns).
    pub rng: ChaCha8Rng,
}

/// A lane change an NPC has chosen for its next turn on a road of several
/// lanes each way: from `from` (the last lane of its path) to its neighbour
/// `to`, then on into `then`, a successor of `to` that `from` does not lead
/// to. The path ends at `from` until the change is made (with a gap,
/// [`crate::traffic::Traffic::step`]) or given up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PlannedChange {
    /// The lane it changes from.
    pub from: LaneIdx,
    /// The neighbour lane it changes to (same direction).
    pub to: LaneIdx,
    /// Where it goes after `to`: a junction lane only `to` leads into.
    pub then: LaneIdx,
}

/// Makes sure the path reaches `ahead_m` beyond the position, choosing random successors.
///
/// A successor that leads nowhere (no successors of its own: a connecting
/// lane the map links to no exit, a road that ends) is driven around: it is
/// chosen only when no other successor is left. On a map without such lanes
/// the choices, and the random stream, are as they were. This never plans
/// a lane change ([`extend_path_planning`] does).
pub fn extend_path(town: &Town, path: &mut LanePath, rng: &mut ChaCha8Rng, ahead_m: f32) {
    extend(town, path, rng, ahead_m, None);
}

/// [`extend_path`] that also chooses among the turns of the lanes beside
/// the path's last one: where that lane has a neighbour of the same
/// direction, every way on from it, and every way on from a neighbour that
/// leads to a road it does not, is equally likely. A way from a neighbour
/// is planned as `change` ([`PlannedChange`]) and the path stops there. On
/// a road of one lane each way the choices, and the random stream, are
/// those of [`extend_path`]. Nothing is extended while a change is planned.
pub fn extend_path_planning(
    town: &Town,
    path: &mut LanePath,
    rng: &mut ChaCha8Rng,
    ahead_m: f32,
    change: &mut Option<PlannedChange>,
) {
    extend(town, path, rng, ahead_m, Some(change));
}

fn extend(
    town: &Town,
    path: &mut LanePath,
    rng: &mut ChaCha8Rng,
    ahead_m: f32,
    mut change: Option<&mut Option<PlannedChange>>,
) {
    let leads_on = |l: LaneIdx| leads_on(town, l);
    while path.remaining_m(town) < ahead_m {
        if change.as_ref().is_some_and(|c| c.is_some()) {
            return;
        }
        let last = *path.lanes.back().expect("path has a lane");
        // Planning: the turns of the lanes beside count too (and are the
        // only way on from a lane that ends).
        if let Some(change) = change.as_deref_mut()
            && let Some((lane, then)) = choose_with_neighbours(town, last, rng)
        {
            if lane == last {
                path.lanes.push_back(then);
            } else {
                *change = Some(PlannedChange {
                    from: last,
                    to: lane,
                    then,
                });
            }
            continue;
        }
        let succ = &town.lanes[last.0 as usize].successors;
        if succ.is_empty() {
            return;
        }
        let on = succ.iter().filter(|&&l| leads_on(l)).count();
        let next = if on == succ.len() || on == 0 {
            let k = if succ.len() == 1 {
                0
            } else {
                rng.random_range(0..succ.len())
            };
            succ[k]
        } else {
            let k = if on == 1 { 0 } else { rng.random_range(0..on) };
            *succ
                .iter()
                .filter(|&&l| leads_on(l))
                .nth(k)
                .expect("k < on")
        };
        path.lanes.push_back(next);
    }
}

/// A planned lane change is given up when less road than this is left
/// before the lane's end, beyond the stopping distance (metres): the car
/// then takes a way on from its own lane. A lane shorter than this (that
/// leads on) is never planned to change from ([`choose_with_neighbours`]).
pub const CHANGE_GIVE_UP_M: f32 = 25.0;

/// The way on from `last` drawn among its own successors and those of its
/// same-direction neighbours that lead to a road it does not reach: (the
/// lane it is taken from, the successor). `None` (nothing drawn) when
/// `last` is a junction lane or has no neighbour with such a way on, and
/// when it is shorter than [`CHANGE_GIVE_UP_M`] and leads on: a change
/// planned there would be given up as soon as the car is on it, and the car
/// would come onto it without the way on it takes (Town03's road 14, 6.4 m
/// between two junctions, where such a car stopped over the next entry). A
/// lane whose own ways lead nowhere (or that ends) can only be left by a lane
/// beside it.
fn choose_with_neighbours(
    town: &Town,
    last: LaneIdx,
    rng: &mut ChaCha8Rng,
) -> Option<(LaneIdx, LaneIdx)> {
    let lane = &town.lanes[last.0 as usize];
    if lane.junction.is_some() {
        return None;
    }
    let leads_on = |l: LaneIdx| leads_on(town, l);
    if lane.length_m() < CHANGE_GIVE_UP_M && !leads_nowhere(town, last) {
        return None;
    }
    // The road a way on leads to: its successor's road (or its own).
    let exit_road = |l: LaneIdx| {
        let d = &town.lanes[l.0 as usize];
        d.successors
            .first()
            .map_or(&d.road_id, |s| &town.lanes[s.0 as usize].road_id)
    };
    let own: Vec<LaneIdx> = lane
        .successors
        .iter()
        .copied()
        .filter(|&l| leads_on(l))
        .collect();
    let mut options: Vec<(LaneIdx, LaneIdx)> = own.iter().map(|&l| (last, l)).collect();
    for n in [lane.left, lane.right].into_iter().flatten() {
        for &l in &town.lanes[n.0 as usize].successors {
            if leads_on(l) && !own.iter().any(|&o| exit_road(o) == exit_road(l)) {
                options.push((n, l));
            }
        }
    }
    if options.len() == own.len() {
        return None;
    }
    Some(options[rng.random_range(0..options.len())])
}

/// Whether a car can go on from the end of `lane` (it has a successor).
fn leads_on(town: &Town, lane: LaneIdx) -> bool {
    !town.lanes[lane.0 as usize].successors.is_empty()
}

/// Whether no way on from `lane` leads anywhere: it ends, or every
/// successor is a lane to nowhere.
pub fn leads_nowhere(town: &Town, lane: LaneIdx) -> bool {
    !town.lanes[lane.0 as usize]
        .successors
        .iter()
        .any(|&s| leads_on(town, s))
}

/// What an NPC's driver decided this tick and why.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Decision {
    /// The control to apply.
    pub control: VehicleControl,
    /// The acceleration asked of the vehicle (metres per second squared).
    pub accel_mps2: f32,
    /// The acceleration it would ask with nothing ahead (to tell "waiting" from "stuck").
    pub free_accel_mps2: f32,
}

/// Within this distance of a junction lane's start (front bumper, metres) a car
/// stands at that junction's entry: it means to stop `NpcParams::stop_gap_m` (0.5 m)
/// before it, and its IDM brakes it to a stop up to a metre and a half before.
pub const AT_ENTRY_M: f32 = 2.0;

/// The shortest road between two junctions on which a car waiting at the
/// second's lane `next` has its rear out of the first by the release metre
/// (metres): a car length, that metre, the place it waits back from the entry
/// (`JunctionConflicts::hold_back_m`) and the slack of its stop
/// ([`AT_ENTRY_M`]). Shorter (Town03's road 14, 6.4 m between junctions 685
/// and 678), the two junctions are chained: a car asks for the second's lane
/// while it holds the first's, and brakes for the second's entry from inside
/// the first ([`chained_junction_lane`]).
pub fn chained_link_m(conflicts: &JunctionConflicts, vp: &VehicleParams, next: LaneIdx) -> f32 {
    vp.length_m + 1.0 + conflicts.hold_back_m(next) + AT_ENTRY_M
}

/// For an NPC inside a junction whose road out leads, in less than
/// [`chained_link_m`] (over one lane section or several), into the next
/// junction: that junction's lane on its
/// path and the path distance from its front bumper to the lane's entry
/// (metres). None elsewhere ([`next_junction_lane`] serves cars outside
/// junctions).
pub fn chained_junction_lane(
    town: &Town,
    conflicts: &JunctionConflicts,
    npc: &Npc,
    params: &VehicleParams,
) -> Option<(LaneIdx, f32)> {
    let lanes = &npc.path.lanes;
    let junction = town.lanes[lanes[0].0 as usize].junction?;
    let mut off = -npc.path.s_m;
    let mut k = 0;
    while k < lanes.len() && town.lanes[lanes[k].0 as usize].junction == Some(junction) {
        off += town.lane(lanes[k]).length_m();
        k += 1;
    }
    // The road out, in as many lane sections as it has (Town03's roads 11 and
    // 38 between junctions 595 and 524, 3.5 m in all), up to the next
    // junction's lane.
    let mut link_m = 0.0;
    while town.lanes[lanes.get(k)?.0 as usize].junction.is_none() {
        link_m += town.lane(lanes[k]).length_m();
        k += 1;
    }
    let next = lanes[k];
    let chained = link_m > 0.0 && link_m < chained_link_m(conflicts, params, next);
    chained.then_some((next, off + link_m - params.length_m * 0.5))
}

/// The junction lane an NPC must reserve next: (lane, path distance from its front bumper to the lane's entry).
pub fn next_junction_lane(
    town: &Town,
    npc: &Npc,
    params: &VehicleParams,
) -> Option<(LaneIdx, f32)> {
    let mut off = -npc.path.s_m;
    for (k, &l) in npc.path.lanes.iter().enumerate() {
        if town.lanes[l.0 as usize].junction.is_some() {
            if k == 0 {
                return None; // already inside
            }
            return Some((l, off - params.length_m * 0.5));
        }
        off += town.lane(l).length_m();
        if off > 60.0 {
            break;
        }
    }
    None
}

/// The first stop line ahead of the front bumper: (path distance from the front bumper, light).
pub fn next_stop_line(
    town: &Town,
    rules: &RuleBook,
    npc: &Npc,
    params: &VehicleParams,
    max_m: f32,
) -> Option<(f32, LightIdx)> {
    stop_lines_ahead(town, rules, npc, params, max_m).next()
}

/// Every stop line ahead of the front bumper within `max_m` along its path, nearest
/// first: (path distance from the front bumper, light). A driver sees the light of
/// the junction after next too: the second of two close junctions may turn yellow
/// while the car is still before the first (Town03's road 77).
pub fn stop_lines_ahead<'a>(
    town: &'a Town,
    rules: &'a RuleBook,
    npc: &'a Npc,
    params: &VehicleParams,
    max_m: f32,
) -> impl Iterator<Item = (f32, LightIdx)> + 'a {
    let half = params.length_m * 0.5;
    npc.path
        .lanes
        .iter()
        .scan(-npc.path.s_m, move |off, &l| {
            let start = *off;
            *off += town.lane(l).length_m();
            (start <= max_m + half).then_some((start, l))
        })
        .flat_map(move |(start, l)| {
            rules
                .stop_lines
                .on_lane(l)
                .map(move |line| (start + line.s - half, line.light))
        })
        .filter(move |&(d, _)| d > -0.3 && d < max_m)
}

fn idm_term(p: &NpcParams, v: f32, gap: f32, v_lead: f32, s0: f32) -> f32 {
    let s_star = s0
        + (v * p.time_headway_s
            + v * (v - v_lead) / (2.0 * (p.max_accel_mps2 * p.comfort_decel_mps2).sqrt()))
        .max(0.0);
    let g = (gap - 0.0).max(0.05);
    -p.max_accel_mps2 * (s_star / g) * (s_star / g)
}

/// Scratch buffers reused across ticks.
#[derive(Debug, Default)]
pub struct Scratch {
    /// Path samples.
    pub pts: Vec<Vec2>,
}

/// Decides one NPC's control for this tick. `granted` says whether it holds the reservation for its next junction lane.
#[allow(clippy::too_many_arguments)]
pub fn decide(
    town: &Town,
    rules: &RuleBook,
    p: &NpcParams,
    vp: &VehicleParams,
    npc: &Npc,
    actors: &[ActorView],
    lights: &[LightState],
    scratch: &mut Scratch,
) -> Decision {
    let v = npc.state.speed_mps;
    let half = vp.length_m * 0.5;
    let look = (v * v / (2.0 * p.comfort_decel_mps2) + v * 2.0 + 20.0).max(25.0);
    npc.path
        .sample_ahead(town, 1.0, look + half, &mut scratch.pts);

    // Desired speed: the limit, lowered on curves ahead.
    let limit = town.lanes[npc.path.lane().0 as usize].speed_limit_mps * p.speed_factor;
    let mut v0 = limit.max(0.1);
    let pts = &scratch.pts;
    let horizon = pts.len().min(((v * 2.5) as usize).max(8) + 3);
    for i in 1..horizon.saturating_sub(1) {
        let (a, b, c) = (pts[i - 1], pts[i], pts[i + 1]);
        let k = curvature(a, b, c);
        if k > 1e-3 {
            let vc = rules::pursuit::curve_speed_mps(k, p.max_lateral_accel_mps2);
            // Allow braking toward the curve at the comfortable rate.
            let d = (i as f32 - half).max(0.0);
            v0 = v0.min((vc * vc + 2.0 * p.comfort_decel_mps2 * d).sqrt());
        }
    }
    let free = p.max_accel_mps2 * (1.0 - (v / v0).powi(4));
    let mut accel = free;

    // Actors ahead.
    let corridor = vp.width_m * 0.5 + p.corridor_margin_m;
    if let Some(a) = nearest_ahead(
        pts,
        actors,
        Some(npc.id),
        corridor,
        look + half,
        walker_horizon_s(v),
    ) {
        let gap = a.distance_m - half;
        let s0 = if a.kind == crate::agents::actor::ActorKind::Pedestrian {
            p.pedestrian_gap_m
        } else {
            p.min_gap_m
        };
        accel = accel.min(free + idm_term(p, v, gap, a.speed_along_mps.max(0.0), s0));
    }
    // Lights: every stop line within the look-ahead, each by the one rule.
    for (d, light) in stop_lines_ahead(town, rules, npc, vp, look) {
        let stop = rules::must_stop(
            rules::light_state(lights, light),
            d,
            v,
            p.comfort_decel_mps2,
        );
        if stop {
            accel = accel.min(free + idm_term(p, v, d, 0.0, p.stop_gap_m));
        }
    }
    // The end of a lane that leads nowhere (a lane drop waiting for a gap beside, a dead end).
    if leads_nowhere(town, *npc.path.lanes.back().expect("path has a lane")) {
        let end = npc.path.remaining_m(town) - half;
        if end < look {
            accel = accel.min(free + idm_term(p, v, end, 0.0, p.stop_gap_m));
        }
    }
    // Junction entry without a reservation: wait before it, further back where a
    // car of another movement would swing over the usual place (`hold_back_m`).
    if let Some((lane, d)) = next_junction_lane(town, npc, vp)
        .or_else(|| chained_junction_lane(town, &rules.conflicts, npc, vp))
        && npc.reservation != Some(lane)
        && d > -0.5
    {
        let back = rules.conflicts.hold_back_m(lane);
        let gap = if d - back > -0.5 { d - back } else { d };
        accel = accel.min(free + idm_term(p, v, gap, 0.0, p.stop_gap_m));
    }
    accel = accel.clamp(-vp.brake_decel_mps2, p.max_accel_mps2);

    let steer = pursuit_steer(town, vp, npc);
    let (throttle, brake) = if v < 0.05 && accel <= 0.0 {
        (0.0, 1.0)
    } else {
        vp.pedals_for_accel(accel, v)
    };
    Decision {
        control: VehicleControl {
            steer,
            throttle,
            brake,
        },
        accel_mps2: accel,
        free_accel_mps2: free,
    }
}

/// Steer that follows the NPC's path ([`rules::pursuit::pursuit_steer`]).
pub fn pursuit_steer(town: &Town, vp: &VehicleParams, npc: &Npc) -> f32 {
    rules::pursuit::pursuit_steer(town, vp, &npc.state, &npc.path)
}
