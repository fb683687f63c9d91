//! Junction conflicts: which connecting lanes of a junction may not be
//! driven at the same time.
//!
//! Two connecting lanes of one junction conflict when
//!
//! - their centrelines come within [`CONFLICT_M`] of each other anywhere
//!   (crossing paths, paths that merge into one exit or leave one entry), or
//! - the bodies of two cars driving them come within [`CLEARANCE_M`] of each
//!   other: each lane is driven once as an NPC drives it ([`sweep`]: pure
//!   pursuit from the rear axle, [`VehicleState::step`], at the speed its
//!   sharpest curve allows), from its entry until the car's rear has left
//!   it, and the car's footprints along the two drives are compared.
//!
//! The second test is CARLA's Traffic Manager's: its collision stage checks
//! the bounding box swept along each vehicle's path (the "geodesic
//! boundary", `collision_stage.cpp`), not the path. A turn sharper than a car
//! can steer swings its body out of its lane: Town02's right turns have about
//! 3.5 m of radius against the Model 3's 5.5 m, so the turning car's front
//! reaches into the lane beside its exit, where the left turn from that
//! road starts, 4 m from its centreline. The centrelines never come within
//! 3 m there; the bodies touch.
//!
//! The NPCs' junction reservations grant a lane only while no conflicting
//! lane is held ([`crate::traffic::Reservations`]).
//!
//! A connecting road drawn in several lane sections (most of those of CARLA's
//! Town03, Town04 and Town06, none of Town01's, Town02's or our generated
//! towns') is several connecting lanes of one junction in a row: one
//! movement through the junction ([`movement`]). A car reserves the first
//! and holds it until it has left the last, so two lanes conflict when any
//! lane of the one's movement conflicts with any lane of the other's: a car
//! entering a road of 14 sections would otherwise hold only the first, which
//! crosses nothing, and meet the cross traffic in the fifth.

use glam::Vec2;

use crate::agents::vehicle::{VehicleControl, VehicleParams, VehicleState};
use crate::map::town::{LaneIdx, Town};
use crate::physics::DT_S;
use crate::road::geometry::curvature;
use crate::road::lane_path::LanePath;
use crate::rules::pursuit::{pursuit_lookahead_m, pursuit_steer};

/// Distance between two centrelines below which connecting lanes conflict (metres).
pub const CONFLICT_M: f32 = 3.0;

/// Gap between the bodies of two cars on two connecting lanes below which
/// the lanes conflict (metres): what a car's tracking may differ from the
/// sweep's (it enters faster or slower, brakes in the turn).
pub const CLEARANCE_M: f32 = 0.25;

/// The slower of the two speeds a lane is swept at (metres per second).
const CREEP_MPS: f32 = 1.0;

/// Spacing of the footprints kept along a sweep (metres of travel).
const SWEEP_STEP_M: f32 = 0.5;

/// The most lanes a sweep's path holds (the lane and the successors after it).
const MAX_SWEEP_LANES: usize = 32;

/// For each lane of a town, the connecting lanes of its junction it
/// conflicts with, and those of them it gives way to.
#[derive(Debug, Clone, Default)]
pub struct JunctionConflicts {
    by_lane: Vec<Vec<LaneIdx>>,
    gives_way_to: Vec<Vec<LaneIdx>>,
    /// Each lane's [`movement`], where it is more than the lane itself (a
    /// junction with chained lanes); empty otherwise.
    movements: Vec<Vec<LaneIdx>>,
    /// For each entry lane of a junction, how far before its usual waiting
    /// place a car waits for it (metres; 0 almost everywhere): see
    /// [`JunctionConflicts::hold_back_m`].
    hold_back: Vec<f32>,
}

/// Where a car's body is while it drives one connecting lane: its centre
/// and unit heading every [`SWEEP_STEP_M`] of travel, and the box they lie in.
#[derive(Debug, Clone, PartialEq)]
pub struct Sweep {
    /// Body centres and unit headings, in driving order (metres).
    pub poses: Vec<(Vec2, Vec2)>,
    /// The lowest corner of the box the centres lie in (metres).
    pub lo: Vec2,
    /// The highest corner of that box (metres).
    pub hi: Vec2,
}

impl JunctionConflicts {
    /// Finds the conflicts of every junction of a town for the default car
    /// (every vehicle of a run shares one model) and the NPCs' default curve speed.
    pub fn new(town: &Town) -> JunctionConflicts {
        Self::for_vehicle(
            town,
            &VehicleParams::default(),
            crate::rules::pursuit::CURVE_LATERAL_ACCEL_MPS2,
        )
    }

    /// Finds the conflicts of every junction of a town for a car of `vp`
    /// that takes curves at up to `lateral_accel_mps2` (metres per second squared).
    pub fn for_vehicle(
        town: &Town,
        vp: &VehicleParams,
        lateral_accel_mps2: f32,
    ) -> JunctionConflicts {
        let mut by_lane = vec![Vec::new(); town.lanes.len()];
        let mut by_junction: std::collections::BTreeMap<u32, Vec<usize>> = Default::default();
        for (i, l) in town.lanes.iter().enumerate() {
            if let Some(j) = l.junction {
                by_junction.entry(j.0).or_default().push(i);
            }
        }
        let half = vp.half_extents() + Vec2::splat(CLEARANCE_M * 0.5);
        let mut hold_back = vec![0.0; town.lanes.len()];
        for lanes in by_junction.values() {
            let sweeps: Vec<Sweep> = lanes
                .iter()
                .map(|&l| lane_sweep(town, vp, lateral_accel_mps2, LaneIdx(l as u32)))
                .collect();
            // A car enters a turn faster than the sweep's curve speed (it brakes
            // into it) and swings wider: the places where cars wait are kept clear
            // of that drive too.
            let entering: Vec<Sweep> = lanes
                .iter()
                .map(|&l| {
                    let v = entry_speed_mps(town, LaneIdx(l as u32), lateral_accel_mps2);
                    sweep(town, vp, v, LaneIdx(l as u32))
                })
                .collect();
            // A car that waited at its entry meets a lane that starts at an
            // angle to its approach with the approach's heading, and swings
            // wider than the lane's own start has it (Town04's road 691).
            let from_wait: Vec<Sweep> = lanes
                .iter()
                .map(|&l| lane_sweep_from_wait(town, vp, lateral_accel_mps2, LaneIdx(l as u32)))
                .collect();
            for &entry in lanes {
                hold_back[entry] = entry_hold_back_m(
                    town,
                    vp,
                    LaneIdx(entry as u32),
                    lanes,
                    &[&sweeps, &entering, &from_wait],
                );
            }
            for (k, &a) in lanes.iter().enumerate() {
                for (m, &b) in lanes.iter().enumerate().skip(k + 1) {
                    if centrelines_within(town, a, b, CONFLICT_M)
                        || sweeps_touch(&sweeps[k], &sweeps[m], half)
                    {
                        by_lane[a].push(LaneIdx(b as u32));
                        by_lane[b].push(LaneIdx(a as u32));
                    }
                }
            }
        }
        let movements = extend_to_movements(town, &mut by_lane);
        // Right of way the map gives, where the two lanes conflict.
        let mut gives_way_to = vec![Vec::new(); town.lanes.len()];
        for j in &town.junctions {
            for &(high, low) in &j.priorities {
                let (h, l) = (high.0 as usize, low.0 as usize);
                if h < by_lane.len()
                    && l < by_lane.len()
                    && by_lane[l].contains(&high)
                    && !gives_way_to[l].contains(&high)
                {
                    gives_way_to[l].push(high);
                }
            }
        }
        JunctionConflicts {
            by_lane,
            gives_way_to,
            movements,
            hold_back,
        }
    }

    /// How far before the usual place a car waits to enter junction lane
    /// `lane` (metres): 0, unless a car standing there, its front bumper
    /// [`WAIT_GAP_M`] before the lane, would be touched by a car driving
    /// another movement of the junction, swept at its curve speeds or at the
    /// speed it enters the turn with ([`entry_speed_mps`]): a right turn too
    /// tight to steer swings its body over the lane beside its exit, where the
    /// cars of that road wait for their turn (Town03's junction 813). Then the
    /// car waits this much further back, the first place every such sweep
    /// misses, in steps of [`SWEEP_STEP_M`] up to [`MAX_HOLD_BACK_M`]. 0 for a
    /// lane outside junctions or not entered from outside its junction, and for
    /// every lane of Town01, Town02 and our generated towns.
    pub fn hold_back_m(&self, lane: LaneIdx) -> f32 {
        self.hold_back.get(lane.0 as usize).copied().unwrap_or(0.0)
    }

    /// The lanes `lane` conflicts with (none for a lane outside junctions).
    pub fn of(&self, lane: LaneIdx) -> &[LaneIdx] {
        self.by_lane.get(lane.0 as usize).map_or(&[], |v| &v[..])
    }

    /// Whether `lane` is on the movement through the junction that starts at
    /// connecting lane `entry` ([`movement`]), found once when the conflicts were.
    pub fn in_movement(&self, entry: LaneIdx, lane: LaneIdx) -> bool {
        entry == lane
            || self
                .movements
                .get(entry.0 as usize)
                .is_some_and(|m| m.contains(&lane))
    }

    /// The conflicting lanes the map gives priority over `lane` (its
    /// junction's `<priority>`, e.g. a roundabout's ring over its entry): a
    /// car about to take `lane` gives way to a vehicle on or about to enter
    /// one of them ([`crate::rules::must_give_way`]). Empty where the map
    /// says nothing: first come, first served.
    pub fn gives_way_to(&self, lane: LaneIdx) -> &[LaneIdx] {
        self.gives_way_to
            .get(lane.0 as usize)
            .map_or(&[], |v| &v[..])
    }
}

/// Where a car waits before a junction lane (front bumper to the lane's start,
/// metres): the NPCs' standstill gap (`NpcParams::stop_gap_m`).
pub const WAIT_GAP_M: f32 = 0.5;

/// The farthest a car waits before its usual waiting place (metres).
pub const MAX_HOLD_BACK_M: f32 = 8.0;

/// The deceleration an NPC brakes into a curve with (metres per second
/// squared; `NpcParams::comfort_decel_mps2`).
const CURVE_BRAKE_MPS2: f32 = 3.0;

/// The speed a car enters connecting lane `lane` with when it brakes into its
/// sharpest curve at [`CURVE_BRAKE_MPS2`] and reaches that curve's speed there
/// (metres per second; at most the lane's limit).
pub fn entry_speed_mps(town: &Town, lane: LaneIdx, lateral_accel_mps2: f32) -> f32 {
    let l = town.lane(lane);
    let pts: Vec<Vec2> = l.centerline.iter().map(|p| p.truncate()).collect();
    let sharpest = pts
        .windows(3)
        .enumerate()
        .map(|(i, w)| (i + 1, curvature(w[0], w[1], w[2])))
        .fold((0, 0.0f32), |a, b| if b.1 > a.1 { b } else { a });
    if sharpest.1 <= 1e-4 {
        return l.speed_limit_mps;
    }
    let vc = crate::rules::pursuit::curve_speed_mps(sharpest.1, lateral_accel_mps2);
    let s = l.s.get(sharpest.0).copied().unwrap_or(0.0);
    (vc * vc + 2.0 * CURVE_BRAKE_MPS2 * s)
        .sqrt()
        .min(l.speed_limit_mps)
        .max(CREEP_MPS)
}

/// [`JunctionConflicts::hold_back_m`] for `entry`, a lane of the junction
/// whose lanes are `lanes` (indices into the town's lanes), swept each way of
/// `sweeps` (one sweep per lane, in `lanes`' order).
fn entry_hold_back_m(
    town: &Town,
    vp: &VehicleParams,
    entry: LaneIdx,
    lanes: &[usize],
    sweeps: &[&[Sweep]],
) -> f32 {
    let e = town.lane(entry);
    // Entered from outside the junction (the first lane of a movement).
    let approaches: Vec<LaneIdx> = e
        .predecessors
        .iter()
        .copied()
        .filter(|p| town.lanes[p.0 as usize].junction != e.junction)
        .collect();
    if approaches.is_empty() {
        return 0.0;
    }
    // The lanes of movements from the same approach lanes: their cars queue
    // with this one.
    let same_approach = |l: usize| {
        movement_before(town, LaneIdx(l as u32)).iter().any(|b| {
            town.lanes[b.0 as usize]
                .predecessors
                .iter()
                .any(|q| approaches.contains(q))
        })
    };
    let others: Vec<&Sweep> = lanes
        .iter()
        .enumerate()
        .filter(|&(_, &l)| !same_approach(l))
        .flat_map(|(k, _)| sweeps.iter().map(move |s| &s[k]))
        .collect();
    let half = vp.half_extents() + Vec2::splat(CLEARANCE_M * 0.5);
    let mut back = 0.0;
    while back <= MAX_HOLD_BACK_M {
        let clear = approaches.iter().all(|&a| {
            let l = town.lane(a);
            let s = l.length_m() - WAIT_GAP_M - vp.length_m * 0.5 - back;
            let (p, yaw, _) = l.pose_at(s.max(0.0));
            let standing = Sweep {
                poses: vec![(p, Vec2::from_angle(yaw))],
                lo: p,
                hi: p,
            };
            others.iter().all(|o| !sweeps_touch(&standing, o, half))
        });
        if clear {
            return back;
        }
        back += SWEEP_STEP_M;
    }
    MAX_HOLD_BACK_M
}

/// The lanes of the movement through a junction that starts at connecting lane
/// `entry`: it and every lane of its junction reached from it by successors
/// without leaving the junction, in the order found (breadth first). Just
/// `entry` where its road is one lane section, as on Town01 and Town02.
pub fn movement(town: &Town, entry: LaneIdx) -> Vec<LaneIdx> {
    along_movement(town, entry, |l| &l.successors)
}

/// The lanes of the movements through `lane`'s junction that reach `lane`: it
/// and every lane of its junction it is reached from without leaving it.
fn movement_before(town: &Town, lane: LaneIdx) -> Vec<LaneIdx> {
    along_movement(town, lane, |l| &l.predecessors)
}

fn along_movement(
    town: &Town,
    from: LaneIdx,
    next: impl Fn(&crate::map::town::DriveLane) -> &Vec<LaneIdx>,
) -> Vec<LaneIdx> {
    let junction = town.lanes[from.0 as usize].junction;
    let mut found = vec![from];
    let mut k = 0;
    while k < found.len() {
        for &n in next(&town.lanes[found[k].0 as usize]) {
            if junction.is_some()
                && town.lanes[n.0 as usize].junction == junction
                && !found.contains(&n)
            {
                found.push(n);
            }
        }
        k += 1;
    }
    found
}

/// The lane a car enters junction lane `lane`'s movement from: the last lane
/// before its junction, following first predecessors (None for a lane
/// outside junctions or one no lane leads to).
pub fn movement_entry(town: &Town, lane: LaneIdx) -> Option<LaneIdx> {
    let junction = town.lanes[lane.0 as usize].junction?;
    let mut at = lane;
    for _ in 0..town.lanes.len() {
        let &prev = town.lanes[at.0 as usize].predecessors.first()?;
        if town.lanes[prev.0 as usize].junction != Some(junction) {
            return Some(prev);
        }
        at = prev;
    }
    None
}

/// Whether connecting lanes `a` and `b` belong to two movements driven side
/// by side: from neighbouring lanes of one road into the neighbouring lanes
/// of one road, the one on the right staying on the right (a double right
/// turn, two lanes going straight on). Such lanes may still conflict: their
/// cars' bodies come close where one lags the other by part of the turn
/// (Town06's junction 509, Town03's 545), not where they drive beside each
/// other; [`crate::traffic::Reservations`] lets them enter together. Town01,
/// Town02 and our generated towns with one lane each way have no such pairs.
pub fn side_by_side(town: &Town, a: LaneIdx, b: LaneIdx) -> bool {
    let (Some(ia), Some(ib)) = (movement_entry(town, a), movement_entry(town, b)) else {
        return false;
    };
    let (oa, ob) = (movement_exit(town, a), movement_exit(town, b));
    let (ia, oa) = (&town.lanes[ia.0 as usize], &town.lanes[oa.0 as usize]);
    (ia.right == Some(ib) && oa.right == Some(ob)) || (ia.left == Some(ib) && oa.left == Some(ob))
}

/// The lane a car leaves `entry`'s movement by: the first lane out of the
/// junction, following first successors (`entry` itself if it leads nowhere).
pub fn movement_exit(town: &Town, entry: LaneIdx) -> LaneIdx {
    let junction = town.lanes[entry.0 as usize].junction;
    let mut lane = entry;
    for _ in 0..town.lanes.len() {
        let Some(&next) = town.lanes[lane.0 as usize].successors.first() else {
            return lane;
        };
        if junction.is_none() || town.lanes[next.0 as usize].junction != junction {
            return next;
        }
        lane = next;
    }
    lane
}

/// Makes lanes conflict whose movements do ([`movement`]): `b` conflicts with
/// `a` when a lane of `a`'s movement conflicts with a lane of `b`'s. Lanes of
/// junctions without chained lanes keep their conflicts as they are. Returns
/// each lane's movement for those junctions (empty for the others).
fn extend_to_movements(town: &Town, by_lane: &mut [Vec<LaneIdx>]) -> Vec<Vec<LaneIdx>> {
    let n = town.lanes.len();
    let mut movements = vec![Vec::new(); n];
    let chained = |i: usize| {
        let l = &town.lanes[i];
        l.junction.is_some()
            && l.successors
                .iter()
                .chain(&l.predecessors)
                .any(|n| town.lanes[n.0 as usize].junction == l.junction)
    };
    let junctions: std::collections::BTreeSet<_> = (0..n)
        .filter(|&i| chained(i))
        .filter_map(|i| town.lanes[i].junction)
        .collect();
    let in_chained = |i: usize| {
        town.lanes[i]
            .junction
            .is_some_and(|j| junctions.contains(&j))
    };
    // Each lane's movements before it, walked once.
    let mut before = vec![Vec::new(); n];
    for i in (0..n).filter(|&i| in_chained(i)) {
        movements[i] = movement(town, LaneIdx(i as u32));
        before[i] = movement_before(town, LaneIdx(i as u32));
    }
    let raw = by_lane.to_vec();
    for a in (0..n).filter(|&a| in_chained(a)) {
        let mut all: Vec<LaneIdx> = movements[a]
            .iter()
            .flat_map(|a2| raw[a2.0 as usize].iter())
            // A conflicting lane is of the same junction: its movements were walked.
            .flat_map(|c| before[c.0 as usize].iter())
            .copied()
            .filter(|b| b.0 as usize != a)
            .collect();
        all.sort();
        all.dedup();
        by_lane[a] = all;
    }
    movements
}

/// The speeds a lane is swept at: creeping (a car that starts from the
/// entry) and the speed an NPC takes its sharpest curve at (the lane's
/// limit, or where that curve asks `lateral_accel_mps2`; metres per second).
pub fn sweep_speeds_mps(town: &Town, lane: LaneIdx, lateral_accel_mps2: f32) -> [f32; 2] {
    let l = town.lane(lane);
    let pts: Vec<Vec2> = l.centerline.iter().map(|p| p.truncate()).collect();
    let k_max = pts
        .windows(3)
        .map(|w| curvature(w[0], w[1], w[2]))
        .fold(0.0f32, f32::max);
    let v_curve = if k_max > 1e-4 {
        crate::rules::pursuit::curve_speed_mps(k_max, lateral_accel_mps2)
    } else {
        f32::INFINITY
    };
    [CREEP_MPS, l.speed_limit_mps.min(v_curve).max(CREEP_MPS)]
}

/// Where a car's body is while it drives `lane` at either of its
/// [`sweep_speeds_mps`]: the two drives of [`sweep`] together.
pub fn lane_sweep(
    town: &Town,
    vp: &VehicleParams,
    lateral_accel_mps2: f32,
    lane: LaneIdx,
) -> Sweep {
    let [slow, fast] = sweep_speeds_mps(town, lane, lateral_accel_mps2);
    sweep(town, vp, slow, lane).join(sweep(town, vp, fast, lane))
}

/// Where a car's body is while it drives `lane` from where it waited for it,
/// on each approach from outside the junction, at either of its
/// [`sweep_speeds_mps`]: the drives of [`sweep_from_wait`] together (no
/// footprints for a lane entered from inside its junction).
pub fn lane_sweep_from_wait(
    town: &Town,
    vp: &VehicleParams,
    lateral_accel_mps2: f32,
    lane: LaneIdx,
) -> Sweep {
    let l = town.lane(lane);
    let speeds = sweep_speeds_mps(town, lane, lateral_accel_mps2);
    l.predecessors
        .iter()
        .filter(|p| town.lane(**p).junction != l.junction)
        .flat_map(|&a| speeds.map(|v| sweep_from_wait(town, vp, v, a, lane)))
        .flatten()
        .fold(Sweep::empty(), Sweep::join)
}

impl Sweep {
    /// A sweep with no footprints (touches nothing).
    pub fn empty() -> Sweep {
        Sweep {
            poses: Vec::new(),
            lo: Vec2::splat(f32::INFINITY),
            hi: Vec2::splat(f32::NEG_INFINITY),
        }
    }

    /// The footprints of both sweeps, this one's first.
    pub fn join(mut self, other: Sweep) -> Sweep {
        self.poses.extend(other.poses);
        self.lo = self.lo.min(other.lo);
        self.hi = self.hi.max(other.hi);
        self
    }
}

/// Drives a car of `vp` through `lane` as an NPC would, at `speed_mps`
/// throughout: from the lane's start, on its centreline and heading,
/// steering by [`pursuit_steer`] along the lane and its first successors (as
/// many as its pursuit point needs to stay on the path),
/// until the car's rear is 1 m past the lane's end (as a reservation is
/// released) or it has driven three times the lane's length.
pub fn sweep(town: &Town, vp: &VehicleParams, speed_mps: f32, lane: LaneIdx) -> Sweep {
    let (p0, yaw0, _) = town.lane(lane).pose_at(0.0);
    drive_through(
        town,
        vp,
        speed_mps,
        LanePath::new(lane, 0.0),
        (p0, yaw0),
        lane,
    )
}

/// Drives `lane` as [`sweep`] does, but from where a car waits to enter it:
/// standing on `approach` (a lane leading into it from outside its
/// junction), its front bumper [`WAIT_GAP_M`] before the lane, on the
/// approach's centreline and heading. A car that starts there meets the lane
/// with the approach's heading, not the lane's: where a connecting road
/// starts at an angle to the road before it (Town04's road 691, 17 degrees
/// off road 9), it turns further than its lane and swings wider than
/// [`sweep`]'s car. The footprints are kept from the car's centre entering
/// `lane`, as [`sweep`]'s start. None when the approach is shorter than the
/// car's place there.
pub fn sweep_from_wait(
    town: &Town,
    vp: &VehicleParams,
    speed_mps: f32,
    approach: LaneIdx,
    lane: LaneIdx,
) -> Option<Sweep> {
    let a = town.lane(approach);
    let s = a.length_m() - WAIT_GAP_M - vp.length_m * 0.5;
    if s < 0.0 {
        return None;
    }
    let (p0, yaw0, _) = a.pose_at(s);
    let mut path = LanePath::new(approach, s);
    path.lanes.push_back(lane);
    Some(drive_through(town, vp, speed_mps, path, (p0, yaw0), lane))
}

/// The drive of [`sweep`] and [`sweep_from_wait`]: a car at `start` (centre,
/// yaw in radians) at `speed_mps` along `path`, whose lane `lane` is swept;
/// footprints are kept from the car's centre leaving the path's first lane
/// (from the start where that lane is `lane`).
fn drive_through(
    town: &Town,
    vp: &VehicleParams,
    speed_mps: f32,
    mut path: LanePath,
    start: (Vec2, f32),
    lane: LaneIdx,
) -> Sweep {
    let l = town.lane(lane);
    let v = speed_mps.max(0.1);
    let len = l.length_m();
    let leave_m = vp.length_m * 0.5 + 1.0;
    // The path goes on by first successors until the car can leave the lane
    // with its pursuit point still on the path: past a path's end the car
    // would steer for the end point, off the lanes (a connecting road in
    // lane sections of 0.3 m, Town06's, is a chain of such lanes).
    let mut beyond_m = 0.0;
    let mut last_lane = l;
    while beyond_m < leave_m + pursuit_lookahead_m(v) && path.lanes.len() < MAX_SWEEP_LANES {
        let Some(&next) = last_lane.successors.first() else {
            break;
        };
        path.lanes.push_back(next);
        last_lane = town.lane(next);
        beyond_m += last_lane.length_m();
    }
    let before_m = if path.lane() == lane {
        0.0
    } else {
        path.remaining_m(town) - beyond_m - len
    };
    let (p0, yaw0) = start;
    let mut state = VehicleState::at_rest(p0, yaw0);
    state.speed_mps = v;
    let max_ticks = ((before_m + 3.0 * len + 2.0 * leave_m) / (v * DT_S)).ceil() as usize;
    let first = path.lane();
    let mut poses = Vec::new();
    if first == lane {
        poses.push((p0, Vec2::from_angle(yaw0)));
    }
    let mut last = p0;
    for _ in 0..max_ticks {
        let steer = pursuit_steer(town, vp, &state, &path);
        let control = VehicleControl {
            steer,
            throttle: 0.0,
            brake: 0.0,
        };
        state.step(vp, control, DT_S);
        state.speed_mps = v;
        path.advance_to(town, state.position);
        if poses.is_empty() {
            if path.lane() == first {
                continue;
            }
            poses.push((state.position, Vec2::from_angle(state.yaw)));
            last = state.position;
        }
        if (state.position - last).length() >= SWEEP_STEP_M {
            poses.push((state.position, Vec2::from_angle(state.yaw)));
            last = state.position;
        }
        let gone = if path.lane() == lane {
            path.lanes.len() == 1 && path.s_m >= len - 1e-3
        } else {
            path.s_m > leave_m
        };
        if gone {
            break;
        }
    }
    poses.push((state.position, Vec2::from_angle(state.yaw)));
    let mut lo = Vec2::splat(f32::INFINITY);
    let mut hi = Vec2::splat(f32::NEG_INFINITY);
    for (p, _) in &poses {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    Sweep { poses, lo, hi }
}

/// Whether a box of half extents `half` (length, width) somewhere along
/// `a` overlaps one along `b`.
fn sweeps_touch(a: &Sweep, b: &Sweep, half: Vec2) -> bool {
    let reach = half.length() * 2.0;
    if (a.lo - b.hi).cmpgt(Vec2::splat(reach)).any()
        || (b.lo - a.hi).cmpgt(Vec2::splat(reach)).any()
    {
        return false;
    }
    a.poses.iter().any(|&(pa, da)| {
        b.poses.iter().any(|&(pb, db)| {
            (pa - pb).length_squared() < reach * reach && boxes_overlap(pa, da, pb, db, half)
        })
    })
}

/// Whether two boxes of half extents `half` (along, across their heading)
/// at centres `pa`, `pb` with unit headings `da`, `db` overlap (separating axes).
fn boxes_overlap(pa: Vec2, da: Vec2, pb: Vec2, db: Vec2, half: Vec2) -> bool {
    let d = pb - pa;
    let extent =
        |dir: Vec2, axis: Vec2| half.x * dir.dot(axis).abs() + half.y * dir.perp().dot(axis).abs();
    [da, da.perp(), db, db.perp()]
        .into_iter()
        .all(|axis| d.dot(axis).abs() <= extent(da, axis) + extent(db, axis))
}

fn centrelines_within(town: &Town, a: usize, b: usize, d: f32) -> bool {
    let (la, lb) = (&town.lanes[a].centerline, &town.lanes[b].centerline);
    la.iter().any(|p| {
        lb.iter()
            .any(|q| (p.truncate() - q.truncate()).length_squared() < d * d)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::testtown::grid;
    use crate::map::town::{DriveLane, JunctionIdx};

    #[test]
    fn crossing_connecting_lanes_conflict_and_parallel_right_turns_do_not() {
        let t = grid(3, 3, 60.0);
        let conflicts = JunctionConflicts::new(&t);
        // In the centre junction (index 4), a straight east-bound lane and a
        // straight north-bound lane cross.
        let dir = |l: &DriveLane| {
            let a = l.centerline[0].truncate();
            let b = l.centerline.last().unwrap().truncate();
            (b - a).normalize()
        };
        let jl: Vec<usize> = (0..t.lanes.len())
            .filter(|&i| t.lanes[i].junction == Some(JunctionIdx(4)))
            .collect();
        assert_eq!(jl.len(), 12);
        let east = *jl.iter().find(|&&i| dir(&t.lanes[i]).x > 0.99).unwrap();
        let north = *jl.iter().find(|&&i| dir(&t.lanes[i]).y > 0.99).unwrap();
        assert!(
            conflicts
                .of(LaneIdx(east as u32))
                .contains(&LaneIdx(north as u32))
        );
        // Two right turns from opposite approaches never come close.
        let rights: Vec<usize> = jl
            .iter()
            .copied()
            .filter(|&i| {
                let l = &t.lanes[i];
                let d0 = (l.centerline[1] - l.centerline[0]).truncate();
                let n = l.centerline.len();
                let d1 = (l.centerline[n - 1] - l.centerline[n - 2]).truncate();
                d0.perp_dot(d1) < -0.5 * d0.length() * d1.length()
            })
            .collect();
        assert_eq!(rights.len(), 4);
        for &a in &rights {
            for &b in &rights {
                assert!(!conflicts.of(LaneIdx(a as u32)).contains(&LaneIdx(b as u32)));
            }
        }
        // Plain lanes conflict with nothing.
        assert!(conflicts.of(LaneIdx(0)).is_empty());
        assert!(conflicts.of(LaneIdx(9999)).is_empty());
    }

    #[test]
    fn a_right_turn_too_tight_to_steer_conflicts_with_the_left_turn_beside_its_exit() {
        // Town02's shape: the right turn north -> west (lane 9) has a 3.5 m
        // radius; the left turn west -> north (lane 8) starts beside its exit,
        // 4 m from it. The centrelines stay more than CONFLICT_M apart, but a
        // car cannot steer that tight and its body swings into the left turn.
        let t = crate::map::testtown::t_junction(3.5);
        let (right, left) = (9usize, 8usize);
        assert!(!centrelines_within(&t, right, left, CONFLICT_M));
        let vp = VehicleParams::default();
        let a = lane_sweep(&t, &vp, 2.5, LaneIdx(right as u32));
        let b = lane_sweep(&t, &vp, 2.5, LaneIdx(left as u32));
        assert!(sweeps_touch(&a, &b, vp.half_extents()), "the bodies touch");
        let conflicts = JunctionConflicts::new(&t);
        assert!(
            conflicts
                .of(LaneIdx(right as u32))
                .contains(&LaneIdx(left as u32))
        );
        assert!(
            conflicts
                .of(LaneIdx(left as u32))
                .contains(&LaneIdx(right as u32))
        );
        // The two straights, 4 m apart, never do.
        assert!(!conflicts.of(LaneIdx(6)).contains(&LaneIdx(7)));
        // A right turn a car can steer stays in its lane: no conflict.
        let gentle = crate::map::testtown::t_junction(7.0);
        let conflicts = JunctionConflicts::new(&gentle);
        assert!(
            !conflicts
                .of(LaneIdx(right as u32))
                .contains(&LaneIdx(left as u32))
        );
    }

    #[test]
    fn a_sweep_follows_its_lane_and_leaves_it() {
        let t = grid(3, 3, 60.0);
        let vp = VehicleParams::default();
        let lane = (0..t.lanes.len())
            .find(|&i| t.lanes[i].junction.is_some())
            .unwrap();
        let s = lane_sweep(&t, &vp, 2.5, LaneIdx(lane as u32));
        let l = &t.lanes[lane];
        let (end, _, _) = l.pose_at(l.length_m());
        let last = s.poses.last().unwrap().0;
        // Ends with the rear past the lane's end, every pose near the path.
        assert!((last - end).length() > vp.length_m * 0.5);
        let line: Vec<Vec2> = l
            .centerline
            .iter()
            .chain(&t.lanes[l.successors[0].0 as usize].centerline)
            .map(|q| q.truncate())
            .collect();
        for (p, _) in &s.poses {
            let off = line
                .windows(2)
                .map(|w| {
                    let (a, b) = (w[0], w[1]);
                    let t = ((*p - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
                    (*p - a.lerp(b, t)).length()
                })
                .fold(f32::INFINITY, f32::min);
            assert!(off < 0.5, "sweep {off} m off the lane at {p}");
        }
    }
}
