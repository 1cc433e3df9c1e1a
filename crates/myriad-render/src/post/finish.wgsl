// The image: each pixel the mean of its factor x factor block of the g-buffer, the background
// where nothing was drawn, black where hidden (a headset lens's area). Mirror: finish.rs.

@group(0) @binding(3) var<storage, read_write> image: array<u32>;
// Or a texture (a window's, on the same device): no readback.
@group(0) @binding(5) var out_texture: texture_storage_2d<rgba8unorm, write>;

// The mean colour of image pixel (x, y)'s block; opaque black where the block is hidden.
fn block(x: u32, y: u32) -> vec4<f32> {
    if (hidden(y * r.factor * r.width + x * r.factor)) {
        return vec4<f32>(0.0, 0.0, 0.0, 1.0);
    }
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
    return sum / f32(r.factor * r.factor);
}

@compute @workgroup_size(128)
fn finish(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = thread_pixel(id, groups);
    if (i < r.out_width * r.out_height) {
        image[i] = pack4x8unorm(block(i % r.out_width, i / r.out_width));
    }
}

@compute @workgroup_size(128)
fn finish_texture(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = thread_pixel(id, groups);
    if (i < r.out_width * r.out_height) {
        let xy = vec2<u32>(i % r.out_width, i / r.out_width);
        textureStore(out_texture, xy, block(xy.x, xy.y));
    }
}
