// A 3x3 binomial blur over the pixels of the same surface (depth within a relative threshold),
// against aliasing and z-fighting (Discher et al. 2018). Mirror: blur.rs.

@compute @workgroup_size(128)
fn blur(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = thread_pixel(id, groups);
    if (i >= r.width * r.height) {
        return;
    }
    if (hidden(i)) {
        keep(i);
        return;
    }
    let d = src_depth[i];
    if (d <= 0.0) {
        keep(i);
        return;
    }
    let x = pixel_x(i);
    let y = i32(i / r.width);
    var sum = vec3<f32>(0.0);
    var weight = 0.0;
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let j = at(x + dx, y + dy);
            if (j < 0) {
                continue;
            }
            let n = src_depth[j];
            if (n <= 0.0 || abs(n - d) > r.blur_threshold * d) {
                continue;
            }
            let w = f32((2 - abs(dx)) * (2 - abs(dy)));
            sum += unpack4x8unorm(src_colour[j]).rgb * w;
            weight += w;
        }
    }
    let a = unpack4x8unorm(src_colour[i]).a;
    put(i, d, pack4x8unorm(vec4<f32>(sum / weight, a)), src_normal[i]);
}
