//! Measurements of the camera: how many pixels a traffic-light lamp covers at
//! a distance and scale, and how many rig frames per second the renderer
//! delivers (render + anti-aliasing + readback).

use std::time::Instant;

use glam::{Vec2, Vec3};
use world::route::DenseRoute;
use world::{ActorSnapshot, LightState, Town, TrafficLight};

use super::classes;
use super::demo;
use super::renderer::{RenderError, Renderer};
use super::rig::RigConfig;
use super::scene::LAMP_DIAMETER_M;
use world::EgoPose;

/// A lamp's size in the image at one distance and scale.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LampSize {
    /// Scale of S0.
    pub scale: f32,
    /// Output size (width, height) in pixels.
    pub size: (u32, u32),
    /// Distance from the camera to the lamp along the optical axis (metres).
    pub distance_m: f32,
    /// Pixels labelled lamp-red in the class image.
    pub class_px: usize,
    /// Pixels whose red channel rises by 30 or more (of 255) when the lamp is
    /// lit, against the same frame with all lamps dark.
    pub tinted_px: usize,
    /// The largest rise of the red channel when the lamp is lit (0..255).
    pub peak_tint: i32,
    /// The lamp's diameter projected analytically (pixels).
    pub analytic_diameter_px: f32,
    /// The lamp disc's area projected analytically (pixels squared).
    pub analytic_area_px: f32,
}

/// Renders a single red lamp straight ahead of the centre camera at each
/// distance and scale, counting lamp pixels, and computes the analytic size.
pub fn lamp_sizes(
    rig: RigConfig,
    scales: &[f32],
    distances_m: &[f32],
) -> Result<Vec<LampSize>, RenderError> {
    let mut out = Vec::new();
    for &d in distances_m {
        // The light faces the ego; its red lamp is on the centre camera's axis
        // horizontally, `d` metres ahead of the camera.
        let mut town = Town::empty("lamp-size");
        town.bounds = (Vec2::splat(-60.0), Vec2::splat(60.0));
        let cam_x = rig.mount_m.x;
        let housing_front = 0.35 * 0.5 + 0.015;
        town.lights.push(TrafficLight {
            od_id: "lamp".into(),
            position: Vec3::new(cam_x + d + housing_front, 0.0, 0.0),
            heading: std::f32::consts::PI,
            head_height_m: demo::HEAD_HEIGHT_M,
            junction: None,
            group: 0,
            stop_lines: Vec::new(),
        });
        let mut r = Renderer::new(&town, rig, 0)?;
        for &scale in scales {
            let ego = EgoPose::default();
            let dark = r.render_rig(&ego, &[], &[], scale)?.0.data.clone();
            let (rgb, labels) = r.render_rig(&ego, &[], &[LightState::Red], scale)?;
            let tints = rgb
                .data
                .chunks_exact(3)
                .zip(dark.chunks_exact(3))
                .map(|(a, b)| i32::from(a[0]) - i32::from(b[0]));
            let fx = rig.cam_width_px as f32 * 0.5 / (rig.fov_deg.to_radians() * 0.5).tan()
                * (labels.width / 3) as f32
                / rig.cam_width_px as f32;
            let diameter = fx * LAMP_DIAMETER_M / d;
            out.push(LampSize {
                scale,
                size: (labels.width, labels.height),
                distance_m: d,
                class_px: labels.count(classes::LAMP_RED),
                tinted_px: tints.clone().filter(|&t| t >= 30).count(),
                peak_tint: tints.max().unwrap_or(0),
                analytic_diameter_px: diameter,
                analytic_area_px: std::f32::consts::FRAC_PI_4 * diameter * diameter,
            });
        }
    }
    Ok(out)
}

/// Frames per second of the full rig at one scale.
#[derive(Debug, Clone, PartialEq)]
pub struct RigSpeed {
    /// Scale of S0.
    pub scale: f32,
    /// Output size (width, height) in pixels.
    pub size: (u32, u32),
    /// Frames per second of each repeat (render + resolve + readback).
    pub fps: Vec<f64>,
}

impl RigSpeed {
    /// The median of the repeats.
    pub fn median_fps(&self) -> f64 {
        let mut v = self.fps.clone();
        v.sort_by(f64::total_cmp);
        let n = v.len();
        if n == 0 {
            return 0.0;
        }
        if n % 2 == 1 {
            v[n / 2]
        } else {
            0.5 * (v[n / 2 - 1] + v[n / 2])
        }
    }
}

/// Times `frames` rig renders per repeat at each scale, starting from `ego0`
/// and driving 0.25 m further along its heading each frame (10 m/s at 40 Hz).
pub fn bench_rig(
    renderer: &mut Renderer,
    (ego0, actors, states): (EgoPose, &[ActorSnapshot], &[LightState]),
    scales: &[f32],
    frames: usize,
    repeats: usize,
) -> Result<Vec<RigSpeed>, RenderError> {
    let (s, c) = ego0.heading.sin_cos();
    let fwd = Vec3::new(c, s, 0.0);
    let mut out = Vec::new();
    for &scale in scales {
        // Warm-up: creates the targets and compiles shaders.
        for _ in 0..5 {
            renderer.render_rig(&ego0, actors, states, scale)?;
        }
        let mut fps = Vec::with_capacity(repeats);
        let mut size = (0, 0);
        for _ in 0..repeats {
            let t0 = Instant::now();
            for f in 0..frames {
                let ego = EgoPose {
                    position: ego0.position + fwd * (0.25 * (f % 100) as f32),
                    heading: ego0.heading,
                };
                let (rgb, _) = renderer.render_rig(&ego, actors, states, scale)?;
                size = (rgb.width, rgb.height);
            }
            fps.push(frames as f64 / t0.elapsed().as_secs_f64());
        }
        out.push(RigSpeed { scale, size, fps });
    }
    Ok(out)
}

/// Times `frames` rig renders per repeat at each scale, cycling through
/// `poses` (e.g. points along a route).
pub fn bench_poses(
    renderer: &mut Renderer,
    poses: &[EgoPose],
    (actors, states): (&[ActorSnapshot], &[LightState]),
    scales: &[f32],
    frames: usize,
    repeats: usize,
) -> Result<Vec<RigSpeed>, RenderError> {
    let mut out = Vec::new();
    let Some(&first) = poses.first() else {
        return Ok(out);
    };
    for &scale in scales {
        for _ in 0..5 {
            renderer.render_rig(&first, actors, states, scale)?;
        }
        let mut fps = Vec::with_capacity(repeats);
        let mut size = (0, 0);
        for _ in 0..repeats {
            let t0 = Instant::now();
            for f in 0..frames {
                let (rgb, _) =
                    renderer.render_rig(&poses[f % poses.len()], actors, states, scale)?;
                size = (rgb.width, rgb.height);
            }
            fps.push(frames as f64 / t0.elapsed().as_secs_f64());
        }
        out.push(RigSpeed { scale, size, fps });
    }
    Ok(out)
}

/// One line of a bench report.
pub fn speed_line(name: &str, m: &RigSpeed) -> String {
    let fps: Vec<String> = m.fps.iter().map(|f| format!("{f:.0}")).collect();
    format!(
        "{name:<9} scale {:.2} {:>4}x{:<4} median {:>7.1} rig fps  (repeats: {})",
        m.scale,
        m.size.0,
        m.size.1,
        m.median_fps(),
        fps.join(" ")
    )
}

/// The `render lamp-size` table: lamp sizes for the CPU and the paper's S0.
pub fn lamp_size_report(
    scales: &[f32],
    distances_m: &[f32],
    antialias: (u32, u32),
) -> Result<String, RenderError> {
    use std::fmt::Write;
    let (supersample, msaa) = antialias;
    let mut s = String::new();
    let aa = RigConfig {
        supersample,
        msaa,
        ..RigConfig::cpu_default()
    }
    .antialias();
    let _ = writeln!(
        s,
        "lamp: {LAMP_DIAMETER_M:.2} m disc, red, on the centre camera's axis; anti-aliasing {aa}\n\
         class_px: pixels labelled lamp_red; tinted_px: red channel +30 or more over dark lamps;\n\
         analytic_d / analytic_a: projected diameter (px) and disc area (px^2)"
    );
    let _ = writeln!(
        s,
        "{:<9} {:>5} {:>8} {:>6} {:>8} {:>9} {:>9} {:>10} {:>10}",
        "rig",
        "scale",
        "size",
        "dist_m",
        "class_px",
        "tinted_px",
        "peak_rise",
        "analytic_d",
        "analytic_a"
    );
    for (name, rig) in [
        ("cpu-S0", RigConfig::cpu_default()),
        ("paper-S0", RigConfig::paper()),
    ] {
        let rig = RigConfig {
            supersample,
            msaa,
            ..rig
        };
        for m in lamp_sizes(rig, scales, distances_m)? {
            let _ = writeln!(
                s,
                "{:<9} {:>5.2} {:>8} {:>6.1} {:>8} {:>9} {:>9} {:>10.2} {:>10.2}",
                name,
                m.scale,
                format!("{}x{}", m.size.0, m.size.1),
                m.distance_m,
                m.class_px,
                m.tinted_px,
                m.peak_tint,
                m.analytic_diameter_px,
                m.analytic_area_px
            );
        }
    }
    Ok(s)
}

/// Ego poses along `route`, one every `spacing_m` metres of route.
pub fn poses_along(route: &DenseRoute, spacing_m: f32) -> Vec<EgoPose> {
    let mut poses = Vec::new();
    let mut next_s = 0.0;
    for p in &route.points {
        if p.route_s >= next_s {
            poses.push(EgoPose {
                position: p.position,
                heading: p.heading,
            });
            next_s = p.route_s + spacing_m;
        }
    }
    poses
}

/// The `bench render --scenario` figures: median rig fps along `route` in
/// `town` (one pose per metre, no actors, every light red) at 1.0 and 0.75
/// of `rig`'s S0, scenery from `seed`.
pub fn route_report(
    town: &Town,
    route: &DenseRoute,
    rig: RigConfig,
    seed: u64,
    frames: usize,
    repeats: usize,
) -> Result<String, RenderError> {
    use std::fmt::Write;
    let mut r = Renderer::new(town, rig, seed)?;
    let poses = poses_along(route, 1.0);
    let states = vec![LightState::Red; town.lights.len()];
    let mut s = format!(
        "backend: {}\ntown {}: {} static triangles in {} cells; route {} ({} poses, 1 m apart); \
         no actors, all lights red; anti-aliasing {}; {} frames x {} repeats\n",
        r.backend(),
        town.name,
        r.scene().triangle_count(),
        r.scene().cells.len(),
        route.id,
        poses.len(),
        r.rig().antialias(),
        frames,
        repeats
    );
    for m in bench_poses(
        &mut r,
        &poses,
        (&[], &states),
        &[1.0, 0.75],
        frames,
        repeats,
    )? {
        let _ = writeln!(s, "{}", speed_line("scenario", &m));
    }
    // The floor: the same frames of a town with nothing in it (the sky, the
    // clear, the anti-aliasing resolve, the sRGB encode and the readback): what a frame
    // costs before the first triangle is drawn.
    let mut empty = Town::empty("empty");
    empty.bounds = town.bounds;
    let mut floor = Renderer::new(&empty, rig, seed)?;
    let speeds = bench_poses(
        &mut floor,
        &poses,
        (&[], &[]),
        &[1.0, 0.75],
        frames,
        repeats,
    )?;
    for m in &speeds {
        let _ = writeln!(s, "{}", speed_line("empty", m));
    }
    let _ = writeln!(
        s,
        "(empty: a town with no road, building, light or actor along the same poses: the \
         per-frame cost of the pipeline itself)"
    );
    Ok(s)
}

/// The `bench render` figures: median rig fps at the CPU S0, 0.75 of it, and
/// the paper's 480x192 (and 0.75 of that), on the 4x4 demo town.
pub fn bench_report(
    frames: usize,
    repeats: usize,
    (supersample, msaa): (u32, u32),
) -> Result<String, RenderError> {
    use std::fmt::Write;
    let mut s = String::new();
    let town = demo::grid_town(4, 4, 100.0, 7);
    let (ego, actors, states) = demo::demo_state(&town);
    for (name, base) in [
        ("cpu-S0", RigConfig::cpu_default()),
        ("paper-S0", RigConfig::paper()),
    ] {
        let rig = RigConfig {
            supersample,
            msaa,
            ..base
        };
        let mut r = Renderer::new(&town, rig, 7)?;
        if name == "cpu-S0" {
            let _ = writeln!(
                s,
                "backend: {}\ntown {}: {} static triangles in {} cells, drawn within {} m; {} actors; \
                 anti-aliasing {}; {} frames x {} repeats",
                r.backend(),
                town.name,
                r.scene().triangle_count(),
                r.scene().cells.len(),
                super::renderer::DRAW_DISTANCE_M,
                actors.len(),
                r.rig().antialias(),
                frames,
                repeats
            );
        }
        for m in bench_rig(
            &mut r,
            (ego, &actors, &states),
            &[1.0, 0.75],
            frames,
            repeats,
        )? {
            let _ = writeln!(s, "{}", speed_line(name, &m));
        }
    }
    Ok(s)
}

#[cfg(test)]
mod tests {
    use world::route::RoutePoint;
    use world::{Command, LaneIdx};

    use super::*;

    #[test]
    fn poses_along_a_route_are_a_metre_apart() {
        let points = (0..=40)
            .map(|i| RoutePoint {
                position: Vec3::new(i as f32 * 0.25, 2.0, 0.0),
                heading: 0.5,
                lane: LaneIdx(0),
                s: i as f32 * 0.25,
                command: Command::LaneFollow,
                route_s: i as f32 * 0.25,
            })
            .collect();
        let route = DenseRoute {
            id: "r".into(),
            points,
            length_m: 10.0,
            waypoint_points: vec![0, 40],
        };
        let poses = poses_along(&route, 1.0);
        assert_eq!(poses.len(), 11);
        assert_eq!(poses[3].position, Vec3::new(3.0, 2.0, 0.0));
        assert_eq!(poses[3].heading, 0.5);
    }
}
