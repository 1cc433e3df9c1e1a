//! `view --vr`'s Vulkan: a wgpu device over the Vulkan device the OpenXR runtime makes
//! (XR_KHR_vulkan_enable2: the runtime creates the instance and the device with the extensions
//! and features wgpu asks for; wgpu-hal then wraps them), and the eyes' swapchain images as wgpu
//! textures. Each frame's side-by-side image (drawn into a texture on the GPU paths, uploaded
//! from the CPU path's image otherwise) is copied eye by eye into the swapchain images on the
//! GPU, and the runtime's hidden-area triangles are drawn over them in black.

use ash::vk;
use ash::vk::Handle;
use eframe::wgpu;
use eframe::wgpu::hal;
use myriad_render::Gpu;
use openxr as xr;

fn err(what: &str) -> impl Fn(xr::sys::Result) -> String + '_ {
    move |e| format!("{what}: {e}")
}

/// The runtime's Vulkan device under wgpu, and what the session needs of it.
pub(crate) struct XrDevice {
    pub gpu: Gpu,
    pub session_info: xr::vulkan::SessionCreateInfo,
}

/// Makes the Vulkan instance and device through the runtime, with wgpu's extensions and
/// features (64-bit atomics where the device has them: the compute path), and wraps them.
pub(crate) fn create(instance: &xr::Instance, system: xr::SystemId) -> Result<XrDevice, String> {
    let requirements = instance
        .graphics_requirements::<xr::Vulkan>(system)
        .map_err(err("Vulkan requirements"))?;
    // SAFETY: loads the system's Vulkan loader.
    let entry = unsafe { ash::Entry::load() }.map_err(|e| format!("no Vulkan loader: {e}"))?;
    // SAFETY: a plain query of the loader.
    let loader = unsafe { entry.try_enumerate_instance_version() }
        .ok()
        .flatten()
        .unwrap_or(vk::API_VERSION_1_0);
    let min = requirements.min_api_version_supported;
    let needed = vk::make_api_version(0, min.major() as u32, min.minor() as u32, 0);
    let api = loader.clamp(vk::API_VERSION_1_1, vk::API_VERSION_1_3);
    if api < needed {
        return Err("the OpenXR runtime needs a newer Vulkan than the loader has".into());
    }
    let flags = wgpu::InstanceFlags::empty();
    let instance_extensions = hal::vulkan::Instance::desired_extensions(&entry, api, flags)
        .map_err(|e| format!("Vulkan instance extensions: {e}"))?;
    let names: Vec<*const std::ffi::c_char> =
        instance_extensions.iter().map(|e| e.as_ptr()).collect();
    let app_info = vk::ApplicationInfo::default()
        .application_name(c"myriad")
        .api_version(api);
    // The loader's vkGetInstanceProcAddr, as the openxr crate types it.
    let get_proc = entry.static_fn().get_instance_proc_addr;
    type XrGetProc = xr::sys::platform::VkGetInstanceProcAddr;
    let vk_result =
        |what: &'static str| move |r: i32| format!("{what}: {:?}", vk::Result::from_raw(r));
    // SAFETY: the create infos and the names they point to outlive the calls; the runtime
    // returns valid handles or errors; wgpu-hal is given the extensions the instance and the
    // device were made with, and owns them from here on.
    unsafe {
        let raw_instance = instance
            .create_vulkan_instance(
                system,
                std::mem::transmute::<vk::PFN_vkGetInstanceProcAddr, XrGetProc>(get_proc),
                &vk::InstanceCreateInfo::default()
                    .application_info(&app_info)
                    .enabled_extension_names(&names) as *const _ as *const _,
            )
            .map_err(err("the runtime's Vulkan instance"))?
            .map_err(vk_result("the runtime's Vulkan instance"))?;
        let vk_instance =
            ash::Instance::load(entry.static_fn(), vk::Instance::from_raw(raw_instance as _));
        let hal_instance = hal::vulkan::Instance::from_raw(
            entry.clone(),
            vk_instance.clone(),
            api,
            0,
            None,
            instance_extensions,
            flags,
            Default::default(),
            false,
            None,
        )
        .map_err(|e| format!("wgpu over the runtime's Vulkan instance: {e}"))?;
        let physical = vk::PhysicalDevice::from_raw(
            instance
                .vulkan_graphics_device(system, raw_instance)
                .map_err(err("the runtime's Vulkan device"))? as _,
        );
        let exposed = hal_instance
            .expose_adapter(physical)
            .ok_or("wgpu cannot use the runtime's Vulkan device")?;
        let features = exposed.features & Gpu::atomics_features();
        let limits = exposed.capabilities.limits.clone();
        let info = exposed.info.clone();
        let device_extensions = exposed.adapter.required_device_extensions(features);
        let mut device_features = exposed
            .adapter
            .physical_device_features(&device_extensions, features);
        let family = vk_instance
            .get_physical_device_queue_family_properties(physical)
            .iter()
            .position(|q| q.queue_flags.contains(vk::QueueFlags::GRAPHICS))
            .ok_or("the Vulkan device has no graphics queue")? as u32;
        let priorities = [1.0];
        let queues = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(family)
            .queue_priorities(&priorities)];
        let names: Vec<*const std::ffi::c_char> =
            device_extensions.iter().map(|e| e.as_ptr()).collect();
        let create = device_features.add_to_device_create(
            vk::DeviceCreateInfo::default()
                .queue_create_infos(&queues)
                .enabled_extension_names(&names),
        );
        let raw_device = instance
            .create_vulkan_device(
                system,
                std::mem::transmute::<vk::PFN_vkGetInstanceProcAddr, XrGetProc>(get_proc),
                physical.as_raw() as _,
                &create as *const _ as *const _,
            )
            .map_err(err("the runtime's Vulkan device"))?
            .map_err(vk_result("the runtime's Vulkan device"))?;
        let vk_device =
            ash::Device::load(vk_instance.fp_v1_0(), vk::Device::from_raw(raw_device as _));
        let open = exposed
            .adapter
            .device_from_raw(
                vk_device,
                None,
                &device_extensions,
                features,
                &limits,
                &wgpu::MemoryHints::Performance,
                family,
                0,
            )
            .map_err(|e| format!("wgpu over the runtime's Vulkan device: {e}"))?;
        let wgpu_instance = wgpu::Instance::from_hal::<hal::api::Vulkan>(hal_instance);
        let adapter = wgpu_instance.create_adapter_from_hal(exposed);
        let (device, queue) = adapter
            .create_device_from_hal(
                open,
                &wgpu::DeviceDescriptor {
                    label: Some("myriad vr"),
                    required_features: features,
                    required_limits: limits,
                    ..Default::default()
                },
            )
            .map_err(|e| format!("wgpu over the runtime's Vulkan device: {e}"))?;
        Ok(XrDevice {
            gpu: Gpu::from_device(device, queue, &info),
            session_info: xr::vulkan::SessionCreateInfo {
                instance: raw_instance,
                physical_device: physical.as_raw() as _,
                device: raw_device,
                queue_family_index: family,
                queue_index: 0,
            },
        })
    }
}

const MASK_WGSL: &str = "
@vertex fn vs(@location(0) p: vec2<f32>) -> @builtin(position) vec4<f32> {
    return vec4<f32>(p, 0.0, 1.0);
}
@fragment fn fs() -> @location(0) vec4<f32> {
    return vec4<f32>(0.0, 0.0, 0.0, 1.0);
}
";

/// The eyes' swapchains with their images as wgpu textures, the side-by-side frame they are
/// cut from, and the hidden-area triangles drawn over them.
pub(crate) struct Eyes {
    pub swapchains: Vec<xr::Swapchain<xr::Vulkan>>,
    images: Vec<Vec<wgpu::Texture>>,
    /// Each eye's image size.
    pub size: (u32, u32),
    format: wgpu::TextureFormat,
    /// The side-by-side frame (Rgba8Unorm: the rasterizer's storage target).
    frame: Option<wgpu::Texture>,
    mask: wgpu::RenderPipeline,
    /// Per eye the hidden-area triangles (clip space of its image): vertices and their count.
    hidden: [Option<(wgpu::Buffer, u32)>; 2],
}

impl Eyes {
    pub(crate) fn new(
        session: &xr::Session<xr::Vulkan>,
        gpu: &Gpu,
        size: (u32, u32),
    ) -> Result<Eyes, String> {
        let (device, _) = gpu.wgpu().ok_or("no GPU device")?;
        let formats = session
            .enumerate_swapchain_formats()
            .map_err(err("swapchain formats"))?;
        let (vk_format, format) = [
            (
                vk::Format::R8G8B8A8_SRGB,
                wgpu::TextureFormat::Rgba8UnormSrgb,
            ),
            (vk::Format::R8G8B8A8_UNORM, wgpu::TextureFormat::Rgba8Unorm),
        ]
        .into_iter()
        .find(|f| formats.contains(&(f.0.as_raw() as u32)))
        .ok_or("the runtime offers no RGBA8 swapchain")?;
        let (w, h) = size;
        let extent = wgpu::Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: 1,
        };
        let mut swapchains = Vec::new();
        let mut images = Vec::new();
        for _ in 0..2 {
            let sc = session
                .create_swapchain(&xr::SwapchainCreateInfo {
                    create_flags: xr::SwapchainCreateFlags::EMPTY,
                    usage_flags: xr::SwapchainUsageFlags::COLOR_ATTACHMENT
                        | xr::SwapchainUsageFlags::TRANSFER_DST
                        | xr::SwapchainUsageFlags::TRANSFER_SRC,
                    format: vk_format.as_raw() as u32,
                    sample_count: 1,
                    width: w,
                    height: h,
                    face_count: 1,
                    array_size: 1,
                    mip_count: 1,
                })
                .map_err(err("a swapchain"))?;
            let usage = wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::COPY_DST
                | wgpu::TextureUsages::COPY_SRC;
            let textures = sc
                .enumerate_images()
                .map_err(err("swapchain images"))?
                .into_iter()
                .map(|raw| {
                    // SAFETY: the runtime's image, made on this device with this size, format
                    // and usage; it stays the runtime's (no drop), and the runtime hands it
                    // over in COLOR_ATTACHMENT_OPTIMAL.
                    unsafe {
                        let hal_device = device
                            .as_hal::<hal::api::Vulkan>()
                            .expect("a Vulkan device");
                        let texture = hal_device.texture_from_raw(
                            vk::Image::from_raw(raw),
                            &hal::TextureDescriptor {
                                label: Some("swapchain"),
                                size: extent,
                                mip_level_count: 1,
                                sample_count: 1,
                                dimension: wgpu::TextureDimension::D2,
                                format,
                                usage: wgpu::TextureUses::COLOR_TARGET
                                    | wgpu::TextureUses::COPY_DST
                                    | wgpu::TextureUses::COPY_SRC,
                                memory_flags: hal::MemoryFlags::empty(),
                                view_formats: Vec::new(),
                            },
                            Some(Box::new(|| {})),
                            hal::vulkan::TextureMemory::External,
                        );
                        device.create_texture_from_hal::<hal::api::Vulkan>(
                            texture,
                            &wgpu::TextureDescriptor {
                                label: Some("swapchain"),
                                size: extent,
                                mip_level_count: 1,
                                sample_count: 1,
                                dimension: wgpu::TextureDimension::D2,
                                format,
                                usage,
                                view_formats: &[],
                            },
                            wgpu::TextureUses::COLOR_TARGET,
                        )
                    }
                })
                .collect();
            swapchains.push(sc);
            images.push(textures);
        }
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("hidden area"),
            source: wgpu::ShaderSource::Wgsl(MASK_WGSL.into()),
        });
        let mask = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("hidden area"),
            layout: None,
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs"),
                compilation_options: Default::default(),
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: 8,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &wgpu::vertex_attr_array![0 => Float32x2],
                })],
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: None,
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs"),
                compilation_options: Default::default(),
                targets: &[Some(format.into())],
            }),
            multiview_mask: None,
            cache: None,
        });
        Ok(Eyes {
            swapchains,
            images,
            size,
            format,
            frame: None,
            mask,
            hidden: [None, None],
        })
    }

    /// Eye `k`'s hidden-area triangles, as tangents of the field its image covers.
    pub(crate) fn set_hidden(
        &mut self,
        gpu: &Gpu,
        k: usize,
        triangles: &[[[f64; 2]; 3]],
        field: crate::vr_nav::Tangents,
    ) {
        let Some((device, queue)) = gpu.wgpu() else {
            return;
        };
        let clip = |v: [f64; 2]| {
            [
                (2.0 * (v[0] - field.left) / (field.right - field.left) - 1.0) as f32,
                (2.0 * (v[1] - field.down) / (field.up - field.down) - 1.0) as f32,
            ]
        };
        let vertices: Vec<u8> = triangles
            .iter()
            .flatten()
            .flat_map(|&v| clip(v))
            .flat_map(f32::to_le_bytes)
            .collect();
        self.hidden[k] = (!vertices.is_empty()).then(|| {
            let buffer = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("hidden area"),
                size: vertices.len() as u64,
                usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            queue.write_buffer(&buffer, 0, &vertices);
            (buffer, (vertices.len() / 8) as u32)
        });
    }

    /// The side-by-side frame's texture for `width` x `height` (both eyes), made anew when the
    /// size changes: the rasterizer's target on the GPU paths.
    pub(crate) fn frame(&mut self, gpu: &Gpu, width: u32, height: u32) -> wgpu::Texture {
        let (device, _) = gpu.wgpu().expect("a GPU device");
        let size = wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        };
        if self.frame.as_ref().is_none_or(|f| f.size() != size) {
            self.frame = Some(device.create_texture(&wgpu::TextureDescriptor {
                label: Some("vr frame"),
                size,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::Rgba8Unorm,
                usage: wgpu::TextureUsages::STORAGE_BINDING
                    | wgpu::TextureUsages::COPY_SRC
                    | wgpu::TextureUsages::COPY_DST,
                view_formats: &[],
            }));
        }
        self.frame.clone().expect("made above")
    }

    /// Both eyes' images into their swapchains: `image` (the side-by-side frame read back or
    /// drawn on the CPU, `width` x `height`) uploaded first where given, else the frame the GPU
    /// drew; each eye's `size` cut from its corner, the hidden area drawn black over it; waits
    /// for the GPU before the images go back to the runtime. With `image` and `verify`, the
    /// swapchain images are read back and compared with it: the pixels that differ (none, but
    /// for the hidden area's rim, where the GPU's rule for a triangle's edges and the mask's
    /// differ).
    pub(crate) fn submit(
        &mut self,
        gpu: &Gpu,
        image: Option<&[u8]>,
        verify: bool,
        (width, height): (u32, u32),
        corners: [(u32, u32); 2],
    ) -> Result<Option<u64>, String> {
        let frame = &self.frame(gpu, width, height);
        let (device, queue) = gpu.wgpu().expect("a GPU device");
        if let Some(rgba) = image {
            queue.write_texture(
                frame.as_image_copy(),
                rgba,
                wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(width * 4),
                    rows_per_image: Some(height),
                },
                frame.size(),
            );
        }
        let mut acquired = Vec::new();
        for sc in self.swapchains.iter_mut() {
            let i = sc.acquire_image().map_err(err("a swapchain image"))? as usize;
            sc.wait_image(xr::Duration::INFINITE)
                .map_err(err("a swapchain image"))?;
            acquired.push(i);
        }
        let (w, h) = self.size;
        let row = (w * 4).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let readback = image.filter(|_| verify).map(|_| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("swapchain readback"),
                size: 2 * row as u64 * h as u64,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        });
        let mut enc = device.create_command_encoder(&Default::default());
        for k in 0..2 {
            let target = &self.images[k][acquired[k]];
            let (x, y) = corners[k];
            enc.copy_texture_to_texture(
                wgpu::TexelCopyTextureInfo {
                    texture: frame,
                    mip_level: 0,
                    origin: wgpu::Origin3d { x, y, z: 0 },
                    aspect: wgpu::TextureAspect::All,
                },
                target.as_image_copy(),
                wgpu::Extent3d {
                    width: w,
                    height: h,
                    depth_or_array_layers: 1,
                },
            );
            // The hidden area black; the pass also leaves the image as a colour attachment,
            // the layout the runtime takes it back in.
            let view = target.create_view(&wgpu::TextureViewDescriptor {
                format: Some(self.format),
                ..Default::default()
            });
            let attachment = |view| {
                [Some(wgpu::RenderPassColorAttachment {
                    view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Load,
                        store: wgpu::StoreOp::Store,
                    },
                })]
            };
            {
                let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("hidden area"),
                    color_attachments: &attachment(&view),
                    ..Default::default()
                });
                if let Some((buffer, n)) = &self.hidden[k] {
                    pass.set_pipeline(&self.mask);
                    pass.set_vertex_buffer(0, buffer.slice(..));
                    pass.draw(0..*n, 0..1);
                }
            }
            if let Some(b) = &readback {
                enc.copy_texture_to_buffer(
                    target.as_image_copy(),
                    wgpu::TexelCopyBufferInfo {
                        buffer: b,
                        layout: wgpu::TexelCopyBufferLayout {
                            offset: k as u64 * row as u64 * h as u64,
                            bytes_per_row: Some(row),
                            rows_per_image: Some(h),
                        },
                    },
                    target.size(),
                );
                // Back to a colour attachment for the runtime.
                enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("hand back"),
                    color_attachments: &attachment(&view),
                    ..Default::default()
                });
            }
        }
        queue.submit([enc.finish()]);
        if let Some(b) = &readback {
            b.slice(..).map_async(wgpu::MapMode::Read, |r| {
                r.expect("map the swapchain images")
            });
        }
        device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| format!("waiting for the GPU: {e}"))?;
        for sc in self.swapchains.iter_mut() {
            sc.release_image().map_err(err("a swapchain image"))?;
        }
        let (Some(b), Some(rgba)) = (readback, image) else {
            return Ok(None);
        };
        let got = b.slice(..).get_mapped_range().expect("mapped").to_vec();
        let mut differ = 0;
        for (k, &(x0, y0)) in corners.iter().enumerate() {
            for y in 0..h as usize {
                for x in 0..w as usize {
                    let a = &got[k * row as usize * h as usize + y * row as usize + x * 4..][..4];
                    let e = ((y0 as usize + y) * width as usize + x0 as usize + x) * 4;
                    differ += (a != &rgba[e..e + 4]) as u64;
                }
            }
        }
        Ok(Some(differ))
    }
}
