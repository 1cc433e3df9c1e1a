//! `myriad view`: a window (eframe: winit, wgpu, egui) showing datasets through the myriad-render
//! pipeline, with navigation, panels and tools. It owns no rendering or level-of-detail logic:
//! each frame a [`Scene`](myriad_render::Scene) selects, streams and draws (on the window's GPU
//! straight into the texture it shows, `present.rs`; or on the CPU where the only adapter is a
//! software one, into an image uploaded as a texture), shown under the panels; or, asked for,
//! the surface the drawn points make (`surface.rs`).
//!
//! The window's state is small values each owned by one file, which `app.rs`'s `App` holds and
//! runs a frame over: what draws and how (`render.rs`), the layers and their filter
//! (`shown.rs`), camera and navigation (`navigation.rs`, over [`nav`], which needs no window
//! and is tested alone), budget pacing (`pacing.rs`, over [`motion`]), the scripted orbit
//! (`orbit.rs`), screenshots (`shots.rs`), the tools (`tools/`: measure, annotate, profile,
//! volume, edit, clip, pick), the panel (`panel.rs`) and datasets being built ([`builds`]). The
//! headset's session is [`vr`]'s (its controllers `vr_hands.rs`, its Vulkan `vr_vulkan.rs`,
//! its navigation and eyes' fields [`vr_nav`]).

mod app;
mod blit;
pub mod builds;
mod legend;
mod map;
pub mod measure;
pub mod motion;
pub mod nav;
mod navigation;
mod options;
mod orbit;
mod pacing;
mod panel;
mod photos;
mod present;
mod render;
mod report;
mod shots;
mod shown;
mod surface;
mod tools;
pub mod vr;
mod vr_hands;
pub mod vr_nav;
mod vr_vulkan;

pub use builds::{Builds, Built};
use eframe::egui;
use eframe::egui_wgpu;
use eframe::wgpu;
use myriad_format::Dataset;
use myriad_render::Gpu;
pub use options::{ViewOptions, VolumeAsked};
use std::sync::Arc;
pub use tools::edit::EditsAsked;
pub use tools::path::PathsAsked;

/// Opens the window and runs until it is closed.
pub fn run(datasets: Vec<(String, Arc<Dataset>)>, o: ViewOptions) -> Result<(), String> {
    let (width, height) = (o.width, o.height);
    let (want_gpu, readback, moving_scale) = (o.gpu, o.readback, o.moving_scale);
    let app = app::App::new(datasets, o)?;
    // The window's device is asked for what the compute path needs, so that frames drawn on it
    // go to the screen without a readback.
    let setup = egui_wgpu::WgpuSetupCreateNew {
        device_descriptor: std::sync::Arc::new(|adapter: &wgpu::Adapter| {
            let atomics = Gpu::atomics_features();
            wgpu::DeviceDescriptor {
                label: Some("myriad view"),
                required_features: if adapter.features().contains(atomics) {
                    atomics
                } else {
                    wgpu::Features::empty()
                },
                required_limits: adapter.limits(),
                ..Default::default()
            }
        }),
        ..egui_wgpu::WgpuSetupCreateNew::without_display_handle()
    };
    let native = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_inner_size([width as f32, height as f32])
            .with_title("Myriad"),
        wgpu_options: egui_wgpu::WgpuConfiguration {
            wgpu_setup: egui_wgpu::WgpuSetup::CreateNew(setup),
            ..Default::default()
        },
        ..Default::default()
    };
    eframe::run_native(
        "Myriad",
        native,
        Box::new(move |cc| {
            let mut app = app;
            app.adopt(
                cc.wgpu_render_state.as_ref(),
                (want_gpu, readback),
                moving_scale,
            );
            Ok(Box::new(app))
        }),
    )
    .map_err(|e| format!("window: {e}"))
}
