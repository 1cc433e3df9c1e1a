// The surface's triangles on the GPU (mirrored by cpu.rs): into the quad path's render targets
// (colour, normal as n * 0.5 + 0.5 with alpha 1, depth), which fb_quads.wgsl hands to the post
// passes. Positions relative to the eye; both faces drawn; one normal and colour per triangle
// (its first vertex's, as the CPU takes them).

struct Uniforms {
    view_proj: mat4x4<f32>,
    // The camera's right, up and forward: world normals into eye coordinates.
    right: vec4<f32>,
    up: vec4<f32>,
    forward: vec4<f32>,
}

@group(0) @binding(0) var<uniform> u: Uniforms;

struct Out {
    @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(flat, first) colour: vec4<f32>,
    @location(1) @interpolate(flat, first) normal: vec3<f32>,
}

@vertex
fn vertex(@location(0) position: vec3<f32>, @location(1) normal: vec3<f32>, @location(2) colour: vec4<f32>) -> Out {
    var o: Out;
    o.clip = u.view_proj * vec4<f32>(position, 1.0);
    o.colour = colour;
    o.normal = vec3<f32>(dot(normal, u.right.xyz), dot(normal, u.up.xyz), dot(normal, u.forward.xyz));
    return o;
}

struct Targets {
    @location(0) colour: vec4<f32>,
    @location(1) normal: vec4<f32>,
}

@fragment
fn fragment(i: Out) -> Targets {
    var t: Targets;
    t.colour = i.colour;
    t.normal = vec4<f32>(i.normal * 0.5 + 0.5, 1.0);
    return t;
}
