// Compute rasterizer (after Schütz et al. 2021): one thread per point projects it and keeps the
// nearest point per pixel with a 64-bit atomicMax of (reversed linear depth << 32 | colour).
// One dispatch draws every node of a frame: their points are copied into one buffer, and each
// draw's threads start on a workgroup boundary; each workgroup looks up its draw.

// One draw's points and what they need (`Draw`'s per-draw fields).
struct Range {
    // The node's cube relative to the frame's origin: min corner, side.
    cube: vec4<f32>,
    // Added to the draw's positions: its origin minus the frame's.
    offset: vec4<f32>,
    // The first position word's step per axis (`decode`).
    unit: vec4<f32>,
    spacing: f32,
    node: u32,
    // The draw's first thread (and index in `splat_codes`), and its points.
    start: u32,
    count: u32,
    // Splats: smallest and largest radius; z 1 when this draw has them. w 1: its lone points
    // drawn small (it draws a leaf node whole).
    radius: vec4<f32>,
    // Where its words are in `points`, words between its arrays, position words (0: f32) and
    // how many of them to read.
    base: u32,
    stride: u32,
    words: u32,
    read: u32,
}

@group(0) @binding(4) var<storage, read> ranges: array<Range>;
// The range each workgroup draws from; `u.count` is the number of workgroups.
@group(0) @binding(5) var<storage, read> group_range: array<u32>;
@group(0) @binding(2) var<storage, read_write> framebuffer: array<atomic<u64>>;
// Mode 1: the normal (pack4x8snorm, eye coordinates) of the splat whose value each pixel kept.
@group(0) @binding(7) var<storage, read_write> normal_fb: array<u32>;
var<private> normal_code: u32;
// The hidden area (a headset lens's), one bit a pixel of the frame; a word of zeros: none.
@group(0) @binding(8) var<storage, read> hidden_bits: array<u32>;
// Mode 2 (blending, blend.wgsl): per pixel the sums of red, green and blue times weight, and of
// the weights, of the fragments near enough to the pixel's nearest depth.
@group(0) @binding(9) var<storage, read_write> blend_fb: array<atomic<u32>>;
// The point being blended: its centre (pixels, in its eye), footprint (`blend_weight`) and the
// depth beyond the nearest within which its fragments count (its size at its depth).
var<private> blend_centre: vec2<f32>;
var<private> blend_shape: vec4<f32>;
var<private> blend_tol: f32;
// The eye being drawn: its width and its first column in the frame (single-pass stereo: the
// right eye's image is right of the left's).
var<private> eye_width: u32;
var<private> eye_offset: u32;

// Nearer is larger, so that atomicMax keeps the nearest; 0 stays "empty".
fn depth_key(w: f32) -> u32 {
    return u32(clamp(1.0 - w / u.far, 0.0, 1.0) * 4294967040.0) + 1u;
}

// The eye depth of a depth key (as fb_atomic.wgsl's `depth_at`).
fn key_depth(key: u32) -> f32 {
    return (1.0 - f32(key - 1u) / 4294967040.0) * u.far;
}

// Keeps the nearest at pixel (x, y) of the eye's image (mode 2: adds the fragment to the
// pixel's blend if it lies near enough behind the nearest); nothing outside it (a point at an eye's
// border never reaches the other eye's image).
fn plot(x: i32, y: i32, value: u64) {
    if (x < 0 || y < 0 || x >= i32(eye_width) || y >= i32(u.height)) {
        return;
    }
    let i = u32(y) * u.width + eye_offset + u32(x);
    if ((i >> 5u) < arrayLength(&hidden_bits) && (hidden_bits[i >> 5u] & (1u << (i & 31u))) != 0u) {
        return;
    }
    if (u.mode == 2u) {
        let near = u32(atomicLoad(&framebuffer[i]) >> 32u);
        if (near == 0u || key_depth(u32(value >> 32u)) > key_depth(near) + blend_tol) {
            return;
        }
        let w = blend_weight(vec2<f32>(f32(x) + 0.5, f32(y) + 0.5) - blend_centre, blend_shape);
        let c = u32(value & 0xfffffffflu);
        let k = i * 4u;
        atomicAdd(&blend_fb[k], (c & 255u) * w);
        atomicAdd(&blend_fb[k + 1u], ((c >> 8u) & 255u) * w);
        atomicAdd(&blend_fb[k + 2u], ((c >> 16u) & 255u) * w);
        atomicAdd(&blend_fb[k + 3u], w);
        return;
    }
    if (u.mode == 1u) {
        if (atomicLoad(&framebuffer[i]) == value) {
            normal_fb[i] = normal_code;
        }
        return;
    }
    atomicMax(&framebuffer[i], value);
}

// A splat's eye normal (`splat_shape`'s yzw) facing the eye, packed.
fn splat_normal_code(sp: vec4<f32>) -> u32 {
    let n = sp.yzw / sqrt(dot(sp.yzw, sp.yzw));
    return pack4x8snorm(vec4<f32>(select(n, -n, n.z > 0.0), 1.0));
}

@compute @workgroup_size(128)
fn rasterize(
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(local_invocation_index) lane: u32,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    // Dispatches are 2D when there are more than 65535 workgroups.
    let g = group.y * groups.x + group.x;
    if (g >= u.count) {
        return;
    }
    let r = ranges[group_range[g]];
    let local = g * 128u + lane - r.start;
    if (local >= r.count) {
        return;
    }
    let p = decode(local, r.base, r.stride, r.words, r.read, r.offset.xyz, r.unit.xyz);
    if (clipped(p)) {
        return;
    }
    if (u.stereo.x == 0u) {
        eye_width = u.width;
        eye_offset = 0u;
        draw_point(p, local, r, u.view_proj);
        return;
    }
    eye_width = u.stereo.x;
    for (var k = 0u; k < 2u; k++) {
        eye_offset = k * u.stereo.x;
        var view_proj = u.view_proj;
        if (k == 1u) {
            view_proj = u.view_proj_right;
        }
        draw_point(p, local, r, view_proj);
    }
}

// Point `local` of range `r` at `p` (relative to the origin) into the eye seen by `view_proj`.
fn draw_point(p: vec3<f32>, local: u32, r: Range, view_proj: mat4x4<f32>) {
    let clip = view_proj * vec4<f32>(p, 1.0);
    if (clip.w <= 0.0) {
        return;
    }
    let ndc = clip / clip.w;
    if (ndc.x < -1.0 || ndc.x >= 1.0 || ndc.y <= -1.0 || ndc.y > 1.0 || ndc.z < 0.0 || ndc.z > 1.0) {
        return;
    }
    let fx = (ndc.x * 0.5 + 0.5) * f32(eye_width);
    let fy = (0.5 - ndc.y * 0.5) * f32(u.height);
    let colour = u64(colour_word(local, r.base, r.stride, r.words));
    let splat = r.radius.z > 0.0 && u.point_size == 0.0;
    if (u.mode == 1u && !splat) {
        return;
    }
    if (splat) {
        // An oriented disc: the pixels whose ray meets it within its radius, each at the depth
        // where it does (the splat seen in a small neighbourhood as in parallel projection).
        let sp = splat_shape(splat_codes[r.start + local], r.radius.xy, clip.w);
        normal_code = splat_normal_code(sp);
        let s = splat_pixels(sp.x);
        blend_centre = vec2<f32>(fx, fy);
        blend_shape = blend_splat(sp);
        blend_tol = f32(s) * clip.w / u.focal;
        let x0 = i32(floor(fx)) - (s - 1) / 2;
        let y0 = i32(floor(fy)) - (s - 1) / 2;
        let c = f32(s - 1) * 0.5;
        let k = clip.w / u.focal;
        for (var dy = 0; dy < s; dy++) {
            for (var dx = 0; dx < s; dx++) {
                let a = f32(dx) - c;
                let b = f32(dy) - c;
                let e = (a * sp.y - b * sp.z) / sp.w;
                if (a * a + b * b + e * e <= sp.x * sp.x) {
                    plot(x0 + dx, y0 + dy, (u64(depth_key(clip.w - k * e)) << 32u) | colour);
                }
            }
        }
        return;
    }
    let s = i32(point_pixels(p, clip.w, r.spacing, r.node, r.cube, lone(local, r.base, r.words) && r.radius.w > 0.0));
    blend_centre = vec2<f32>(fx, fy);
    blend_shape = blend_point(f32(s));
    blend_tol = f32(s) * clip.w / u.focal;
    if (s == 1) {
        let x = u32(fx);
        let y = u32(fy);
        let value = (u64(depth_key(clip.w)) << 32u) | colour;
        if (u.mode == 2u) {
            plot(i32(x), i32(y), value);
            return;
        }
        atomicMax(&framebuffer[y * u.width + eye_offset + x], value);
        return;
    }
    // A square of s x s pixels centred on the point.
    let x0 = i32(floor(fx)) - (s - 1) / 2;
    let y0 = i32(floor(fy)) - (s - 1) / 2;
    // Round shapes keep the pixels whose centres lie within the disc of diameter s.
    let c = f32(s - 1) * 0.5;
    let r2 = max(f32(s * s) * 0.25, 0.5);
    // Paraboloid: the centre stands out towards the eye by half the point's size in the world.
    let bulge = 0.5 * f32(s) * clip.w / u.focal;
    let flat = (u64(depth_key(clip.w)) << 32u) | colour;
    for (var dy = 0; dy < s; dy++) {
        for (var dx = 0; dx < s; dx++) {
            var value = flat;
            if (u.shape != 0u) {
                let ox = f32(dx) - c;
                let oy = f32(dy) - c;
                let d2 = ox * ox + oy * oy;
                if (d2 > r2) {
                    continue;
                }
                if (u.shape == 2u) {
                    let w = clip.w - bulge * (1.0 - d2 / r2);
                    value = (u64(depth_key(w)) << 32u) | colour;
                }
            }
            plot(x0 + dx, y0 + dy, value);
        }
    }
}
