//! The camera commands without the `mrdrive` binary (handy while it is being
//! rebuilt): `render_tool demo OUT.png [labels] [paper] [SCALE]`,
//! `render_tool lamp-size [K] [MSAA]`, `render_tool bench [FRAMES] [REPEATS] [K] [MSAA]`
//! (K: supersampling per axis; MSAA: 1 or 4 samples).

use sim::render::image::save_png;
use sim::render::{RigConfig, demo, measure};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let has = |w: &str| args.iter().any(|a| a == w);
    let num = |i: usize| args.get(i).and_then(|a| a.parse::<f64>().ok());
    match args.first().map(String::as_str) {
        Some("demo") => {
            let out = args.get(1).ok_or("demo needs an output path")?;
            let rig = if has("paper") { RigConfig::paper() } else { RigConfig::cpu_default() };
            let scale = args.iter().filter_map(|a| a.parse::<f32>().ok()).next().unwrap_or(1.0);
            let top = has("top").then_some(256);
            let (img, backend) = demo::render_demo(rig, scale, top, has("labels"))?;
            save_png(&img, out.as_ref())?;
            println!("wrote {out} ({}x{}) on {backend}", img.width, img.height);
        }
        Some("lamp-size") => {
            let aa = (num(1).unwrap_or(2.0) as u32, num(2).unwrap_or(1.0) as u32);
            print!("{}", measure::lamp_size_report(&[1.0, 0.75, 0.5], &[10.0, 20.0, 30.0], aa)?)
        }
        Some("bench") => {
            let frames = num(1).unwrap_or(200.0) as usize;
            let repeats = num(2).unwrap_or(5.0) as usize;
            let aa = (num(3).unwrap_or(2.0) as u32, num(4).unwrap_or(1.0) as u32);
            print!("{}", measure::bench_report(frames, repeats, aa)?);
        }
        _ => return Err("usage: render_tool demo OUT.png [labels] [paper] [top] [SCALE] | lamp-size [K] [MSAA] | bench [FRAMES] [REPEATS] [K] [MSAA]".into()),
    }
    Ok(())
}
