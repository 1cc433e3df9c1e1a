// The compute path's framebuffer: (reversed linear depth << 32 | colour) per pixel, 0 when empty,
// and the splats' normals (0: none).
@group(0) @binding(2) var<storage, read> framebuffer: array<u64>;
@group(0) @binding(4) var<storage, read> normal_fb: array<u32>;
// Blending (compute.wgsl's mode 2): per pixel the weighted sums of red, green, blue and the
// weights; four words of zeros when the frame does not blend.
@group(0) @binding(5) var<storage, read> blend_fb: array<u32>;

fn depth_at(i: u32, xy: vec2<i32>) -> f32 {
    let key = u32(framebuffer[i] >> 32u);
    if (key == 0u) {
        return 0.0;
    }
    return (1.0 - f32(key - 1u) / 4294967040.0) * r.far;
}

fn colour_at(i: u32, xy: vec2<i32>) -> u32 {
    let k = i * 4u;
    if (k + 3u < arrayLength(&blend_fb) && blend_fb[k + 3u] > 0u) {
        // The weighted mean, rounded (as blend::resolve).
        let w = blend_fb[k + 3u];
        let c = (vec3<u32>(blend_fb[k], blend_fb[k + 1u], blend_fb[k + 2u]) + vec3<u32>(w / 2u)) / w;
        return c.x | (c.y << 8u) | (c.z << 16u) | (255u << 24u);
    }
    return u32(framebuffer[i] & 0xfffffffflu);
}

fn normal_at(i: u32, xy: vec2<i32>) -> u32 {
    return normal_fb[i];
}
