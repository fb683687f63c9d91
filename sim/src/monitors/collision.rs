//! Collisions, counted as TimeParam counts them (docs/protocol.md §3): each other
//! actor at most once per run, no new collision within a cooldown of the last
//! one counted, and none while the ego is (almost) standing still, since then
//! the other party hit the ego.

use std::collections::BTreeSet;

use super::{ContactKind, EgoTick, Infraction, InfractionKind, Monitor};

/// Counts collisions by kind.
#[derive(Debug, Clone)]
pub struct CollisionMonitor {
    /// Ticks after a counted collision during which no other is counted.
    pub cooldown_ticks: u64,
    /// Below this ego speed contacts are ignored (metres per second).
    pub min_speed_mps: f32,
    counted: BTreeSet<u32>,
    last_tick: Option<u64>,
}

impl Default for CollisionMonitor {
    fn default() -> Self {
        Self {
            cooldown_ticks: 20,
            min_speed_mps: 0.1,
            counted: BTreeSet::new(),
            last_tick: None,
        }
    }
}

impl CollisionMonitor {}

impl Monitor for CollisionMonitor {
    /// Looks at this tick's contacts; pushes the collisions that count.
    fn observe(&mut self, tick: &EgoTick<'_>, out: &mut Vec<Infraction>) {
        if tick.speed_mps < self.min_speed_mps {
            return;
        }
        for contact in tick.contacts {
            let cooling = self
                .last_tick
                .is_some_and(|last| tick.tick < last + self.cooldown_ticks);
            if cooling || self.counted.contains(&contact.other) {
                continue;
            }
            self.counted.insert(contact.other);
            self.last_tick = Some(tick.tick);
            let kind = match contact.kind {
                ContactKind::Vehicle => InfractionKind::CollisionVehicle,
                ContactKind::Pedestrian => InfractionKind::CollisionPedestrian,
                ContactKind::Static => InfractionKind::CollisionStatic,
            };
            let detail = match contact.static_name {
                Some(name) => format!("a {name}"),
                None => format!("actor {}", contact.other),
            };
            out.push(Infraction::at(tick, kind, detail));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::{EgoContact, scripted};
    use super::*;

    /// Drives 100 ticks at `speed`, touching `contact_at(tick)`.
    fn count(speed: f32, contact_at: impl Fn(u64) -> Vec<EgoContact>) -> Vec<InfractionKind> {
        let mut monitor = CollisionMonitor::default();
        let mut out = Vec::new();
        let poses = scripted::straight(0.0, 0.0, speed, 100);
        scripted::drive(&poses, speed, &[], |t| {
            let contacts = contact_at(t.tick);
            let tick = EgoTick {
                contacts: &contacts,
                ..*t
            };
            monitor.observe(&tick, &mut out);
        });
        out.into_iter().map(|i| i.kind).collect()
    }

    const CAR: EgoContact = EgoContact {
        other: 7,
        kind: ContactKind::Vehicle,
        static_name: None,
    };
    const WALKER: EgoContact = EgoContact {
        other: 9,
        kind: ContactKind::Pedestrian,
        static_name: None,
    };
    const WALL: EgoContact = EgoContact {
        other: 100,
        kind: ContactKind::Static,
        static_name: Some("building"),
    };

    #[test]
    fn a_long_contact_with_one_car_counts_once() {
        assert_eq!(
            count(5.0, |t| if (10..40).contains(&t) {
                vec![CAR]
            } else {
                vec![]
            }),
            vec![InfractionKind::CollisionVehicle]
        );
    }

    #[test]
    fn the_same_actor_never_counts_twice() {
        let got = count(5.0, |t| {
            if t == 10 || t == 80 {
                vec![CAR]
            } else {
                vec![]
            }
        });
        assert_eq!(got, vec![InfractionKind::CollisionVehicle]);
    }

    #[test]
    fn cooldown_hides_a_second_actor_for_twenty_ticks() {
        let got = count(5.0, |t| match t {
            10 => vec![CAR],
            20 => vec![WALKER], // within 20 ticks of the first: ignored
            30 => vec![WALL],   // 20 ticks later: counted
            _ => vec![],
        });
        assert_eq!(
            got,
            vec![
                InfractionKind::CollisionVehicle,
                InfractionKind::CollisionStatic
            ]
        );
    }

    #[test]
    fn contacts_while_standing_still_are_ignored() {
        assert!(count(0.05, |_| vec![CAR]).is_empty());
    }
}
