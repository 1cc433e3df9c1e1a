//! Drawing the view: the device and rasterizer that draw, the points' style, the last frame's
//! statistics, where the frame goes (the window's texture on a GPU, `present.rs`; the CPU
//! path's image through `blit.rs` or an egui texture), and the surfaces and the stereo pair
//! drawn instead of the points when asked for (`surface.rs`).

use crate::present::Present;
use crate::shown::Layers;
use crate::surface::{StereoView, Surfaces};
use crate::{blit, motion};
use eframe::egui;
use eframe::egui_wgpu;
use eframe::wgpu;
use myriad_lod::{Camera, SelectOptions};
use myriad_render::{FrameStats, Gpu, Rasterizer, Scene, Style};

pub(crate) struct Render {
    pub gpu: Gpu,
    pub raster: Rasterizer,
    pub style: Style,
    /// The last frame's statistics, per dataset drawn.
    pub stats: Vec<FrameStats>,
    /// GPU frames drawn into the window's texture.
    present: Option<Present>,
    /// The CPU path's image goes to the window through `blit` (installed).
    blit: bool,
    texture: Option<egui::TextureHandle>,
    /// The size of the last image drawn (shown again while a converged view rests).
    pub last_size: Option<(u32, u32)>,
    pub surfaces: Surfaces,
    pub stereo: StereoView,
}

impl Render {
    pub fn new(
        (gpu, raster): (Gpu, Rasterizer),
        style: Style,
        surfaces: Surfaces,
        stereo: StereoView,
    ) -> Render {
        Render {
            gpu,
            raster,
            style,
            stats: Vec::new(),
            present: None,
            blit: false,
            texture: None,
            last_size: None,
            surfaces,
            stereo,
        }
    }

    /// The window's adapter draws where it is a hardware GPU (or `want_gpu`); else the CPU.
    /// `readback`: GPU frames are read back and uploaded rather than drawn into the window's
    /// texture.
    pub fn adopt(&mut self, rs: Option<&egui_wgpu::RenderState>, want_gpu: bool, readback: bool) {
        let Some(rs) = rs else { return };
        let info = rs.adapter.get_info();
        if want_gpu || info.device_type != wgpu::DeviceType::Cpu {
            self.gpu = Gpu::from_device(rs.device.clone(), rs.queue.clone(), &info);
            self.raster = Rasterizer::new(&self.gpu);
            // The surface's steps on the same device (Schiffner et al. 2015 run them on the
            // GPU).
            let worker = Gpu::from_device(rs.device.clone(), rs.queue.clone(), &info);
            self.surfaces.on_gpu(worker);
            if !readback {
                self.present = Some(Present::new(rs.clone()));
            }
        }
        blit::install(rs);
        self.blit = !readback;
    }

    /// A surface or a stereo pair is drawn (always at the full resolution, read back).
    pub fn whole(&self) -> bool {
        self.surfaces.on || self.stereo.on
    }

    /// Where a frame of `w` x `h` pixels goes: the window's texture (on a GPU drawing for the
    /// window), or None: the frame is read back (a surface's image is, and the window's
    /// texture is let go).
    pub fn target(&mut self, w: u32, h: u32) -> Option<egui::TextureId> {
        if self.whole() {
            if let Some(p) = &mut self.present {
                p.stop(&self.raster);
            }
            None
        } else {
            let raster = &self.raster;
            self.present.as_mut().map(|p| p.texture(raster, w, h))
        }
    }

    /// Draws the visible datasets of `layers` seen by `full` (at `scale` of its size) in one
    /// frame: one budget, one depth buffer. Drawing on a GPU, selection runs on its own thread
    /// per dataset and the frame draws the newest selection in (never waits for it); drawing on
    /// the CPU, the cores that would select are the cores that draw, and the frame selects
    /// itself (the frame-rate budget then sees its own selection).
    pub fn draw(
        &mut self,
        layers: &mut Layers,
        full: &Camera,
        scale: f32,
        options: &SelectOptions,
    ) -> Vec<u8> {
        if self.stereo.on {
            let scene = (layers.list.iter_mut())
                .find(|l| l.visible)
                .map(|l| &mut l.scene);
            let gpu = (&self.gpu, &self.raster);
            let (image, stats) = self.stereo.draw(full, scene, gpu, options, &self.style);
            if let Some(stats) = stats {
                self.stats = vec![stats];
            }
            return image;
        }
        let cam = motion::scaled(full, scale);
        let mut scenes: Vec<&mut Scene> = layers.visible_scenes();
        // On the CPU the occlusion queries are answered at once: each frame waits for them, and
        // the nodes culled that show are drawn in the frame they come into sight (Scheiblauer
        // 2006's queries as Gobbetti and Marton schedule them); on a GPU they are read when it
        // has them.
        let cpu = self.raster.path == myriad_render::Path::Cpu;
        for s in scenes.iter_mut() {
            s.query_wait = cpu;
        }
        let frame = if cpu {
            myriad_render::frame_many
        } else {
            myriad_render::frame_many_threaded
        };
        let (image, stats) = frame(
            &mut scenes,
            &self.gpu,
            &self.raster,
            &cam,
            options,
            &self.style,
        );
        self.stats = stats;
        if self.surfaces.on {
            let visible = layers.list.iter().filter(|l| l.visible).map(|l| &l.scene);
            return (self.surfaces).image(
                full,
                image,
                &self.stats,
                visible,
                &self.style,
                &self.gpu,
            );
        }
        image
    }

    /// The frame over `rect`: the window's texture drawn into (`shown`), or the image of
    /// `w` x `h` pixels drawn now (none: the last one again) through `blit` or an egui
    /// texture.
    pub fn show(
        &mut self,
        ui: &egui::Ui,
        rect: egui::Rect,
        shown: Option<egui::TextureId>,
        image: Option<Vec<u8>>,
        (w, h): (u32, u32),
    ) {
        match shown {
            Some(id) => show_texture(ui.painter(), rect, id),
            None if self.blit => blit::paint(ui.painter(), rect, image, w, h),
            None => {
                if let Some(image) = image {
                    let colour =
                        egui::ColorImage::from_rgba_unmultiplied([w as usize, h as usize], &image);
                    let options = egui::TextureOptions::NEAREST;
                    match &mut self.texture {
                        Some(t) => t.set(colour, options),
                        None => self.texture = Some(ui.ctx().load_texture("view", colour, options)),
                    }
                }
                if let Some(t) = &self.texture {
                    show_texture(ui.painter(), rect, t.id());
                }
            }
        }
    }

    /// Nodes or pages still loading.
    pub fn loading(&self) -> bool {
        self.stats.iter().any(|s| s.in_flight > 0)
    }

    /// The selection of this view in, every node of it drawn, nothing loading, and the
    /// surface of this view shown.
    pub fn converged(&self) -> bool {
        !self.stats.is_empty()
            && self
                .stats
                .iter()
                .all(|s| s.select_current && s.complete && s.in_flight == 0)
            && self.surfaces.settled()
    }

    /// Points drawn in the last frame.
    pub fn points(&self) -> u64 {
        self.stats.iter().map(|s| s.points).sum()
    }
}

/// A texture (the frame drawn on a GPU, or read back) over the view.
fn show_texture(painter: &egui::Painter, rect: egui::Rect, id: egui::TextureId) {
    let uv = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
    painter.image(id, rect, uv, egui::Color32::WHITE);
}
