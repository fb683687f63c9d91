//! A scenario's picture at a moment (`mrdrive render SCENARIO --at SECONDS`):
//! the run is driven there by its driver, with the delay, traffic and driving
//! scale of its request (the settings a sweep passes, so any run of a sweep
//! can be replayed to a moment), then its camera draws the rig, or the
//! top-down view, from the ego at that tick.

use std::path::PathBuf;

use world::{LightState, rules};

use crate::build::{self, BuildError, Drivers, Extras, RunRequest};
use crate::driver::RgbImage;
use crate::observe::Moments;
use crate::record::RunRecord;
use crate::render::{EgoPose, RenderError};
use crate::runner::{self, Prepared};
use crate::scenario::{Scenario, ScenarioError};

/// How far ahead along the route [`MomentPicture::light_ahead`] looks (metres).
pub const LIGHT_AHEAD_RANGE_M: f32 = 60.0;

/// Side of the ground square the top-down view shows (metres).
pub const TOP_DOWN_EXTENT_M: f32 = 60.0;

/// Which picture to draw.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum View {
    /// The policy's rig at this scale of S0.
    Rig {
        /// Fraction of S0.
        scale: f32,
    },
    /// The top-down view, this many pixels square, [`TOP_DOWN_EXTENT_M`] across.
    TopDown {
        /// Side in pixels.
        px: u32,
    },
}

/// A moment to draw: the run that leads there, when, and what to draw.
#[derive(Debug, Clone, Copy)]
pub struct MomentRequest<'a> {
    /// The run (its scale is the driving scale; its tick limit and camera
    /// are set here).
    pub run: RunRequest<'a>,
    /// Seconds of simulated time from the start.
    pub at_s: f64,
    /// The picture.
    pub view: View,
    /// The class image (in its label colours) instead of the colour image.
    pub labels: bool,
}

/// The picture at a moment and the state it shows.
#[derive(Debug)]
pub struct MomentPicture {
    /// The picture.
    pub image: RgbImage,
    /// The moment reached (seconds of simulated time).
    pub reached_s: f64,
    /// The ego's pose there.
    pub ego: EgoPose,
    /// The ego's speed there (m/s).
    pub speed_mps: f32,
    /// The run's record up to the moment (its driver and resolution).
    pub record: RunRecord,
    /// The next stop line of the route within [`LIGHT_AHEAD_RANGE_M`]: its
    /// distance along the route (metres) and its light's state.
    pub light_ahead: Option<(f32, LightState)>,
    /// The camera's backend.
    pub backend: String,
}

/// Why a moment could not be drawn.
#[derive(Debug, thiserror::Error)]
pub enum MomentError {
    /// The scenario file could not be read or is invalid.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// The run could not be built or failed.
    #[error(transparent)]
    Build(#[from] BuildError),
    /// The run gave no camera back.
    #[error("the run handed back no camera (RunRequest::keep_camera)")]
    NoCamera,
    /// The route has no points to start from.
    #[error("route {route} has no points")]
    EmptyRoute {
        /// The route's id.
        route: String,
    },
    /// The run ended before the moment.
    #[error(
        "--at {at_s}: the run ended at {reached_s:.2} s ({why}), before that moment; give --at {reached_s:.2} or less"
    )]
    EndedBefore {
        /// The moment asked for (seconds).
        at_s: f64,
        /// Where the run ended (seconds).
        reached_s: f64,
        /// What ended it.
        why: &'static str,
    },
    /// The camera could not draw.
    #[error(transparent)]
    Render(#[from] RenderError),
}

/// Drives `request.run` to `request.at_s` and draws its picture there
/// (`--at 0`, or a run that ends before its first tick, draws the start).
pub fn render_moment(
    request: &MomentRequest<'_>,
    drivers: &Drivers,
) -> Result<MomentPicture, MomentError> {
    let path = request.run.scenario;
    let scenario = request.run.overrides.apply(&Scenario::from_file(path)?);
    let prepared = runner::prepare(&scenario).map_err(|source| BuildError::Run {
        path: PathBuf::from(path),
        source: Box::new(source),
    })?;
    let tick_s = scenario.timing.tick_s;
    let ticks = (request.at_s / tick_s).round() as u64;
    let mut last = Moments::last();
    let run = RunRequest {
        max_ticks: Some(ticks),
        keep_camera: true,
        ..request.run
    };
    let extras = Extras {
        observer: Some(&mut last),
        prebuilt: Some((&scenario, &prepared)),
        ..Extras::default()
    };
    let done = build::run_scenario_with(&run, drivers, &mut |_| {}, extras)?;
    let record = done.record;
    let mut camera = done.camera.ok_or(MomentError::NoCamera)?;
    let moment = last.kept.pop().unwrap_or_default();
    let (tick, ego) = match moment.actors.first() {
        Some(e) => (moment.tick, EgoPose::from(e)),
        None => {
            let p = prepared
                .route
                .points
                .first()
                .ok_or_else(|| MomentError::EmptyRoute {
                    route: prepared.route.id.clone(),
                })?;
            (
                0,
                EgoPose {
                    position: p.position,
                    heading: p.heading,
                },
            )
        }
    };
    let reached_s = tick as f64 * tick_s;
    if tick < ticks {
        return Err(MomentError::EndedBefore {
            at_s: request.at_s,
            reached_s,
            why: record
                .result
                .termination
                .map_or("route completed", |t| t.name()),
        });
    }
    let (rgb, class) = match request.view {
        View::TopDown { px } => camera.render_top_down(
            &ego,
            &moment.actors,
            &moment.lights,
            px,
            px,
            TOP_DOWN_EXTENT_M,
        )?,
        View::Rig { scale } => camera.render_rig(&ego, &moment.actors, &moment.lights, scale)?,
    };
    let mut image = if request.labels {
        let mut img = RgbImage::default();
        class.to_label_rgb(&mut img);
        img
    } else {
        rgb.clone()
    };
    // The camera does not draw its own car: the top-down colour view outlines it (a
    // class image keeps its label colours only).
    if let (View::TopDown { .. }, false, Some(e)) =
        (request.view, request.labels, moment.actors.first())
    {
        outline_ego(&mut image, e.extent.x, e.extent.y, TOP_DOWN_EXTENT_M);
    }
    let light_ahead = light_ahead(&prepared, &ego, &moment.lights, LIGHT_AHEAD_RANGE_M);
    Ok(MomentPicture {
        image,
        reached_s,
        ego,
        speed_mps: moment.actors.first().map_or(0.0, |e| e.speed_mps),
        record,
        light_ahead,
        backend: camera.backend(),
    })
}

/// Colour of the ego's outline in the top-down view.
pub const EGO_OUTLINE_RGB: [u8; 3] = [230, 30, 30];

/// Outlines the ego's footprint (`length_m` along the heading, `width_m` across;
/// metres), 2 pixels wide, in a top-down view `extent_m` metres across that is
/// centred on the ego with its heading up.
pub fn outline_ego(image: &mut RgbImage, length_m: f32, width_m: f32, extent_m: f32) {
    let (w, h) = (image.width as i64, image.height as i64);
    let px_per_m = image.width as f32 / extent_m;
    let (cx, cy) = (w as f32 / 2.0, h as f32 / 2.0);
    let (half_l, half_w) = (length_m * px_per_m / 2.0, width_m * px_per_m / 2.0);
    let (x0, x1) = ((cx - half_w).round() as i64, (cx + half_w).round() as i64);
    let (y0, y1) = ((cy - half_l).round() as i64, (cy + half_l).round() as i64);
    for y in y0..=y1 {
        for x in x0..=x1 {
            let edge = x - x0 < 2 || x1 - x < 2 || y - y0 < 2 || y1 - y < 2;
            if edge && (0..w).contains(&x) && (0..h).contains(&y) {
                let at = ((y * w + x) * 3) as usize;
                image.data[at..at + 3].copy_from_slice(&EGO_OUTLINE_RGB);
            }
        }
    }
}

/// The next stop line of the route within `range_m` ahead of the ego, as the
/// rule book has it (the route's stop lines, the ego's distance along the
/// route from its nearest route point): distance along the route from the
/// ego's centre (metres) and the light's state.
pub fn light_ahead(
    prepared: &Prepared,
    ego: &EgoPose,
    states: &[LightState],
    range_m: f32,
) -> Option<(f32, LightState)> {
    let route = &prepared.route;
    let (index, _) = rules::nearest_route_point(route, ego.ground(), 0, route.points.len())?;
    let ego_s = rules::route_s_at(route, index, ego.ground());
    let stops = rules::StopLines::new(&prepared.town).on_route(route);
    let (stop, d) = stops.light_ahead(ego_s, range_m)?;
    Some((d, rules::light_state(states, stop.light)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_egos_outline_is_its_footprint_at_the_centre_heading_up() {
        // 60 px for 60 m: 1 px a metre; a car 4 m long and 2 m wide.
        let mut img = RgbImage {
            width: 60,
            height: 60,
            data: vec![0; 60 * 60 * 3],
        };
        outline_ego(&mut img, 4.0, 2.0, 60.0);
        let at = |x: usize, y: usize| &img.data[(y * 60 + x) * 3..(y * 60 + x) * 3 + 3];
        assert_eq!(at(29, 28), EGO_OUTLINE_RGB, "the front left corner");
        assert_eq!(at(31, 32), EGO_OUTLINE_RGB, "the rear right corner");
        assert_eq!(at(30, 27), [0, 0, 0], "ahead of the front");
        assert_eq!(at(32, 30), [0, 0, 0], "right of the side");
        let red = img.data.chunks(3).filter(|p| *p == EGO_OUTLINE_RGB).count();
        assert_eq!(red, 3 * 5, "a footprint of 3 x 5 pixels, every one an edge");
    }
}
