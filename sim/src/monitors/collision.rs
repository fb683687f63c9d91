//! Collisions as they happen: every contact recorded as a touch
//! ([`super::contacts`]) and counted under the paper's rule
//! ([`super::counting::paper`], docs/protocol.md §3). The record counts the
//! same touches under every rule at the run's end.

use super::contacts::{ContactLog, Touch};
use super::counting::{CountingRule, collision_kind};
use super::{EgoTick, Infraction, Monitor};

/// Records the ego's touches and reports the collisions the paper's rule counts.
#[derive(Debug, Clone, Default)]
pub struct CollisionMonitor {
    log: ContactLog,
}

impl CollisionMonitor {
    /// Every touch so far.
    pub fn touches(&self) -> &[Touch] {
        self.log.touches()
    }

    /// Takes the touches out (at the run's end).
    pub fn into_touches(self) -> Vec<Touch> {
        self.log.into_touches()
    }
}

impl Monitor for CollisionMonitor {
    /// Records this tick's touches; pushes the collisions that count.
    fn observe(&mut self, tick: &EgoTick<'_>, out: &mut Vec<Infraction>) {
        let added = self.log.observe(tick, tick.kerbs);
        if added == 0 {
            return;
        }
        let touches = self.log.touches();
        let first_new = touches.len() - added;
        for i in CountingRule::Paper.counted(touches) {
            if i < first_new {
                continue;
            }
            let t = &touches[i];
            let detail = match t.actor {
                Some(id) => format!("actor {id}"),
                None => format!("a {}", t.what),
            };
            out.push(Infraction::at(tick, collision_kind(t), detail));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::scripted::{self, CAR, TREE, WALKER, WALL};
    use super::super::{EgoContact, InfractionKind};
    use super::*;

    /// Drives 100 ticks at `speed`, touching `contact_at(tick)`.
    fn count(speed: f32, contact_at: impl Fn(u64) -> Vec<EgoContact>) -> Vec<InfractionKind> {
        let mut monitor = CollisionMonitor::default();
        let mut out = Vec::new();
        scripted::touching(speed, 100, contact_at, |t| monitor.observe(t, &mut out));
        out.into_iter().map(|i| i.kind).collect()
    }

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
    fn each_actor_counts_once_and_the_map_is_one_actor() {
        let got = count(5.0, |t| match t {
            10 => vec![CAR],
            11 => vec![WALKER], // right after another: counted (no cooldown across actors)
            30 => vec![WALL],
            90 => vec![TREE], // more map geometry: the same actor
            _ => vec![],
        });
        assert_eq!(
            got,
            vec![
                InfractionKind::CollisionVehicle,
                InfractionKind::CollisionPedestrian,
                InfractionKind::CollisionStatic
            ]
        );
    }

    #[test]
    fn contacts_while_standing_still_count() {
        assert_eq!(
            count(0.0, |_| vec![CAR]),
            vec![InfractionKind::CollisionVehicle]
        );
    }
}
