//! A picture of a run, to see in one look where the car went and where it went
//! wrong: the town from above around the route, the planned route, the path
//! driven coloured by the input scale in force, every infraction marked and
//! labelled with its kind and time, the start, the goal, and where the run ended
//! if it failed.
//!
//! It is drawn from a run's record alone (the path is the record's trace,
//! [`RunResult::trace`]), so `mrdrive run` draws it when the run ends and
//! `mrdrive log picture` draws it again from a JSON record or an MCAP log.

use std::path::{Path, PathBuf};

use image::RgbImage;
use world::map::picture::{GLYPH_PX, RenderOptions, draw_text, town_canvas};
use world::route::DenseRoute;
use world::{Town, Vec2};

use crate::monitors::InfractionKind;
use crate::record::RunResult;
use crate::scenario::Scenario;

/// Why a run's picture could not be drawn.
#[derive(Debug, thiserror::Error)]
pub enum PictureError {
    /// The file holds no run result.
    #[error("{path}: {problem}; fix: {fix}")]
    NoResult {
        /// The file given.
        path: PathBuf,
        /// What is wrong with it.
        problem: String,
        /// What would fix it.
        fix: &'static str,
    },
    /// The scenario the record names could not be loaded again.
    #[error(
        "the run's scenario {scenario} (as its record names it): {problem}; fix: draw the \
         picture from the folder the run was made in, where that path leads to the scenario"
    )]
    Scenario {
        /// The scenario file as recorded.
        scenario: String,
        /// What failed.
        problem: String,
    },
    /// The picture could not be written.
    #[error("writing {path}: {problem}; fix: check that its folder can be written")]
    Write {
        /// The PNG.
        path: PathBuf,
        /// What failed.
        problem: String,
    },
}

/// A run's result from a JSON record (`mrdrive run --json`, a sweep's `runs/*.json`)
/// or an MCAP log (`mrdrive run --record`), told apart by the file's extension.
pub fn read_result(path: &Path) -> Result<RunResult, PictureError> {
    let no_result = |problem: String| PictureError::NoResult {
        path: path.to_path_buf(),
        problem,
        fix: "give a run record (.json) or a run log (.mcap) that mrdrive wrote",
    };
    let value = if path.extension().is_some_and(|e| e == "mcap") {
        let summary = crate::recorder::read_summary(path).map_err(|e| no_result(e.to_string()))?;
        summary.result().ok_or_else(|| {
            no_result("the log has no result metadata (the run did not finish)".into())
        })?
    } else {
        let text = std::fs::read_to_string(path).map_err(|e| no_result(e.to_string()))?;
        let record: serde_json::Value =
            serde_json::from_str(&text).map_err(|e| no_result(format!("not JSON ({e})")))?;
        record.get("result").cloned().unwrap_or(record)
    };
    serde_json::from_value(value).map_err(|e| no_result(format!("not a run result ({e})")))
}

/// The picture of a recorded run, its town and route loaded again from the scenario
/// file its record names.
pub fn picture_of(result: &RunResult) -> Result<RgbImage, PictureError> {
    let file = &result.provenance.scenario_file;
    let fail = |problem: String| PictureError::Scenario {
        scenario: file.clone(),
        problem,
    };
    let scenario = Scenario::from_file(Path::new(file)).map_err(|e| fail(e.to_string()))?;
    let prepared = crate::runner::prepare(&scenario).map_err(|e| fail(e.to_string()))?;
    Ok(run_picture(&prepared.town, &prepared.route, result))
}

/// Writes `img` as a PNG to `path`, making its folder if needed.
pub fn save(img: &RgbImage, path: &Path) -> Result<(), PictureError> {
    let fail = |problem: String| PictureError::Write {
        path: path.to_path_buf(),
        problem,
    };
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| fail(e.to_string()))?;
    }
    img.save(path).map_err(|e| fail(e.to_string()))
}

/// Metres around the route and the path that the picture shows.
const MARGIN_M: f32 = 40.0;
/// The longer side of the map part of the picture at most (pixels).
const MAX_SIDE_PX: f32 = 1000.0;
/// The finest ground resolution (metres per pixel).
const FINEST_M_PER_PX: f32 = 0.25;
/// Lines of text above the map.
const HEADER_LINES: u32 = 3;
/// Height of the header above the map (pixels).
const HEADER_PX: u32 = HEADER_LINES * LINE_PX + 6;
const LINE_PX: u32 = GLYPH_PX + 4;
/// The planned route, under the path.
const PLANNED: [u8; 3] = [215, 215, 215];
const INK: [u8; 3] = [245, 245, 245];
const PAPER: [u8; 3] = [20, 20, 24];
const OUTLINE: [u8; 3] = [10, 10, 10];

/// The colour of the path at an input scale: blue at 1.0x, orange at 0.75x, and
/// from violet (small) to cyan (large) for the other scales.
pub fn scale_rgb(scale: f64) -> [u8; 3] {
    if (scale - 1.0).abs() < 1e-6 {
        [40, 120, 255]
    } else if (scale - 0.75).abs() < 1e-6 {
        [255, 150, 20]
    } else {
        let t = ((scale - 0.5) / 0.75).clamp(0.0, 1.0);
        [
            (200.0 - 160.0 * t) as u8,
            (60.0 + 160.0 * t) as u8,
            (220.0 + 30.0 * t) as u8,
        ]
    }
}

/// The colour an infraction is marked in.
pub fn infraction_rgb(kind: InfractionKind) -> [u8; 3] {
    match kind {
        InfractionKind::CollisionPedestrian
        | InfractionKind::CollisionVehicle
        | InfractionKind::CollisionStatic => [235, 30, 30],
        InfractionKind::RedLight => [230, 40, 230],
        InfractionKind::LaneCrossing => [250, 220, 40],
        InfractionKind::OnSidewalk => [40, 220, 220],
        InfractionKind::RouteDeviation
        | InfractionKind::Stuck
        | InfractionKind::LowSpeedTimeout
        | InfractionKind::RouteTimeout => [255, 110, 0],
    }
}

/// A label to place: its anchor (output pixel) and text.
struct Label {
    at: Vec2,
    text: String,
    color: [u8; 3],
}

/// Draws the picture of `result`, a run on `route` in `town`.
pub fn run_picture(town: &Town, route: &DenseRoute, result: &RunResult) -> RgbImage {
    let path: Vec<(f64, Vec2, f64)> = result
        .trace
        .iter()
        .map(|p| (p[0], Vec2::new(p[1] as f32, p[2] as f32), p[3]))
        .collect();
    let route_pts: Vec<Vec2> = route.points.iter().map(|p| p.position.truncate()).collect();
    let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
    for p in route_pts.iter().chain(path.iter().map(|(_, p, _)| p)) {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    if !lo.is_finite() {
        (lo, hi) = town.bounds;
    }
    let (lo, hi) = (lo - Vec2::splat(MARGIN_M), hi + Vec2::splat(MARGIN_M));
    let side = (hi - lo).max_element();
    let opts = RenderOptions {
        metres_per_pixel: (side / MAX_SIDE_PX).max(FINEST_M_PER_PX),
        margin_m: 0.0,
        supersample: 3,
        light_states: None,
        grey_lights: true,
        route: None,
        crop: Some((lo, hi)),
    };
    let mut cv = town_canvas(town, &opts);
    let mpp = cv.metres_per_pixel();
    let px_m = |px: f32| px * mpp;
    cv.dashed(&route_pts, px_m(2.0), px_m(6.0), px_m(4.0), PLANNED);

    // The path, outlined, each stretch in the colour of its scale.
    let pts: Vec<Vec2> = path.iter().map(|(_, p, _)| *p).collect();
    cv.polyline(&pts, px_m(6.0), OUTLINE);
    for w in path.windows(2) {
        cv.segment(w[0].1, w[1].1, px_m(4.0), scale_rgb(w[0].2));
    }
    let mut labels = Vec::new();
    if let Some(&(_, start, _)) = path.first() {
        cv.disc(start, px_m(7.0), OUTLINE);
        cv.disc(start, px_m(5.0), [40, 220, 60]);
        labels.push(Label {
            at: cv.view().pixel(start),
            text: "start".into(),
            color: [40, 220, 60],
        });
    }
    if let Some(goal) = route_pts.last() {
        cv.disc(*goal, px_m(7.0), OUTLINE);
        cv.disc(*goal, px_m(5.0), INK);
        labels.push(Label {
            at: cv.view().pixel(*goal),
            text: "goal".into(),
            color: INK,
        });
    }
    for i in &result.infractions {
        let p = Vec2::new(i.position[0], i.position[1]);
        let color = infraction_rgb(i.kind);
        if i.kind == InfractionKind::LaneCrossing {
            cv.disc(p, px_m(2.5), color);
            continue;
        }
        cv.disc(p, px_m(6.0), OUTLINE);
        cv.disc(p, px_m(4.5), color);
        if i.kind.terminates() {
            continue; // the end mark says it
        }
        labels.push(Label {
            at: cv.view().pixel(p),
            text: format!("{} {:.1} s", i.kind.name(), i.time_s),
            color,
        });
    }
    if !result.success
        && let Some(&(t, end, _)) = path.last()
    {
        let d = Vec2::splat(px_m(7.0));
        let e = Vec2::new(d.x, -d.y);
        for (a, b) in [(end - d, end + d), (end - e, end + e)] {
            cv.segment(a, b, px_m(4.0), OUTLINE);
            cv.segment(a, b, px_m(2.0), [235, 30, 30]);
        }
        let why = result
            .termination
            .map_or("the route not finished", |k| k.name());
        labels.push(Label {
            at: cv.view().pixel(end),
            text: format!("ended: {why} at {t:.1} s"),
            color: [255, 90, 90],
        });
    }
    let map = cv.finish();

    let width = map.width().max(60 * GLYPH_PX);
    let mut img = RgbImage::from_pixel(width, map.height() + HEADER_PX, image::Rgb(PAPER));
    image::imageops::overlay(&mut img, &map, 0, i64::from(HEADER_PX));
    header(&mut img, result);
    place_labels(&mut img, labels, HEADER_PX);
    img
}

/// Three lines above the map: what ran, how it ended, the legend.
fn header(img: &mut RgbImage, r: &RunResult) {
    let outcome = if r.success { "SUCCESS" } else { "FAILURE" };
    let fit = |s: String| {
        let room = (img.width() / GLYPH_PX).saturating_sub(1) as usize;
        if s.len() > room {
            format!("{}~", &s[..room.saturating_sub(1)])
        } else {
            s
        }
    };
    let line1 = fit(format!(
        "{}: {} | D {} ms, {} vehicles + {} walkers, seed {}",
        r.provenance.scenario,
        r.provenance.driver,
        r.settings.delay_ms,
        r.settings.vehicles,
        r.settings.pedestrians,
        r.settings.seed,
    ));
    let rules: Vec<String> = r
        .collisions
        .iter()
        .map(|(rule, c)| format!("{rule} {}", c.total()))
        .collect();
    let line2 = fit(format!(
        "{outcome}: {:.1} % of the {:.0} m route in {:.1} s{}{}",
        r.completion_pct,
        r.route_length_m,
        r.sim_time_s,
        r.termination
            .map_or(String::new(), |k| format!(", ended by {}", k.name())),
        if rules.is_empty() {
            String::new()
        } else {
            format!(" | collisions: {}", rules.join(", "))
        }
    ));
    let outcome_rgb = if r.success {
        [90, 230, 90]
    } else {
        [255, 90, 90]
    };
    draw_text(img, (4, 3), &line1, INK, None, 1);
    draw_text(
        img,
        (4, i64::from(3 + LINE_PX)),
        &line2,
        outcome_rgb,
        None,
        1,
    );
    let y = i64::from(3 + 2 * LINE_PX);
    let mut x = 4i64;
    let mut item = |img: &mut RgbImage, swatch: [u8; 3], text: &str| {
        // A square of the colour, then what it means.
        draw_text(img, (x, y), " ", swatch, Some(swatch), 1);
        draw_text(img, (x + i64::from(GLYPH_PX) + 4, y), text, INK, None, 1);
        x += (text.len() as i64 + 3) * i64::from(GLYPH_PX);
    };
    let mut scales: Vec<f64> = r.trace.iter().map(|p| p[3]).collect();
    scales.sort_by(f64::total_cmp);
    scales.dedup();
    for s in scales {
        item(img, scale_rgb(s), &format!("path at {s}x"));
    }
    let lane_crossings = r
        .infractions
        .iter()
        .filter(|i| i.kind == InfractionKind::LaneCrossing)
        .count();
    item(img, PLANNED, "route");
    item(
        img,
        infraction_rgb(InfractionKind::CollisionVehicle),
        "collision",
    );
    item(img, infraction_rgb(InfractionKind::RedLight), "red light");
    item(
        img,
        infraction_rgb(InfractionKind::OnSidewalk),
        "on sidewalk",
    );
    item(
        img,
        infraction_rgb(InfractionKind::LaneCrossing),
        &format!("lane crossing ({lane_crossings})"),
    );
}

/// Writes each label beside its anchor, moved down or up to the first place where
/// it overlaps no label placed before it.
fn place_labels(img: &mut RgbImage, labels: Vec<Label>, top_px: u32) {
    let mut placed: Vec<(i64, i64, i64, i64)> = Vec::new();
    let h = i64::from(GLYPH_PX) + 2;
    for l in labels {
        let w = l.text.len() as i64 * i64::from(GLYPH_PX) + 2;
        let (ax, ay) = (l.at.x as i64 + 9, l.at.y as i64 + i64::from(top_px) - h / 2);
        let free = |y: i64| {
            placed.iter().all(|&(px, py, pw, ph)| {
                ax + w <= px || px + pw <= ax || y + h <= py || py + ph <= y
            })
        };
        let y = (0..12)
            .flat_map(|k| [ay + k * h, ay - k * h])
            .find(|&y| free(y))
            .unwrap_or(ay);
        draw_text(img, (ax, y), &l.text, l.color, Some(OUTLINE), 1);
        placed.push((ax - 1, y - 1, w, h));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::monitors::Infraction;
    use world::map::testtown;

    #[test]
    fn scales_have_their_own_colours() {
        assert_ne!(scale_rgb(1.0), scale_rgb(0.75));
        assert_ne!(scale_rgb(0.5), scale_rgb(0.625));
        assert_ne!(
            infraction_rgb(InfractionKind::CollisionStatic),
            infraction_rgb(InfractionKind::RedLight)
        );
    }

    /// A failed run on the test town: the path at two scales, a collision, the end.
    #[test]
    fn the_picture_shows_the_path_by_scale_the_infraction_and_where_the_run_ended() {
        let town = testtown::grid(3, 3, 100.0);
        let route = testtown::route_through(&[Vec2::new(-40.0, -1.75), Vec2::new(150.0, -1.75)]);
        let spec = crate::sweep::RunSpec {
            scenario: "s.toml".into(),
            delay_ms: Some(0.0),
            scale: None,
            density: Some((5, 10)),
            seed: 1,
            driver: None,
        };
        let mut result = crate::sweep::fixtures::fake_record(&spec).result;
        result.success = false;
        result.trace = (0..=40)
            .map(|k| {
                let x = -40.0 + 2.5 * k as f64;
                [k as f64 * 0.5, x, -1.75, if k < 20 { 0.75 } else { 1.0 }]
            })
            .collect();
        result.infractions = vec![Infraction {
            tick: 800,
            time_s: 20.0,
            kind: InfractionKind::CollisionStatic,
            position: [60.0, -1.75],
            detail: "a pole".into(),
        }];
        let img = run_picture(&town, &route, &result);
        let (w, h) = img.dimensions();
        assert!(w > 200 && h > HEADER_PX + 50, "{w} x {h}");
        let count = |c: [u8; 3]| img.pixels().filter(|p| p.0 == c).count();
        assert!(count(scale_rgb(0.75)) > 50, "the 0.75x stretch");
        assert!(count(scale_rgb(1.0)) > 50, "the 1.0x stretch");
        assert!(
            count(infraction_rgb(InfractionKind::CollisionStatic)) > 20,
            "the collision and the end cross"
        );
        // Without the trace, no path is drawn.
        result.trace.clear();
        let bare = run_picture(&town, &route, &result);
        assert_eq!(bare.pixels().filter(|p| p.0 == scale_rgb(0.75)).count(), 0);
    }
}
