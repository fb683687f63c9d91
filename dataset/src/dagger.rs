//! A learner that drives while the expert watches: the driver of a DAgger round.
//!
//! Behaviour cloning learns the states the expert visits; a policy that strays
//! from them (stops a metre past a stop line, stands behind nothing) meets
//! states its data never held and does not know what to do there. DAgger
//! (Ross, Gordon and Bagnell 2011) lets the policy drive and labels the states
//! *it* visits; here the labels are world-on-rails action values computed on the
//! recorded frames (`mrdrive label`), which do not care who drove, so a round is
//! a collection driven by [`Dagger`] and the usual labeller.
//!
//! One rule keeps an episode from spending its minutes where the policy is stuck:
//! when the ego has stood (below [`DaggerParams::standing_mps`]) for
//! [`DaggerParams::stuck_s`] seconds while the expert would drive off, the
//! expert takes the wheel for [`DaggerParams::takeover_s`] seconds. The stuck
//! frames before the takeover are the lesson (the labels say go); the takeover
//! carries the episode on to more states of the policy's own. The expert is
//! asked at every boundary, so its state stays that of a driver watching the
//! road.

use sim::driver::{Driver, DriverNeeds, Observation, VehicleControl as Control};

/// When the expert takes over.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DaggerParams {
    /// Below this speed the ego stands (metres per second; the loader's 0.5).
    pub standing_mps: f32,
    /// Standing this long while the expert would drive off hands it the wheel (seconds).
    pub stuck_s: f64,
    /// How long the expert then drives (seconds).
    pub takeover_s: f64,
}

impl Default for DaggerParams {
    /// 3 s stuck, then 5 s of the expert. A wait at a red light never counts (the
    /// expert brakes too); a green phase of Town01's lights lasts about 8 s (the
    /// trace of docs/training.md, "DAgger"), so a learner that stands through green
    /// hands over while it is still green, where 8 s would hand over only at red.
    fn default() -> Self {
        DaggerParams {
            standing_mps: 0.5,
            stuck_s: 3.0,
            takeover_s: 5.0,
        }
    }
}

/// The learner drives; the expert watches and takes over where the learner is stuck.
pub struct Dagger<E> {
    learner: Box<dyn Driver>,
    expert: E,
    params: DaggerParams,
    /// Since when the ego has stood while the expert would go (simulated seconds).
    stuck_since: Option<f64>,
    /// The expert drives until this time (simulated seconds).
    expert_until: Option<f64>,
    /// Control boundaries at which the learner drove.
    pub learner_boundaries: u64,
    /// Control boundaries at which the expert drove.
    pub expert_boundaries: u64,
    /// Times the expert took over.
    pub takeovers: u64,
}

impl<E: Driver> Dagger<E> {
    /// `learner` drives, `expert` takes over by `params`.
    pub fn new(learner: Box<dyn Driver>, expert: E, params: DaggerParams) -> Self {
        Dagger {
            learner,
            expert,
            params,
            stuck_since: None,
            expert_until: None,
            learner_boundaries: 0,
            expert_boundaries: 0,
            takeovers: 0,
        }
    }

    /// Whether the expert's control drives off: throttle and no brake.
    fn goes(c: &Control) -> bool {
        c.throttle > 0.0 && c.brake <= 0.0
    }
}

impl<E: Driver> Driver for Dagger<E> {
    fn name(&self) -> String {
        format!(
            "{} watched by {} (DAgger)",
            self.learner.name(),
            self.expert.name()
        )
    }

    fn needs(&self) -> DriverNeeds {
        let (l, e) = (self.learner.needs(), self.expert.needs());
        DriverNeeds {
            camera: l.camera || e.camera,
            privileged: l.privileged || e.privileged,
            labels: l.labels || e.labels,
        }
    }

    fn act(&mut self, obs: &Observation<'_>) -> Control {
        // Both act at every boundary: each keeps the state of a driver on this road.
        let expert = self.expert.act(obs);
        let learner = self.learner.act(obs);
        let t = obs.time_s;
        if self.expert_until.is_some_and(|end| t >= end) {
            self.expert_until = None;
        }
        if self.expert_until.is_none() {
            if obs.speed_mps < self.params.standing_mps && Self::goes(&expert) {
                let since = *self.stuck_since.get_or_insert(t);
                if t - since >= self.params.stuck_s {
                    self.expert_until = Some(t + self.params.takeover_s);
                    self.stuck_since = None;
                    self.takeovers += 1;
                }
            } else {
                self.stuck_since = None;
            }
        }
        if self.expert_until.is_some() {
            self.expert_boundaries += 1;
            expert
        } else {
            self.learner_boundaries += 1;
            learner
        }
    }

    fn checkpoint(&self) -> Option<sim::record::CheckpointId> {
        self.learner.checkpoint()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use world::Command;

    /// A driver that always gives one control.
    struct Always(Control, &'static str);
    impl Driver for Always {
        fn name(&self) -> String {
            self.1.into()
        }
        fn needs(&self) -> DriverNeeds {
            DriverNeeds::default()
        }
        fn act(&mut self, _: &Observation<'_>) -> Control {
            self.0
        }
    }

    const BRAKE: Control = Control {
        steer: 0.0,
        throttle: 0.0,
        brake: 1.0,
    };
    /// The expert braking too, told apart from the learner by its steer.
    const EXPERT_BRAKE: Control = Control {
        steer: -0.1,
        throttle: 0.0,
        brake: 1.0,
    };
    const GO: Control = Control {
        steer: 0.1,
        throttle: 0.5,
        brake: 0.0,
    };

    /// Who drove at each boundary of `seconds` at 20 Hz, the ego at `speed`.
    fn drive(learner: Control, expert: Control, speed: f32, seconds: f64) -> Vec<bool> {
        let mut d = Dagger::new(
            Box::new(Always(learner, "learner")),
            Always(expert, "expert"),
            DaggerParams::default(),
        );
        (0..(seconds * 20.0) as usize)
            .map(|i| {
                let c = d.act(&Observation {
                    time_s: i as f64 * 0.05,
                    speed_mps: speed,
                    command: Command::LaneFollow,
                    scale: 1.0,
                    image: None,
                    labels: None,
                    privileged: None,
                });
                c == expert && c != learner
            })
            .collect()
    }

    #[test]
    fn a_learner_stuck_where_the_expert_would_go_hands_over_for_the_takeover() {
        let by_expert = drive(BRAKE, GO, 0.0, 30.0);
        let p = DaggerParams::default();
        // Stuck from t = 0: the learner drives the first 3 s, the expert the next 5,
        // then the learner again (still standing: 3 s more, and again).
        let first = by_expert.iter().position(|&e| e).expect("a takeover");
        assert_eq!(first, (p.stuck_s * 20.0) as usize);
        let len = by_expert[first..].iter().take_while(|&&e| e).count();
        assert_eq!(len, (p.takeover_s * 20.0) as usize);
        let share = by_expert.iter().filter(|&&e| e).count() as f64 / by_expert.len() as f64;
        let cycle = p.takeover_s / (p.stuck_s + p.takeover_s);
        assert!(
            (share - cycle).abs() < 0.05,
            "share {share} against {cycle}"
        );
    }

    #[test]
    fn waiting_where_the_expert_waits_or_moving_never_hands_over() {
        // Both brake (a red light): the learner keeps the wheel however long.
        assert!(drive(BRAKE, EXPERT_BRAKE, 0.0, 60.0).iter().all(|&e| !e));
        // The learner moves (above the standing speed): no takeover.
        assert!(drive(BRAKE, GO, 3.0, 60.0).iter().all(|&e| !e));
    }

    #[test]
    fn it_needs_what_either_needs_and_names_both() {
        let d = Dagger::new(
            Box::new(Always(GO, "learner")),
            Always(BRAKE, "expert"),
            DaggerParams::default(),
        );
        assert_eq!(d.needs(), DriverNeeds::default());
        assert_eq!(d.name(), "learner watched by expert (DAgger)");
    }
}
