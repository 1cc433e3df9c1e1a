// Reconstruct (Schiffner et al. 2015, section 3.3) on the GPU, after cluster.wgsl (its parameters,
// grid and reduced cells), mirrored by reconstruct.rs: per reduced cell its element's triangles, as
// the CPU's Mesh::polygon fans them, straight into a vertex buffer (position relative to the eye in
// world axes, normal in world axes, colour), which draw.wgsl draws: the cells never leave the
// GPU to be drawn.

// Seven words a vertex: position (3), normal (3), colour.
@group(0) @binding(7) var<storage, read_write> vertices: array<u32>;

fn world(e: vec3<f32>) -> vec3<f32> {
    return e.x * P.right.xyz + e.y * P.up.xyz + e.z * P.forward.xyz;
}

fn put(v: u32, e: vec3<f32>, n: vec3<f32>, colour: u32) {
    let p = world(e);
    let w = world(n);
    let o = v * 7u;
    vertices[o] = bitcast<u32>(p.x);
    vertices[o + 1u] = bitcast<u32>(p.y);
    vertices[o + 2u] = bitcast<u32>(p.z);
    vertices[o + 3u] = bitcast<u32>(w.x);
    vertices[o + 4u] = bitcast<u32>(w.y);
    vertices[o + 5u] = bitcast<u32>(w.z);
    vertices[o + 6u] = colour;
}

// A convex quad (corners in order) as the fan (0, 1, 2), (0, 2, 3) from vertex `v`.
fn quad(v: u32, a: vec3<f32>, b: vec3<f32>, c: vec3<f32>, d: vec3<f32>, n: vec3<f32>, colour: u32) {
    put(v, a, n, colour);
    put(v + 1u, b, n, colour);
    put(v + 2u, c, n, colour);
    put(v + 3u, a, n, colour);
    put(v + 4u, c, n, colour);
    put(v + 5u, d, n, colour);
}

fn word_f(o: u32) -> f32 {
    return bitcast<f32>(cells[o]);
}

// Vertices per cell: quads 6, boxes 36, splats 18.
fn per_cell() -> u32 {
    return select(select(18u, 36u, P.flags.y == 1u), 6u, P.flags.y == 0u);
}

@compute @workgroup_size(128)
fn reconstruct(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let s = thread(id, groups);
    if (s >= P.flags.x) {
        return;
    }
    let o = s * CELL_WORDS;
    let key = cells[o];
    let mean = vec3<f32>(word_f(o + 2u), word_f(o + 3u), word_f(o + 4u));
    let plo = vec3<f32>(word_f(o + 5u), word_f(o + 6u), word_f(o + 7u));
    let phi = vec3<f32>(word_f(o + 8u), word_f(o + 9u), word_f(o + 10u));
    var n = normalize(-mean);
    if (cells[o + 14u] == 1u) {
        n = vec3<f32>(word_f(o + 11u), word_f(o + 12u), word_f(o + 13u));
    }
    let colour = cells[o + 15u];
    let v = s * per_cell();
    if (P.flags.y == 1u) {
        // Boxes: the points' box, faces as reconstruct.rs orders their corners.
        for (var a = 0u; a < 3u; a++) {
            let b = (a + 1u) % 3u;
            let d = (a + 2u) % 3u;
            for (var side = 0u; side < 2u; side++) {
                var p0 = vec3<f32>(0.0);
                var p1 = vec3<f32>(0.0);
                var p2 = vec3<f32>(0.0);
                var p3 = vec3<f32>(0.0);
                let value = select(plo[a], phi[a], side == 1u);
                p0[a] = value; p1[a] = value; p2[a] = value; p3[a] = value;
                p0[b] = plo[b]; p0[d] = plo[d];
                p1[b] = phi[b]; p1[d] = plo[d];
                p2[b] = phi[b]; p2[d] = phi[d];
                p3[b] = plo[b]; p3[d] = phi[d];
                var fnorm = vec3<f32>(0.0);
                fnorm[a] = select(-1.0, 1.0, side == 1u);
                let at = v + (a * 2u + side) * 6u;
                if (side == 0u) {
                    quad(at, p3, p2, p1, p0, fnorm, colour);
                } else {
                    quad(at, p0, p1, p2, p3, fnorm, colour);
                }
            }
        }
        return;
    }
    let e = extent(mean.z);
    if (P.flags.y == 2u) {
        // Splats: an octagon of half the cell's diagonal across the view, on the normal's plane.
        var any = vec3<f32>(0.0, 1.0, 0.0);
        if (abs(n.x) < 0.9) {
            any = vec3<f32>(1.0, 0.0, 0.0);
        }
        let t1 = normalize(cross(n, any));
        let t2 = cross(n, t1);
        let r = 0.5 * sqrt(e.x * e.x + e.y * e.y);
        var ring: array<vec3<f32>, 8>;
        for (var k = 0u; k < 8u; k++) {
            let angle = f32(k) * 0.7853981633974483;
            ring[k] = mean + r * (cos(angle) * t1 + sin(angle) * t2);
        }
        for (var k = 1u; k < 7u; k++) {
            let at = v + (k - 1u) * 3u;
            put(at, ring[0], n, colour);
            put(at + 1u, ring[k], n, colour);
            put(at + 2u, ring[k + 1u], n, colour);
        }
        return;
    }
    // Cell-filling quads: the grid cell's box at the mean's depth grown to the points' box; the
    // normal's plane over its two axes most across the normal.
    let c = centre(cell_index(key));
    let x = c.x * mean.z / c.z;
    let y = c.y * mean.z / c.z;
    let half = exp(P.more.w * 0.5 / f32(P.dims.z));
    let lo = min(vec3<f32>(x - e.x * 0.5, y - e.y * 0.5, c.z / half), plo);
    let hi = max(vec3<f32>(x + e.x * 0.5, y + e.y * 0.5, c.z * half), phi);
    var k = 0u;
    if (abs(n.y) > abs(n[k])) {
        k = 1u;
    }
    if (abs(n.z) > abs(n[k])) {
        k = 2u;
    }
    let a = (k + 1u) % 3u;
    let b = (k + 2u) % 3u;
    var corners: array<vec3<f32>, 4>;
    var us = array<f32, 4>(lo[a], hi[a], hi[a], lo[a]);
    var vs = array<f32, 4>(lo[b], lo[b], hi[b], hi[b]);
    for (var i = 0u; i < 4u; i++) {
        var p = vec3<f32>(0.0);
        p[a] = us[i];
        p[b] = vs[i];
        p[k] = clamp(mean[k] - (n[a] * (us[i] - mean[a]) + n[b] * (vs[i] - mean[b])) / n[k], lo[k], hi[k]);
        corners[i] = p;
    }
    quad(v, corners[0], corners[1], corners[2], corners[3], n, colour);
}
