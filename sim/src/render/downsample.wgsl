// Supersampling resolve: k x k subsamples -> one output pixel (k = 1 copies).
// Colour: box filter in linear light (a float texture), then sRGB's 8-bit
// code by counting the encode steps at or below the value (`render::srgb`):
// comparisons only, the same bits on every CPU. Class: a lit lamp in any subsample wins (the
// most frequent lamp colour, ties to the lower id); otherwise the most
// frequent class, ties to the higher id (objects over the surface under them).

struct Params {
    k: u32,
    // Bit i set: class i is a small object (wins when present).
    small_mask: u32,
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

@fragment
fn fs_down(@builtin(position) pos: vec4<f32>) -> FsOut {
    let k = i32(params.k);
    let n = k * k;
    let base = vec2<i32>(floor(pos.xy)) * k;
    var sum = vec3<f32>(0.0);
    for (var i = 0; i < n; i++) {
        sum += textureLoad(hi_color, base + vec2<i32>(i % k, i / k), 0).rgb;
    }
    // acc = (best class, its count, best small class, its count).
    var acc = vec4<u32>(0u, 0u, 0u, 0u);
    if (k == 2) {
        // The common case, unrolled: pairwise counts of four samples.
        let c0 = textureLoad(hi_class, base, 0).r;
        let c1 = textureLoad(hi_class, base + vec2<i32>(1, 0), 0).r;
        let c2 = textureLoad(hi_class, base + vec2<i32>(0, 1), 0).r;
        let c3 = textureLoad(hi_class, base + vec2<i32>(1, 1), 0).r;
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
            let c = textureLoad(hi_class, base + vec2<i32>(i % k, i / k), 0).r;
            var m = 0u;
            for (var j = 0; j < n; j++) {
                m += select(0u, 1u, textureLoad(hi_class, base + vec2<i32>(j % k, j / k), 0).r == c);
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
