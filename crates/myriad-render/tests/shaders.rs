//! Every WGSL shader parses and validates with naga (no GPU needed), with the capabilities the
//! renderer asks the device for.

fn validate(name: &str, src: &str) {
    let module = naga::front::wgsl::parse_str(src)
        .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(src)));
    let caps = naga::valid::Capabilities::SHADER_INT64
        | naga::valid::Capabilities::SHADER_INT64_ATOMIC_MIN_MAX;
    naga::valid::Validator::new(naga::valid::ValidationFlags::all(), caps)
        .validate(&module)
        .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(src)));
}

#[test]
fn shaders_validate() {
    validate("raster.wgsl", myriad_render::RASTER_WGSL);
    validate("resolve.wgsl", myriad_render::RESOLVE_WGSL);
}

#[test]
fn a_broken_shader_is_caught() {
    let broken = myriad_render::RASTER_WGSL.replace("atomicMax(", "atomicMaxx(");
    assert!(
        std::panic::catch_unwind(|| validate("broken", &broken)).is_err(),
        "the validator must reject an unknown function"
    );
}
