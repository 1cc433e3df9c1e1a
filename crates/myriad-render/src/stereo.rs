//! Stereo (Discher et al. 2018): two eyes' images of one selection, side by side.
//!
//! - Single-pass stereo (Discher et al. 2018, section 4.3): each point decoded once and projected
//!   into both eyes' images: on the CPU path into each eye's framebuffer (`cpu::gbuffers`), on the
//!   compute path by one dispatch into a frame twice as wide (compute.wgsl's `draw_point` per eye,
//!   each eye's pixels clipped to its half), so a point at an eye's border never reaches the other
//!   eye's image; on the quad path by one instanced draw of twice the points, each square clamped
//!   to its eye's columns. Two passes (one frame per eye) are the baseline.
//! - The hidden-area mask (Discher et al. 2018, section 4.1): the pixels a lens cannot show: a
//!   headset runtime's own triangles (`triangles_mask`), else those outside the ellipse inscribed
//!   in an eye's image (a lens shows a disc). The CPU's point pass and post passes skip them; every
//!   path leaves them black.

use crate::{Draw, Gpu, Path, Rasterizer, Style};
use myriad_lod::Camera;

/// How a stereo frame is drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stereo {
    /// Distance between the eyes, in the data's units.
    pub ipd: f64,
    /// Both eyes in one pass over the points (else a frame per eye).
    pub single_pass: bool,
    /// Mask the pixels the lens cannot show.
    pub hidden_area: bool,
}

impl Default for Stereo {
    fn default() -> Stereo {
        Stereo {
            ipd: 0.064,
            single_pass: true,
            hidden_area: false,
        }
    }
}

/// Per pixel of a `width` x `height` eye image, row by row, whether it is hidden: its centre
/// outside the ellipse inscribed in the image.
pub fn hidden_area(width: u32, height: u32) -> Vec<bool> {
    use rayon::prelude::*;
    let (a, b) = (width as f64 / 2.0, height as f64 / 2.0);
    (0..width as usize * height as usize)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % width as usize, i / width as usize);
            let dx = (x as f64 + 0.5 - a) / a;
            let dy = (y as f64 + 0.5 - b) / b;
            dx * dx + dy * dy > 1.0
        })
        .collect()
}

/// Per pixel of a `width` x `height` image, row by row, whether its centre lies in one of
/// `triangles` (pixel coordinates: x right, y down, the image's corner at 0, 0; either winding):
/// a headset runtime's hidden-area mesh (XR_KHR_visibility_mask) as a mask.
pub fn triangles_mask(width: u32, height: u32, triangles: &[[[f64; 2]; 3]]) -> Vec<bool> {
    let (w, h) = (width as usize, height as usize);
    let mut mask = vec![false; w * h];
    let cross = |a: [f64; 2], b: [f64; 2], p: [f64; 2]| {
        (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
    };
    for t in triangles {
        let lo = |a: usize| t.iter().map(|v| v[a]).fold(f64::INFINITY, f64::min);
        let hi = |a: usize| t.iter().map(|v| v[a]).fold(f64::NEG_INFINITY, f64::max);
        // Pixels whose centres can lie in the triangle's box.
        let span = |lo: f64, hi: f64, n: usize| {
            let a = (lo - 0.5).ceil().max(0.0) as usize;
            let b = ((hi - 0.5).floor() + 1.0).clamp(0.0, n as f64) as usize;
            a..b.max(a)
        };
        for y in span(lo(1), hi(1), h) {
            for x in span(lo(0), hi(0), w) {
                let p = [x as f64 + 0.5, y as f64 + 0.5];
                let e = [
                    cross(t[0], t[1], p),
                    cross(t[1], t[2], p),
                    cross(t[2], t[0], p),
                ];
                if e.iter().all(|&c| c >= 0.0) || e.iter().all(|&c| c <= 0.0) {
                    mask[y * w + x] = true;
                }
            }
        }
    }
    mask
}

impl Rasterizer {
    /// The two eyes' images of `draws` side by side: RGBA8, `2 * width` x `height`, the left
    /// eye on the left. `masks`: each eye's hidden pixels (a runtime's, e.g. from
    /// [`triangles_mask`]), in place of the ellipse `stereo.hidden_area` asks for.
    #[allow(clippy::too_many_arguments)]
    pub fn render_stereo(
        &self,
        gpu: &Gpu,
        eyes: &[Camera; 2],
        draws: &[Draw],
        tree: &[[u32; 4]],
        style: &Style,
        stereo: &Stereo,
        masks: Option<&[Vec<bool>; 2]>,
    ) -> Vec<u8> {
        let (w, h) = (eyes[0].width.max(1), eyes[0].height.max(1));
        let ellipse;
        let mask: Option<[&[bool]; 2]> = match masks {
            Some(m) => Some([&m[0], &m[1]]),
            None if stereo.hidden_area => {
                // Made once for a size, as a runtime's masks are.
                let mut last = self.ellipse.lock().unwrap_or_else(|e| e.into_inner());
                if last.as_ref().is_none_or(|l| l.0 != (w, h)) {
                    *last = Some(((w, h), std::sync::Arc::new(hidden_area(w, h))));
                }
                ellipse = last.as_ref().expect("made above").1.clone();
                Some([&ellipse[..], &ellipse[..]])
            }
            None => None,
        };
        // Hidden pixels come out black from each path's finish pass.
        if self.path == Path::Cpu {
            let passes = style.passes;
            let f = self.factor(gpu, &eyes[0], &passes);
            let eyes = eyes.map(|e| crate::style::supersampled(&e, style, f));
            let style = &eyes[0].1;
            // The masks at the supersampled size (the image's where there is no supersampling).
            let big = mask
                .filter(|_| f > 1)
                .map(|m| m.map(|m| crate::post::upsampled(m, w as usize, f as usize)));
            let eye_mask = |k: usize| match &big {
                Some(b) => Some(&b[k][..]),
                None => mask.map(|m| m[k]),
            };
            let list: Vec<(Camera, Option<&[bool]>)> =
                (0..2).map(|k| (eyes[k].0, eye_mask(k))).collect();
            let gs = if stereo.single_pass {
                crate::cpu::gbuffers(&list, draws, tree, style, passes.normals(), self.precision)
            } else {
                list.iter()
                    .flat_map(|e| {
                        crate::cpu::gbuffers(
                            std::slice::from_ref(e),
                            draws,
                            tree,
                            style,
                            passes.normals(),
                            self.precision,
                        )
                    })
                    .collect()
            };
            // The post passes skip the hidden pixels too.
            let images: Vec<Vec<u8>> = gs
                .into_iter()
                .zip(&list)
                .map(|(g, (camera, mask))| {
                    let view = crate::post::View::new(camera, passes.sun(), style.background, f);
                    crate::post::run_masked(g, &passes, &view, *mask)
                })
                .collect();
            side_by_side(&images, w, h)
        } else {
            // The masks for the GPU's point pass (the compute path) and post passes to skip.
            let hidden = |eyes| crate::post::Hidden {
                eyes,
                width: w as usize,
            };
            if stereo.single_pass {
                // One dispatch (compute) or one instanced draw (quads) for both eyes into a
                // frame twice as wide: already side by side.
                let mut wide = eyes[0];
                wide.width = 2 * w;
                let both = mask.as_ref().map(|m| hidden(&m[..]));
                self.render_eyes(gpu, &wide, Some(eyes), draws, tree, style, both)
            } else {
                let images: Vec<Vec<u8>> = (0..2)
                    .map(|k| {
                        let one = mask.as_ref().map(|m| hidden(std::slice::from_ref(&m[k])));
                        self.render_eyes(gpu, &eyes[k], None, draws, tree, style, one)
                    })
                    .collect();
                side_by_side(&images, w, h)
            }
        }
    }
}

/// Two `w` x `h` images (RGBA8) in one, the first on the left.
fn side_by_side(images: &[Vec<u8>], w: u32, h: u32) -> Vec<u8> {
    let row = w as usize * 4;
    let mut out = Vec::with_capacity(2 * row * h as usize);
    for y in 0..h as usize {
        for img in images {
            out.extend_from_slice(&img[y * row..(y + 1) * row]);
        }
    }
    out
}

impl crate::Scene {
    /// One selection for both eyes (the union of their frusta, each node's detail as the
    /// nearer eye sees it: [`myriad_lod::select::select_eyes`]); occlusion culling is not
    /// applied to stereo selections.
    pub fn select_eyes(
        &self,
        eyes: &[Camera],
        options: &myriad_lod::SelectOptions,
        clip: Option<crate::Clip>,
    ) -> myriad_lod::Selection {
        myriad_lod::select::select_eyes(
            &self.hierarchy,
            eyes,
            options,
            &|cube| crate::Clip::keeps(clip, cube),
            None,
        )
    }

    #[allow(clippy::too_many_arguments)]
    /// A stereo frame: both eyes' selection, loads (never waiting), uploads, and the two
    /// images side by side ([`Rasterizer::render_stereo`]).
    pub fn frame_stereo(
        &mut self,
        gpu: &Gpu,
        raster: &Rasterizer,
        eyes: &[Camera; 2],
        options: &myriad_lod::SelectOptions,
        style: &Style,
        stereo: &Stereo,
        masks: Option<&[Vec<bool>; 2]>,
    ) -> (Vec<u8>, crate::FrameStats) {
        let t = std::time::Instant::now();
        let selection = self.select_eyes(eyes, options, style.clip);
        self.take(&selection);
        let select = t.elapsed();
        let (image, stats, keys) =
            self.draw_selected(gpu, &selection, select, options, |draws, tree| {
                let image = raster.render_stereo(gpu, eyes, draws, tree, style, stereo, masks);
                (image, 0)
            });
        self.drawn = keys;
        self.last = selection;
        (image, stats)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Passes, PointSize, Points};

    fn camera(size: u32) -> Camera {
        Camera {
            position: [0.0, 0.0, 0.0],
            target: [0.0, 1.0, 0.0],
            up: [0.0, 0.0, 1.0],
            fov_y: 60.0,
            width: size,
            height: size,
            near: 0.1,
            far: 100.0,
        }
    }

    fn style(px: f32) -> Style {
        Style {
            size: PointSize::Fixed(px),
            passes: Passes::default(),
            ..Style::default()
        }
    }

    /// The lit columns of each half of a side-by-side image.
    fn lit_columns(img: &[u8], w: usize, h: usize) -> [Vec<usize>; 2] {
        let mut out = [Vec::new(), Vec::new()];
        for y in 0..h {
            for x in 0..2 * w {
                let p = &img[(y * 2 * w + x) * 4..][..3];
                if p != [0, 0, 0] {
                    out[x / w].push(x % w);
                }
            }
        }
        out
    }

    #[test]
    fn the_hidden_area_is_outside_the_inscribed_ellipse() {
        let (w, h) = (400u32, 300u32);
        let hidden = hidden_area(w, h).iter().filter(|&&m| m).count() as f64;
        let expected = (1.0 - std::f64::consts::PI / 4.0) * (w * h) as f64;
        assert!(
            (hidden - expected).abs() < 0.01 * expected,
            "{hidden} {expected}"
        );
        // The centre shows, the corners do not.
        let m = hidden_area(w, h);
        assert!(!m[(150 * w + 200) as usize] && m[0] && m[(w * h - 1) as usize]);
    }

    #[test]
    fn a_runtimes_triangles_mask_the_pixels_whose_centres_they_hold() {
        // Two triangles over the columns 0..10 of rows 2..6 (one clockwise, one not), and one
        // reaching outside the image: 40 pixels, then the 3 x 3 corner it covers.
        let quad = [
            [[0.0, 2.0], [10.0, 2.0], [10.0, 6.0]],
            [[0.0, 2.0], [0.0, 6.0], [10.0, 6.0]],
        ];
        let m = triangles_mask(20, 10, &quad);
        assert_eq!(m.iter().filter(|&&b| b).count(), 40);
        assert!(m[2 * 20] && m[5 * 20 + 9] && !m[20] && !m[6 * 20] && !m[2 * 20 + 10]);
        let corner = [[[17.0, 7.0], [40.0, 7.0], [17.0, 40.0]]];
        assert_eq!(
            triangles_mask(20, 10, &corner)
                .iter()
                .filter(|&&b| b)
                .count(),
            9
        );
        // A sliver between pixel centres holds none.
        let sliver = [[[3.6, 0.0], [3.9, 0.0], [3.6, 10.0]]];
        assert!(triangles_mask(20, 10, &sliver).iter().all(|&b| !b));
    }

    #[test]
    fn each_eye_takes_its_own_mask() {
        let gpu = Gpu::cpu();
        let raster = Rasterizer::new(&gpu);
        let cam = camera(40);
        // A wall filling both eyes' views.
        let positions: Vec<[f64; 3]> = (0..6000)
            .map(|i| {
                [
                    (i % 100) as f64 * 0.1 - 5.0,
                    5.0,
                    (i / 100) as f64 * 0.1 - 3.0,
                ]
            })
            .collect();
        let points = Points::upload(&gpu, [0.0; 3], &positions, &vec![[255; 4]; 6000]);
        // The left eye hides its left half, the right eye its top rows.
        let left = (0..1600).map(|i| i % 40 < 20).collect();
        let right = triangles_mask(
            40,
            40,
            &[
                [[0.0, 0.0], [80.0, 0.0], [0.0, 10.0]],
                [[80.0, 0.0], [80.0, 10.0], [0.0, 10.0]],
            ],
        );
        assert_eq!(right.iter().filter(|&&b| b).count(), 400);
        let masks = [left, right];
        for (f, single_pass) in [(0, true), (0, false), (2, true)] {
            let s = Stereo {
                ipd: 0.1,
                single_pass,
                hidden_area: true,
            };
            let st = Style {
                passes: Passes {
                    aa: f,
                    ..Passes::default()
                },
                ..style(2.0)
            };
            let img = raster.render_stereo(
                &gpu,
                &cam.eyes(0.1),
                &[points.all(1.0)],
                &[],
                &st,
                &s,
                Some(&masks),
            );
            let lit = |x: usize, y: usize| img[(y * 80 + x) * 4..][..3] != [0, 0, 0];
            for y in 0..40 {
                for x in 0..40 {
                    assert_eq!(lit(x, y), x >= 20 && lit(x, y), "left {x} {y}");
                    assert_eq!(lit(40 + x, y), y >= 10 && lit(40 + x, y), "right {x} {y}");
                }
            }
            // Not the ellipse: the left eye's top right corner and the right eye's bottom
            // left corner show.
            assert!(lit(38, 1) && lit(41, 38), "aa {f}");
        }
    }

    #[test]
    fn a_point_straight_ahead_shows_the_disparity_of_the_eyes_distance() {
        let gpu = Gpu::cpu();
        let raster = Rasterizer::new(&gpu);
        let cam = camera(201);
        let (ipd, depth) = (0.5, 10.0);
        let points = Points::upload(&gpu, [0.0; 3], &[[0.0, depth, 0.0]], &[[255; 4]]);
        let eyes = cam.eyes(ipd);
        for single_pass in [true, false] {
            let s = Stereo {
                ipd,
                single_pass,
                hidden_area: false,
            };
            let img =
                raster.render_stereo(&gpu, &eyes, &[points.all(1.0)], &[], &style(1.0), &s, None);
            let [l, r] = lit_columns(&img, 201, 201);
            assert_eq!((l.len(), r.len()), (1, 1), "{l:?} {r:?}");
            // The left eye sees the point right of its centre, the right eye left of it, by
            // half the disparity ipd * focal / depth each.
            let disparity = ipd * cam.focal() / depth;
            assert!(
                (l[0] as f64 - r[0] as f64 - disparity).abs() <= 1.0,
                "{l:?} {r:?} {disparity}"
            );
            assert!(l[0] > 100 && r[0] < 100);
        }
    }

    #[test]
    fn single_pass_draws_the_two_passes_images_and_nothing_crosses_a_border() {
        let gpu = Gpu::cpu();
        let mut raster = Rasterizer::new(&gpu);
        // All position words read by both: the passes differ only in how they are scheduled.
        raster.precision = 0.0;
        let cam = camera(96);
        let mut seed = 7u64;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let positions: Vec<[f64; 3]> = (0..20_000)
            .map(|_| [next() * 16.0 - 8.0, 4.0 + next() * 10.0, next() * 8.0 - 4.0])
            .collect();
        let colours: Vec<[u8; 4]> = (0..positions.len())
            .map(|i| [(i % 251) as u8, 100, 200, 255])
            .collect();
        let points = Points::upload(&gpu, [0.0; 3], &positions, &colours);
        let eyes = cam.eyes(1.0);
        let draw = |single_pass, hidden_area| {
            let s = Stereo {
                ipd: 1.0,
                single_pass,
                hidden_area,
            };
            raster.render_stereo(&gpu, &eyes, &[points.all(1.0)], &[], &style(3.0), &s, None)
        };
        for hidden in [false, true] {
            assert_eq!(draw(true, hidden), draw(false, hidden));
        }
        // Masked pixels are black; the rest of each eye has the points.
        let img = draw(true, true);
        let mask = hidden_area(96, 96);
        for y in 0..96 {
            for x in 0..192 {
                let p = &img[(y * 192 + x) * 4..][..3];
                if mask[y * 96 + x % 96] {
                    assert_eq!(p, [0, 0, 0]);
                }
            }
        }
        // A point the right eye sees near its right border and the left eye not at all (2 apart,
        // the left eye's view ends at x = 4.77 at depth 10, the right's at 6.77): nothing of
        // it in the left image.
        let eyes = cam.eyes(2.0);
        let lone = Points::upload(&gpu, [0.0; 3], &[[5.5, 10.0, 0.0]], &[[255; 4]]);
        for single_pass in [true, false] {
            let s = Stereo {
                ipd: 2.0,
                single_pass,
                hidden_area: false,
            };
            let img =
                raster.render_stereo(&gpu, &eyes, &[lone.all(1.0)], &[], &style(5.0), &s, None);
            let [l, r] = lit_columns(&img, 96, 96);
            assert!(l.is_empty() && r.len() == 25, "{l:?} {r:?}");
        }
    }
}
