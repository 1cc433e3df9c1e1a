// Resolve: the colour of the nearest point per pixel, or the background; with eye-dome lighting
// (Boucheny 2009) when asked: a pixel is darkened by how far it lies behind its neighbours at
// `radius` pixels, in log depth, so edges and relief show without normals. The framebuffer it
// reads (`depth_at`, `colour_at`) is defined by the path that drew it, appended to this source.

struct Resolve {
    width: u32,
    height: u32,
    background: u32,
    edl: u32,
    strength: f32,
    radius: f32,
    far: f32,
    near: f32,
}

@group(0) @binding(0) var<uniform> r: Resolve;
@group(0) @binding(3) var<storage, read_write> image: array<u32>;

// Eight neighbours around the circle, unit length.
const AROUND = array<vec2<f32>, 8>(
    vec2<f32>(1.0, 0.0), vec2<f32>(0.70710677, 0.70710677),
    vec2<f32>(0.0, 1.0), vec2<f32>(-0.70710677, 0.70710677),
    vec2<f32>(-1.0, 0.0), vec2<f32>(-0.70710677, -0.70710677),
    vec2<f32>(0.0, -1.0), vec2<f32>(0.70710677, -0.70710677),
);

// Linear eye depth of the point drawn at (x, y); 0 where nothing is (or outside the image).
fn depth_or_empty(x: i32, y: i32) -> f32 {
    if (x < 0 || y < 0 || x >= i32(r.width) || y >= i32(r.height)) {
        return 0.0;
    }
    return depth_at(u32(y) * r.width + u32(x), vec2<i32>(x, y));
}

@compute @workgroup_size(128)
fn resolve(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    // Dispatches are 2D when there are more than 65535 workgroups.
    let i = id.y * groups.x * 128u + id.x;
    if (i >= r.width * r.height) {
        return;
    }
    let xy = vec2<i32>(i32(i % r.width), i32(i / r.width));
    let d = depth_at(i, xy);
    if (d <= 0.0) {
        image[i] = r.background;
        return;
    }
    let colour = colour_at(i, xy);
    if (r.edl == 0u) {
        image[i] = colour;
        return;
    }
    let l = log2(d);
    var sum = 0.0;
    for (var k = 0; k < 8; k++) {
        let o = vec2<i32>(round(AROUND[k] * r.radius));
        let n = depth_or_empty(xy.x + o.x, xy.y + o.y);
        if (n > 0.0) {
            sum += max(0.0, l - log2(n));
        }
    }
    let shade = exp(-sum / 8.0 * 300.0 * r.strength);
    let c = unpack4x8unorm(colour);
    image[i] = pack4x8unorm(vec4<f32>(c.rgb * shade, c.a));
}
