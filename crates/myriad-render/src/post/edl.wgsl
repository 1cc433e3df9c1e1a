// Eye-dome lighting (Boucheny 2009): a pixel darkened by how far it lies behind its neighbours
// at `edl_radius` pixels, in log depth, so edges and relief show without normals. Mirror: edl.rs.

@compute @workgroup_size(128)
fn edl(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
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
    let l = log2(d);
    var sum = 0.0;
    for (var k = 0; k < 8; k++) {
        let o = vec2<i32>(round(AROUND[k] * r.edl_radius));
        let j = at(x + o.x, y + o.y);
        if (j >= 0 && src_depth[j] > 0.0) {
            sum += max(0.0, l - log2(src_depth[j]));
        }
    }
    let shade = exp(-sum / 8.0 * 300.0 * r.edl_strength);
    put(i, d, scale_colour(src_colour[i], shade), src_normal[i]);
}
