//! `mrdrive data show`: one picture of one frame, for a person to check its
//! label by eye.
//!
//! Layout, with S0 = W x H and a margin M = [`MARGIN_PX`] (see [`picture_size`]):
//!
//! ```text
//! +--------------------------------------------------------------+
//! | title: frame N of the dataset, episode and frame, view, town |
//! | [rig image W x H]  [class image W x H, WoR palette]           |
//! | [bird's-eye view]  command, speed, bin, best action          |
//! | [BEV_PX square  ]  Q heatmap: 3 throttle x 9 steer + brake   |
//! |                    soft target softmax(Q / 0.01), the same   |
//! +--------------------------------------------------------------+
//! ```
//!
//! The bird's-eye view is [`BEV_M`] metres across, heading up, the ego
//! a quarter from the bottom: the town's lanes, the route, every stop line
//! in its light's colour, the other actors' boxes (vehicles blue,
//! pedestrians red) and the ego (green). The heatmaps show the frame's
//! command at the speed bin nearest the ego's speed, from the frame's label
//! for the view shown: throttle 1 on the top row, 0 at the bottom; steer -1
//! (left) in the left column, +1 (right) in the right one; the brake cell
//! apart on the right; the best action framed in white. Colours run from
//! dark blue (the lowest value of the map) to yellow (the highest).

use std::path::{Path, PathBuf};

use image::{Rgb, RgbImage};
use sim::render::classes::wor_rgb;
use world::agents::VehicleParams;
use world::map::picture::{Canvas, GLYPH_PX, ROAD, View, draw_text, light_rgb};
use world::{Command, LightState, Vec2};

use crate::action::{
    Action, BRAKE, NUM_ACTIONS, NUM_SPEED_BINS, NUM_STEERS, NUM_THROTTLES, action,
};
use crate::collect::replan;
use crate::decode::{SPEED_BIN_CENTRES_MPS, softmax};
use crate::format::{
    ActorRow, DataError, INDEX_FILE, Index, MappedLabels, MappedShard, Q_PER_VIEW, light_of_code,
};
use crate::info::TownSource;
use crate::label_driver::TEMPERATURE;
use crate::labels::LABEL_VERSION;

/// Margin around and between panels (pixels).
pub const MARGIN_PX: u32 = 8;
/// Side of the bird's-eye view (pixels).
pub const BEV_PX: u32 = 256;
/// Ground across the bird's-eye view (metres).
pub const BEV_M: f32 = 40.0;
/// Side of one heatmap cell (pixels).
pub const CELL_PX: u32 = 20;
/// Width of the text and heatmap panel (pixels).
pub const PANEL_PX: u32 = 312;

const LINE_PX: u32 = 11;
const TITLE_PX: u32 = MARGIN_PX + LINE_PX;
const BACKGROUND: [u8; 3] = [24, 24, 28];
const TEXT: [u8; 3] = [230, 230, 230];
const BEV_GROUND: [u8; 3] = [52, 66, 50];
const ROUTE: [u8; 3] = [40, 140, 255];
const EGO: [u8; 3] = [40, 220, 80];
const VEHICLE: [u8; 3] = [60, 90, 255];
const PEDESTRIAN: [u8; 3] = [230, 40, 60];

/// Height of the panel's text above the first heatmap (pixels).
const PANEL_TEXT_PX: u32 = 6 * LINE_PX;
/// Height of one heatmap with its heading (pixels).
const HEATMAP_PX: u32 = LINE_PX + NUM_THROTTLES as u32 * CELL_PX + MARGIN_PX;

/// The picture's width and height for images of size `s0` (pixels): wide
/// enough for both images side by side, or for the bird's-eye view beside
/// the panel, whichever is wider.
pub fn picture_size(s0: [u32; 2]) -> (u32, u32) {
    let images_w = 2 * s0[0] + 3 * MARGIN_PX;
    let lower_w = BEV_PX + PANEL_PX + 3 * MARGIN_PX;
    let lower_h = BEV_PX.max(PANEL_TEXT_PX + 2 * HEATMAP_PX);
    (
        images_w.max(lower_w),
        TITLE_PX + s0[1] + 2 * MARGIN_PX + lower_h,
    )
}

/// Why a frame could not be shown.
#[derive(Debug, thiserror::Error)]
pub enum ShowError {
    /// The dataset could not be read.
    #[error(transparent)]
    Data(#[from] DataError),
    /// The frame number is past the dataset's end.
    #[error(
        "{index}: frame {frame} is out of range: the dataset has {frames} frames, 0 to {last}; pick one of those with --frame",
        last = frames.saturating_sub(1)
    )]
    Frame {
        /// The dataset's index.
        index: PathBuf,
        /// The frame asked for.
        frame: u64,
        /// Frames in the dataset.
        frames: u64,
    },
    /// The view number is past the dataset's views.
    #[error(
        "{index}: view {view} is out of range: the dataset has {views} views (yaws {yaws:?} deg), 0 to {last}; pick one of those with --view",
        last = views.saturating_sub(1)
    )]
    View {
        /// The dataset's index.
        index: PathBuf,
        /// The view asked for.
        view: usize,
        /// Views per frame.
        views: usize,
        /// Their yaws (degrees).
        yaws: Vec<f32>,
    },
    /// The episode's town could not be had for the bird's-eye view.
    #[error("episode {episode}: {msg}")]
    Town {
        /// The episode's id.
        episode: u32,
        /// What went wrong.
        msg: String,
    },
}

/// The label drawn: values of the frame's command at its speed bin.
struct Shown {
    q: [f32; NUM_ACTIONS],
    soft: [f32; NUM_ACTIONS],
    best: usize,
}

/// Draws frame `frame` (counted over the whole dataset in index order) seen
/// from `view`; `towns` gives the episode's town.
pub fn show(
    dir: &Path,
    frame: u64,
    view: usize,
    towns: &mut TownSource<'_>,
) -> Result<RgbImage, ShowError> {
    let index = Index::load(dir)?;
    let views = index.view_yaws_deg.len();
    if view >= views {
        return Err(ShowError::View {
            index: dir.join(INDEX_FILE),
            view,
            views,
            yaws: index.view_yaws_deg.clone(),
        });
    }
    let mut first = 0u64;
    let Some(episode) = index.episodes.iter().find(|e| {
        first += u64::from(e.frames);
        frame < first
    }) else {
        return Err(ShowError::Frame {
            index: dir.join(INDEX_FILE),
            frame,
            frames: index.frames(),
        });
    };
    let i = (frame - (first - u64::from(episode.frames))) as usize;
    let shard = MappedShard::open(&dir.join(&episode.shard), index.s0, views)?;
    let state = &shard.state;
    let command = usize::from(state.command[i]);
    let ego = state.ego[i];
    let bin = nearest_bin(ego.speed);
    let label = match &episode.labels {
        None => Err("no labels: run `mrdrive label` on the dataset".to_string()),
        Some(name) => {
            let labels = MappedLabels::open(&dir.join(name), LABEL_VERSION, state.len(), views)?;
            if labels.valid[i] {
                let mut all = vec![0.0; Q_PER_VIEW];
                labels.q_into(i, view, &mut all);
                let at = (command * NUM_SPEED_BINS + bin) * NUM_ACTIONS;
                let q: [f32; NUM_ACTIONS] = std::array::from_fn(|a| all[at + a]);
                let best = (0..NUM_ACTIONS).fold(0, |b, a| if q[a] > q[b] { a } else { b });
                Ok(Shown {
                    q,
                    soft: soft_target(&q),
                    best,
                })
            } else {
                Err("no label: the end of the episode (its future was not driven)".to_string())
            }
        }
    };
    let town = towns(episode).map_err(|msg| ShowError::Town {
        episode: episode.id,
        msg,
    })?;

    let (w, h) = (index.s0[0], index.s0[1]);
    let (pw, ph) = picture_size(index.s0);
    let mut img = RgbImage::from_pixel(pw, ph, Rgb(BACKGROUND));
    let yaw = index.view_yaws_deg[view];
    text(
        &mut img,
        MARGIN_PX,
        MARGIN_PX,
        &format!(
            "frame {frame}: episode {} frame {i}, view {view} ({yaw:+.0} deg), {}",
            episode.id, episode.town
        ),
    );
    let top = TITLE_PX + MARGIN_PX / 2;
    let (rgb, classes) = shard.view_images(i, view)?;
    for y in 0..h {
        for x in 0..w {
            let p = (y * w + x) as usize;
            let c = [rgb[3 * p], rgb[3 * p + 1], rgb[3 * p + 2]];
            img.put_pixel(MARGIN_PX + x, top + y, Rgb(c));
            img.put_pixel(2 * MARGIN_PX + w + x, top + y, Rgb(wor_rgb(classes[p])));
        }
    }

    let lower = top + h + MARGIN_PX;
    let route = replan(&town, &episode.route).ok();
    let bev = bird_eye(&town, route.as_ref(), state, i);
    image::imageops::replace(&mut img, &bev, i64::from(MARGIN_PX), i64::from(lower));

    let px = 2 * MARGIN_PX + BEV_PX;
    let name = Command::from_index(command).map_or("?", Command::name);
    let mut lines = vec![
        format!("command {name}"),
        format!(
            "speed {:.2} m/s: bin {bin} ({} m/s)",
            ego.speed, SPEED_BIN_CENTRES_MPS[bin]
        ),
    ];
    match &label {
        Ok(s) => {
            lines.push(format!("best: {}", describe(s.best)));
            let (lo, hi) = min_max(&s.q);
            lines.push(format!("Q {lo:.3} .. {hi:.3}"));
            lines.push(format!(
                "P(best) {:.2}  P(brake) {:.2}",
                s.soft[s.best], s.soft[BRAKE]
            ));
        }
        Err(why) => lines.push(why.clone()),
    }
    let wrapped: Vec<String> = lines
        .iter()
        .flat_map(|l| wrap(l, PANEL_PX / GLYPH_PX))
        .collect();
    for (k, line) in wrapped.iter().take(6).enumerate() {
        text(&mut img, px, lower + k as u32 * LINE_PX, line);
    }
    if let Ok(s) = &label {
        let y0 = lower + PANEL_TEXT_PX;
        heatmap(
            &mut img,
            px,
            y0,
            &format!("Q, {name}, bin {bin}"),
            &s.q,
            s.best,
        );
        heatmap(
            &mut img,
            px,
            y0 + HEATMAP_PX,
            &format!("softmax(Q / {TEMPERATURE})"),
            &s.soft,
            s.best,
        );
    }
    Ok(img)
}

/// The speed bin whose centre is nearest `speed_mps`.
fn nearest_bin(speed_mps: f32) -> usize {
    (0..NUM_SPEED_BINS)
        .min_by(|&a, &b| {
            let da = (SPEED_BIN_CENTRES_MPS[a] - speed_mps).abs();
            let db = (SPEED_BIN_CENTRES_MPS[b] - speed_mps).abs();
            da.total_cmp(&db)
        })
        .unwrap_or(0)
}

/// The soft target `softmax(q / TEMPERATURE)`.
fn soft_target(q: &[f32; NUM_ACTIONS]) -> [f32; NUM_ACTIONS] {
    softmax(&q.map(|v| v / TEMPERATURE))
}

fn min_max(v: &[f32]) -> (f32, f32) {
    v.iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &x| {
            (lo.min(x), hi.max(x))
        })
}

fn describe(a: usize) -> String {
    match action(a) {
        Action::Brake => format!("a{a} = brake"),
        Action::Drive { steer, throttle } => {
            format!("a{a} = steer {steer:+.2}, throttle {throttle:.1}")
        }
    }
}

/// A box `length x width` at `centre`, turned by `yaw`.
fn footprint(centre: Vec2, yaw: f32, length: f32, width: f32) -> [Vec2; 4] {
    let (f, l) = (
        Vec2::from_angle(yaw) * length * 0.5,
        Vec2::from_angle(yaw).perp() * width * 0.5,
    );
    [
        centre + f + l,
        centre + f - l,
        centre - f - l,
        centre - f + l,
    ]
}

fn bird_eye(
    town: &world::Town,
    route: Option<&world::route::DenseRoute>,
    state: &crate::format::Shard,
    i: usize,
) -> RgbImage {
    let ego = state.ego[i];
    let at = Vec2::new(BEV_PX as f32 / 2.0, BEV_PX as f32 * 0.75);
    let view = View::heading_up(Vec2::new(ego.x, ego.y), ego.yaw, BEV_M / BEV_PX as f32, at);
    let mut cv = Canvas::new(BEV_PX, BEV_PX, 2, view, BEV_GROUND);
    cv.lanes(town, ROAD);
    if let Some(r) = route {
        let pts: Vec<Vec2> = r.points.iter().map(|p| p.position.truncate()).collect();
        cv.polyline(&pts, 0.4, ROUTE);
    }
    let states: Vec<LightState> = state.lights[i].iter().map(|&c| light_of_code(c)).collect();
    cv.stop_lines(
        town,
        |i| light_rgb(states.get(i).copied().unwrap_or_default()),
        0.6,
    );
    for a in &state.actors[i] {
        let colour = if a.kind == ActorRow::PEDESTRIAN {
            PEDESTRIAN
        } else {
            VEHICLE
        };
        let (len, wid) = (a.length.max(0.4), a.width.max(0.4));
        cv.fill(&footprint(Vec2::new(a.x, a.y), a.yaw, len, wid), colour);
    }
    let ego_size = VehicleParams::default().half_extents() * 2.0;
    cv.fill(
        &footprint(Vec2::new(ego.x, ego.y), ego.yaw, ego_size.x, ego_size.y),
        EGO,
    );
    cv.finish()
}

/// A colour from dark blue (0) through green to yellow (1), after viridis.
fn colormap(t: f32) -> [u8; 3] {
    const STOPS: [[f32; 3]; 5] = [
        [68.0, 1.0, 84.0],
        [59.0, 82.0, 139.0],
        [33.0, 145.0, 140.0],
        [94.0, 201.0, 98.0],
        [253.0, 231.0, 37.0],
    ];
    let x = t.clamp(0.0, 1.0) * 4.0;
    let k = (x.floor() as usize).min(3);
    let f = x - k as f32;
    std::array::from_fn(|c| (STOPS[k][c] + (STOPS[k + 1][c] - STOPS[k][c]) * f).round() as u8)
}

/// A heading, then 3 throttle rows x 9 steer columns and the brake cell.
fn heatmap(img: &mut RgbImage, x0: u32, y0: u32, title: &str, v: &[f32; NUM_ACTIONS], best: usize) {
    text(img, x0, y0, title);
    let (lo, hi) = min_max(v);
    let span = hi - lo;
    let top = y0 + LINE_PX;
    let label_w = 3 * GLYPH_PX;
    for t in 0..NUM_THROTTLES {
        let row = (NUM_THROTTLES - 1 - t) as u32;
        let y = top + row * CELL_PX;
        text(img, x0, y + (CELL_PX - GLYPH_PX) / 2, ["0", ".5", "1"][t]);
        for s in 0..NUM_STEERS {
            let a = crate::action::index(s, t);
            let x = x0 + label_w + s as u32 * CELL_PX;
            cell(img, x, y, v[a], lo, span, a == best);
        }
    }
    let bx = x0 + label_w + NUM_STEERS as u32 * CELL_PX + MARGIN_PX;
    cell(img, bx, top + CELL_PX, v[BRAKE], lo, span, best == BRAKE);
    text(
        img,
        bx + CELL_PX + 2,
        top + CELL_PX + (CELL_PX - GLYPH_PX) / 2,
        "brake",
    );
    text(
        img,
        bx + CELL_PX + 2,
        top + (CELL_PX - GLYPH_PX) / 2,
        "L<->R",
    );
}

fn cell(img: &mut RgbImage, x: u32, y: u32, v: f32, lo: f32, span: f32, framed: bool) {
    let t = if span > 0.0 { (v - lo) / span } else { 0.5 };
    let c = colormap(t);
    for dy in 0..CELL_PX - 1 {
        for dx in 0..CELL_PX - 1 {
            let edge = dx == 0 || dy == 0 || dx == CELL_PX - 2 || dy == CELL_PX - 2;
            let px = if framed && edge { [255, 255, 255] } else { c };
            put(img, x + dx, y + dy, px);
        }
    }
}

fn put(img: &mut RgbImage, x: u32, y: u32, c: [u8; 3]) {
    if x < img.width() && y < img.height() {
        img.put_pixel(x, y, Rgb(c));
    }
}

/// `s` broken at spaces into lines of at most `width` characters (longer words stay whole).
fn wrap(s: &str, width: u32) -> Vec<String> {
    let mut lines = vec![String::new()];
    for word in s.split(' ') {
        let last = lines.last_mut().expect("one line at least");
        if !last.is_empty() && last.len() + 1 + word.len() > width as usize {
            lines.push(word.to_string());
        } else {
            if !last.is_empty() {
                last.push(' ');
            }
            last.push_str(word);
        }
    }
    lines
}

/// Draws `s` with the 8 x 8 font (ASCII; other characters as `?`), top-left at `(x, y)`.
fn text(img: &mut RgbImage, x: u32, y: u32, s: &str) {
    draw_text(img, (i64::from(x), i64::from(y)), s, TEXT, None, 1);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{self, SyntheticSpec};
    use std::sync::Arc;

    fn towns() -> impl FnMut(&crate::format::Episode) -> Result<Arc<world::Town>, String> {
        let town = Arc::new(synthetic::town());
        move |_| Ok(town.clone())
    }

    fn count(img: &RgbImage, c: [u8; 3]) -> usize {
        img.pixels().filter(|p| p.0 == c).count()
    }

    #[test]
    fn a_frame_is_drawn_at_the_documented_size_with_every_panel() {
        let dir = tempfile::tempdir().unwrap();
        let spec = SyntheticSpec::tiny(2, 30);
        synthetic::write(dir.path(), &spec).unwrap();
        // Frame 32 is frame 2 of episode 1: lights red, ego at x = 24.
        let img = show(dir.path(), 32, 1, &mut towns()).unwrap();
        assert_eq!(img.dimensions(), picture_size(spec.s0));
        // The rig image is copied as stored.
        let (x, y) = (3, 5);
        let p = img.get_pixel(MARGIN_PX + x, TITLE_PX + MARGIN_PX / 2 + y).0;
        let want: [u8; 3] =
            std::array::from_fn(|c| synthetic::rgb_byte(x as usize, y as usize, c, 2, 1, 1));
        assert_eq!(p, want);
        // The class image in the WoR palette.
        let cx = 2 * MARGIN_PX + spec.s0[0] + x;
        let class = synthetic::class_id(x as usize, spec.s0[0] as usize, 2, 1);
        assert_eq!(
            img.get_pixel(cx, TITLE_PX + MARGIN_PX / 2 + y).0,
            wor_rgb(class)
        );
        // The BEV: the ego, a vehicle ahead, road, and a red stop line
        // (86 - 24 = 62 m ahead: outside the 30 m ahead of the view, so
        // none); the heatmaps' best cell is framed.
        assert!(count(&img, EGO) > 50, "ego");
        assert!(count(&img, VEHICLE) > 50, "vehicle");
        assert!(count(&img, ROAD) > 1000, "road");
        assert!(count(&img, TEXT) > 500, "text");
        assert!(
            count(&img, colormap(1.0)) >= 2 * (CELL_PX as usize - 3).pow(2),
            "best cells"
        );
        assert_eq!(
            count(&img, light_rgb(LightState::Red)),
            0,
            "no stop line in view"
        );
        // Frame 50 (episode 1, frame 20): the stop line 86 - 60 = 26 m ahead, red.
        let img = show(dir.path(), 50, 0, &mut towns()).unwrap();
        assert!(count(&img, light_rgb(LightState::Red)) > 5, "red stop line");
    }

    #[test]
    fn the_best_action_and_soft_target_follow_the_label() {
        // Frame 3 (LANEFOLLOW, 6 m/s: bin 2 (5 m/s) and 3 (7 m/s) tie; the
        // first wins), view 2: best action (3 + 2 + 3 + 2) mod 28 = 10.
        let q: [f32; NUM_ACTIONS] = std::array::from_fn(|a| synthetic::q_value(3, 2, 3, 2, a));
        let soft = soft_target(&q);
        assert_eq!(nearest_bin(6.0), 2);
        assert!(soft[10] > 0.999, "{soft:?}");
        assert!((soft.iter().sum::<f32>() - 1.0).abs() < 1e-5);
        assert_eq!(describe(10), "a10 = steer -0.75, throttle 0.5");
        assert_eq!(describe(BRAKE), "a27 = brake");
        assert_eq!(wrap("ab cd ef", 5), ["ab cd", "ef"]);
        let dir = tempfile::tempdir().unwrap();
        synthetic::write(dir.path(), &SyntheticSpec::tiny(1, 10)).unwrap();
        let img = show(dir.path(), 3, 2, &mut towns()).unwrap();
        // The framed cell is action 10: steer bin 1, throttle bin 1 (middle row).
        let lower = TITLE_PX + MARGIN_PX / 2 + 8 + MARGIN_PX;
        let x = 2 * MARGIN_PX + BEV_PX + 3 * GLYPH_PX + CELL_PX;
        let y = lower + PANEL_TEXT_PX + LINE_PX + CELL_PX;
        assert_eq!(
            img.get_pixel(x, y).0,
            [255, 255, 255],
            "frame of the best cell"
        );
        assert_eq!(img.get_pixel(x + 5, y + 5).0, colormap(1.0), "best value");
    }

    #[test]
    fn a_bad_frame_or_view_is_an_error_naming_the_range() {
        let dir = tempfile::tempdir().unwrap();
        synthetic::write(dir.path(), &SyntheticSpec::tiny(2, 10)).unwrap();
        let err = show(dir.path(), 20, 0, &mut towns())
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("frame 20")
                && err.contains("20 frames, 0 to 19")
                && err.contains(INDEX_FILE),
            "{err}"
        );
        let err = show(dir.path(), 0, 3, &mut towns())
            .unwrap_err()
            .to_string();
        assert!(err.contains("view 3") && err.contains("0 to 2"), "{err}");
        // The last frame has no label: drawn, and says so.
        let img = show(dir.path(), 19, 0, &mut towns()).unwrap();
        assert_eq!(count(&img, [255, 255, 255]), 0, "no heatmap");
    }
}
