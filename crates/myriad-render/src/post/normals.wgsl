// Normals in image space (Kanzok et al. 2015) where the points gave none: the cross product of the
// tangents to the neighbour nearer in depth on each axis, facing the eye. Mirror: normals.rs.

// The tangent along (dx, dy) at the pixel (x, y, p, d); w = 0 when there is no neighbour.
fn tangent(x: i32, y: i32, p: vec3<f32>, d: f32, dx: i32, dy: i32) -> vec4<f32> {
    var best = vec4<f32>(0.0);
    var best_diff = 0.0;
    for (var k = 0; k < 2; k++) {
        let s = select(-1, 1, k == 0);
        let j = at(x + s * dx, y + s * dy);
        if (j < 0) {
            continue;
        }
        let n = src_depth[j];
        if (n <= 0.0) {
            continue;
        }
        let diff = abs(n - d);
        if (best.w == 0.0 || diff < best_diff) {
            let q = eye_position(x + s * dx, y + s * dy, n);
            best = vec4<f32>(select(p - q, q - p, s == 1), 1.0);
            best_diff = diff;
        }
    }
    return best;
}

@compute @workgroup_size(128)
fn normals(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = thread_pixel(id, groups);
    if (i >= r.width * r.height) {
        return;
    }
    if (hidden(i)) {
        keep(i);
        return;
    }
    let d = src_depth[i];
    if (d <= 0.0 || src_normal[i] != 0u) {
        keep(i);
        return;
    }
    let x = pixel_x(i);
    let y = i32(i / r.width);
    let p = eye_position(x, y, d);
    let a = tangent(x, y, p, d, 1, 0);
    let b = tangent(x, y, p, d, 0, 1);
    var n = vec3<f32>(0.0, 0.0, -1.0);
    if (a.w > 0.0 && b.w > 0.0) {
        let c = vec3<f32>(
            a.y * b.z - a.z * b.y,
            a.z * b.x - a.x * b.z,
            a.x * b.y - a.y * b.x,
        );
        let len = sqrt(dot(c, c));
        if (len > 0.0) {
            n = c * (select(1.0, -1.0, dot(c, p) > 0.0) / len);
        }
    }
    put(i, d, src_colour[i], pack4x8snorm(vec4<f32>(n, 1.0)));
}
