//! Leaderboard-1.0's driving score: route completion times a penalty factor
//! per infraction (docs/protocol.md §3), times the share of the route driven inside the
//! lanes (`OUTSIDE_ROUTE_LANES_INFRACTION`: `score_penalty *= 1 - percentage / 100`).

use super::InfractionKind;

/// The penalty factor one infraction of this kind multiplies the score by
/// (1.0: no penalty).
pub fn penalty(kind: InfractionKind) -> f64 {
    match kind {
        InfractionKind::CollisionPedestrian => 0.50,
        InfractionKind::CollisionVehicle => 0.60,
        InfractionKind::CollisionStatic => 0.65,
        InfractionKind::RedLight => 0.70,
        _ => 1.0,
    }
}

/// The driving score in percent: completion (percent) times the product of
/// the penalties of all infractions, times `1 - outside_pct / 100` (the share of the
/// route driven outside the lanes, percent).
pub fn driving_score(
    completion_pct: f64,
    infractions: impl IntoIterator<Item = InfractionKind>,
    outside_pct: f64,
) -> f64 {
    let inside = (1.0 - outside_pct / 100.0).clamp(0.0, 1.0);
    completion_pct * infractions.into_iter().map(penalty).product::<f64>() * inside
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn score_multiplies_penalties() {
        use InfractionKind::*;
        assert_eq!(driving_score(100.0, [], 0.0), 100.0);
        // A quarter of the route outside the lanes takes a quarter off; a sidewalk
        // event itself costs nothing.
        assert!((driving_score(80.0, [OnSidewalk], 25.0) - 60.0).abs() < 1e-9);
        assert!(
            (driving_score(80.0, [RedLight, CollisionVehicle, LaneCrossing], 0.0)
                - 80.0 * 0.7 * 0.6)
                .abs()
                < 1e-9
        );
        assert!(
            (driving_score(100.0, [CollisionPedestrian, CollisionStatic], 0.0)
                - 100.0 * 0.5 * 0.65)
                .abs()
                < 1e-9
        );
    }
}
