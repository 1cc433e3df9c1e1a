//! Every WGSL shader parses and validates with naga (no GPU needed), with the capabilities the
//! renderer asks the device for: 64-bit atomics for the compute path, none for the quad path.

use naga::valid::Capabilities;

fn validate(name: &str, src: &str, caps: Capabilities) {
    let module = naga::front::wgsl::parse_str(src)
        .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(src)));
    naga::valid::Validator::new(naga::valid::ValidationFlags::all(), caps)
        .validate(&module)
        .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(src)));
}

const ATOMICS: Capabilities =
    Capabilities::SHADER_INT64.union(Capabilities::SHADER_INT64_ATOMIC_MIN_MAX);

#[test]
fn shaders_validate() {
    validate(
        "draw.wgsl + compute.wgsl",
        myriad_render::RASTER_WGSL,
        ATOMICS,
    );
    validate(
        "gbuffer.wgsl + fb_atomic.wgsl",
        &myriad_render::gbuffer_source(myriad_render::FB_ATOMIC_WGSL),
        ATOMICS,
    );
    // The quad path runs where there are no 64-bit integers at all.
    let none = Capabilities::empty();
    validate("quads.wgsl", myriad_render::QUADS_WGSL, none);
    validate(
        "gbuffer.wgsl + fb_quads.wgsl",
        &myriad_render::gbuffer_source(myriad_render::FB_QUADS_WGSL),
        none,
    );
    // Occlusion queries on either path (the framebuffer read as pairs of 32-bit words).
    validate("queries.wgsl", myriad_render::QUERIES_WGSL, none);
    // The surface's cluster, move and reduce: 32-bit atomics only.
    validate(
        "cluster.wgsl",
        myriad_render::surface::gpu::CLUSTER_WGSL,
        none,
    );
    validate(
        "cluster.wgsl + reconstruct.wgsl",
        myriad_render::surface::gpu::RECONSTRUCT_WGSL,
        none,
    );
    validate("surface draw.wgsl", myriad_render::surface::DRAW_WGSL, none);
    // The post passes need nothing beyond WebGPU.
    for (entry, src) in myriad_render::PASS_SOURCES {
        validate(entry, src, none);
    }
}

#[test]
fn a_broken_shader_is_caught() {
    let broken = myriad_render::RASTER_WGSL.replace("atomicMax(", "atomicMaxx(");
    assert!(
        std::panic::catch_unwind(|| validate("broken", &broken, ATOMICS)).is_err(),
        "the validator must reject an unknown function"
    );
    // The compute path's shader needs 64-bit atomics.
    assert!(
        std::panic::catch_unwind(|| validate(
            "raster without atomics",
            myriad_render::RASTER_WGSL,
            Capabilities::empty()
        ))
        .is_err()
    );
}
