//! `mrdrive serve`: one environment for a client in another process (the Python
//! package in `python/`), over this process's stdin and stdout. The protocol and
//! the episodes are [`sim::remote::server`]'s; this names WoR's discrete actions
//! (`dataset::action`) as the action space a step may index.

use anyhow::Result;
use dataset::action::{self, NUM_ACTIONS};
use sim::driver::VehicleControl;
use sim::remote::server::{self, DiscreteActions};

/// WoR's action `j` as a control.
fn wor_control(j: usize) -> VehicleControl {
    match action::action(j) {
        action::Action::Brake => VehicleControl::BRAKE,
        action::Action::Drive { steer, throttle } => VehicleControl {
            steer,
            throttle,
            brake: 0.0,
        },
    }
}

/// Runs the server on stdin/stdout until `close` or the end of input.
pub fn serve() -> Result<()> {
    let actions = DiscreteActions {
        count: NUM_ACTIONS,
        control: wor_control,
    };
    server::serve(
        &mut std::io::stdin().lock(),
        &mut std::io::stdout().lock(),
        &actions,
    )?;
    Ok(())
}
