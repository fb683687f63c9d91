//! A top-down picture of a town: lanes, junctions, sidewalks, crosswalks,
//! markings, buildings, traffic lights coloured by state and optionally a
//! route, rasterised with supersampling (antialiased) into an RGB image; and
//! 8 x 8 pixel text to label pictures ([`draw_text`]).

use glam::{Mat2, Vec2, Vec3};
use image::RgbImage;

use crate::map::town::{LightState, MarkColor, MarkKind, Town};

/// How to draw a town.
#[derive(Debug, Clone)]
pub struct RenderOptions {
    /// Ground size of one output pixel (metres).
    pub metres_per_pixel: f32,
    /// Border around the town's bounds (metres).
    pub margin_m: f32,
    /// Samples per pixel along each axis (antialiasing); 1 to 4.
    pub supersample: u32,
    /// The state of each light (indexed like `Town::lights`); `None` draws them all red.
    pub light_states: Option<Vec<LightState>>,
    /// Draw the lights and their stop lines in grey, whatever their state (for a
    /// picture whose own marks use red).
    pub grey_lights: bool,
    /// A route to draw over the town (points in driving order).
    pub route: Option<Vec<Vec3>>,
    /// Draw only this part of the town, (lowest, highest) corner in metres; `None`
    /// fits the town's bounds and buildings.
    pub crop: Option<(Vec2, Vec2)>,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            metres_per_pixel: 0.5,
            margin_m: 10.0,
            supersample: 3,
            light_states: None,
            grey_lights: false,
            route: None,
            crop: None,
        }
    }
}

/// An sRGB colour.
pub type Rgb = [u8; 3];
const BACKGROUND: Rgb = [52, 66, 50];
/// The colour of the road surface.
pub const ROAD: Rgb = [72, 72, 78];
const SIDEWALK: Rgb = [168, 164, 156];
const BUILDING: Rgb = [140, 112, 96];
const BUILDING_EDGE: Rgb = [90, 70, 60];
const WHITE: Rgb = [240, 240, 240];
const YELLOW: Rgb = [235, 200, 40];
const CURB: Rgb = [120, 120, 120];
const ROUTE: Rgb = [40, 140, 255];
const LIGHT_GREY: Rgb = [150, 150, 150];

/// The colour a light's stop lines and head are drawn in.
pub fn light_rgb(state: LightState) -> Rgb {
    match state {
        LightState::Red => [230, 30, 30],
        LightState::Yellow => [250, 200, 0],
        LightState::Green => [30, 220, 60],
    }
}

/// Where the ground lies on a canvas: an output pixel `(x, y)` (x to the
/// right, y down) shows the world point `p` with
/// `(x, y) = offset_px + axes * (p - origin) / metres_per_pixel`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    /// The world point at `offset_px` (metres).
    pub origin: Vec2,
    /// Image directions of the world's x and y axes (columns of a rotation,
    /// possibly with a flip: north up is `x -> (1, 0)`, `y -> (0, -1)`).
    pub axes: Mat2,
    /// Ground size of one output pixel (metres).
    pub metres_per_pixel: f32,
    /// The output pixel of `origin`.
    pub offset_px: Vec2,
}

impl View {
    /// North up: `top_left` at the image's top-left corner.
    pub fn north_up(top_left: Vec2, metres_per_pixel: f32) -> View {
        View {
            origin: top_left,
            axes: Mat2::from_cols(Vec2::X, Vec2::NEG_Y),
            metres_per_pixel,
            offset_px: Vec2::ZERO,
        }
    }

    /// The output pixel (x right, y down; fractional) that shows world point `p`.
    pub fn pixel(&self, p: Vec2) -> Vec2 {
        self.offset_px + self.axes * (p - self.origin) / self.metres_per_pixel
    }

    /// Heading up: `centre` at output pixel `at_px`, the direction `heading`
    /// (radians, counter-clockwise from +x) pointing up the image.
    pub fn heading_up(centre: Vec2, heading: f32, metres_per_pixel: f32, at_px: Vec2) -> View {
        // Forward (heading) maps to (0, -1), left to (-1, 0).
        let fwd = Vec2::from_angle(heading);
        let left = fwd.perp();
        // The inverse of [fwd left] is its transpose; then forward -> up, left -> left.
        let to_local = Mat2::from_cols(fwd, left).transpose();
        let local_to_image = Mat2::from_cols(Vec2::NEG_Y, Vec2::NEG_X);
        View {
            origin: centre,
            axes: local_to_image * to_local,
            metres_per_pixel,
            offset_px: at_px,
        }
    }
}

/// An antialiased rasteriser of ground shapes: draws at `supersample` x the
/// output resolution, then box-filters down in [`Canvas::finish`].
pub struct Canvas {
    w: usize,
    h: usize,
    ss: usize,
    view: View,
    scale: f32,
    buf: Vec<Rgb>,
}

impl Canvas {
    /// A `width x height` canvas showing `view`, filled with `background`;
    /// `supersample` samples per pixel along each axis (1 to 4).
    pub fn new(width: u32, height: u32, supersample: u32, view: View, background: Rgb) -> Canvas {
        let ss = supersample.clamp(1, 4) as usize;
        let (w, h) = (width as usize * ss, height as usize * ss);
        Canvas {
            w,
            h,
            ss,
            view,
            scale: ss as f32 / view.metres_per_pixel.max(1e-3),
            buf: vec![background; w * h],
        }
    }

    /// Ground size of one output pixel (metres).
    pub fn metres_per_pixel(&self) -> f32 {
        self.view.metres_per_pixel
    }

    fn px(&self, p: Vec2) -> Vec2 {
        self.view.offset_px * self.ss as f32 + self.view.axes * (p - self.view.origin) * self.scale
    }

    /// What the canvas shows: where a world point lands in the output image.
    pub fn view(&self) -> View {
        self.view
    }

    /// Fills a polygon given in world coordinates (even-odd rule).
    pub fn fill(&mut self, poly: &[Vec2], c: Rgb) {
        if poly.len() < 3 {
            return;
        }
        let pts: Vec<Vec2> = poly.iter().map(|p| self.px(*p)).collect();
        let (mut y0, mut y1) = (f32::MAX, f32::MIN);
        for p in &pts {
            y0 = y0.min(p.y);
            y1 = y1.max(p.y);
        }
        let ys = (y0.floor().max(0.0)) as usize;
        let ye = (y1.ceil().min(self.h as f32)) as usize;
        let mut xs: Vec<f32> = Vec::new();
        for y in ys..ye {
            let yc = y as f32 + 0.5;
            xs.clear();
            for i in 0..pts.len() {
                let (a, b) = (pts[i], pts[(i + 1) % pts.len()]);
                if (a.y > yc) != (b.y > yc) {
                    xs.push(a.x + (yc - a.y) / (b.y - a.y) * (b.x - a.x));
                }
            }
            xs.sort_by(f32::total_cmp);
            for pair in xs.chunks_exact(2) {
                let xa = (pair[0] - 0.5).ceil().max(0.0) as usize;
                let xb = ((pair[1] - 0.5).floor() + 1.0).clamp(0.0, self.w as f32) as usize;
                for x in xa..xb {
                    self.buf[y * self.w + x] = c;
                }
            }
        }
    }

    /// A thick line segment in world coordinates, `width_m` wide.
    pub fn segment(&mut self, a: Vec2, b: Vec2, width_m: f32, c: Rgb) {
        let d = (b - a).normalize_or_zero();
        if d == Vec2::ZERO {
            return;
        }
        let n = d.perp() * (width_m * 0.5);
        self.fill(&[a - n, b - n, b + n, a + n], c);
    }

    /// Thick segments through `pts` (world coordinates), `width_m` wide.
    pub fn polyline(&mut self, pts: &[Vec2], width_m: f32, c: Rgb) {
        for w in pts.windows(2) {
            self.segment(w[0], w[1], width_m, c);
        }
    }

    /// A dashed polyline: `dash` metres drawn, `gap` metres left, along `pts`.
    pub fn dashed(&mut self, pts: &[Vec2], width_m: f32, dash: f32, gap: f32, c: Rgb) {
        let period = dash + gap;
        let mut s = 0.0f32;
        for w in pts.windows(2) {
            let len = w[0].distance(w[1]);
            if len <= 0.0 {
                continue;
            }
            let mut t = 0.0;
            while t < len {
                let phase = (s + t) % period;
                let step = if phase < dash {
                    dash - phase
                } else {
                    period - phase
                };
                let t1 = (t + step).min(len);
                if phase < dash {
                    self.segment(
                        w[0].lerp(w[1], t / len),
                        w[0].lerp(w[1], t1 / len),
                        width_m,
                        c,
                    );
                }
                t = t1 + 1e-4;
            }
            s += len;
        }
    }

    /// A filled disc of radius `r` metres around `c0`.
    pub fn disc(&mut self, c0: Vec2, r: f32, c: Rgb) {
        let poly: Vec<Vec2> = (0..20)
            .map(|k| c0 + Vec2::from_angle(k as f32 / 20.0 * std::f32::consts::TAU) * r)
            .collect();
        self.fill(&poly, c);
    }

    /// The town's drivable lanes: one quad per centreline step, as wide as the lane.
    pub fn lanes(&mut self, town: &Town, c: Rgb) {
        for l in &town.lanes {
            for i in 0..l.centerline.len().saturating_sub(1) {
                let a = l.centerline[i].truncate();
                let b = l.centerline[i + 1].truncate();
                let d = (b - a).normalize_or_zero().perp();
                let (wa, wb) = (l.width[i] * 0.5 + 0.05, l.width[i + 1] * 0.5 + 0.05);
                // Overlap consecutive quads a little to avoid seams.
                let e = (b - a).normalize_or_zero() * 0.05;
                self.fill(
                    &[
                        a - e - d * wa,
                        b + e - d * wb,
                        b + e + d * wb,
                        a - e + d * wa,
                    ],
                    c,
                );
            }
        }
    }

    /// Every light's stop lines, `width_m` wide, light `i`'s in `colour(i)`
    /// (`i` indexes `Town::lights`).
    pub fn stop_lines(&mut self, town: &Town, colour: impl Fn(usize) -> Rgb, width_m: f32) {
        for (i, l) in town.lights.iter().enumerate() {
            let col = colour(i);
            for sl in &l.stop_lines {
                self.segment(sl.ends[0].truncate(), sl.ends[1].truncate(), width_m, col);
            }
        }
    }

    /// The output image: each pixel the mean of its samples.
    pub fn finish(self) -> RgbImage {
        let (ss, w) = (self.ss, self.w);
        let (out_w, out_h) = (self.w / ss, self.h / ss);
        let mut img = RgbImage::new(out_w as u32, out_h as u32);
        let n = (ss * ss) as u32;
        for y in 0..out_h {
            for x in 0..out_w {
                let mut acc = [0u32; 3];
                for dy in 0..ss {
                    for dx in 0..ss {
                        let c = self.buf[(y * ss + dy) * w + x * ss + dx];
                        for k in 0..3 {
                            acc[k] += c[k] as u32;
                        }
                    }
                }
                img.put_pixel(
                    x as u32,
                    y as u32,
                    image::Rgb([(acc[0] / n) as u8, (acc[1] / n) as u8, (acc[2] / n) as u8]),
                );
            }
        }
        img
    }
}

/// Rasterises `town` into an RGB image fitted to its bounds.
pub fn render_town(town: &Town, opts: &RenderOptions) -> RgbImage {
    town_canvas(town, opts).finish()
}

/// A canvas fitted to `town`'s bounds with the town drawn on it, for a caller to
/// draw more over it before [`Canvas::finish`].
pub fn town_canvas(town: &Town, opts: &RenderOptions) -> Canvas {
    let ss = opts.supersample.clamp(1, 4) as usize;
    let mpp = opts.metres_per_pixel.max(0.01);
    let (mut lo, mut hi) = town.bounds;
    for b in &town.buildings {
        for p in &b.footprint {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
    }
    if let Some(crop) = opts.crop {
        (lo, hi) = crop;
    }
    lo -= Vec2::splat(opts.margin_m);
    hi += Vec2::splat(opts.margin_m);
    let out_w = (((hi.x - lo.x) / mpp).ceil() as usize).clamp(1, 8192);
    let out_h = (((hi.y - lo.y) / mpp).ceil() as usize).clamp(1, 8192);
    let mut cv = Canvas::new(
        out_w as u32,
        out_h as u32,
        ss as u32,
        View::north_up(Vec2::new(lo.x, hi.y), mpp),
        BACKGROUND,
    );
    let min_line = mpp * 1.2; // keep thin paint visible: at least ~1 output pixel

    for sw in &town.sidewalks {
        for i in 0..sw.inner.len().min(sw.outer.len()).saturating_sub(1) {
            let q = [
                sw.inner[i].truncate(),
                sw.inner[i + 1].truncate(),
                sw.outer[i + 1].truncate(),
                sw.outer[i].truncate(),
            ];
            cv.fill(&q, SIDEWALK);
        }
    }
    for j in &town.junctions {
        cv.fill(&j.outline, ROAD);
    }
    cv.lanes(town, ROAD);
    for c in &town.crosswalks {
        let k = c.corners.map(|p| p.truncate());
        // Stripes across: split the edge k0-k1 (along the road) into bars.
        let along = k[1] - k[0];
        let across = k[3] - k[0];
        let bars = (across.length() / 1.0).floor().max(1.0) as usize;
        for i in (0..bars).step_by(2) {
            let t0 = i as f32 / bars as f32;
            let t1 = (i + 1) as f32 / bars as f32;
            let p0 = k[0] + across * t0;
            let p1 = k[0] + across * t1;
            cv.fill(&[p0, p0 + along, p1 + along, p1], WHITE);
        }
    }
    for m in &town.markings {
        let pts: Vec<Vec2> = m.points.iter().map(|p| p.truncate()).collect();
        let width = m.width_m.max(min_line);
        let col = match (m.kind, m.color) {
            (MarkKind::Curb, _) => CURB,
            (_, MarkColor::Yellow) => YELLOW,
            (_, MarkColor::White) => WHITE,
        };
        match (m.kind, m.dash_m) {
            (MarkKind::Broken | MarkKind::BrokenBroken, Some((d, g))) => {
                cv.dashed(&pts, width, d, g, col)
            }
            _ => cv.polyline(&pts, width, col),
        }
    }
    for b in &town.buildings {
        cv.fill(&b.footprint, BUILDING_EDGE);
        // Inset the fill a little so the edge shows.
        let c = b.footprint.iter().copied().sum::<Vec2>() / b.footprint.len().max(1) as f32;
        let inset: Vec<Vec2> = b
            .footprint
            .iter()
            .map(|p| *p + (c - *p).normalize_or_zero() * 0.8)
            .collect();
        cv.fill(&inset, BUILDING);
    }
    if let Some(route) = &opts.route {
        let pts: Vec<Vec2> = route.iter().map(|p| p.truncate()).collect();
        cv.polyline(&pts, 1.0_f32.max(min_line * 2.0), ROUTE);
        if let (Some(a), Some(b)) = (pts.first(), pts.last()) {
            cv.disc(*a, 3.0, [40, 220, 60]);
            cv.disc(*b, 3.0, [230, 40, 40]);
        }
    }
    let states = opts.light_states.clone().unwrap_or_default();
    let light_col = |i: usize| {
        if opts.grey_lights {
            LIGHT_GREY
        } else {
            light_rgb(states.get(i).copied().unwrap_or_default())
        }
    };
    cv.stop_lines(town, light_col, 0.6_f32.max(min_line));
    for (i, l) in town.lights.iter().enumerate() {
        let col = light_col(i);
        let p = l.position.truncate();
        cv.disc(p, 1.8, [10, 10, 10]);
        cv.disc(p, 1.3, col);
    }
    cv
}

/// Width and height of one character of [`draw_text`] at `scale` 1 (pixels).
pub const GLYPH_PX: u32 = 8;

/// Writes `s` (ASCII; anything else shows as `?`) into `img` with its top-left corner at
/// pixel `(x, y)`, each glyph `scale` times its 8 x 8 pixels, in `color`; with
/// `background`, on a box of that colour one pixel larger all round. Whatever falls
/// outside the image is left out.
pub fn draw_text(
    img: &mut RgbImage,
    (x, y): (i64, i64),
    s: &str,
    color: Rgb,
    background: Option<Rgb>,
    scale: u32,
) {
    let k = i64::from(scale.max(1));
    let glyph = i64::from(GLYPH_PX) * k;
    let mut put = |px: i64, py: i64, c: Rgb| {
        if px >= 0 && py >= 0 && px < i64::from(img.width()) && py < i64::from(img.height()) {
            img.put_pixel(px as u32, py as u32, image::Rgb(c));
        }
    };
    if let Some(bg) = background {
        let w = glyph * s.chars().count() as i64;
        for py in y - 1..y + glyph + 1 {
            for px in x - 1..x + w + 1 {
                put(px, py, bg);
            }
        }
    }
    for (n, ch) in s.chars().enumerate() {
        let code = if ch.is_ascii() {
            ch as usize
        } else {
            '?' as usize
        };
        for (row, bits) in font8x8::legacy::BASIC_LEGACY[code].iter().enumerate() {
            for col in 0..8 {
                if bits & (1 << col) != 0 {
                    for dy in 0..k {
                        for dx in 0..k {
                            let px = x + n as i64 * glyph + col * k + dx;
                            put(px, y + row as i64 * k + dy, color);
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::town::*;

    #[test]
    fn lane_and_light_colours_land_where_they_should() {
        let centerline: Vec<Vec3> = (0..=20).map(|i| Vec3::new(i as f32, 0.0, 0.0)).collect();
        let s = crate::road::geometry::arc_lengths(&centerline);
        let lane = DriveLane {
            road_id: "r".into(),
            od_lane: -1,
            centerline,
            s,
            width: vec![4.0; 21],
            speed_limit_mps: 10.0,
            junction: None,
            successors: vec![],
            predecessors: vec![],
            left: None,
            right: None,
        };
        let light = TrafficLight {
            od_id: "l".into(),
            position: Vec3::new(10.0, 8.0, 0.0),
            heading: 0.0,
            head_height_m: 3.0,
            junction: None,
            group: 0,
            stop_lines: vec![],
        };
        let town = Town {
            lanes: vec![lane],
            lights: vec![light],
            bounds: (Vec2::new(0.0, -2.0), Vec2::new(20.0, 2.0)),
            ..Town::empty("t")
        };
        let opts = RenderOptions {
            metres_per_pixel: 0.5,
            margin_m: 10.0,
            light_states: Some(vec![LightState::Green]),
            ..Default::default()
        };
        let img = render_town(&town, &opts);
        // Image spans x -10..30, y -12..12 -> 80 x 48 px.
        assert_eq!(img.dimensions(), (80, 48));
        let at =
            |x: f32, y: f32| *img.get_pixel(((x + 10.0) / 0.5) as u32, ((12.0 - y) / 0.5) as u32);
        assert_eq!(at(5.0, 0.0).0, ROAD);
        assert_eq!(at(5.0, 6.0).0, BACKGROUND);
        assert_eq!(at(10.0, 8.0).0, [30, 220, 60], "green light");
    }

    #[test]
    fn text_lands_at_its_corner_in_its_colour_and_stops_at_the_edge() {
        let mut img = RgbImage::new(40, 20);
        // "I" in font8x8: a vertical bar in columns 2-5 of rows 0-6 (rows 0 and 6 the serifs).
        draw_text(&mut img, (4, 2), "I", [255, 0, 0], Some([0, 0, 255]), 1);
        assert_eq!(img.get_pixel(4 + 3, 2 + 3).0, [255, 0, 0], "the bar");
        assert_eq!(img.get_pixel(4, 2 + 3).0, [0, 0, 255], "the box around");
        assert_eq!(img.get_pixel(30, 10).0, [0, 0, 0], "untouched");
        // Twice the size, and partly outside: no panic, the inside drawn.
        draw_text(&mut img, (30, 10), "II", [0, 255, 0], None, 2);
        assert_eq!(img.get_pixel(30 + 6, 10 + 6).0, [0, 255, 0]);
        let view = View::north_up(Vec2::new(-10.0, 12.0), 0.5);
        assert_eq!(view.pixel(Vec2::new(-10.0, 12.0)), Vec2::ZERO);
        assert_eq!(view.pixel(Vec2::new(0.0, 0.0)), Vec2::new(20.0, 24.0));
    }

    #[test]
    fn a_heading_up_view_puts_ahead_up_and_left_left() {
        // Facing north-west: ahead is (-1, 1), left is (-1, -1).
        let heading = 0.75 * std::f32::consts::PI;
        let centre = Vec2::new(5.0, -3.0);
        let v = View::heading_up(centre, heading, 0.5, Vec2::new(50.0, 80.0));
        let mut cv = Canvas::new(100, 100, 1, v, BACKGROUND);
        let at = |d: Vec2| cv.px(centre + d);
        let ahead = at(Vec2::from_angle(heading) * 10.0);
        assert!((ahead - Vec2::new(50.0, 60.0)).length() < 1e-3, "{ahead}");
        let left = at(Vec2::from_angle(heading).perp() * 10.0);
        assert!((left - Vec2::new(30.0, 80.0)).length() < 1e-3, "{left}");
        // A disc 10 m ahead is drawn 20 px above the centre pixel.
        cv.disc(centre + Vec2::from_angle(heading) * 10.0, 1.0, ROAD);
        let img = cv.finish();
        assert_eq!(img.get_pixel(50, 60).0, ROAD);
        assert_eq!(img.get_pixel(50, 80).0, BACKGROUND);
    }
}
