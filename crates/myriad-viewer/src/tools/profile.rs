//! Cross-sections in the window: a line clicked on the data (X, then points; a right click or
//! "cut" cuts) and a width give the profile of the first visible dataset's original points in
//! that corridor (`myriad_measure::profile`, as `myriad profile` cuts it, on a thread of its
//! own), shown in a window of its own: distance along the line against height, coloured as the
//! view. Two clicks in it measure along, in height, the slope and straight; its points save as
//! CSV, DXF, PNG or LAZ in the current folder, never over a file. One asked for on the command
//! line (`view --section`) is cut on the first frame.

use crate::shown::Layers;
use eframe::egui;
use myriad_core::Aabb;
use myriad_format::Dataset;
use myriad_measure::profile::{Frame, Profile, between};
use myriad_measure::{Corridor, Filter};
use myriad_render::ColorBy;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, channel};

/// The section line's colour in the view.
pub const LINE: egui::Color32 = egui::Color32::from_rgb(0, 220, 255);
/// Pixels across of the profile's picture.
const PICTURE: u32 = 640;

struct Shown {
    profile: Profile,
    corridor: Corridor,
    frame: Frame,
    texture: Option<egui::TextureHandle>,
    rgba: Vec<u8>,
    /// Points clicked in the picture: (distance along, elevation).
    picks: Vec<[f64; 2]>,
    said: Option<String>,
}

pub(crate) struct Section {
    /// Whether clicks add points to the line.
    pub drawing: bool,
    pub line: Vec<[f64; 3]>,
    pub width: f64,
    job: Option<Receiver<Result<(Profile, Corridor), String>>>,
    shown: Option<Shown>,
    pub problem: Option<String>,
    /// The dataset's name, for the files saved; its units.
    name: String,
    units: &'static str,
    saves: u32,
    /// The line in plan and the width asked for on the command line, cut on the first frame.
    asked: Option<(Vec<[f64; 2]>, f64)>,
}

impl Section {
    /// `spacing`: the data's point spacing (the width starts at four of it).
    pub fn new(name: &str, units: &'static str, spacing: f64) -> Section {
        Section {
            asked: None,
            drawing: false,
            line: Vec::new(),
            width: (4.0 * spacing).max(1e-3),
            job: None,
            shown: None,
            problem: None,
            name: name.to_string(),
            units,
            saves: 0,
        }
    }

    /// The tool for the first of `layers` (its name and spacing; `crs`: its units), `asked`
    /// (a line in plan and a width) to cut on the first frame.
    pub fn first(
        layers: &Layers,
        crs: Option<&str>,
        asked: Option<(Vec<[f64; 2]>, f64)>,
    ) -> Section {
        let first = &layers.list[0];
        let m = &first.dataset.meta;
        let s = m.bounds.size();
        let spacing = (s[0] * s[1] / m.points.max(1) as f64).sqrt();
        let stem = std::path::Path::new(&first.name)
            .file_stem()
            .map_or_else(|| "view".into(), |n| n.to_string_lossy().into_owned());
        let units = myriad_measure::measurement::crs_units(crs);
        Section {
            asked,
            ..Section::new(&stem, units, spacing)
        }
    }

    /// The line asked for on the command line, at the top of `bounds` (the data's extent), cut
    /// across `layers` (once).
    pub fn start(&mut self, bounds: &Aabb, layers: &Layers) {
        if let Some((line, width)) = self.asked.take() {
            let z = bounds.max[2];
            self.line = line.iter().map(|p| [p[0], p[1], z]).collect();
            self.width = width;
            self.cut_first(layers);
        }
    }

    /// Cuts the section line drawn across the first visible dataset of `layers`, drawing what
    /// they draw in their colours.
    pub fn cut_first(&mut self, layers: &Layers) {
        let filter = layers.filter();
        if let Some(l) = layers.first_visible() {
            self.cut(l.dataset.clone(), &filter, layers.colour);
        }
    }

    /// Cuts the profile along the line so far, on a thread of its own.
    pub fn cut(&mut self, ds: Arc<Dataset>, filter: &Filter, colour: ColorBy) {
        self.drawing = false;
        let plan: Vec<[f64; 2]> = self.line.iter().map(|p| [p[0], p[1]]).collect();
        let corridor = match Corridor::new(&plan, self.width) {
            Ok(c) => c,
            Err(e) => {
                self.problem = Some(e);
                return;
            }
        };
        let bound = match filter.bind(&ds.meta.schema) {
            Ok(b) => b,
            Err(e) => {
                self.problem = Some(e);
                return;
            }
        };
        let (tx, rx) = channel();
        std::thread::spawn(move || {
            let p = myriad_measure::profile::profile(&ds, &corridor, &bound, colour);
            let _ = tx.send(p.map(|p| (p, corridor)));
        });
        self.problem = None;
        self.job = Some(rx);
    }

    /// Whether a profile is being cut.
    pub fn busy(&self) -> bool {
        self.job.is_some()
    }

    fn take(&mut self) {
        let Some(rx) = &self.job else { return };
        let Ok(done) = rx.try_recv() else { return };
        self.job = None;
        match done {
            Ok((profile, _)) if profile.is_empty() => {
                self.problem = Some(
                    "the corridor holds no point: the line is off the data, or the width too small"
                        .into(),
                );
            }
            Ok((profile, corridor)) => {
                let (_, _, rgba, _) = profile.plot(PICTURE);
                self.shown = Some(Shown {
                    frame: profile.frame(PICTURE),
                    profile,
                    corridor,
                    texture: None,
                    rgba,
                    picks: Vec::new(),
                    said: None,
                });
            }
            Err(e) => self.problem = Some(e),
        }
    }

    /// Starts drawing a section line anew (`on`), or stops drawing it.
    pub fn draw_line(&mut self, on: bool) {
        self.drawing = on;
        if on {
            self.line.clear();
        }
    }

    /// The panel's part: the line tool, the width, the cut.
    pub fn panel(&mut self, ui: &mut egui::Ui) -> bool {
        ui.label("profile");
        let mut cut = false;
        ui.horizontal(|ui| {
            if ui
                .selectable_label(self.drawing, "line (X)")
                .on_hover_text("click points of the section line; a right click cuts")
                .clicked()
            {
                self.draw_line(!self.drawing);
            }
            ui.add(
                egui::DragValue::new(&mut self.width)
                    .range(1e-3..=1e6)
                    .speed(0.05)
                    .prefix("width "),
            );
            if ui
                .add_enabled(
                    self.line.len() >= 2 && !self.busy(),
                    egui::Button::new("cut"),
                )
                .clicked()
            {
                cut = true;
            }
        });
        if self.busy() {
            ui.horizontal(|ui| {
                ui.spinner();
                ui.label("cutting…");
            });
        }
        if let Some(p) = &self.problem {
            ui.colored_label(egui::Color32::LIGHT_RED, p);
        }
        cut
    }

    /// The section line over the view.
    pub fn draw(&self, painter: &egui::Painter, screen: &dyn Fn([f64; 3]) -> Option<egui::Pos2>) {
        let pts: Vec<Option<egui::Pos2>> = self.line.iter().map(|&p| screen(p)).collect();
        for w in pts.windows(2) {
            if let [Some(a), Some(b)] = w {
                painter.line_segment([*a, *b], egui::Stroke::new(2.0, LINE));
            }
        }
        for p in pts.iter().flatten() {
            painter.circle_filled(*p, 3.5, LINE);
        }
    }

    /// The profile's window, once cut.
    pub fn window(&mut self, ctx: &egui::Context, ds: Option<&Dataset>, filter: &Filter) {
        self.take();
        let Some(s) = &mut self.shown else { return };
        let mut open = true;
        let (units, name) = (self.units, self.name.clone());
        let mut save = None;
        egui::Window::new("profile")
            .open(&mut open)
            .default_pos([300.0, 60.0])
            .default_width(PICTURE as f32 + 16.0)
            .show(ctx, |ui| {
                let p = &s.profile;
                let (z0, z1) = p.z_range();
                ui.label(format!(
                    "{} points within {} {units} of a {:.3} {units} line, elevation {z0:.3} to {z1:.3}, vertical exaggeration {:.2}",
                    p.len(),
                    p.width / 2.0,
                    p.length,
                    s.frame.exaggeration
                ));
                let texture = s.texture.get_or_insert_with(|| {
                    let img = egui::ColorImage::from_rgba_unmultiplied(
                        [s.frame.width as usize, s.frame.height as usize],
                        &s.rgba,
                    );
                    ctx.load_texture("profile", img, egui::TextureOptions::NEAREST)
                });
                let fit = ui.available_width().max(200.0) * ctx.pixels_per_point()
                    / s.frame.width as f32;
                let size = egui::vec2(s.frame.width as f32, s.frame.height as f32) * fit.min(1.0)
                    / ctx.pixels_per_point();
                let response = ui.add(
                    egui::Image::new((texture.id(), size)).sense(egui::Sense::click()),
                );
                let rect = response.rect;
                let k = s.frame.width as f64 / rect.width() as f64;
                if response.clicked()
                    && let Some(at) = response.interact_pointer_pos()
                {
                    if s.picks.len() >= 2 {
                        s.picks.clear();
                    }
                    let (x, y) = ((at.x - rect.min.x) as f64 * k, (at.y - rect.min.y) as f64 * k);
                    s.picks.push(s.frame.from_px(x, y));
                }
                let to_screen = |q: [f64; 2]| {
                    let (x, y) = s.frame.to_px(q[0], q[1]);
                    rect.min + egui::vec2((x / k) as f32, (y / k) as f32)
                };
                let painter = ui.painter_at(rect);
                axis_labels(&painter, rect, p, &s.frame, units, &to_screen);
                let colour = egui::Color32::from_rgb(200, 0, 120);
                for q in &s.picks {
                    painter.circle_filled(to_screen(*q), 4.0, colour);
                }
                if let [a, b] = s.picks[..] {
                    painter.line_segment([to_screen(a), to_screen(b)], egui::Stroke::new(2.0, colour));
                    ui.monospace(between(a, b, units));
                } else {
                    ui.small("click two points of the profile to measure between them");
                }
                ui.horizontal(|ui| {
                    for ext in ["csv", "dxf", "png", "laz"] {
                        if ui.button(format!("save .{ext}")).clicked() {
                            save = Some(ext);
                        }
                    }
                });
                if let Some(said) = &s.said {
                    ui.small(said);
                }
            });
        if let Some(ext) = save {
            self.saves += 1;
            let said = save_profile(s, &name, self.saves, ext, ds, filter);
            s.said = Some(said);
        }
        if !open {
            self.shown = None;
        }
    }

    /// Whether a profile is shown (tests: the screenshot waits for it).
    pub fn settled(&self) -> bool {
        self.job.is_none()
    }
}

/// Writes the profile to the first free `NAME-profile-N.EXT` in the current folder; what
/// happened, in a line.
fn save_profile(
    s: &Shown,
    name: &str,
    from: u32,
    ext: &str,
    ds: Option<&Dataset>,
    filter: &Filter,
) -> String {
    let path = (from..from + 1000)
        .map(|n| PathBuf::from(format!("{name}-profile-{n}.{ext}")))
        .find(|p| !p.exists())
        .unwrap_or_else(|| PathBuf::from(format!("{name}-profile.{ext}")));
    let p = &s.profile;
    let done = match ext {
        "csv" => myriad_measure::files::write_atomic(&path, false, |w| p.write_csv(w)),
        "dxf" => myriad_measure::files::profile_drawing(p, &s.corridor)
            .and_then(|d| myriad_measure::files::save_drawing(&d, &path, false)),
        // The picture with its axes labelled, as `myriad profile -o .png` writes it.
        "png" => myriad_io::atomic::AtomicFile::create(&path, false).and_then(|f| {
            let units =
                myriad_measure::measurement::crs_units(ds.and_then(|d| d.meta.crs.as_deref()));
            let (w, h, rgba, _) = myriad_render::legend::labelled_profile(p, PICTURE, units);
            myriad_io::image::write_png(f.temp_path(), w, h, &rgba)?;
            f.commit()
        }),
        _ => match ds {
            None => Err(myriad_core::Error::Invalid("no dataset".into())),
            Some(ds) => myriad_build::extract::extract(
                ds,
                &path,
                &myriad_build::extract::ExtractOptions {
                    region: Some(Arc::new(s.corridor.clone())),
                    filter: filter.clone(),
                    ..Default::default()
                },
            )
            .map(|_| ()),
        },
    };
    match done {
        Ok(()) => format!("{}: written", path.display()),
        Err(e) => format!("error: {e}"),
    }
}

/// The profile's grid lines labelled over its picture (`rect`, `to_screen` from distance along
/// and elevation): distances along its foot, elevations at its left, the unit, the vertical
/// exaggeration.
fn axis_labels(
    painter: &egui::Painter,
    rect: egui::Rect,
    p: &myriad_measure::profile::Profile,
    frame: &myriad_measure::profile::Frame,
    units: &str,
    to_screen: &dyn Fn([f64; 2]) -> egui::Pos2,
) {
    use myriad_measure::profile::nice_step;
    use myriad_render::legend::number;
    let font = egui::FontId::monospace(11.0);
    let ink = egui::Color32::from_rgb(40, 40, 40);
    let (z0, z1) = p.z_range();
    let (along, heights) = p.grid(frame.width);
    let (sa, sz) = (
        nice_step(p.length / 10.0),
        nice_step((z1 - z0).max(1e-3) / 5.0),
    );
    for (i, g) in along.iter().enumerate() {
        if along.len() > 8 && i % 2 == 1 {
            continue;
        }
        let at = to_screen([*g, z0]);
        painter.text(
            at + egui::vec2(0.0, -2.0),
            egui::Align2::CENTER_BOTTOM,
            number(*g, sa),
            font.clone(),
            ink,
        );
    }
    for z in &heights {
        let at = egui::pos2(rect.left() + 4.0, to_screen([0.0, *z]).y);
        painter.text(
            at,
            egui::Align2::LEFT_BOTTOM,
            number(*z, sz),
            font.clone(),
            ink,
        );
    }
    let mut caption = format!("distance along ({units})");
    if (frame.exaggeration - 1.0).abs() > 0.005 {
        caption.push_str(&format!(
            ", vertical exaggeration {:.2}x",
            frame.exaggeration
        ));
    }
    painter.text(
        rect.right_top() + egui::vec2(-4.0, 2.0),
        egui::Align2::RIGHT_TOP,
        caption,
        font.clone(),
        ink,
    );
    painter.text(
        rect.left_top() + egui::vec2(4.0, 2.0),
        egui::Align2::LEFT_TOP,
        format!("elevation ({units})"),
        font,
        ink,
    );
}
