// Compute rasterizer (after Schütz et al. 2021): one thread per point projects it and keeps the
// nearest point per pixel with a 64-bit atomicMax of (reversed depth << 32 | colour).

struct Uniforms {
    view_proj: mat4x4<f32>,
    width: u32,
    height: u32,
    count: u32,
    pad: u32,
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
    let x = min(u32((ndc.x * 0.5 + 0.5) * f32(u.width)), u.width - 1u);
    let y = min(u32((0.5 - ndc.y * 0.5) * f32(u.height)), u.height - 1u);
    // Nearer is larger, so that atomicMax keeps the nearest; 0 stays "empty".
    let depth = u32((1.0 - ndc.z) * 4294967040.0) + 1u;
    let value = (u64(depth) << 32u) | u64(bitcast<u32>(p.w));
    atomicMax(&framebuffer[y * u.width + x], value);
}
