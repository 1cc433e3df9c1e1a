// The image: each pixel the mean of its factor x factor block of the g-buffer, the background
// where nothing was drawn. Mirror: mod.rs.

@group(0) @binding(3) var<storage, read_write> image: array<u32>;

@compute @workgroup_size(128)
fn finish(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = thread_pixel(id, groups);
    if (i >= r.out_width * r.out_height) {
        return;
    }
    let x = i % r.out_width;
    let y = i / r.out_width;
    var sum = vec4<f32>(0.0);
    for (var sy = 0u; sy < r.factor; sy++) {
        for (var sx = 0u; sx < r.factor; sx++) {
            let j = (y * r.factor + sy) * r.width + x * r.factor + sx;
            var c = r.background;
            if (src_depth[j] > 0.0) {
                c = src_colour[j];
            }
            sum += unpack4x8unorm(c);
        }
    }
    image[i] = pack4x8unorm(sum / f32(r.factor * r.factor));
}

// The same into a texture (a window's, on the same device): no readback.
@group(0) @binding(5) var out_texture: texture_storage_2d<rgba8unorm, write>;

@compute @workgroup_size(128)
fn finish_texture(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = thread_pixel(id, groups);
    if (i >= r.out_width * r.out_height) {
        return;
    }
    let x = i % r.out_width;
    let y = i / r.out_width;
    var sum = vec4<f32>(0.0);
    for (var sy = 0u; sy < r.factor; sy++) {
        for (var sx = 0u; sx < r.factor; sx++) {
            let j = (y * r.factor + sy) * r.width + x * r.factor + sx;
            var c = r.background;
            if (src_depth[j] > 0.0) {
                c = src_colour[j];
            }
            sum += unpack4x8unorm(c);
        }
    }
    textureStore(out_texture, vec2<u32>(x, y), sum / f32(r.factor * r.factor));
}
