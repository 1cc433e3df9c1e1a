//! Photos and panoramas in the window (`myriad photos` keeps them with a dataset): a marker at
//! each placed one, its name under the cursor; a click on a marker (or the panel's list, or
//! `view --photo N`) opens it: the image in a window, "view from here" puts the camera at its
//! pose, and from there the photo is drawn over the points ("photo over the view": a pinhole
//! photo fitted to the view, a panorama as a sphere around the eye), so the points show where
//! the photo has them. A visual reference (no pose) is listed and opened, not placed.

use eframe::egui;
use myriad_lod::Camera;
use myriad_measure::photos::{Kind, Photo, PhotoView};
use std::path::PathBuf;

const MARK: egui::Color32 = egui::Color32::from_rgb(255, 150, 40);

pub(crate) struct Photos {
    list: Vec<Photo>,
    folder: PathBuf,
    /// The photo open, its texture (loaded on opening), and how opaque it is over the view.
    open: Option<(usize, Option<egui::TextureHandle>)>,
    pub opacity: f32,
    /// The camera is at the open photo's pose (set by "view from here", cleared by a move).
    at_pose: Option<[f64; 3]>,
    /// `view --photo N`, taken on the first frame.
    asked: Option<usize>,
    pub problem: Option<String>,
}

impl Photos {
    /// The photos kept with `dataset` (none: an empty list; one that does not read: said).
    pub fn new(dataset: Option<&std::path::Path>, asked: Option<usize>) -> Photos {
        let mut problem = None;
        let (list, folder) = match dataset {
            None => (Vec::new(), PathBuf::new()),
            Some(d) => {
                let f = myriad_measure::photos::sidecar_for(d);
                let list = match std::fs::read_to_string(&f) {
                    Err(_) => Vec::new(),
                    Ok(t) => myriad_measure::photos::parse(&t).unwrap_or_else(|e| {
                        problem = Some(format!("{}: {e}", f.display()));
                        eprintln!("warning: {}", problem.as_deref().unwrap_or_default());
                        Vec::new()
                    }),
                };
                (list, myriad_measure::photos::folder_for(d))
            }
        };
        Photos {
            list,
            folder,
            open: None,
            opacity: 0.6,
            at_pose: None,
            asked,
            problem,
        }
    }

    /// The first frame: `view --photo N` opened, the camera at its pose.
    pub fn start(&mut self, ctx: &egui::Context) -> Option<PhotoView> {
        let n = self.asked.take()?;
        match n.checked_sub(1).filter(|&i| i < self.list.len()) {
            Some(i) => {
                self.open_photo(ctx, i);
                self.list[i].view().inspect(|v| {
                    self.at_pose = Some(v.eye);
                    println!("photo {n} \"{}\": viewed from its pose", self.list[i].name);
                })
            }
            None => {
                eprintln!(
                    "warning: --photo {n}: the dataset keeps {} photos",
                    self.list.len()
                );
                None
            }
        }
    }

    fn open_photo(&mut self, ctx: &egui::Context, i: usize) {
        let path = self.folder.join(&self.list[i].file);
        let tex = match image::open(&path) {
            Ok(img) => {
                // At most the GPU's largest texture (a 20,000-pixel panorama shrunk).
                let side = ctx.input(|i| i.max_texture_side).clamp(256, 8192) as u32;
                let img = if img.width() > side || img.height() > side {
                    img.resize(side, side, image::imageops::FilterType::Triangle)
                } else {
                    img
                };
                let img = img.to_rgba8();
                let size = [img.width() as usize, img.height() as usize];
                let c = egui::ColorImage::from_rgba_unmultiplied(size, img.as_raw());
                Some(ctx.load_texture(format!("photo {i}"), c, egui::TextureOptions::LINEAR))
            }
            Err(e) => {
                self.problem = Some(format!("{}: {e}", path.display()));
                None
            }
        };
        self.open = Some((i, tex));
        self.at_pose = None;
    }

    /// The panel's list: each photo, opened by a click.
    pub fn panel(&mut self, ui: &mut egui::Ui) {
        if self.list.is_empty() && self.problem.is_none() {
            return;
        }
        let mut opened = None;
        egui::CollapsingHeader::new(format!("photos ({})", self.list.len()))
            .default_open(false)
            .show(ui, |ui| {
                for (i, p) in self.list.iter().enumerate() {
                    let placed = if p.pose.is_some() { "" } else { ", not placed" };
                    if ui
                        .link(format!("{} ({}{placed})", p.name, p.kind_name()))
                        .clicked()
                    {
                        opened = Some(i);
                    }
                }
                ui.add(egui::Slider::new(&mut self.opacity, 0.0..=1.0).text("photo over the view"));
                if let Some(p) = &self.problem {
                    ui.colored_label(egui::Color32::LIGHT_RED, p);
                }
            });
        if let Some(i) = opened {
            self.open_photo(ui.ctx(), i);
        }
    }

    /// The markers over the view (`screen` projects a point), the photo over the view where
    /// the camera is at its pose, and the photo's window; a click on a marker opens it. Returns
    /// a camera asked for ("view from here"): eye, target, up, field of view.
    pub fn draw(
        &mut self,
        ui: &egui::Ui,
        rect: egui::Rect,
        response: &egui::Response,
        cam: &Camera,
        screen: &dyn Fn([f64; 3]) -> Option<egui::Pos2>,
    ) -> Option<PhotoView> {
        if self.at_pose.is_some_and(|e| e != cam.position) {
            self.at_pose = None;
        }
        if let (Some(_), Some((i, Some(tex)))) = (self.at_pose, &self.open) {
            over_view(
                ui.painter(),
                rect,
                &self.list[*i],
                tex,
                cam,
                self.opacity,
                screen,
            );
        }
        let painter = ui.painter();
        let hover = response.hover_pos();
        let mut clicked = None;
        for (i, p) in self.list.iter().enumerate() {
            let Some(at) = p.pose.and_then(|q| screen(q.position)) else {
                continue;
            };
            let r = egui::Rect::from_center_size(at, egui::vec2(10.0, 8.0));
            painter.rect_filled(r, 1.0, MARK);
            painter.circle_filled(at, 2.0, egui::Color32::BLACK);
            if hover.is_some_and(|h| h.distance(at) < 8.0) {
                painter.text(
                    at + egui::vec2(8.0, -8.0),
                    egui::Align2::LEFT_BOTTOM,
                    &p.name,
                    egui::FontId::proportional(13.0),
                    MARK,
                );
                if response.clicked() {
                    clicked = Some(i);
                }
            }
        }
        if let Some(i) = clicked {
            self.open_photo(ui.ctx(), i);
        }
        let mut asked = None;
        let mut close = false;
        if let Some((i, tex)) = &self.open {
            let p = &self.list[*i];
            egui::Window::new(format!("photo: {}", p.name))
                .default_width(360.0)
                .show(ui.ctx(), |ui| {
                    ui.label(format!(
                        "{} {}x{}{}",
                        p.kind_name(),
                        p.width,
                        p.height,
                        if p.pose.is_some() {
                            ""
                        } else {
                            ", not placed (no pose)"
                        }
                    ));
                    if let Some(t) = tex {
                        let w = ui.available_width().min(360.0);
                        let h = w * p.height as f32 / p.width.max(1) as f32;
                        ui.image(egui::load::SizedTexture::new(t.id(), egui::vec2(w, h)));
                    }
                    ui.horizontal(|ui| {
                        if let Some(v) = p.view()
                            && ui.button("view from here").clicked()
                        {
                            asked = Some(v);
                        }
                        if ui.button("close").clicked() {
                            close = true;
                        }
                    });
                });
        }
        if close {
            self.open = None;
        }
        if let Some(v) = &asked {
            self.at_pose = Some(v.eye);
        }
        asked
    }
}

/// The open photo over the view from its pose: a pinhole photo as its camera frames it (its
/// field of view is the view's), a panorama as a sphere around the eye (a mesh of 48 x 24 cells
/// with the image's coordinates, cells behind the eye left out).
fn over_view(
    painter: &egui::Painter,
    rect: egui::Rect,
    p: &Photo,
    tex: &egui::TextureHandle,
    cam: &Camera,
    opacity: f32,
    screen: &dyn Fn([f64; 3]) -> Option<egui::Pos2>,
) {
    let tint = egui::Color32::from_white_alpha((opacity * 255.0) as u8);
    match p.kind {
        Kind::Pinhole { .. } => {
            let h = rect.height();
            let w = h * p.width as f32 / p.height.max(1) as f32;
            let r = egui::Rect::from_center_size(rect.center(), egui::vec2(w, h));
            let uv = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
            painter.image(tex.id(), r, uv, tint);
        }
        Kind::Spherical => {
            let Some(pose) = p.pose else { return };
            let (cols, rows) = (48usize, 24usize);
            let mut mesh = egui::Mesh::with_texture(tex.id());
            let point = |u: f64, v: f64| {
                // Column fraction u: azimuth from +180 to -180; row fraction v: elevation +90 to -90.
                let az = std::f64::consts::PI - u * std::f64::consts::TAU;
                let el = std::f64::consts::FRAC_PI_2 - v * std::f64::consts::PI;
                let d = pose.rotate([el.cos() * az.cos(), el.cos() * az.sin(), el.sin()]);
                std::array::from_fn(|i| cam.position[i] + d[i] * 10.0)
            };
            for r in 0..rows {
                for c in 0..cols {
                    let (u0, u1) = (c as f64 / cols as f64, (c + 1) as f64 / cols as f64);
                    let (v0, v1) = (r as f64 / rows as f64, (r + 1) as f64 / rows as f64);
                    let corners = [(u0, v0), (u1, v0), (u1, v1), (u0, v1)];
                    let pts: Option<Vec<egui::Pos2>> =
                        corners.iter().map(|&(u, v)| screen(point(u, v))).collect();
                    let Some(pts) = pts else { continue };
                    let base = mesh.vertices.len() as u32;
                    for (q, &(u, v)) in pts.iter().zip(&corners) {
                        mesh.vertices.push(egui::epaint::Vertex {
                            pos: *q,
                            uv: egui::pos2(u as f32, v as f32),
                            color: tint,
                        });
                    }
                    mesh.indices
                        .extend([base, base + 1, base + 2, base, base + 2, base + 3]);
                }
            }
            painter.with_clip_rect(rect).add(egui::Shape::mesh(mesh));
        }
        Kind::Reference => {}
    }
}
