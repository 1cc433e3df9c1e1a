// Resolve: the colour of the nearest point per pixel, or the background.

struct Uniforms {
    view_proj: mat4x4<f32>,
    width: u32,
    height: u32,
    count: u32,
    background: u32,
    point_size: f32,
    spacing: f32,
    focal: f32,
    max_size: f32,
}

@group(0) @binding(0) var<uniform> u: Uniforms;
@group(0) @binding(2) var<storage, read> framebuffer: array<u64>;
@group(0) @binding(3) var<storage, read_write> image: array<u32>;

@compute @workgroup_size(128)
fn resolve(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    // Dispatches are 2D when there are more than 65535 workgroups.
    let i = id.y * groups.x * 128u + id.x;
    if (i >= u.width * u.height) {
        return;
    }
    let v = framebuffer[i];
    if (v == 0lu) {
        image[i] = u.background;
    } else {
        image[i] = u32(v & 0xfffffffflu);
    }
}
