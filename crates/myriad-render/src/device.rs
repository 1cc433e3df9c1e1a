//! The device frames are drawn on: a GPU (headless, or a window's) or the CPU.

use std::sync::Mutex;

/// Where frames are drawn: a GPU device and queue (without a window), or the CPU.
pub struct Gpu {
    wgpu: Option<(wgpu::Device, wgpu::Queue)>,
    /// The adapter's name and type, e.g. "llvmpipe (LLVM 15.0.6, 256 bits) (Cpu)".
    pub name: String,
    /// The device has 64-bit integer atomics (the compute path).
    pub atomics: bool,
    /// A software rasterizer (lavapipe, llvmpipe, SwiftShader, WARP).
    pub software: bool,
}

impl Gpu {
    /// The best adapter there is (a real GPU, or lavapipe), without a surface; 64-bit atomics are
    /// asked for where the adapter has them.
    pub fn headless() -> Result<Gpu, String> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            ..Default::default()
        }))
        .map_err(|e| format!("no GPU adapter: {e}"))?;
        let atomics_features =
            wgpu::Features::SHADER_INT64 | wgpu::Features::SHADER_INT64_ATOMIC_MIN_MAX;
        let info = adapter.get_info();
        let atomics = adapter.features().contains(atomics_features);
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("myriad"),
            required_features: if atomics {
                atomics_features
            } else {
                wgpu::Features::empty()
            },
            required_limits: adapter.limits(),
            ..Default::default()
        }))
        .map_err(|e| format!("{}: {e}", info.name))?;
        Ok(Gpu {
            wgpu: Some((device, queue)),
            name: format!("{} ({:?})", info.name, info.device_type),
            atomics,
            software: info.device_type == wgpu::DeviceType::Cpu,
        })
    }

    /// The features the compute path needs (64-bit integer atomics), for a device made elsewhere.
    pub fn atomics_features() -> wgpu::Features {
        wgpu::Features::SHADER_INT64 | wgpu::Features::SHADER_INT64_ATOMIC_MIN_MAX
    }

    /// A device made elsewhere (a window's), with the features it was made with.
    pub fn from_device(device: wgpu::Device, queue: wgpu::Queue, info: &wgpu::AdapterInfo) -> Gpu {
        let atomics = device.features().contains(Gpu::atomics_features());
        Gpu {
            wgpu: Some((device, queue)),
            name: format!("{} ({:?})", info.name, info.device_type),
            atomics,
            software: info.device_type == wgpu::DeviceType::Cpu,
        }
    }

    /// The CPU: the compute path's algorithm on all cores.
    pub fn cpu() -> Gpu {
        Gpu {
            wgpu: None,
            name: format!(
                "CPU ({} threads)",
                std::thread::available_parallelism().map_or(1, |n| n.get())
            ),
            atomics: false,
            software: true,
        }
    }

    /// For headless images: a hardware GPU if there is one, else the CPU, with why there is no
    /// adapter at all. A software adapter is passed over: on the 2-core machines here the CPU
    /// path draws the same frames in half of lavapipe's time (`myriad bench render --cpu`).
    pub fn best() -> (Gpu, Option<String>) {
        match Gpu::headless() {
            Ok(g) if !g.software => (g, None),
            Ok(_) => (Gpu::cpu(), None),
            // wgpu's reason lists every backend; its first clause says it.
            Err(e) => (
                Gpu::cpu(),
                Some(e.split(';').next().unwrap_or(&e).trim().to_string()),
            ),
        }
    }

    pub fn is_cpu(&self) -> bool {
        self.wgpu.is_none()
    }

    /// The wgpu device and queue; None on the CPU.
    pub fn wgpu(&self) -> Option<(&wgpu::Device, &wgpu::Queue)> {
        self.wgpu.as_ref().map(|(d, q)| (d, q))
    }

    pub(crate) fn device(&self) -> &wgpu::Device {
        &self.wgpu.as_ref().expect("a GPU path on a GPU").0
    }
    pub(crate) fn queue(&self) -> &wgpu::Queue {
        &self.wgpu.as_ref().expect("a GPU path on a GPU").1
    }
}

/// A lock whose holder panicked still guards valid data here (plain buffers and values).
pub(crate) fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}
