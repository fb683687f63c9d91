//! Every contact of the ego, recorded as touches, so that a counting rule
//! ([`super::counting`]) can be applied to a run afterwards without running it
//! again.
//!
//! A touch is what CARLA's collision sensor reports (`sensor.other.collision`,
//! one event per frame of contact): the first tick the ego touches a vehicle, a
//! pedestrian or a piece of map geometry (a building, a pole, a tree); then,
//! while the contact goes on, a repeat every [`REPEAT_M`] moved or [`REPEAT_S`]
//! elapsed (the sensor fires every frame; the rules only ever tell two frames of
//! one contact apart by where the ego is and how much time has passed; a
//! contact broken off for less than [`REPEAT_S`] goes on); and
//! every kerb an axle goes up or down (CARLA's wheels climb its sidewalks, whose
//! mesh is the map actor `static.sidewalk`).
//!
//! Each touch also keeps the first later tick at which the ego's centre was
//! more than [`FORGET_M`] from where it was at the touch: leaderboard 1.0
//! forgets a collision's location then (`MAX_AREA_OF_COLLISION`).

use std::collections::BTreeMap;

use glam::Vec2;
use serde::{Deserialize, Serialize};
use world::agents::kerb::KerbCrossing;

use super::{ContactKind, EgoTick};

/// A continued contact is touched again after the ego moved this far (metres).
pub const REPEAT_M: f32 = 0.5;
/// ... or after this long (seconds).
pub const REPEAT_S: f64 = 1.0;
/// How far the ego must go from a touch for leaderboard 1.0 to forget its
/// location (metres; scenario_runner `leaderboard-1.0`, `atomic_criteria.py`
/// `CollisionTest.MAX_AREA_OF_COLLISION`).
pub const FORGET_M: f32 = 5.0;

/// What the ego touched.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TouchWith {
    /// An NPC vehicle.
    Vehicle,
    /// A pedestrian.
    Pedestrian,
    /// Map geometry: a building, a pole, a tree, a lamp (CARLA's actor 0).
    Map,
    /// A kerb, up or down (CARLA's `static.sidewalk`, also actor 0).
    Kerb,
}

/// The axle and motion of a kerb touch.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct KerbTouch {
    /// The front axle (`false`: the rear).
    pub front_axle: bool,
    /// The height climbed (metres; negative: down).
    pub height_m: f32,
    /// The angle between the heading and the kerb (degrees, 0 to 90).
    pub angle_deg: f32,
    /// The speed before and after the axle crossed (metres per second).
    pub speed_mps: (f32, f32),
}

/// One contact event of the ego (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Touch {
    /// The tick it happened in.
    pub tick: u64,
    /// Simulation time at the tick's end (seconds).
    pub time_s: f64,
    /// What was touched.
    pub with: TouchWith,
    /// The other actor's id (vehicles and pedestrians; `None` for the map).
    pub actor: Option<u32>,
    /// In a word: "vehicle", "pedestrian", "building", "pole", "kerb up", "kerb down".
    pub what: String,
    /// The ego's centre (metres, world frame).
    pub position: [f32; 2],
    /// The ego's speed at the tick's end (metres per second).
    pub speed_mps: f32,
    /// A repeat of a contact that goes on (`false`: its first tick).
    pub repeat: bool,
    /// For a kerb: the axle and the speed it lost.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kerb: Option<KerbTouch>,
    /// The first later tick at which the ego's centre was more than [`FORGET_M`]
    /// from `position`; `None` if it never was before the run ended.
    pub left_tick: Option<u64>,
}

/// Which contact a repeat continues: an actor by id, or a kind of map geometry.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Party {
    Actor(u32),
    Map(&'static str),
}

/// A contact going on.
#[derive(Debug, Clone, Copy)]
struct Ongoing {
    /// When and where its last touch was recorded (seconds, metres).
    touched_s: f64,
    touched_at: Vec2,
    /// The last tick it was in contact (seconds).
    contact_s: f64,
}

/// Turns each tick's contacts and kerb crossings into [`Touch`]es.
#[derive(Debug, Clone, Default)]
pub struct ContactLog {
    touches: Vec<Touch>,
    /// Touches the ego has not yet left by [`FORGET_M`].
    near: Vec<usize>,
    /// Contacts going on, by party.
    ongoing: BTreeMap<Party, Ongoing>,
}

impl ContactLog {
    /// Every touch so far, in order.
    pub fn touches(&self) -> &[Touch] {
        &self.touches
    }

    /// Takes the touches out (at the run's end).
    pub fn into_touches(self) -> Vec<Touch> {
        self.touches
    }

    /// Records one tick: its contacts (`tick.contacts`) and the ego's kerb
    /// crossings. Returns how many touches the tick added (they are the last ones).
    pub fn observe(&mut self, tick: &EgoTick<'_>, kerbs: &[KerbCrossing]) -> usize {
        let here = tick.now.ground();
        let before = self.touches.len();
        self.near.retain(|&i| {
            let t = &mut self.touches[i];
            let left = (Vec2::from(t.position) - here).length() > FORGET_M;
            if left {
                t.left_tick = Some(tick.tick);
            }
            !left
        });
        let touch = |with, actor, what: &str, repeat, kerb| Touch {
            tick: tick.tick,
            time_s: tick.time_s,
            with,
            actor,
            what: what.to_string(),
            position: here.to_array(),
            speed_mps: tick.speed_mps,
            repeat,
            kerb,
            left_tick: None,
        };
        // A contact broken off for less than REPEAT_S goes on: a car pressed
        // against a wall touches it on every other tick.
        self.ongoing
            .retain(|_, o| tick.time_s - o.contact_s < REPEAT_S - 1e-9);
        let mut seen: Vec<Party> = Vec::with_capacity(tick.contacts.len());
        for c in tick.contacts {
            let (party, with, actor, what) = match c.kind {
                ContactKind::Vehicle => (
                    Party::Actor(c.other),
                    TouchWith::Vehicle,
                    Some(c.other),
                    "vehicle",
                ),
                ContactKind::Pedestrian => (
                    Party::Actor(c.other),
                    TouchWith::Pedestrian,
                    Some(c.other),
                    "pedestrian",
                ),
                ContactKind::Static => {
                    let name = c.static_name.unwrap_or("static");
                    (Party::Map(name), TouchWith::Map, None, name)
                }
            };
            if seen.contains(&party) {
                continue;
            }
            seen.push(party);
            let repeat = match self.ongoing.get_mut(&party) {
                None => false,
                Some(o) => {
                    o.contact_s = tick.time_s;
                    if tick.time_s - o.touched_s < REPEAT_S - 1e-9
                        && (here - o.touched_at).length() < REPEAT_M
                    {
                        continue;
                    }
                    true
                }
            };
            let o = Ongoing {
                touched_s: tick.time_s,
                touched_at: here,
                contact_s: tick.time_s,
            };
            self.ongoing.insert(party, o);
            self.touches.push(touch(with, actor, what, repeat, None));
        }
        for k in kerbs {
            let what = if k.height_m > 0.0 {
                "kerb up"
            } else {
                "kerb down"
            };
            let kerb = KerbTouch {
                front_axle: k.front,
                height_m: k.height_m,
                angle_deg: k.angle_rad.to_degrees(),
                speed_mps: k.speed_mps,
            };
            self.touches
                .push(touch(TouchWith::Kerb, None, what, false, Some(kerb)));
        }
        self.near.extend(before..self.touches.len());
        self.touches.len() - before
    }
}

#[cfg(test)]
mod tests {
    use super::super::EgoContact;
    use super::super::scripted::{self, CAR, WALL};
    use super::*;

    /// Drives 200 ticks (5 s) along +x at `speed`, touching `contact_at(tick)`.
    fn log(speed: f32, contact_at: impl Fn(u64) -> Vec<EgoContact>) -> Vec<Touch> {
        let mut log = ContactLog::default();
        scripted::touching(speed, 200, contact_at, |t| {
            log.observe(t, &[]);
        });
        log.into_touches()
    }

    #[test]
    fn a_contact_is_touched_at_its_start_and_again_every_half_metre_or_second() {
        // 1 m/s for 100 ticks (2.5 s): moved 2.5 m; repeats each 0.5 m.
        let moving = log(1.0, |t| if t <= 100 { vec![CAR] } else { vec![] });
        assert!(!moving[0].repeat && moving[0].tick == 1);
        assert_eq!(moving.len(), 5, "{moving:?}");
        assert!(moving[1..].iter().all(|t| t.repeat));
        // Standing against a wall for 5 s: a repeat every second.
        let standing = log(0.0, |_| vec![WALL]);
        let ticks: Vec<u64> = standing.iter().map(|t| t.tick).collect();
        assert_eq!(ticks.len(), 5, "{ticks:?}");
        assert!(ticks.windows(2).all(|w| w[1] - w[0] == 40), "{ticks:?}");
        assert!(
            standing
                .iter()
                .all(|t| t.with == TouchWith::Map && t.actor.is_none())
        );
        assert_eq!(standing[0].what, "building");
        // A contact that flickers (pressed against a wall, on every other tick)
        // goes on; one broken off for a second or more is a new contact.
        let flicker = log(0.0, |t| if t % 2 == 0 { vec![WALL] } else { vec![] });
        assert_eq!(flicker.len(), 5, "{flicker:?}");
        assert_eq!(flicker.iter().filter(|t| !t.repeat).count(), 1);
        let twice = log(0.0, |t| if t == 5 || t == 45 { vec![CAR] } else { vec![] });
        assert_eq!(twice.iter().filter(|t| !t.repeat).count(), 2);
        let soon = log(0.0, |t| if t == 5 || t == 44 { vec![CAR] } else { vec![] });
        assert_eq!(soon.len(), 1, "{soon:?}");
    }

    #[test]
    fn a_touch_remembers_when_the_ego_went_five_metres_from_it() {
        // 10 m/s: 0.25 m a tick; the touch at tick 1 (x = 0.25) is left when x > 5.25.
        let touches = log(10.0, |t| if t == 1 { vec![CAR] } else { vec![] });
        assert_eq!(touches.len(), 1);
        assert_eq!(touches[0].left_tick, Some(22));
        let standing = log(0.0, |t| if t == 1 { vec![CAR] } else { vec![] });
        assert_eq!(standing[0].left_tick, None);
    }

    #[test]
    fn a_kerb_crossing_is_a_touch_with_its_axle_and_speeds() {
        let mut log = ContactLog::default();
        let poses = scripted::straight(0.0, 0.0, 3.0, 1);
        scripted::drive(&poses, 3.0, &[], |t| {
            let up = KerbCrossing {
                front: true,
                height_m: 0.15,
                angle_rad: std::f32::consts::FRAC_PI_6,
                speed_mps: (3.2, 3.0),
            };
            assert_eq!(log.observe(t, &[up]), 1);
        });
        let t = &log.touches()[0];
        assert_eq!((t.with, t.what.as_str()), (TouchWith::Kerb, "kerb up"));
        let k = t.kerb.unwrap();
        assert!(k.front_axle && (k.angle_deg - 30.0).abs() < 1e-3);
        assert_eq!(k.speed_mps, (3.2, 3.0));
    }
}
