// What every draw of points shares (the compute and quad paths both start with this): the
// draw's uniforms, and the tree of drawn nodes that adaptive point sizes walk.

struct Draw {
    view_proj: mat4x4<f32>,
    width: u32,
    height: u32,
    count: u32,
    // 0 square, 1 round, 2 paraboloid.
    shape: u32,
    // Fixed point size in pixels; 0: adaptive, the world `spacing` projected at each point.
    point_size: f32,
    spacing: f32,
    // Pixels per unit of length at depth 1.
    focal: f32,
    max_size: f32,
    // Depth keys are linear in eye depth over 0..far.
    far: f32,
    near: f32,
    // This draw's node in `tree`, or 0xffffffff: its own spacing for every point.
    node: u32,
    // 0: the point pass; 1 (compute path): splats write their normal where their value won.
    mode: u32,
    // The node's cube relative to the origin: min corner, side.
    cube: vec4<f32>,
    // Clipping box relative to the origin; clip_min.w: 0 none, 1 keep inside, 2 keep outside.
    clip_min: vec4<f32>,
    clip_max: vec4<f32>,
    // The eye's right, up and forward unit vectors (world), for oriented splats.
    eye_right: vec4<f32>,
    eye_up: vec4<f32>,
    eye_forward: vec4<f32>,
    // Quad path, this draw's splats: smallest and largest radius, z 1 when it has splats; w 1:
    // its lone points drawn small (it draws a leaf node whole).
    radius: vec4<f32>,
    // Quad path, this draw's points (as `Range` in compute.wgsl): its origin relative to the
    // frame's, its first word's step per axis, and its place: base, stride, words, read (`decode`).
    offset: vec4<f32>,
    unit: vec4<f32>,
    place: vec4<u32>,
    // Single-pass stereo (compute path): the right eye's view-projection and, in x, each eye's
    // width in the side-by-side frame (0: one eye).
    view_proj_right: mat4x4<f32>,
    stereo: vec4<u32>,
}

@group(0) @binding(0) var<uniform> u: Draw;
// The drawn nodes (myriad_lod::DrawnTree): child mask, first child, spacing bits (0: not drawn).
@group(0) @binding(3) var<storage, read> tree: array<vec4<u32>>;
// Splats (mwkd): per point, a normal's cube-map index (low 16 bits) and an 8-bit radius code.
@group(0) @binding(6) var<storage, read> splat_codes: array<u32>;
// Points (myriad_render::Points): for each draw, at `base`, arrays of `stride` words each: the
// position words (f32 x, y, z; or 1 to 3 words of 10 bits an axis, most significant first),
// then the RGBA8 colours.
@group(0) @binding(1) var<storage, read> points: array<u32>;

// A position word's three 10-bit parts.
fn split(w: u32) -> vec3<f32> {
    return vec3<f32>(f32(w & 1023u), f32((w >> 10u) & 1023u), f32((w >> 20u) & 1023u));
}

// Point `i`'s position relative to the frame's origin (`offset`: its draw's origin there; `unit`:
// the first word's step per axis). Quantized points read `read` of their `words` words and take
// the rest at the middle of its range (as points::decode on the CPU).
fn decode(i: u32, base: u32, stride: u32, words: u32, read: u32, offset: vec3<f32>, unit: vec3<f32>) -> vec3<f32> {
    if (words == 0u) {
        let x = bitcast<f32>(points[base + i]);
        let y = bitcast<f32>(points[base + stride + i]);
        let z = bitcast<f32>(points[base + 2u * stride + i]);
        return vec3<f32>(offset.x + x, offset.y + y, offset.z + z);
    }
    var p = offset;
    var u = unit;
    for (var k = 0u; k < read; k++) {
        let w = points[base + k * stride + i];
        p = p + split(w) * u;
        u = u * (1.0 / 1024.0);
    }
    if (read < words) {
        p = p + u * 512.0;
    }
    return p;
}

// Whether point `i` is lone (points.rs's LONE_BIT above the axes of its first position word;
// f32 positions have none).
fn lone(i: u32, base: u32, words: u32) -> bool {
    return words != 0u && (points[base + i] & 0x40000000u) != 0u;
}

// Point `i`'s colour word (RGBA8), after its position words.
fn colour_word(i: u32, base: u32, stride: u32, words: u32) -> u32 {
    return points[base + select(words, 3u, words == 0u) * stride + i];
}

// The unit direction at the centre of a cube-map cell (104 x 104 per face), as
// myriad_format::splat::normal_from_code.
fn splat_normal(code: u32) -> vec3<f32> {
    let c = code & 0xffffu;
    let face = min(c / 10816u, 5u);
    let rest = c % 10816u;
    let cu = (f32(rest % 104u) + 0.5) / 104.0 * 2.0 - 1.0;
    let cv = (f32(rest / 104u) + 0.5) / 104.0 * 2.0 - 1.0;
    let s = select(1.0, -1.0, (face % 2u) == 1u);
    let axis = face / 2u;
    var n = vec3<f32>(cu, cv, s);
    if (axis == 0u) {
        n = vec3<f32>(s, cu, cv);
    } else if (axis == 1u) {
        n = vec3<f32>(cv, s, cu);
    }
    return n / sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
}

// A splat at eye depth `w`: its radius in pixels (at most what the largest point size holds, so
// that a near splat shrinks rather than being cut square) and its normal in eye coordinates
// (right, up, forward; the forward part kept at least 0.05 from zero so that edge-on splats stay
// thin ellipses).
fn splat_shape(code: u32, range: vec2<f32>, w: f32) -> vec4<f32> {
    let n = splat_normal(code);
    let r = range.x + (range.y - range.x) * f32((code >> 16u) & 0xffu) / 255.0;
    var nf = dot(n, u.eye_forward.xyz);
    if (abs(nf) < 0.05) {
        nf = select(0.05, -0.05, nf < 0.0);
    }
    let rho = min(r * u.focal / w, (u.max_size - 1.0) * 0.5);
    return vec4<f32>(rho, dot(n, u.eye_right.xyz), dot(n, u.eye_up.xyz), nf);
}

// The odd side of the square of pixels a splat of `rho` pixels' radius may cover.
fn splat_pixels(rho: f32) -> i32 {
    let s = i32(clamp(2.0 * round(rho) + 1.0, 1.0, u.max_size));
    return s - 1 + (s & 1);
}

// Whether the clipping box hides the point at `p` (relative to the origin).
fn clipped(p: vec3<f32>) -> bool {
    let mode = u.clip_min.w;
    if (mode == 0.0) {
        return false;
    }
    let inside = all(p >= u.clip_min.xyz) && all(p <= u.clip_max.xyz);
    return inside == (mode == 2.0);
}

// Pixels on a side for a point at `p` (relative to the origin) at eye depth `w`: fixed, or the
// spacing of the finest drawn node around it, as seen. `draw_spacing`, `node` and `cube` are the
// point's draw's (as in `Draw`); `alone`: the point is lone (at most LONE_PIXELS wide).
fn point_pixels(p: vec3<f32>, w: f32, draw_spacing: f32, node: u32, cube: vec4<f32>, alone: bool) -> f32 {
    if (u.point_size > 0.0) {
        return clamp(round(u.point_size), 1.0, u.max_size);
    }
    var spacing = draw_spacing;
    if (node != 0xffffffffu) {
        var i = node;
        var lo = cube.xyz;
        var side = cube.w;
        // The style's scale: the draw's spacing over its node's own.
        let own = bitcast<f32>(tree[i].z);
        let scale = select(1.0, draw_spacing / own, own > 0.0);
        for (var depth = 0; depth < 32; depth++) {
            let e = tree[i];
            side = side * 0.5;
            let mid = lo + vec3<f32>(side);
            let o = select(0u, 1u, p.x >= mid.x) | select(0u, 2u, p.y >= mid.y) | select(0u, 4u, p.z >= mid.z);
            if ((e.x & (1u << o)) == 0u) {
                break;
            }
            i = e.y + countOneBits(e.x & ((1u << o) - 1u));
            lo = lo + vec3<f32>(f32(o & 1u), f32((o >> 1u) & 1u), f32((o >> 2u) & 1u)) * side;
            let s = bitcast<f32>(tree[i].z);
            if (s > 0.0) {
                spacing = s * scale;
            }
        }
    }
    let s = clamp(round(spacing * u.focal / w), 1.0, u.max_size);
    // A lone point: at most points.rs's LONE_PIXELS.
    return select(s, min(s, 3.0), alone);
}
