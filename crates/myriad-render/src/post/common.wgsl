// What every post pass shares (each pass's .rs file beside it holds its CPU mirror): the
// uniforms, the g-buffer it reads (src_*) and the one it writes (dst_*), one pixel per thread.

struct Post {
    // The g-buffer's size (the image's times `factor`) and the image's.
    width: u32,
    height: u32,
    out_width: u32,
    out_height: u32,
    background: u32,
    factor: u32,
    fill_radius: u32,
    fill_min: u32,
    fill_threshold: f32,
    // Pixels per unit of length at depth 1; depth range of the compute path's keys.
    focal: f32,
    far: f32,
    near: f32,
    ambient: f32,
    headlight: f32,
    sun: f32,
    ssao_radius: f32,
    // Towards the sun in eye coordinates (right, up, forward).
    sun_eye: vec4<f32>,
    ssao_strength: f32,
    edl_strength: f32,
    edl_radius: f32,
    blur_threshold: f32,
    // Side-by-side stereo (the compute path's single pass): each eye's width; 0: one image.
    eye_width: u32,
}

@group(0) @binding(0) var<uniform> r: Post;
@group(0) @binding(10) var<storage, read> src_depth: array<f32>;
@group(0) @binding(11) var<storage, read> src_colour: array<u32>;
@group(0) @binding(12) var<storage, read> src_normal: array<u32>;
@group(0) @binding(13) var<storage, read_write> dst_depth: array<f32>;
@group(0) @binding(14) var<storage, read_write> dst_colour: array<u32>;
@group(0) @binding(15) var<storage, read_write> dst_normal: array<u32>;
// The hidden area (a headset lens's), one bit a pixel; a word of zeros: none. The passes skip it.
@group(0) @binding(16) var<storage, read> hidden_bits: array<u32>;

// Whether pixel `i` is hidden: a pass leaves it as it is.
fn hidden(i: u32) -> bool {
    let k = i >> 5u;
    return k < arrayLength(&hidden_bits) && (hidden_bits[k] & (1u << (i & 31u))) != 0u;
}

const AROUND = array<vec2<f32>, 8>(
    vec2<f32>(1.0, 0.0), vec2<f32>(0.70710677, 0.70710677),
    vec2<f32>(0.0, 1.0), vec2<f32>(-0.70710677, 0.70710677),
    vec2<f32>(-1.0, 0.0), vec2<f32>(-0.70710677, -0.70710677),
    vec2<f32>(0.0, -1.0), vec2<f32>(0.70710677, -0.70710677),
);

// The pixel of a thread (dispatches are 2D beyond 65535 workgroups); `n` pixels in all.
fn thread_pixel(id: vec3<u32>, groups: vec3<u32>) -> u32 {
    return id.y * groups.x * 128u + id.x;
}

// The columns of the thread's eye (the whole width but in side-by-side stereo), set by
// `pixel_x`: a pass never reads across the eyes' border.
var<private> eye_lo: i32;
var<private> eye_hi: i32;

// The column of pixel `i`, and its eye's columns.
fn pixel_x(i: u32) -> i32 {
    let x = i32(i % r.width);
    if (r.eye_width == 0u) {
        eye_lo = 0;
        eye_hi = i32(r.width);
    } else {
        eye_lo = x / i32(r.eye_width) * i32(r.eye_width);
        eye_hi = eye_lo + i32(r.eye_width);
    }
    return x;
}

// Index of pixel (x, y), or -1 outside the g-buffer (or the thread's eye).
fn at(x: i32, y: i32) -> i32 {
    if (x < eye_lo || y < 0 || x >= eye_hi || y >= i32(r.height)) {
        return -1;
    }
    return y * i32(r.width) + x;
}

fn keep(i: u32) {
    dst_depth[i] = src_depth[i];
    dst_colour[i] = src_colour[i];
    dst_normal[i] = src_normal[i];
}

fn put(i: u32, depth: f32, colour: u32, normal: u32) {
    dst_depth[i] = depth;
    dst_colour[i] = colour;
    dst_normal[i] = normal;
}

// Eye-space position (right, up, forward) of pixel (x, y) at depth d.
fn eye_position(x: i32, y: i32, d: f32) -> vec3<f32> {
    return vec3<f32>(
        (f32(x - eye_lo) + 0.5 - f32(eye_hi - eye_lo) * 0.5) / r.focal * d,
        (f32(r.height) * 0.5 - f32(y) - 0.5) / r.focal * d,
        d,
    );
}

fn scale_colour(c: u32, k: f32) -> u32 {
    let v = unpack4x8unorm(c);
    return pack4x8unorm(vec4<f32>(v.rgb * k, v.a));
}
