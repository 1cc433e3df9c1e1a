// Compute rasterizer (after Schütz et al. 2021): one thread per point projects it and keeps the
// nearest point per pixel with a 64-bit atomicMax of (reversed depth << 32 | colour).

struct Uniforms {
    view_proj: mat4x4<f32>,
    width: u32,
    height: u32,
    count: u32,
    pad: u32,
    // Fixed point size in pixels; 0: adaptive, the world `spacing` projected at each point.
    point_size: f32,
    spacing: f32,
    // Pixels per unit of length at depth 1.
    focal: f32,
    max_size: f32,
}

@group(0) @binding(0) var<uniform> u: Uniforms;
// xyz relative to the upload origin; w: the colour, RGBA8 as bits.
@group(0) @binding(1) var<storage, read> points: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> framebuffer: array<atomic<u64>>;

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
    // Nearer is larger, so that atomicMax keeps the nearest; 0 stays "empty".
    let depth = u32((1.0 - ndc.z) * 4294967040.0) + 1u;
    let value = (u64(depth) << 32u) | u64(bitcast<u32>(p.w));
    var size = u.point_size;
    if (size <= 0.0) {
        size = u.spacing * u.focal / clip.w;
    }
    let s = i32(clamp(round(size), 1.0, u.max_size));
    // A square of s x s pixels centred on the point.
    let x0 = i32(floor(fx)) - (s - 1) / 2;
    let y0 = i32(floor(fy)) - (s - 1) / 2;
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
            atomicMax(&framebuffer[u32(y) * u.width + u32(x)], value);
        }
    }
}
