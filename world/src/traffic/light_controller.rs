//! Traffic-light controllers: one per junction, cycling its groups.
//!
//! Each junction's groups (the `group` of its lights, in ascending order)
//! take turns: the group's lights are green for `green_s`, yellow for
//! `yellow_s`, then every light of the junction is red for `all_red_s` before
//! the next group's green. Every other group is red meanwhile. A junction
//! whose map sets its yellow (lights generated for a file without any:
//! `Junction::yellow_s`) stays yellow that long, if longer. Each junction
//! starts at a random point of its cycle, drawn from the seed
//! (`ChaCha8Rng`), so the same seed gives the same states at every step.
//! Lights with no junction cycle alone, as a junction of their own with one
//! group and a red phase as long as the green and yellow.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::map::town::{LightIdx, LightState, Town};

/// Phase durations of a light cycle (seconds).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightTiming {
    /// Green per group (seconds). CARLA's default: 10.
    pub green_s: f64,
    /// Yellow per group (seconds). CARLA's default: 3.
    pub yellow_s: f64,
    /// All red between groups (seconds).
    pub all_red_s: f64,
}

impl Default for LightTiming {
    fn default() -> Self {
        LightTiming {
            green_s: 10.0,
            yellow_s: 3.0,
            all_red_s: 2.0,
        }
    }
}

impl LightTiming {
    /// One group's slot: green + yellow + all red (seconds).
    pub fn slot_s(&self) -> f64 {
        self.green_s + self.yellow_s + self.all_red_s
    }
}

/// One junction's cycle.
#[derive(Debug, Clone)]
struct Cycle {
    /// Distinct groups in cycle order.
    groups: Vec<u32>,
    /// Slots in the cycle (groups, plus one red slot for a lone light).
    slots: usize,
    /// Initial phase offset (seconds, in [0, cycle length)).
    offset_s: f64,
    /// Its phase durations: the controller's, with the junction's own yellow
    /// where the map sets one ([`crate::map::town::Junction::yellow_s`]).
    timing: LightTiming,
}

/// The light controllers of a town, stepped with the simulation clock.
#[derive(Debug, Clone)]
pub struct LightController {
    timing: LightTiming,
    cycles: Vec<Cycle>,
    /// Per light: its cycle and its slot in that cycle.
    light_slot: Vec<(usize, usize)>,
    time_s: f64,
}

impl LightController {
    /// Controllers for every junction of `town` with lights, initial phase
    /// offsets drawn from `seed`.
    pub fn new(town: &Town, timing: LightTiming, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut cycles = Vec::new();
        let mut light_slot = vec![(0, 0); town.lights.len()];
        let mut make =
            |groups: Vec<u32>, slots: usize, timing: LightTiming, rng: &mut ChaCha8Rng| {
                let len = slots as f64 * timing.slot_s();
                let offset_s = if len > 0.0 {
                    rng.random::<f64>() * len
                } else {
                    0.0
                };
                cycles.push(Cycle {
                    groups,
                    slots,
                    offset_s,
                    timing,
                });
                cycles.len() - 1
            };
        for (ji, _) in town.junctions.iter().enumerate() {
            let mine: Vec<usize> = (0..town.lights.len())
                .filter(|&i| town.lights[i].junction.map(|j| j.0 as usize) == Some(ji))
                .collect();
            if mine.is_empty() {
                continue;
            }
            let mut groups: Vec<u32> = mine.iter().map(|&i| town.lights[i].group).collect();
            groups.sort();
            groups.dedup();
            let slots = groups.len().max(2);
            let own = LightTiming {
                yellow_s: town.junctions[ji]
                    .yellow_s
                    .map_or(timing.yellow_s, |y| timing.yellow_s.max(f64::from(y))),
                ..timing
            };
            let c = make(groups.clone(), slots, own, &mut rng);
            for &i in &mine {
                let slot = groups
                    .iter()
                    .position(|g| *g == town.lights[i].group)
                    .unwrap_or(0);
                light_slot[i] = (c, slot);
            }
        }
        for (i, l) in town.lights.iter().enumerate() {
            if l.junction.is_none() {
                let c = make(vec![l.group], 2, timing, &mut rng);
                light_slot[i] = (c, 0);
            }
        }
        LightController {
            timing,
            cycles,
            light_slot,
            time_s: 0.0,
        }
    }

    /// Advances the clock by `dt_s` seconds.
    pub fn step(&mut self, dt_s: f64) {
        self.time_s += dt_s;
    }

    /// Seconds since the start.
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// The phase timing in use (a junction may keep its lights yellow longer:
    /// `Junction::yellow_s`).
    pub fn timing(&self) -> LightTiming {
        self.timing
    }

    /// The state of one light now. Lights out of range are red.
    pub fn state(&self, light: LightIdx) -> LightState {
        let Some(&(c, slot)) = self.light_slot.get(light.0 as usize) else {
            return LightState::Red;
        };
        let cycle = &self.cycles[c];
        let timing = cycle.timing;
        let slot_s = timing.slot_s();
        let len = cycle.slots as f64 * slot_s;
        if len <= 0.0 {
            return LightState::Red;
        }
        let phase = (self.time_s + cycle.offset_s).rem_euclid(len);
        let current = ((phase / slot_s) as usize).min(cycle.slots - 1);
        if current != slot {
            return LightState::Red;
        }
        let within = phase - current as f64 * slot_s;
        if within < timing.green_s {
            LightState::Green
        } else if within < timing.green_s + timing.yellow_s {
            LightState::Yellow
        } else {
            LightState::Red
        }
    }

    /// The states of all lights, indexed like `Town::lights`.
    pub fn states(&self) -> Vec<LightState> {
        (0..self.light_slot.len())
            .map(|i| self.state(LightIdx(i as u32)))
            .collect()
    }

    /// Number of junction cycles (junctions with lights, plus lone lights).
    pub fn cycle_count(&self) -> usize {
        self.cycles.len()
    }

    /// The groups of each cycle, in cycle order (for display).
    pub fn cycle_groups(&self) -> impl Iterator<Item = &[u32]> {
        self.cycles.iter().map(|c| c.groups.as_slice())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::town::*;
    use glam::Vec3;

    fn light(j: Option<u32>, group: u32) -> TrafficLight {
        TrafficLight {
            od_id: format!("{j:?}-{group}"),
            position: Vec3::ZERO,
            heading: 0.0,
            head_height_m: 3.0,
            junction: j.map(JunctionIdx),
            group,
            stop_lines: vec![],
        }
    }

    fn town(lights: Vec<TrafficLight>, junctions: usize) -> Town {
        Town {
            junctions: (0..junctions)
                .map(|i| Junction {
                    od_id: i.to_string(),
                    outline: vec![],
                    lights: vec![],
                    priorities: vec![],
                    yellow_s: None,
                })
                .collect(),
            lights,
            ..Town::empty("t")
        }
    }

    /// Step through a whole cycle at 0.05 s and record each light's state.
    fn trace(c: &mut LightController, n: usize, steps: usize) -> Vec<Vec<LightState>> {
        (0..steps)
            .map(|_| {
                c.step(0.05);
                (0..n).map(|i| c.state(LightIdx(i as u32))).collect()
            })
            .collect()
    }

    #[test]
    fn groups_take_turns_with_yellow_and_all_red() {
        let t = town(
            vec![
                light(Some(0), 0),
                light(Some(0), 1),
                light(Some(0), 2),
                light(Some(0), 0),
            ],
            1,
        );
        let timing = LightTiming::default();
        let mut c = LightController::new(&t, timing, 7);
        let tr = trace(&mut c, 4, (3.0 * timing.slot_s() / 0.05) as usize);
        for s in &tr {
            // Never two groups non-red at once; lights of one group agree.
            let live = [s[0], s[1], s[2]]
                .iter()
                .filter(|x| **x != LightState::Red)
                .count();
            assert!(live <= 1, "{s:?}");
            assert_eq!(s[0], s[3]);
        }
        // Each group is green for 10 s and yellow for 3 s per cycle.
        for g in 0..3 {
            let green = tr.iter().filter(|s| s[g] == LightState::Green).count() as f64 * 0.05;
            let yellow = tr.iter().filter(|s| s[g] == LightState::Yellow).count() as f64 * 0.05;
            assert!((green - 10.0).abs() < 0.11, "group {g} green {green}");
            assert!((yellow - 3.0).abs() < 0.11, "group {g} yellow {yellow}");
        }
        // All-red gaps exist: 3 x 2 s per cycle.
        let all_red = tr
            .iter()
            .filter(|s| s.iter().all(|x| *x == LightState::Red))
            .count() as f64
            * 0.05;
        assert!((all_red - 6.0).abs() < 0.2, "all red {all_red}");
        // Green is followed by yellow, never straight by red.
        for w in tr.windows(2) {
            for (a, b) in w[0].iter().zip(&w[1]) {
                assert!(!(*a == LightState::Green && *b == LightState::Red));
            }
        }
    }

    #[test]
    fn a_junction_whose_map_sets_a_longer_yellow_keeps_it() {
        // Junction 0 sets 5.8 s (generated lights on a 65 mph road), junction 1 sets
        // less than the controller's 3 s, junction 2 sets nothing.
        let lights: Vec<TrafficLight> = (0..6).map(|i| light(Some(i / 2), i % 2)).collect();
        let mut t = town(lights, 3);
        t.junctions[0].yellow_s = Some(5.8);
        t.junctions[1].yellow_s = Some(2.4);
        let timing = LightTiming::default();
        let mut c = LightController::new(&t, timing, 5);
        let tr = trace(
            &mut c,
            6,
            (3.0 * 2.0 * (timing.slot_s() + 2.8) / 0.05) as usize,
        );
        // The longest unbroken stretch of a colour (seconds).
        let longest = |l: usize, colour: LightState| {
            let (mut best, mut run) = (0, 0);
            for s in &tr {
                run = if s[l] == colour { run + 1 } else { 0 };
                best = best.max(run);
            }
            best as f64 * 0.05
        };
        for l in [0, 1] {
            let yellow = longest(l, LightState::Yellow);
            assert!((yellow - 5.8).abs() < 0.06, "light {l}: {yellow}");
            let green = longest(l, LightState::Green);
            assert!((green - 10.0).abs() < 0.06, "light {l}: {green}");
        }
        for l in 2..6 {
            let yellow = longest(l, LightState::Yellow);
            assert!((yellow - 3.0).abs() < 0.06, "light {l}: {yellow}");
        }
        // Its groups still never show two colours at once.
        for s in &tr {
            assert!(s[0] == LightState::Red || s[1] == LightState::Red, "{s:?}");
        }
    }

    #[test]
    fn same_seed_same_states_and_seeds_shift_junction_phases() {
        let lights: Vec<TrafficLight> = (0..6).map(|i| light(Some(i / 2), i % 2)).collect();
        let t = town(lights, 3);
        let mut a = LightController::new(&t, LightTiming::default(), 42);
        let mut b = LightController::new(&t, LightTiming::default(), 42);
        assert_eq!(trace(&mut a, 6, 500), trace(&mut b, 6, 500));
        let offsets = |seed| {
            LightController::new(&t, LightTiming::default(), seed)
                .cycles
                .iter()
                .map(|c| c.offset_s)
                .collect::<Vec<_>>()
        };
        assert_ne!(offsets(42), offsets(43));
        let o = offsets(42);
        assert!(
            o[0] != o[1] && o[1] != o[2],
            "junctions get their own offsets: {o:?}"
        );
    }

    #[test]
    fn custom_timing_is_used() {
        let t = town(vec![light(Some(0), 0), light(Some(0), 1)], 1);
        let timing = LightTiming {
            green_s: 5.0,
            yellow_s: 1.0,
            all_red_s: 0.5,
        };
        let mut c = LightController::new(&t, timing, 1);
        let tr = trace(&mut c, 2, (2.0 * timing.slot_s() / 0.05).round() as usize);
        let green = tr.iter().filter(|s| s[0] == LightState::Green).count() as f64 * 0.05;
        assert!((green - 5.0).abs() < 0.11, "{green}");
    }
}
