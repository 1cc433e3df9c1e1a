// Compute rasterizer (after Schütz et al. 2021): one thread per point projects it and keeps the
// nearest point per pixel with a 64-bit atomicMax of (reversed linear depth << 32 | colour).

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
    pad1: f32,
    pad2: f32,
}

@group(0) @binding(0) var<uniform> u: Draw;
// xyz relative to the upload origin; w: the colour, RGBA8 as bits.
@group(0) @binding(1) var<storage, read> points: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> framebuffer: array<atomic<u64>>;

// Nearer is larger, so that atomicMax keeps the nearest; 0 stays "empty".
fn depth_key(w: f32) -> u32 {
    return u32(clamp(1.0 - w / u.far, 0.0, 1.0) * 4294967040.0) + 1u;
}

@compute @workgroup_size(128)
fn rasterize(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    // Dispatches are 2D when there are more than 65535 workgroups.
    let i = id.y * groups.x * 128u + id.x;
    if (i >= u.count) {
        return;
    }
    let p = points[i];
    let clip = u.view_proj * vec4<f32>(p.xyz, 1.0);
    if (clip.w <= 0.0) {
        return;
    }
    let ndc = clip.xyz / clip.w;
    if (ndc.x < -1.0 || ndc.x >= 1.0 || ndc.y <= -1.0 || ndc.y > 1.0 || ndc.z < 0.0 || ndc.z > 1.0) {
        return;
    }
    let fx = (ndc.x * 0.5 + 0.5) * f32(u.width);
    let fy = (0.5 - ndc.y * 0.5) * f32(u.height);
    let colour = u64(bitcast<u32>(p.w));
    var size = u.point_size;
    if (size <= 0.0) {
        size = u.spacing * u.focal / clip.w;
    }
    let s = i32(clamp(round(size), 1.0, u.max_size));
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
        let y = y0 + dy;
        if (y < 0 || y >= i32(u.height)) {
            continue;
        }
        for (var dx = 0; dx < s; dx++) {
            let x = x0 + dx;
            if (x < 0 || x >= i32(u.width)) {
                continue;
            }
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
            atomicMax(&framebuffer[u32(y) * u.width + u32(x)], value);
        }
    }
}
