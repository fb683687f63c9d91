//! Subcommands of the `mrdrive` program, one file each.

pub mod bench;
pub mod collect;
pub mod data;
pub mod log;
pub mod map;
pub mod paper;
pub mod policy;
pub mod recalibrate;
pub mod render;
pub mod routes;
pub mod run;
pub mod serve;
pub mod study;
pub mod sweep;
pub mod traffic;
pub mod train;

/// Every driver kind a scenario can name: the expert (built by `sim`) and the
/// policy (built by `policy` from its checkpoint).
pub fn drivers() -> sim::build::Drivers {
    sim::build::Drivers::new().with(sim::scenario::DriverKind::Policy, ::policy::PolicyFactory)
}

/// `YYYY-MM-DD HH:MM` of a time, UTC (the job logs' clock).
pub fn time_utc(t: std::time::SystemTime) -> String {
    chrono::DateTime::<chrono::Utc>::from(t)
        .format("%Y-%m-%d %H:%M")
        .to_string()
}
