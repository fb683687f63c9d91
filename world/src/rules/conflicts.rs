//! Junction conflicts: which connecting lanes of a junction may not be
//! driven at the same time.
//!
//! Two connecting lanes of one junction conflict when their centrelines come
//! within [`CONFLICT_M`] of each other anywhere (crossing paths, and paths
//! that merge into one exit). The NPCs' junction reservations grant a lane
//! only while no conflicting lane is held.

use crate::map::town::{LaneIdx, Town};

/// Distance between two centrelines below which connecting lanes conflict (metres).
pub const CONFLICT_M: f32 = 3.0;

/// For each lane of a town, the connecting lanes of its junction it conflicts with.
#[derive(Debug, Clone, Default)]
pub struct JunctionConflicts {
    by_lane: Vec<Vec<LaneIdx>>,
}

impl JunctionConflicts {
    /// Finds the conflicts of every junction of a town.
    pub fn new(town: &Town) -> JunctionConflicts {
        let mut by_lane = vec![Vec::new(); town.lanes.len()];
        let mut by_junction: std::collections::BTreeMap<u32, Vec<usize>> = Default::default();
        for (i, l) in town.lanes.iter().enumerate() {
            if let Some(j) = l.junction {
                by_junction.entry(j.0).or_default().push(i);
            }
        }
        for lanes in by_junction.values() {
            for (k, &a) in lanes.iter().enumerate() {
                for &b in &lanes[k + 1..] {
                    if centrelines_within(town, a, b, CONFLICT_M) {
                        by_lane[a].push(LaneIdx(b as u32));
                        by_lane[b].push(LaneIdx(a as u32));
                    }
                }
            }
        }
        JunctionConflicts { by_lane }
    }

    /// The lanes `lane` conflicts with (none for a lane outside junctions).
    pub fn of(&self, lane: LaneIdx) -> &[LaneIdx] {
        self.by_lane.get(lane.0 as usize).map_or(&[], |v| &v[..])
    }
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
}
