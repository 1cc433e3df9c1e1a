// The g-buffer from the point pass's framebuffer (`depth_at`, `colour_at`, `normal_at`, defined
// by the path that drew it and appended to this source): linear eye depth (0: empty), colour,
// and the points' normal where they gave one (0: none); hidden pixels (a headset lens's) empty,
// whatever the quad path drew there. Mirror: cpu.rs (whose point pass skips them).

@compute @workgroup_size(128)
fn gbuffer(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = thread_pixel(id, groups);
    if (i >= r.width * r.height) {
        return;
    }
    let xy = vec2<i32>(i32(i % r.width), i32(i / r.width));
    let d = depth_at(i, xy);
    if (d <= 0.0 || hidden(i)) {
        put(i, 0.0, 0u, 0u);
        return;
    }
    put(i, d, colour_at(i, xy), normal_at(i, xy));
}
