//! Screenshots: the one asked for on the command line (`view --screenshot`, what the tests
//! compare with `render`'s image), written once the view has converged, the window closed after
//! it where asked; and those saved from the panel or with P (myriad-screenshot-N.png).

use crate::report::write_png;
use eframe::egui;
use std::path::PathBuf;

pub(crate) struct Shots {
    /// Write the window to this PNG once the view has converged, and close it then.
    path: Option<PathBuf>,
    exit_after: bool,
    requested: bool,
    /// The view's rectangle in the window, pixels: left, top, width, height.
    view_px: [u32; 4],
    /// Screenshots saved from the panel.
    saved: u32,
}

impl Shots {
    pub fn new(path: Option<PathBuf>, exit_after: bool) -> Shots {
        Shots {
            path,
            exit_after,
            requested: false,
            view_px: [0; 4],
            saved: 0,
        }
    }

    /// Where the view is in the window: `rect` in points, `ppp` pixels a point, `w` x `h`
    /// pixels.
    pub fn view_at(&mut self, rect: egui::Rect, ppp: f32, (w, h): (u32, u32)) {
        self.view_px = [
            (rect.left() * ppp).round() as u32,
            (rect.top() * ppp).round() as u32,
            w,
            h,
        ];
    }

    /// Saves the window as myriad-screenshot-N.png in the current folder.
    pub fn now(&mut self, ctx: &egui::Context) {
        self.saved += 1;
        let path = PathBuf::from(format!("myriad-screenshot-{}.png", self.saved));
        ctx.request_screenshot(move |image| match write_png(&path, &image) {
            Ok(()) => println!("{}: screenshot written", path.display()),
            Err(e) => eprintln!("error: {}: {e}", path.display()),
        });
    }

    /// The command line's screenshot, once the view has been converged for two frames
    /// (`settled`), and the window closed after it where asked.
    pub fn when_settled(&mut self, ctx: &egui::Context, settled: u32) {
        if settled >= 2
            && !self.requested
            && let Some(path) = self.path.clone()
        {
            self.requested = true;
            let exit = self.exit_after;
            let c = ctx.clone();
            let [x, y, w, h] = self.view_px;
            ctx.request_screenshot(move |image| {
                if let Err(e) = write_png(&path, &image) {
                    eprintln!("error: {}: {e}", path.display());
                } else {
                    // Where the view is in it (tests compare it with `render`'s image).
                    let path = path.display();
                    println!("{path}: screenshot written (the view {w}x{h} at {x},{y})");
                }
                if exit {
                    c.send_viewport_cmd(egui::ViewportCommand::Close);
                }
                c.request_repaint();
            });
        }
    }
}
