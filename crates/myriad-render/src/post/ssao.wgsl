// Screen-space ambient occlusion: neighbours at two radii in eight directions, as points in eye
// space; those above the pixel's tangent plane occlude it, less with distance. Mirror: ssao.rs.

@compute @workgroup_size(128)
fn ssao(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
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
    let p = eye_position(x, y, d);
    let n = unpack4x8snorm(src_normal[i]).xyz;
    let reach = r.ssao_radius * d / r.focal;
    var occlusion = 0.0;
    for (var k = 0; k < 8; k++) {
        let radius = select(r.ssao_radius * 0.5, r.ssao_radius, k % 2 == 0);
        let o = vec2<i32>(round(AROUND[k] * radius));
        let j = at(x + o.x, y + o.y);
        if (j < 0 || src_depth[j] <= 0.0) {
            continue;
        }
        let t = eye_position(x + o.x, y + o.y, src_depth[j]) - p;
        let dist = sqrt(dot(t, t));
        if (dist <= 0.0) {
            continue;
        }
        let rise = max(dot(n, t) / dist - 0.1, 0.0);
        occlusion += rise * clamp(1.0 - dist / (2.0 * reach), 0.0, 1.0);
    }
    let ao = clamp(1.0 - r.ssao_strength * occlusion / 8.0, 0.0, 1.0);
    put(i, d, scale_colour(src_colour[i], ao), src_normal[i]);
}
