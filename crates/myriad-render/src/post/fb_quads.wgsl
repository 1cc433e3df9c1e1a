// The quad path's render targets: colour, the splats' normals (n * 0.5 + 0.5, alpha 1 where
// there is one), and the depth buffer (0 at the near plane, 1 at the far plane and where nothing
// was drawn).
@group(0) @binding(1) var colour_target: texture_2d<f32>;
@group(0) @binding(2) var depth_target: texture_depth_2d;
@group(0) @binding(4) var normal_target: texture_2d<f32>;
// Blending (quads.wgsl's `blend`): colour times weight and the weights added up; a texel of zeros
// when the frame does not blend.
@group(0) @binding(5) var blend_target: texture_2d<f32>;

fn depth_at(i: u32, xy: vec2<i32>) -> f32 {
    let z = textureLoad(depth_target, xy, 0);
    if (z >= 1.0) {
        return 0.0;
    }
    // The projection maps eye depth w to z = a (1 - near / w), a = far / (far - near).
    let a = r.far / (r.far - r.near);
    return r.near / (1.0 - z / a);
}

fn colour_at(i: u32, xy: vec2<i32>) -> u32 {
    if (all(vec2<u32>(xy) < textureDimensions(blend_target))) {
        let b = textureLoad(blend_target, xy, 0);
        if (b.a > 0.0) {
            return pack4x8unorm(vec4<f32>(b.rgb / b.a, 1.0));
        }
    }
    return pack4x8unorm(textureLoad(colour_target, xy, 0));
}

fn normal_at(i: u32, xy: vec2<i32>) -> u32 {
    let n = textureLoad(normal_target, xy, 0);
    if (n.a < 0.5) {
        return 0u;
    }
    return pack4x8snorm(vec4<f32>(n.rgb * 2.0 - 1.0, 1.0));
}
