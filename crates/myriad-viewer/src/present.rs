//! The viewer's frame on a GPU without a readback (the window's texture), and the panel of the
//! post passes.

use eframe::egui;
use eframe::egui_wgpu;
use eframe::wgpu;
use myriad_render::{Edl, Rasterizer};

/// The window's texture a GPU frame is drawn into, shown without a readback.
pub(crate) struct Presented {
    pub texture: wgpu::Texture,
    pub id: egui::TextureId,
}

/// GPU frames drawn into the window's texture: the window's render state and the texture.
pub(crate) struct Present {
    rs: egui_wgpu::RenderState,
    presented: Option<Presented>,
}

impl Present {
    pub fn new(rs: egui_wgpu::RenderState) -> Present {
        Present {
            rs,
            presented: None,
        }
    }

    /// The window's texture of `w` x `h` pixels (made or remade at that size, registered with
    /// egui), set as `raster`'s target.
    pub fn texture(&mut self, raster: &Rasterizer, w: u32, h: u32) -> egui::TextureId {
        let (rs, presented) = (&self.rs, &mut self.presented);
        let size = wgpu::Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: 1,
        };
        if presented.as_ref().is_none_or(|p| p.texture.size() != size) {
            let texture = rs.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("view"),
                size,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::Rgba8Unorm,
                usage: wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::TEXTURE_BINDING,
                // egui samples it as sRGB, as the textures it uploads itself.
                view_formats: &[wgpu::TextureFormat::Rgba8UnormSrgb],
            });
            let shown = texture.create_view(&wgpu::TextureViewDescriptor {
                format: Some(wgpu::TextureFormat::Rgba8UnormSrgb),
                usage: Some(wgpu::TextureUsages::TEXTURE_BINDING),
                ..Default::default()
            });
            let mut renderer = rs.renderer.write();
            let id = match presented.take() {
                Some(p) => {
                    renderer.update_egui_texture_from_wgpu_texture(
                        &rs.device,
                        &shown,
                        wgpu::FilterMode::Nearest,
                        p.id,
                    );
                    p.id
                }
                None => {
                    renderer.register_native_texture(&rs.device, &shown, wgpu::FilterMode::Nearest)
                }
            };
            raster.present_to(Some(texture.create_view(&Default::default())));
            *presented = Some(Presented { texture, id });
        }
        presented.as_ref().map(|p| p.id).expect("made above")
    }

    /// Frames read back again (for a surface, drawn on the CPU): the window's texture freed.
    pub fn stop(&mut self, raster: &Rasterizer) {
        if let Some(p) = self.presented.take() {
            self.rs.renderer.write().free_texture(&p.id);
            raster.present_to(None);
        }
    }
}

/// Checkboxes for the post passes (in the pipeline's order) and their main parameters.
pub(crate) fn passes_panel(ui: &mut egui::Ui, p: &mut myriad_render::Passes) {
    use myriad_render::{Blur, Fill, Shade, Ssao};
    fn toggle<T: Default>(ui: &mut egui::Ui, v: &mut Option<T>, label: &str) -> bool {
        let mut on = v.is_some();
        ui.checkbox(&mut on, label);
        match (on, v.is_some()) {
            (true, false) => *v = Some(T::default()),
            (false, true) => *v = None,
            _ => {}
        }
        on
    }
    ui.label("passes");
    ui.checkbox(&mut p.blend, "blend overlapping points");
    if toggle::<Fill>(ui, &mut p.fill, "fill holes")
        && let Some(f) = &mut p.fill
    {
        ui.add(egui::Slider::new(&mut f.radius, 1..=4).text("fill radius (px)"));
    }
    if toggle::<Shade>(ui, &mut p.shade, "shading")
        && let Some(s) = &mut p.shade
    {
        ui.add(egui::Slider::new(&mut s.sun, 0.0..=1.0).text("sun"));
    }
    if toggle::<Ssao>(ui, &mut p.ssao, "ambient occlusion")
        && let Some(s) = &mut p.ssao
    {
        ui.add(egui::Slider::new(&mut s.radius, 2.0..=32.0).text("radius (px)"));
        ui.add(egui::Slider::new(&mut s.strength, 0.0..=4.0).text("strength"));
    }
    if toggle::<Edl>(ui, &mut p.edl, "eye-dome lighting")
        && let Some(e) = &mut p.edl
    {
        ui.add(egui::Slider::new(&mut e.strength, 0.0..=4.0).text("strength"));
        ui.add(egui::Slider::new(&mut e.radius, 0.5..=4.0).text("radius (px)"));
    }
    toggle::<Blur>(ui, &mut p.blur, "blur");
    let mut aa = p.aa > 1;
    ui.checkbox(&mut aa, "antialiasing (2x2 supersampling)");
    p.aa = if aa { 2 } else { 0 };
}
