// The fixed-function path for adapters without 64-bit atomics: each point an instanced quad of
// the same pixels the compute rasterizer covers, the depth test keeping the nearest.

struct Corner {
    @builtin(position) position: vec4<f32>,
    @location(0) colour: vec4<f32>,
    // Pixels from the square's centre.
    @location(1) local: vec2<f32>,
    // Eye depth, and the paraboloid's bulge in the same units.
    @location(2) @interpolate(flat) depth: vec2<f32>,
    @location(3) @interpolate(flat) radius2: f32,
    // A splat's radius in pixels and its eye normal (splat_shape); x < 0: not a splat.
    @location(4) @interpolate(flat) splat: vec4<f32>,
    // Blending: the point's centre (pixels of the frame) and the depth beyond the nearest within
    // which its fragments count (z); its footprint (blend.wgsl).
    @location(5) @interpolate(flat) blend: vec4<f32>,
    @location(6) @interpolate(flat) footprint: vec4<f32>,
}

// A headset's hidden area (Discher et al. 2018, section 4.1), one bit a g-buffer pixel (a few words
// of zeros: none): set where every pixel within REJECT_REACH of it is hidden. A point whose centre
// falls there covers hidden pixels alone and is dropped before it is rasterized; the g-buffer pass
// empties the hidden pixels the others reach.
@group(0) @binding(7) var<storage, read> reject_bits: array<u32>;
// chain.rs's REJECT_REACH.
const REJECT_REACH: f32 = 8.0;

const CORNERS = array<vec2<f32>, 6>(
    vec2<f32>(0.0, 0.0), vec2<f32>(1.0, 0.0), vec2<f32>(0.0, 1.0),
    vec2<f32>(0.0, 1.0), vec2<f32>(1.0, 0.0), vec2<f32>(1.0, 1.0),
);

@vertex
fn vertex(
    @builtin(vertex_index) v: u32,
    @builtin(instance_index) drawn: u32,
) -> Corner {
    // Single-pass stereo (`u.stereo.x`: each eye's width in a frame twice as wide): instances
    // from `u.count` on draw the points again for the right eye.
    var eye = 0u;
    var instance = drawn;
    var view_proj = u.view_proj;
    var width = u.width;
    if (u.stereo.x > 0u) {
        eye = drawn / u.count;
        instance = drawn % u.count;
        width = u.stereo.x;
        if (eye == 1u) {
            view_proj = u.view_proj_right;
        }
    }
    let l = u.place;
    let p = decode(instance, l.x, l.y, l.z, l.w, u.offset.xyz, u.unit.xyz);
    var out: Corner;
    // Culled: outside every clip volume.
    out.position = vec4<f32>(2.0, 2.0, 2.0, 1.0);
    out.colour = unpack4x8unorm(colour_word(instance, l.x, l.y, l.z));
    out.local = vec2<f32>(0.0);
    out.depth = vec2<f32>(0.0);
    out.radius2 = 0.0;
    out.splat = vec4<f32>(-1.0, 0.0, 0.0, 1.0);
    out.blend = vec4<f32>(0.0);
    out.footprint = vec4<f32>(0.0, 0.0, 0.0, 1.0);
    if (clipped(p)) {
        return out;
    }
    let clip = view_proj * vec4<f32>(p, 1.0);
    if (clip.w <= 0.0) {
        return out;
    }
    let ndc = clip.xyz / clip.w;
    if (ndc.x < -1.0 || ndc.x >= 1.0 || ndc.y <= -1.0 || ndc.y > 1.0 || ndc.z < 0.0 || ndc.z > 1.0) {
        return out;
    }
    let fx = (ndc.x * 0.5 + 0.5) * f32(width);
    let fy = (0.5 - ndc.y * 0.5) * f32(u.height);
    var s = point_pixels(p, clip.w, u.spacing, u.node, u.cube, lone(instance, l.x, l.z) && u.radius.w > 0.0);
    out.footprint = blend_point(s);
    if (u.radius.z > 0.0 && u.point_size == 0.0) {
        out.splat = splat_shape(splat_codes[instance], u.radius.xy, clip.w);
        s = f32(splat_pixels(out.splat.x));
        out.footprint = blend_splat(out.splat);
    }
    if (s * 0.5 + 1.0 <= REJECT_REACH) {
        let i = u32(fy) * u.width + u32(fx) + eye * width;
        if ((i >> 5u) < arrayLength(&reject_bits) && (reject_bits[i >> 5u] & (1u << (i & 31u))) != 0u) {
            return out;
        }
    }
    let x0 = floor(fx) - floor((s - 1.0) * 0.5);
    let y0 = floor(fy) - floor((s - 1.0) * 0.5);
    let corner = CORNERS[v % 6u];
    // In the eye's own columns: a square across the eye's side is cut there (the depth test's
    // early rejection kept, no discard), so nothing reaches the other eye's image.
    let shift = f32(eye * width);
    var px = vec2<f32>(x0, y0) + corner * s;
    px.x = clamp(px.x, 0.0, f32(width)) + shift;
    let x = px.x / f32(u.width) * 2.0 - 1.0;
    let y = 1.0 - px.y / f32(u.height) * 2.0;
    out.position = vec4<f32>(x, y, ndc.z, 1.0);
    out.local = px - shift - vec2<f32>(x0, y0) - vec2<f32>(0.5) * s;
    out.depth = vec2<f32>(clip.w, 0.5 * s * clip.w / u.focal);
    out.radius2 = max(s * s * 0.25, 0.5);
    out.blend = vec4<f32>(fx + shift, fy, s * clip.w / u.focal, 0.0);
    return out;
}

struct Fragment {
    @location(0) colour: vec4<f32>,
    // A splat's eye normal facing the eye, as n * 0.5 + 0.5, alpha 1; all 0 for other points.
    @location(1) normal: vec4<f32>,
    @builtin(frag_depth) depth: f32,
}

// The eye depth of a fragment: the splat's plane or the paraboloid where they are; -1 outside
// the point's shape.
fn fragment_depth(in: Corner) -> f32 {
    var w = in.depth.x;
    if (in.splat.x >= 0.0) {
        let e = (in.local.x * in.splat.y - in.local.y * in.splat.z) / in.splat.w;
        if (dot(in.local, in.local) + e * e > in.splat.x * in.splat.x) {
            return -1.0;
        }
        w = w - w / u.focal * e;
    } else if (u.shape != 0u) {
        let d2 = dot(in.local, in.local);
        if (d2 > in.radius2) {
            return -1.0;
        }
        if (u.shape == 2u) {
            w = w - in.depth.y * (1.0 - d2 / in.radius2);
        }
    }
    return w;
}

@fragment
fn fragment(in: Corner) -> Fragment {
    var out: Fragment;
    out.colour = in.colour;
    out.normal = vec4<f32>(0.0);
    let w = fragment_depth(in);
    if (w < 0.0) {
        discard;
    }
    if (in.splat.x >= 0.0) {
        let n = in.splat.yzw / sqrt(dot(in.splat.yzw, in.splat.yzw));
        out.normal = vec4<f32>(select(n, -n, n.z > 0.0) * 0.5 + 0.5, 1.0);
    }
    // The same depth the projection gives: a (1 - near / w).
    let a = u.far / (u.far - u.near);
    out.depth = clamp(a * (1.0 - u.near / max(w, u.near)), 0.0, 1.0);
    return out;
}

// Blending's second pass (as compute.wgsl's mode 2): the depth the first left, and each fragment
// near enough behind it added to the blend target, colour times weight and the weight (in
// 255ths, the compute path's integers).
@group(0) @binding(9) var near_depth: texture_depth_2d;

@fragment
fn blend(in: Corner) -> @location(0) vec4<f32> {
    let w = fragment_depth(in);
    if (w < 0.0) {
        discard;
    }
    let z = textureLoad(near_depth, vec2<i32>(in.position.xy), 0);
    if (z >= 1.0) {
        discard;
    }
    let a = u.far / (u.far - u.near);
    if (w > u.near / (1.0 - z / a) + in.blend.z) {
        discard;
    }
    let k = f32(blend_weight(in.position.xy - in.blend.xy, in.footprint)) / 255.0;
    return vec4<f32>(round(in.colour.rgb * 255.0) / 255.0 * k, k);
}
