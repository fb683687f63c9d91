// The scene pass: linear colour (a float target; the resolve pass encodes sRGB)
// + class id (flat) + depth.

struct Camera {
    view_proj: mat4x4<f32>,
    // xyz: eye position (metres); w: 1 for fog, 0 without.
    eye: vec4<f32>,
    // x: focal length (drawn pixels); y: smallest lamp diameter drawn
    // (drawn pixels), 0 to draw lamps at their true size.
    lamp: vec4<f32>,
};

@group(0) @binding(0) var<uniform> cam: Camera;

// sRGB's tables (`render::srgb`): the linear value of each 8-bit code, then the
// encode steps (unused here). Entry i is at [i / 4][i % 4].
struct Srgb {
    decode: array<vec4<f32>, 64>,
    steps: array<vec4<f32>, 64>,
};

@group(0) @binding(1) var<uniform> srgb: Srgb;

fn srgb_to_linear(code: u32) -> f32 {
    return srgb.decode[code >> 2u][code & 3u];
}

struct VsIn {
    @location(0) pos: vec3<f32>,
    @location(1) color: u32,
    @location(2) i_pos: vec3<f32>,
    @location(3) i_heading: f32,
    @location(4) i_scale: vec3<f32>,
    @location(5) i_color: u32,
};

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) @interpolate(flat) color: u32,
    // Radiance factor of emissive surfaces (1, or less for an enlarged lamp).
    @location(2) @interpolate(flat) energy: f32,
    // The material's linear colour, decoded from its sRGB code by table.
    @location(3) @interpolate(flat) rgb: vec3<f32>,
};

@vertex
fn vs_main(v: VsIn) -> VsOut {
    let c = cos(v.i_heading);
    let s = sin(v.i_heading);
    // A lit lamp smaller than `cam.lamp.y` drawn pixels is drawn at that size
    // with its radiance cut by the area ratio: the pixel integrates the same
    // light, as a real sensor would, and the supersampling cannot miss it.
    var grow = 1.0;
    if ((v.i_color >> 31u) != 0u && cam.lamp.y > 0.0) {
        let depth = (cam.view_proj * vec4<f32>(v.i_pos, 1.0)).w;
        let d_px = v.i_scale.y * cam.lamp.x / max(depth, 1e-3);
        grow = max(1.0, cam.lamp.y / max(d_px, 1e-6));
    }
    let p = v.pos * v.i_scale * vec3<f32>(1.0, grow, grow);
    let world = vec3<f32>(c * p.x - s * p.y, s * p.x + c * p.y, p.z) + v.i_pos;
    var color = v.color;
    if (((v.i_color >> 24u) & 0x7fu) != 0u) {
        color = v.i_color;
    }
    var out: VsOut;
    out.clip = cam.view_proj * vec4<f32>(world, 1.0);
    out.world = world;
    out.color = color;
    out.energy = 1.0 / (grow * grow);
    out.rgb = vec3<f32>(
        srgb_to_linear(color & 0xffu),
        srgb_to_linear((color >> 8u) & 0xffu),
        srgb_to_linear((color >> 16u) & 0xffu),
    );
    return out;
}

struct FsOut {
    @location(0) color: vec4<f32>,
    @location(1) class_id: u32,
};

const SUN: vec3<f32> = vec3<f32>(0.3713907, 0.5570860, 0.7427813);
const AMBIENT: f32 = 0.45;
// Linear sky colour (sRGB 150, 190, 230), the fog's target.
const SKY: vec3<f32> = vec3<f32>(0.3049874, 0.5149178, 0.7912979);
const FOG_START_M: f32 = 60.0;
const FOG_END_M: f32 = 200.0;
const FOG_MAX: f32 = 0.7;

@fragment
fn fs_main(in: VsOut) -> FsOut {
    // Flat normal from the triangle's plane (screen-space derivatives are
    // exact on a planar triangle); faced toward the camera.
    let cr = cross(dpdx(in.world), dpdy(in.world));
    let len = length(cr);
    var n = vec3<f32>(0.0, 0.0, 1.0);
    if (len > 1e-12) {
        n = cr / len;
    }
    let to_eye = cam.eye.xyz - in.world;
    if (dot(n, to_eye) < 0.0) {
        n = -n;
    }
    let rgb = in.rgb;
    let emissive = (in.color >> 31u) != 0u;
    var lit = rgb * (AMBIENT + (1.0 - AMBIENT) * max(dot(n, SUN), 0.0));
    if (emissive) {
        lit = rgb * in.energy;
    }
    let fog = cam.eye.w * FOG_MAX * clamp((length(to_eye) - FOG_START_M) / (FOG_END_M - FOG_START_M), 0.0, 1.0);
    var out: FsOut;
    out.color = vec4<f32>(mix(lit, SKY, fog), 1.0);
    out.class_id = (in.color >> 24u) & 0x7fu;
    return out;
}
