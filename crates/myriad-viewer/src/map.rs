//! The map beside the view (`view --map-tiles TEMPLATE`, or the panel's box): the first
//! dataset's footprint, the camera and its view cone on a web map of tiles from the template
//! (`{z}/{x}/{y}`; none built in), in the view's top right corner, north up, with a scale bar and
//! the cursor's latitude and longitude; a click moves the camera there. Where the dataset lies
//! comes from PROJ (`myriad_measure::map::georef_of`); without a coordinate system, or without
//! PROJ, the map says why it is off. Tiles are fetched on threads (`ureq`) and decoded (`image`:
//! PNG or JPEG) off the frame.

use eframe::egui;
use myriad_core::Aabb;
use myriad_lod::Camera;
use myriad_measure::map::{Georef, MapView, from_unit, georef_of, metres_per_unit, tile_url};
use std::collections::HashMap;
use std::sync::mpsc::{Receiver, Sender, channel};

/// The map's side, points.
const SIDE: f32 = 256.0;

type Key = (u32, u32, u32);
type Fetched = (Key, Result<egui::ColorImage, String>);

enum Tile {
    Loading,
    Ready(egui::TextureHandle),
    Failed,
}

pub(crate) struct MiniMap {
    /// The tile address template (none: no map).
    pub template: Option<String>,
    /// The box's text in the panel.
    typed: String,
    /// Where the dataset lies, or why the map is off.
    georef: Result<Georef, String>,
    footprint: [[f64; 2]; 4],
    view: Option<MapView>,
    tiles: HashMap<Key, Tile>,
    sent: Sender<Fetched>,
    fetched: Receiver<Fetched>,
    /// Every tile address asked, in order (printed for the tests as `map tile: URL`).
    pub requested: Vec<String>,
}

impl MiniMap {
    /// The map of a dataset of `crs` and `bounds` from tiles of `template`.
    pub fn new(template: Option<String>, crs: Option<&str>, bounds: &Aabb) -> MiniMap {
        let georef = match crs {
            None => Err("the dataset names no coordinate system".to_string()),
            Some(c) => myriad_io::proj::Geographic::new(c).and_then(|mut g| {
                georef_of(bounds, |p| g.of(p))
                    .ok_or_else(|| "the dataset's extent does not transform to WGS 84".into())
            }),
        };
        let (lo, hi) = (bounds.min, bounds.max);
        let (sent, fetched) = channel();
        let mut m = MiniMap {
            typed: template.clone().unwrap_or_default(),
            template: None,
            georef,
            footprint: [
                [lo[0], lo[1]],
                [hi[0], lo[1]],
                [hi[0], hi[1]],
                [lo[0], hi[1]],
            ],
            view: None,
            tiles: HashMap::new(),
            sent,
            fetched,
            requested: Vec::new(),
        };
        if let Some(t) = template {
            m.set(t);
        }
        m
    }

    fn set(&mut self, template: String) {
        self.tiles.clear();
        self.view = None;
        if let Err(e) = myriad_measure::map::check_template(&template) {
            eprintln!("warning: --map-tiles {e}");
            self.template = None;
            return;
        }
        if let Ok(g) = &self.georef {
            let m: Vec<[f64; 2]> = self
                .footprint
                .iter()
                .map(|p| g.to_unit(p[0], p[1]))
                .collect();
            let lo = [
                m.iter().map(|p| p[0]).fold(f64::MAX, f64::min),
                m.iter().map(|p| p[1]).fold(f64::MAX, f64::min),
            ];
            let hi = [
                m.iter().map(|p| p[0]).fold(f64::MIN, f64::max),
                m.iter().map(|p| p[1]).fold(f64::MIN, f64::max),
            ];
            self.view = Some(MapView::fitting(lo, hi, SIDE as f64, SIDE as f64));
        }
        self.template = Some(template);
    }

    /// Whether `pos` (in points) is on the map drawn over `rect`: clicks there are the map's.
    pub fn covers(&self, rect: egui::Rect, pos: egui::Pos2) -> bool {
        self.template.is_some()
            && egui::Rect::from_min_size(
                rect.right_top() + egui::vec2(-SIDE - 8.0, 8.0),
                egui::vec2(SIDE, SIDE),
            )
            .contains(pos)
    }

    /// No tile still being fetched.
    pub fn settled(&self) -> bool {
        !self.tiles.values().any(|t| matches!(t, Tile::Loading))
    }

    /// The panel's box for the tile address.
    pub fn panel(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            ui.label("map tiles");
            let r = ui.add(
                egui::TextEdit::singleline(&mut self.typed).hint_text("https://…/{z}/{x}/{y}.png"),
            );
            if r.lost_focus() && self.template.as_deref() != Some(self.typed.trim()) {
                let t = self.typed.trim().to_string();
                if t.is_empty() {
                    self.template = None;
                } else {
                    self.set(t);
                }
            }
        });
    }

    fn fetch(&mut self, ctx: &egui::Context, key: Key, url: String) {
        println!("map tile: {url}");
        self.requested.push(url.clone());
        self.tiles.insert(key, Tile::Loading);
        let (sent, ctx) = (self.sent.clone(), ctx.clone());
        std::thread::spawn(move || {
            let got = (|| -> Result<egui::ColorImage, String> {
                // A tile that does not come within 20 s is given up (the view converges).
                let agent: ureq::Agent = ureq::Agent::config_builder()
                    .timeout_global(Some(std::time::Duration::from_secs(20)))
                    .build()
                    .into();
                let body = agent
                    .get(&url)
                    .call()
                    .map_err(|e| e.to_string())?
                    .into_body()
                    .with_config()
                    .limit(8 << 20)
                    .read_to_vec()
                    .map_err(|e| e.to_string())?;
                let img = image::load_from_memory(&body).map_err(|e| e.to_string())?;
                if img.width() > 1024 || img.height() > 1024 {
                    return Err(format!(
                        "a tile of {}x{}: at most 1024 pixels a side",
                        img.width(),
                        img.height()
                    ));
                }
                let img = img.to_rgba8();
                let size = [img.width() as usize, img.height() as usize];
                Ok(egui::ColorImage::from_rgba_unmultiplied(size, img.as_raw()))
            })();
            let _ = sent.send((key, got));
            ctx.request_repaint();
        });
    }

    /// Draws the map in `rect`'s top right corner seen from `cam`; a click there gives the
    /// place in the dataset's plan the camera goes to.
    pub fn draw(
        &mut self,
        ui: &egui::Ui,
        rect: egui::Rect,
        response: &egui::Response,
        cam: &Camera,
    ) -> Option<[f64; 2]> {
        let template = self.template.clone()?;
        let area = egui::Rect::from_min_size(
            rect.right_top() + egui::vec2(-SIDE - 8.0, 8.0),
            egui::vec2(SIDE, SIDE),
        );
        let painter = ui.painter().with_clip_rect(area);
        painter.rect_filled(area, 0.0, egui::Color32::from_gray(40));
        let font = egui::FontId::monospace(11.0);
        let ink = egui::Color32::from_rgb(20, 20, 20);
        let (g, view) = match (&self.georef, self.view) {
            (Ok(g), Some(v)) => (*g, v),
            (Err(why), _) => {
                painter.text(
                    area.left_top() + egui::vec2(8.0, 8.0),
                    egui::Align2::LEFT_TOP,
                    format!("map off: {why}"),
                    font,
                    egui::Color32::LIGHT_GRAY,
                );
                return None;
            }
            _ => return None,
        };
        while let Ok((key, got)) = self.fetched.try_recv() {
            let t = match got {
                Ok(img) => Tile::Ready(ui.ctx().load_texture(
                    format!("tile {key:?}"),
                    img,
                    egui::TextureOptions::LINEAR,
                )),
                Err(e) => {
                    eprintln!("warning: map tile {key:?}: {e}");
                    Tile::Failed
                }
            };
            self.tiles.insert(key, t);
        }
        let at = |p: [f64; 2]| area.left_top() + egui::vec2(p[0] as f32, p[1] as f32);
        for (x, y, corner) in view.tiles() {
            let key = (view.zoom, x, y);
            if !self.tiles.contains_key(&key) {
                self.fetch(ui.ctx(), key, tile_url(&template, view.zoom, x, y));
            }
            if let Some(Tile::Ready(t)) = self.tiles.get(&key) {
                let r = egui::Rect::from_min_size(at(corner), egui::vec2(SIDE, SIDE));
                painter.image(
                    t.id(),
                    r,
                    egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0)),
                    egui::Color32::WHITE,
                );
            }
        }
        let px = |x: f64, y: f64| at(view.to_px(g.to_unit(x, y)));
        let outline: Vec<egui::Pos2> = self.footprint.iter().map(|p| px(p[0], p[1])).collect();
        painter.add(egui::Shape::closed_line(
            outline,
            egui::Stroke::new(2.0, egui::Color32::from_rgb(255, 210, 0)),
        ));
        // The camera and its view cone.
        let (eye, target) = (
            px(cam.position[0], cam.position[1]),
            px(cam.target[0], cam.target[1]),
        );
        let d = target - eye;
        let heading = d.y.atan2(d.x);
        let half =
            (cam.fov_y as f32 / 2.0).to_radians() * cam.width as f32 / cam.height.max(1) as f32;
        let reach = d.length().max(20.0);
        let side = |a: f32| eye + reach * egui::vec2(a.cos(), a.sin());
        painter.add(egui::Shape::convex_polygon(
            vec![eye, side(heading - half), side(heading + half)],
            egui::Color32::from_rgba_unmultiplied(80, 200, 255, 90),
            egui::Stroke::NONE,
        ));
        painter.circle_filled(eye, 4.0, egui::Color32::from_rgb(80, 200, 255));
        // North up; a scale bar; the cursor's latitude and longitude.
        painter.text(
            area.right_top() + egui::vec2(-6.0, 4.0),
            egui::Align2::RIGHT_TOP,
            "N ↑",
            font.clone(),
            ink,
        );
        let (_, lat) = from_unit(view.centre);
        let per_px = metres_per_unit(lat) / view.scale();
        let km = |len: f64| {
            if len >= 1000.0 {
                format!("{} km", len / 1000.0)
            } else {
                format!("{len} m")
            }
        };
        crate::legend::scale_bar(
            &painter,
            area.left_bottom() + egui::vec2(12.0, -10.0),
            per_px,
            80.0,
            &km,
        );
        let hover = response.hover_pos().filter(|p| area.contains(*p));
        if let Some(p) = hover {
            let m = view.from_px([(p.x - area.left()) as f64, (p.y - area.top()) as f64]);
            let (lon, lat) = from_unit(m);
            painter.text(
                area.right_bottom() + egui::vec2(-4.0, -4.0),
                egui::Align2::RIGHT_BOTTOM,
                format!("{lat:.5}, {lon:.5}"),
                font,
                ink,
            );
        }
        let clicked = response
            .clicked()
            .then(|| response.interact_pointer_pos())
            .flatten();
        clicked.filter(|p| area.contains(*p)).map(|p| {
            g.from_unit(view.from_px([(p.x - area.left()) as f64, (p.y - area.top()) as f64]))
        })
    }
}
