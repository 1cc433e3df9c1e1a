// Deferred shading: ambient, a headlight along the view direction and a sun. Mirror: shade.rs.

@compute @workgroup_size(128)
fn shade(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = thread_pixel(id, groups);
    if (i >= r.width * r.height) {
        return;
    }
    if (hidden(i)) {
        keep(i);
        return;
    }
    if (src_depth[i] <= 0.0) {
        keep(i);
        return;
    }
    let n = unpack4x8snorm(src_normal[i]).xyz;
    let light = r.ambient + r.headlight * max(-n.z, 0.0) + r.sun * max(dot(n, r.sun_eye.xyz), 0.0);
    put(i, src_depth[i], scale_colour(src_colour[i], light), src_normal[i]);
}
