// Hole filling (Discher et al. 2018 after Dobrev), one 1-D pass: a pixel with nearer neighbours on
// both sides within the radius, at least `fill_min` of them, takes the nearest one. Mirror:
// fill.rs.

fn fill(i: u32, axis: u32) {
    if (hidden(i)) {
        keep(i);
        return;
    }
    let x = pixel_x(i);
    let y = i32(i / r.width);
    let d = src_depth[i];
    var best = -1;
    var count = 0u;
    var sides = 0u;
    for (var k = 1; k <= i32(r.fill_radius); k++) {
        for (var s = 0; s < 2; s++) {
            let side = select(1, -1, s == 0);
            var j = at(x + side * k, y);
            if (axis == 1u) {
                j = at(x, y + side * k);
            }
            if (j < 0) {
                continue;
            }
            let n = src_depth[j];
            if (n > 0.0 && (d == 0.0 || n < d * r.fill_threshold)) {
                count++;
                sides |= select(2u, 1u, s == 0);
                if (best < 0 || n < src_depth[best]) {
                    best = j;
                }
            }
        }
    }
    if (sides == 3u && count >= r.fill_min) {
        put(i, src_depth[best], src_colour[best], src_normal[best]);
    } else {
        keep(i);
    }
}

@compute @workgroup_size(128)
fn fill_rows(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = thread_pixel(id, groups);
    if (i < r.width * r.height) {
        fill(i, 0u);
    }
}

@compute @workgroup_size(128)
fn fill_columns(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = thread_pixel(id, groups);
    if (i < r.width * r.height) {
        fill(i, 1u);
    }
}
