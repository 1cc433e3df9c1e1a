// The compute path's framebuffer: (reversed linear depth << 32 | colour) per pixel, 0 when empty,
// and the splats' normals (0: none).
@group(0) @binding(2) var<storage, read> framebuffer: array<u64>;
@group(0) @binding(4) var<storage, read> normal_fb: array<u32>;

fn depth_at(i: u32, xy: vec2<i32>) -> f32 {
    let key = u32(framebuffer[i] >> 32u);
    if (key == 0u) {
        return 0.0;
    }
    return (1.0 - f32(key - 1u) / 4294967040.0) * r.far;
}

fn colour_at(i: u32, xy: vec2<i32>) -> u32 {
    return u32(framebuffer[i] & 0xfffffffflu);
}

fn normal_at(i: u32, xy: vec2<i32>) -> u32 {
    return normal_fb[i];
}
