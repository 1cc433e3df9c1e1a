//! What the rasterizer tests share (not every test file uses all of it).
#![allow(dead_code)]

use myriad_render::{Gpu, Path, Rasterizer};

/// Every (device, path) this machine runs: the CPU, then the GPU's paths if there is one.
pub fn paths() -> Vec<(Gpu, Rasterizer)> {
    let cpu = Gpu::cpu();
    let r = Rasterizer::new(&cpu);
    let mut out = vec![(cpu, r)];
    match Gpu::headless() {
        Ok(gpu) => {
            eprintln!("adapter: {}, 64-bit atomics: {}", gpu.name, gpu.atomics);
            if gpu.atomics {
                let other = Gpu::headless().expect("found above");
                let r = Rasterizer::with_path(&other, Path::Compute);
                out.push((other, r));
            }
            let r = Rasterizer::with_path(&gpu, Path::Quads);
            out.push((gpu, r));
        }
        Err(e) => eprintln!(
            "SKIPPED on the GPU paths: {e}; they need a Vulkan driver (CI installs lavapipe)"
        ),
    }
    out
}

/// The GPU adapter, or None having said the test is skipped without one.
pub fn gpu_or_skip() -> Option<Gpu> {
    Gpu::headless()
        .map_err(|e| eprintln!("SKIPPED: no GPU adapter ({e}); CI installs lavapipe"))
        .ok()
}

/// Numbers uniform in [0, 1) from `seed` (xorshift), the same on every run.
pub fn random(mut s: u64) -> impl FnMut() -> f64 {
    move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    }
}
