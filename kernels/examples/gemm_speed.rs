//! GFLOP/s of this crate's product on each kernel this CPU has, beside the `gemm`
//! crate (burn's CPU kernel), on the network's shapes, one thread, median of 9.
//!
//! `cargo run --release -p kernels --example gemm_speed`

use kernels::isa::Isa;
use kernels::{Mat, PackedRhs, gemm::gemm_on, gemm::gemm_packed_on};
use std::time::Instant;

fn noise(len: usize) -> Vec<f32> {
    (0..len)
        .map(|i| ((i * 7919 % 1000) as f32) / 500.0 - 1.0)
        .collect()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn time(flops: f64, mut f: impl FnMut()) -> f64 {
    f();
    let reps = ((2e9 / flops) as usize).clamp(1, 1000);
    median(
        (0..9)
            .map(|_| {
                let t = Instant::now();
                for _ in 0..reps {
                    f();
                }
                flops * reps as f64 / t.elapsed().as_secs_f64() / 1e9
            })
            .collect(),
    )
}

fn main() {
    // (what, m, k, n): inference tiles (pixels x 9 cin x cout) and training products.
    let shapes = [
        ("infer layer1 3x3 (96 px, 288, 32)", 96, 288, 32),
        ("infer layer3 3x3 (96 px, 1152, 128)", 96, 1152, 128),
        ("infer layer4 3x3 (96 px, 2304, 256)", 96, 2304, 256),
        ("train fwd layer1 (32, 288, 4096)", 32, 288, 4096),
        ("train fwd layer4 (256, 2304, 256)", 256, 2304, 256),
        ("train dW layer1 (32, 4096, 288)", 32, 4096, 288),
    ];
    println!("one thread, GFLOP/s (median of 9)");
    for (what, m, k, n) in shapes {
        let (a, b) = (noise(m * k), noise(k * n));
        let mut c = vec![0.0f32; m * n];
        let flops = 2.0 * (m * k * n) as f64;
        let mut line = format!("{what:<40}");
        for isa in Isa::available() {
            let g = time(flops, || {
                gemm_on(
                    isa,
                    &mut c,
                    (m, k, n),
                    Mat::rows(&a, k),
                    Mat::rows(&b, n),
                    false,
                )
            });
            line += &format!(" {}:{g:6.1}", isa.name());
        }
        let packed = PackedRhs::new(Mat::rows(&b, n), k, n);
        let g = time(flops, || {
            gemm_packed_on(Isa::best(), &mut c, m, Mat::rows(&a, k), &packed, false)
        });
        line += &format!(" packed:{g:6.1}");
        let g = time(flops, || unsafe {
            gemm::gemm(
                m,
                n,
                k,
                c.as_mut_ptr(),
                1,
                n as isize,
                false,
                a.as_ptr(),
                1,
                k as isize,
                b.as_ptr(),
                1,
                n as isize,
                0.0,
                1.0,
                false,
                false,
                false,
                gemm::Parallelism::None,
            )
        });
        line += &format!(" gemm-crate:{g:6.1}");
        println!("{line}");
    }
}
