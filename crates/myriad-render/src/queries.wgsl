// Occlusion queries (Scheiblauer 2006): node boxes drawn against a frame's depth inside occlusion
// queries, no colour, no depth written. The frame's depth is first written into a depth texture as
// near / w (1 at the near plane, 0 where nothing was drawn: reversed, so that f32 keeps its
// precision far away), from the compute path's framebuffer or the quad path's depth buffer; a
// box's fragment passes where it is as near or nearer. The CPU path's mirror is queries.rs.

struct Boxes {
    view_proj: mat4x4<f32>,
    far: f32,
    near: f32,
    width: u32,
    pad: u32,
}

@group(0) @binding(0) var<uniform> q: Boxes;
// Eight corners a box (as myriad_core::Aabb::corners: bit i of the index picks the far side of
// axis i), relative to the frame's origin.
@group(0) @binding(1) var<storage, read> corners: array<vec4<f32>>;
// The compute path's framebuffer as (colour, reversed depth key) pairs (fb_atomic.wgsl).
@group(0) @binding(2) var<storage, read> framebuffer: array<vec2<u32>>;
// The quad path's depth buffer, a (1 - near / w) (quads.wgsl).
@group(0) @binding(3) var quad_depth: texture_depth_2d;

// The twelve triangles of a box, by corner.
const FACES = array<u32, 36>(
    0u, 2u, 1u, 1u, 2u, 3u, 4u, 5u, 6u, 5u, 7u, 6u,
    0u, 1u, 4u, 1u, 5u, 4u, 2u, 6u, 3u, 3u, 6u, 7u,
    0u, 4u, 2u, 2u, 4u, 6u, 1u, 3u, 5u, 3u, 7u, 5u,
);

// A box corner at depth near / w (z = near, divided by w).
@vertex
fn box_vertex(@builtin(vertex_index) v: u32) -> @builtin(position) vec4<f32> {
    let c = corners[(v / 36u) * 8u + FACES[v % 36u]];
    let p = q.view_proj * vec4<f32>(c.xyz, 1.0);
    return vec4<f32>(p.xy, q.near, p.w);
}

// One triangle over the whole target.
@vertex
fn full_vertex(@builtin(vertex_index) v: u32) -> @builtin(position) vec4<f32> {
    return vec4<f32>(f32((v << 1u) & 2u) * 2.0 - 1.0, f32(v & 2u) * 2.0 - 1.0, 0.0, 1.0);
}

// near / w of the compute path's pixel, from its key (as `depth_at` in fb_atomic.wgsl).
@fragment
fn compute_depth(@builtin(position) at: vec4<f32>) -> @builtin(frag_depth) f32 {
    let key = framebuffer[u32(at.y) * q.width + u32(at.x)].y;
    if (key == 0u) {
        return 0.0;
    }
    let w = (1.0 - f32(key - 1u) / 4294967040.0) * q.far;
    return clamp(q.near / max(w, q.near), 0.0, 1.0);
}

// near / w of the quad path's pixel.
@fragment
fn quad_depth_fragment(@builtin(position) at: vec4<f32>) -> @builtin(frag_depth) f32 {
    let d = textureLoad(quad_depth, vec2<i32>(at.xy), 0);
    if (d >= 1.0) {
        return 0.0;
    }
    let a = q.far / (q.far - q.near);
    return clamp(1.0 - d / a, 0.0, 1.0);
}
