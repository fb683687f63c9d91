// Anti-aliasing resolve: the samples under one output pixel -> its colour and
// class. The scene pass draws k x k pixels per output pixel (supersampling),
// each with `samples` multisamples (1, or 4 with MSAA); an output pixel takes
// all n = k * k * samples of them, sample i being multisample i % samples of
// drawn pixel i / samples (row-major in its k x k block).
// Colour: box filter in linear light (a float texture), then sRGB's 8-bit
// code by counting the encode steps at or below the value (`render::srgb`):
// comparisons only, the same bits on every CPU. Class: a lit lamp in any sample wins (the
// most frequent lamp colour, ties to the lower id); otherwise the most
// frequent class, ties to the higher id (objects over the surface under them).
// With MSAA the renderer declares the two textures `texture_multisampled_2d`
// (the third argument of textureLoad is then the sample, else the mip level 0).

struct Params {
    k: u32,
    // Bit i set: class i is a small object (wins when present).
    small_mask: u32,
    // Multisamples per drawn pixel (1 or 4).
    samples: u32,
};

@group(0) @binding(0) var hi_color: texture_2d<f32>;
@group(0) @binding(1) var hi_class: texture_2d<u32>;
@group(0) @binding(2) var<uniform> params: Params;

// sRGB's tables (`render::srgb`): the decode table (unused here), then the
// linear values at which the 8-bit code steps up. Entry i is at [i / 4][i % 4].
struct Srgb {
    decode: array<vec4<f32>, 64>,
    steps: array<vec4<f32>, 64>,
};

@group(0) @binding(3) var<uniform> srgb: Srgb;

// The 8-bit sRGB code of a linear value: how many steps lie at or below it.
fn linear_to_srgb8(x: f32) -> u32 {
    var lo = 0u;
    for (var half = 128u; half > 0u; half = half >> 1u) {
        let i = lo + half - 1u;
        if (x >= srgb.steps[i >> 2u][i & 3u]) {
            lo += half;
        }
    }
    return lo;
}

@vertex
fn vs_full(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let x = f32((i << 1u) & 2u);
    let y = f32(i & 2u);
    return vec4<f32>(x * 2.0 - 1.0, 1.0 - y * 2.0, 0.0, 1.0);
}

struct FsOut {
    @location(0) color: vec4<u32>,
    @location(1) class_id: u32,
};

fn is_small(c: u32) -> bool {
    return c < 32u && ((params.small_mask >> c) & 1u) != 0u;
}

// Offers class `c` seen `m` times to the running choice (best, best_n, small, small_n).
fn offer(acc: vec4<u32>, c: u32, m: u32) -> vec4<u32> {
    var r = acc;
    if (m > r.y || (m == r.y && c > r.x)) {
        r.x = c;
        r.y = m;
    }
    if (is_small(c) && (m > r.w || (m == r.w && c < r.z))) {
        r.z = c;
        r.w = m;
    }
    return r;
}

// The drawn pixel of sample i under the output pixel whose block starts at `base`.
fn sample_pixel(base: vec2<i32>, i: i32) -> vec2<i32> {
    let k = i32(params.k);
    let p = i / i32(params.samples);
    return base + vec2<i32>(p % k, p / k);
}

// Which multisample of its drawn pixel sample i is (0 without MSAA: the mip level).
fn sample_index(i: i32) -> i32 {
    return i % i32(params.samples);
}

fn color_of(base: vec2<i32>, i: i32) -> vec3<f32> {
    return textureLoad(hi_color, sample_pixel(base, i), sample_index(i)).rgb;
}

fn class_of(base: vec2<i32>, i: i32) -> u32 {
    return textureLoad(hi_class, sample_pixel(base, i), sample_index(i)).r;
}

@fragment
fn fs_down(@builtin(position) pos: vec4<f32>) -> FsOut {
    let k = i32(params.k);
    let n = k * k * i32(params.samples);
    let base = vec2<i32>(floor(pos.xy)) * k;
    var sum = vec3<f32>(0.0);
    for (var i = 0; i < n; i++) {
        sum += color_of(base, i);
    }
    // acc = (best class, its count, best small class, its count).
    var acc = vec4<u32>(0u, 0u, 0u, 0u);
    if (n == 4) {
        // The common case, unrolled: pairwise counts of four samples.
        let c0 = class_of(base, 0);
        let c1 = class_of(base, 1);
        let c2 = class_of(base, 2);
        let c3 = class_of(base, 3);
        let e01 = select(0u, 1u, c0 == c1);
        let e02 = select(0u, 1u, c0 == c2);
        let e03 = select(0u, 1u, c0 == c3);
        let e12 = select(0u, 1u, c1 == c2);
        let e13 = select(0u, 1u, c1 == c3);
        let e23 = select(0u, 1u, c2 == c3);
        acc = offer(acc, c0, 1u + e01 + e02 + e03);
        acc = offer(acc, c1, 1u + e01 + e12 + e13);
        acc = offer(acc, c2, 1u + e02 + e12 + e23);
        acc = offer(acc, c3, 1u + e03 + e13 + e23);
    } else {
        for (var i = 0; i < n; i++) {
            let c = class_of(base, i);
            var m = 0u;
            for (var j = 0; j < n; j++) {
                m += select(0u, 1u, class_of(base, j) == c);
            }
            acc = offer(acc, c, m);
        }
    }
    var out: FsOut;
    let mean = sum / f32(n);
    out.color = vec4<u32>(
        linear_to_srgb8(mean.r),
        linear_to_srgb8(mean.g),
        linear_to_srgb8(mean.b),
        255u,
    );
    out.class_id = select(acc.x, acc.z, acc.w > 0u);
    return out;
}
