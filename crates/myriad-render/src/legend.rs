//! What a picture needs to be read: labelled axes on a profile (distance along, elevation, the
//! unit, the vertical exaggeration), a scale bar on a parallel view, a legend for a gradient
//! colouring. Drawn into RGBA8 images on the CPU (the PNGs `profile` and `render --legend`
//! write); text through `ab_glyph` with the Hack font egui ships (`epaint_default_fonts`), so
//! no font is looked for on the machine.

use ab_glyph::{Font, FontRef, PxScale, ScaleFont};
use myriad_core::colour::Gradient;
use myriad_measure::profile::{Profile, nice_step};

/// An RGBA8 image being drawn on.
pub struct Canvas<'a> {
    pub width: u32,
    pub height: u32,
    pub px: &'a mut [u8],
}

/// Where a text's point is: its left, its centre or its right, at its baseline's middle.
#[derive(Clone, Copy, PartialEq)]
pub enum Anchor {
    Left,
    Centre,
    Right,
}

fn font() -> FontRef<'static> {
    FontRef::try_from_slice(epaint_default_fonts::HACK_REGULAR).expect("egui's Hack font")
}

impl Canvas<'_> {
    fn blend(&mut self, x: i64, y: i64, c: [u8; 3], a: f32) {
        if x < 0 || y < 0 || x >= self.width as i64 || y >= self.height as i64 || a <= 0.0 {
            return;
        }
        let at = ((y as u32 * self.width + x as u32) * 4) as usize;
        for k in 0..3 {
            let v = self.px[at + k] as f32 * (1.0 - a) + c[k] as f32 * a;
            self.px[at + k] = v.round() as u8;
        }
        self.px[at + 3] = 255;
    }

    /// A filled rectangle.
    pub fn rect(&mut self, x0: i64, y0: i64, x1: i64, y1: i64, c: [u8; 3], alpha: f32) {
        for y in y0..y1 {
            for x in x0..x1 {
                self.blend(x, y, c, alpha);
            }
        }
    }

    /// The width `text` takes at `size` pixels.
    pub fn text_width(text: &str, size: f32) -> f32 {
        let f = font();
        let s = f.as_scaled(PxScale::from(size));
        text.chars().map(|ch| s.h_advance(f.glyph_id(ch))).sum()
    }

    /// `text` at `size` pixels, its baseline's middle at `y`, anchored at `x`.
    pub fn text(&mut self, x: f32, y: f32, size: f32, c: [u8; 3], anchor: Anchor, text: &str) {
        let f = font();
        let scaled = f.as_scaled(PxScale::from(size));
        let w = Canvas::text_width(text, size);
        let mut pen = match anchor {
            Anchor::Left => x,
            Anchor::Centre => x - w / 2.0,
            Anchor::Right => x - w,
        };
        let base = y + (scaled.ascent() - scaled.ascent().abs() * 0.3) / 2.0;
        for ch in text.chars() {
            let id = f.glyph_id(ch);
            let glyph = id.with_scale_and_position(size, ab_glyph::point(pen, base));
            pen += scaled.h_advance(id);
            if let Some(o) = f.outline_glyph(glyph) {
                let b = o.px_bounds();
                let mut dots = Vec::new();
                o.draw(|gx, gy, a| {
                    dots.push((b.min.x as i64 + gx as i64, b.min.y as i64 + gy as i64, a))
                });
                for (px, py, a) in dots {
                    self.blend(px, py, c, a);
                }
            }
        }
    }

    /// `text` on a pale box, for reading over points.
    pub fn label(&mut self, x: f32, y: f32, size: f32, anchor: Anchor, text: &str) {
        let w = Canvas::text_width(text, size);
        let left = match anchor {
            Anchor::Left => x,
            Anchor::Centre => x - w / 2.0,
            Anchor::Right => x - w,
        };
        let pad = size * 0.25;
        self.rect(
            (left - pad) as i64,
            (y - size * 0.55) as i64,
            (left + w + pad).ceil() as i64,
            (y + size * 0.55).ceil() as i64,
            [255, 255, 255],
            0.8,
        );
        self.text(x, y, size, [20, 20, 20], anchor, text);
    }
}

/// A number as a label: no more decimals than `step` needs.
pub fn number(v: f64, step: f64) -> String {
    let d = (-step.abs().max(1e-9).log10()).ceil().clamp(0.0, 9.0) as usize;
    let s = format!("{v:.d$}");
    if s.trim_start_matches('-')
        .chars()
        .all(|c| c == '0' || c == '.')
    {
        format!("{:.d$}", 0.0)
    } else {
        s
    }
}

/// The pixels left of a labelled profile's picture and below it.
pub const PROFILE_GUTTER: (u32, u32) = (64, 40);

/// The profile drawn `width` pixels wide in all, with labelled axes: the distances along
/// below, the elevations to the left, both in `units`, and the vertical exaggeration where
/// it is not 1. RGBA rows, the height, and the exaggeration.
pub fn labelled_profile(p: &Profile, width: u32, units: &str) -> (u32, u32, Vec<u8>, f64) {
    let (gx, gy) = PROFILE_GUTTER;
    let inner = width.saturating_sub(gx).max(64);
    let (pw, ph, plot, exaggeration) = p.plot(inner);
    let frame = p.frame(inner);
    let (w, h) = (pw + gx, ph + gy);
    let mut px = vec![250u8; (w * h * 4) as usize];
    for y in 0..ph {
        let from = (y * pw * 4) as usize;
        let to = ((y * w + gx) * 4) as usize;
        px[to..to + (pw * 4) as usize].copy_from_slice(&plot[from..from + (pw * 4) as usize]);
    }
    let mut c = Canvas {
        width: w,
        height: h,
        px: &mut px,
    };
    let ink = [40, 40, 40];
    let (along, heights) = p.grid(inner);
    let step_along = nice_step(p.length / 10.0);
    let (z0, z1) = p.z_range();
    let step_z = nice_step((z1 - z0).max(1e-3) / 5.0);
    let size = 12.0;
    let bottom = (frame.margin + frame.inner_h) as f32;
    for (i, g) in along.iter().enumerate() {
        let (x, _) = frame.to_px(*g, z0);
        let x = x as f32 + gx as f32;
        c.rect(
            x as i64,
            bottom as i64,
            x as i64 + 1,
            bottom as i64 + 5,
            ink,
            1.0,
        );
        // Every other label where they would crowd.
        if along.len() > 8 && i % 2 == 1 {
            continue;
        }
        c.text(
            x,
            bottom + 14.0,
            size,
            ink,
            Anchor::Centre,
            &number(*g, step_along),
        );
    }
    for g in &heights {
        let (_, y) = frame.to_px(0.0, *g);
        let left = gx as f32 + frame.margin as f32;
        c.rect(
            left as i64 - 5,
            y as i64,
            left as i64,
            y as i64 + 1,
            ink,
            1.0,
        );
        c.text(
            left - 8.0,
            y as f32,
            size,
            ink,
            Anchor::Right,
            &number(*g, step_z),
        );
    }
    let mut caption = format!("distance along ({units})");
    if (exaggeration - 1.0).abs() > 0.005 {
        caption.push_str(&format!(", vertical exaggeration {exaggeration:.2}x"));
    }
    c.text(
        gx as f32 + pw as f32 / 2.0,
        h as f32 - 9.0,
        size,
        ink,
        Anchor::Centre,
        &caption,
    );
    c.text(
        4.0,
        10.0,
        size,
        ink,
        Anchor::Left,
        &format!("elevation ({units})"),
    );
    (w, h, px, exaggeration)
}

/// A scale bar's length near `want`: 1, 2 or 5 times a power of ten (2.5 where 5 would pass
/// half as much again).
pub fn bar_length(want: f64) -> f64 {
    let len = nice_step(want);
    if len > want * 1.5 { len / 2.0 } else { len }
}

/// A scale bar at the bottom left of an image whose pixels are `per_pixel` units wide (a
/// parallel view): a round length of about a fifth of the width, labelled in `units`.
pub fn scale_bar(c: &mut Canvas, per_pixel: f64, units: &str) {
    if !(per_pixel.is_finite() && per_pixel > 0.0) {
        return;
    }
    let len = bar_length(per_pixel * c.width as f64 / 5.0);
    let bar = (len / per_pixel).round() as i64;
    let (x0, y0) = (16i64, c.height as i64 - 20);
    c.rect(x0 - 6, y0 - 22, x0 + bar + 6, y0 + 12, [255, 255, 255], 0.8);
    c.rect(x0, y0, x0 + bar, y0 + 4, [20, 20, 20], 1.0);
    c.rect(x0, y0 - 6, x0 + 2, y0 + 4, [20, 20, 20], 1.0);
    c.rect(x0 + bar - 2, y0 - 6, x0 + bar, y0 + 4, [20, 20, 20], 1.0);
    let text = format!("{} {units}", number(len, len));
    c.text(
        (x0 + bar / 2) as f32,
        y0 as f32 - 11.0,
        13.0,
        [20, 20, 20],
        Anchor::Centre,
        &text,
    );
}

/// A legend for a gradient colouring at the bottom right: the gradient from `range[0]` (left)
/// to `range[1]`, both labelled, under `name`.
pub fn gradient_legend(c: &mut Canvas, gradient: Gradient, range: [f64; 2], name: &str) {
    let bar_w = (c.width as i64 / 4).clamp(80, 320);
    let (x1, y0) = (c.width as i64 - 16, c.height as i64 - 30);
    let x0 = x1 - bar_w;
    c.rect(x0 - 8, y0 - 24, x1 + 8, y0 + 26, [255, 255, 255], 0.8);
    for x in x0..x1 {
        let t = (x - x0) as f64 / (bar_w - 1).max(1) as f64;
        c.rect(x, y0, x + 1, y0 + 10, gradient.at(t), 1.0);
    }
    let step = nice_step((range[1] - range[0]).abs().max(1e-9) / 10.0);
    let ink = [20, 20, 20];
    c.text(
        x0 as f32,
        y0 as f32 + 20.0,
        12.0,
        ink,
        Anchor::Left,
        &number(range[0], step),
    );
    c.text(
        x1 as f32,
        y0 as f32 + 20.0,
        12.0,
        ink,
        Anchor::Right,
        &number(range[1], step),
    );
    c.text(
        ((x0 + x1) / 2) as f32,
        y0 as f32 - 12.0,
        12.0,
        ink,
        Anchor::Centre,
        name,
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_and_bars_are_drawn_where_asked() {
        let (w, h) = (200u32, 100u32);
        let mut px = vec![0u8; (w * h * 4) as usize];
        let mut c = Canvas {
            width: w,
            height: h,
            px: &mut px,
        };
        c.text(10.0, 20.0, 14.0, [255, 255, 255], Anchor::Left, "123 m");
        let lit = |px: &[u8], x0: u32, x1: u32, y0: u32, y1: u32| {
            let mut n = 0;
            for y in y0..y1 {
                for x in x0..x1 {
                    n += (px[((y * w + x) * 4) as usize] > 128) as usize;
                }
            }
            n
        };
        assert!(lit(&px, 10, 60, 10, 30) > 30, "the text's pixels");
        assert_eq!(lit(&px, 100, 200, 0, 100), 0, "nothing beyond it");
        assert_eq!(number(12.5, 0.5), "12.5");
        assert_eq!(number(-0.0001, 10.0), "0");
        assert_eq!(number(250.0, 50.0), "250");
        let mut px = vec![0u8; (w * h * 4) as usize];
        let mut c = Canvas {
            width: w,
            height: h,
            px: &mut px,
        };
        // 0.5 units a pixel: a fifth of 200 pixels is 20 units, a bar of 20 (40 pixels).
        scale_bar(&mut c, 0.5, "m");
        let dark = (0..w)
            .filter(|&x| {
                let at = (((h - 18) * w + x) * 4) as usize;
                px[at] == 20
            })
            .count();
        assert_eq!(dark, 40, "a bar of 20 m at 0.5 m a pixel");
    }
}
