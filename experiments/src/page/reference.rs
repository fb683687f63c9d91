//! What the paper reports (its §IV), set beside ours.

/// Realised pedestrians (mean, sd) on a town's two routes, for the targets
/// (5, 10) and (20, 40).
pub type RoutesPedestrians = [[(f64, f64); 2]; 2];
/// A Table III row: success %, collision %, lane crossings mean and sd,
/// red lights in total.
pub type Table3Row = (f64, f64, f64, f64, u32);

/// Table I, realised pedestrians (mean, sd) for targets (5, 10) and
/// (20, 40), per town and route (vehicles were always all spawned).
pub const TABLE1_PEDESTRIANS: [(&str, RoutesPedestrians); 2] = [
    (
        "Town01",
        [[(7.0, 1.5), (26.7, 3.1)], [(7.0, 1.5), (26.5, 3.1)]],
    ),
    (
        "Town02",
        [[(6.6, 1.4), (27.2, 2.9)], [(6.6, 1.4), (27.2, 2.9)]],
    ),
];
/// Table II: success (%) per town for Original, NRA 0.75, NRA 1.0, RA 0.75, RA 1.0.
pub const TABLE2_SUCCESS: [(&str, [f64; 5]); 2] = [("Town01", [100.0; 5]), ("Town02", [100.0; 5])];
/// Table II: collision incidence (runs of 6) per town, same columns.
pub const TABLE2_COLLISIONS: [(&str, [u32; 5]); 2] =
    [("Town01", [0, 0, 0, 0, 0]), ("Town02", [0, 1, 1, 1, 2])];
/// Table III per envelope (high, low ms): fixed low @ low, RA switcher,
/// fixed high @ high; each (success %, collision %, lane crossings mean,
/// sd, red lights total) over 12 runs.
pub const TABLE3: [((f64, f64), [Table3Row; 3]); 2] = [
    (
        (100.0, 50.0),
        [
            (100.0, 16.65, 6.67, 5.63, 42),
            (100.0, 0.0, 5.50, 5.21, 15),
            (91.65, 8.35, 9.84, 9.33, 14),
        ],
    ),
    (
        (150.0, 100.0),
        [
            (100.0, 25.0, 11.25, 9.14, 43),
            (100.0, 0.0, 10.84, 9.10, 17),
            (91.65, 58.35, 66.50, 76.01, 18),
        ],
    ),
];
/// Table III's runs per configuration.
pub const TABLE3_RUNS: f64 = 12.0;
/// A range of success and one of collisions, low and high (percent).
pub type Ranges = ((f64, f64), (f64, f64));
/// Fig. 5 up to D = 100 ms: success 91.65-100 %, collisions 0-25 % (percent).
pub const FIG5_UP_TO_100: Ranges = ((91.65, 100.0), (0.0, 25.0));
/// Fig. 5 at D = 200 ms: success 0-8.35 %, collisions 83-100 % (percent).
pub const FIG5_AT_200: Ranges = ((0.0, 8.35), (83.0, 100.0));
/// Fig. 5 in words (§IV-D).
pub const FIG5: &str = "with D <= 100 ms success stays at 91.65-100 % and collisions at 0-25 %; \
    at D = 150 ms collisions jump and success begins to drop; at D = 200 ms success is 0-8.35 % \
    and collisions 83-100 %, for NRA and RA at both scales";
