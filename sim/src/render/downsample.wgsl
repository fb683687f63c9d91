// Supersampling resolve: k x k subsamples -> one output pixel.
// Colour: box filter in linear light (the sRGB texture decodes on load, the
// sRGB target encodes on store). Class: a lit lamp in any subsample wins (the
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

@vertex
fn vs_full(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let x = f32((i << 1u) & 2u);
    let y = f32(i & 2u);
    return vec4<f32>(x * 2.0 - 1.0, 1.0 - y * 2.0, 0.0, 1.0);
}

struct FsOut {
    @location(0) color: vec4<f32>,
    @location(1) class_id: u32,
};

@fragment
fn fs_down(@builtin(position) pos: vec4<f32>) -> FsOut {
    let k = i32(params.k);
    let base = vec2<i32>(floor(pos.xy)) * k;
    var sum = vec3<f32>(0.0);
    var counts: array<u32, 32>;
    for (var dy = 0; dy < k; dy++) {
        for (var dx = 0; dx < k; dx++) {
            let q = base + vec2<i32>(dx, dy);
            sum += textureLoad(hi_color, q, 0).rgb;
            let c = min(textureLoad(hi_class, q, 0).r, 31u);
            counts[c] += 1u;
        }
    }
    var best = 0u;
    var best_n = 0u;
    var small = 0u;
    var small_n = 0u;
    for (var c = 0u; c < 32u; c++) {
        let n = counts[c];
        if (n >= best_n && n > 0u) {
            best = c;
            best_n = n;
        }
        if (((params.small_mask >> c) & 1u) != 0u && n > small_n) {
            small = c;
            small_n = n;
        }
    }
    var out: FsOut;
    out.color = vec4<f32>(sum / f32(k * k), 1.0);
    out.class_id = select(best, small, small_n > 0u);
    return out;
}
