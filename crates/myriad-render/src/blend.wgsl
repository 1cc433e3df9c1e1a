// Blending (blend.rs, its CPU mirror): a fragment's weight in its point's blend, by its offset
// `d` (pixels) from the point's projected centre and the point's footprint `shape`: the
// reconstruction kernel's variance in pixels² and, for an oriented splat, its eye normal as
// (right, -up, forward) (points: 0, 0, 1). The splat's Gaussian, projected to the screen (an
// ellipse), convolved with a low-pass filter of BLEND_PREFILTER pixels² (EWA: Schiffner et al. 2015
// after Zwicker et al.); 1 to 255.
const BLEND_PREFILTER: f32 = 0.5;

fn blend_weight(d: vec2<f32>, shape: vec4<f32>) -> u32 {
    let v = shape.yz;
    let vv = dot(v, v);
    let alpha = shape.x + BLEND_PREFILTER;
    let beta = shape.x / (shape.w * shape.w + vv);
    let vd = dot(v, d);
    let q = (dot(d, d) + beta * vd * vd / (alpha - beta * vv)) / alpha;
    return max(1u, u32(exp(-0.5 * q) * 255.0 + 0.5));
}

// The footprint of a point drawn `s` pixels wide: a Gaussian of half its radius.
fn blend_point(s: f32) -> vec4<f32> {
    return vec4<f32>(s * s / 16.0, 0.0, 0.0, 1.0);
}

// The footprint of a splat (`splat_shape`'s): a Gaussian of half its radius on its plane.
fn blend_splat(sp: vec4<f32>) -> vec4<f32> {
    return vec4<f32>(sp.x * sp.x * 0.25, sp.y, -sp.z, sp.w);
}
