//! `myriad bench render DATASET...`: image quality of the level-of-detail selection and the frame
//! time of the whole pipeline.
//!
//! Quality: for each of the three standard views, the PSNR of the image drawn at `--budget`
//! against the image of every point (`--full`), next to a baseline that draws the same number of
//! points picked uniformly at random from the whole dataset, with the same point size and shape
//! (adaptive sizes: a random subset of a fraction f of the points is drawn at the finest point
//! spacing of its node over the square root of f, the spacing such a subset has on a surface).
//! Speed: the median time of `--frames` frames at `--frame-budget` once the view has converged
//! (selection, GPU cache lookups, drawing, resolve and readback), and its parts; in the overview,
//! without a pixel threshold, so that the frames draw the whole budget.

mod positions;

use anyhow::{Result, bail};
use clap::Args;
use myriad_format::Dataset;
use myriad_io::image::write_png;
use myriad_lod::{Camera, SelectOptions, point_spacing};
use myriad_render::{Gpu, PointSize, Points, Rasterizer, Scene, Style, colours};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

#[derive(Args)]
pub struct RenderBenchArgs {
    #[arg(required = true)]
    datasets: Vec<PathBuf>,
    /// Point budget of the images compared with the full one
    #[arg(long, value_parser = myriad_core::units::parse_count, default_value = "1M")]
    pub(crate) budget: u64,
    /// Point budget of the timed frames
    #[arg(long, value_parser = myriad_core::units::parse_count, default_value = "5M")]
    pub(crate) frame_budget: u64,
    #[arg(long, default_value_t = 1280)]
    pub(crate) width: u32,
    #[arg(long, default_value_t = 720)]
    pub(crate) height: u32,
    /// Timed frames per dataset
    #[arg(long, default_value_t = 9)]
    pub(crate) frames: usize,
    /// Scale of the adaptive point size
    #[arg(long, default_value_t = PointSize::ADAPTIVE_SCALE)]
    pub(crate) scale: f32,
    /// Seed of the random baseline
    #[arg(long, default_value_t = 1)]
    seed: u64,
    #[command(flatten)]
    device: crate::render::Device,
    /// Write every image compared into this folder (NAME-VIEW-full|lod|random-MODE.png)
    #[arg(long)]
    images: Option<PathBuf>,
    /// Only the comparison of positions on the GPU (f32 and quantized)
    #[arg(long)]
    positions_only: bool,
}

/// The side, in pixels, from which a square of one colour counts as a block ([`blocks`]).
pub const BLOCK: usize = 6;

/// Blocks in an RGBA8 image `width` pixels wide drawn without post passes: the tiles of 16 x 16
/// pixels (column, row) holding a square of [`BLOCK`] x [`BLOCK`] pixels of one colour other
/// than the background (black). A point drawn that wide (its square is of its own colour,
/// passes off) is one: near the camera, where every point is that wide, a surface closed; amid
/// points of a pixel or two, a block. So a view's blocks are those of its image at a budget in
/// tiles where its image of every point has none.
pub fn blocks(img: &[u8], width: usize) -> std::collections::HashSet<(usize, usize)> {
    let px: Vec<u32> = img
        .chunks_exact(4)
        .map(|p| u32::from_le_bytes([p[0], p[1], p[2], 0]))
        .collect();
    let height = px.len() / width.max(1);
    // Per pixel: the run of its colour ending there along its row, and the rows above it
    // whose runs there are as long.
    let mut run = vec![0usize; px.len()];
    let mut tall = vec![0usize; px.len()];
    let mut tiles = std::collections::HashSet::new();
    for y in 0..height {
        for x in 0..width {
            let i = y * width + x;
            run[i] = if x > 0 && px[i] == px[i - 1] {
                run[i - 1] + 1
            } else {
                1
            };
            let wide = run[i] >= BLOCK && px[i] != 0;
            tall[i] = match (wide, y > 0) {
                (false, _) => 0,
                (true, true) if px[i - width] == px[i] && tall[i - width] > 0 => {
                    tall[i - width] + 1
                }
                (true, _) => 1,
            };
            if tall[i] >= BLOCK {
                tiles.insert((x / 16, y / 16));
            }
        }
    }
    tiles
}

/// Peak signal-to-noise ratio of RGB between two RGBA8 images, in dB (infinite when equal).
pub fn psnr(a: &[u8], b: &[u8]) -> f64 {
    assert_eq!(a.len(), b.len());
    let (mut sum, mut n) = (0.0f64, 0u64);
    for (p, q) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
        for c in 0..3 {
            let d = p[c] as f64 - q[c] as f64;
            sum += d * d;
            n += 1;
        }
    }
    let mse = sum / n.max(1) as f64;
    if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (255.0f64 * 255.0 / mse).log10()
    }
}

/// A small, fast, seeded generator (xorshift64*), so that baselines repeat.
struct Rng(u64);
impl Rng {
    fn next_f64(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545f4914f6cdd1d) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Where a benchmark draws (its `--cpu` and `--gpu`).
#[derive(Args)]
pub struct Device {
    /// Draw on the CPU even where there is a hardware GPU
    #[arg(long, conflicts_with = "gpu")]
    cpu: bool,
    /// Draw on the GPU adapter even where it is a software one (lavapipe)
    #[arg(long)]
    gpu: bool,
}

impl Device {
    /// The CPU (`--cpu`), the GPU adapter even if a software one (`--gpu`), or the best there is
    /// (a warning when that is the CPU for want of an adapter).
    pub fn gpu(&self) -> Result<Gpu> {
        let (gpu, why) = if self.cpu {
            (Gpu::cpu(), None)
        } else if self.gpu {
            (Gpu::headless().map_err(anyhow::Error::msg)?, None)
        } else {
            Gpu::best()
        };
        if let Some(why) = why {
            eprintln!("warning: {why}: drawing on the CPU");
        }
        Ok(gpu)
    }
}

pub fn run(a: RenderBenchArgs) -> Result<()> {
    let gpu = a.device.gpu()?;
    let mut raster = Rasterizer::new(&gpu);
    println!(
        "{}, {:?} path, {}x{}; quality at a budget of {} points against every point, \
         baseline: as many points uniformly at random",
        gpu.name,
        raster.path,
        a.width,
        a.height,
        myriad_core::units::thousands(a.budget)
    );
    if let Some(dir) = &a.images {
        std::fs::create_dir_all(dir)?;
    }
    let mut lost = 0;
    for path in &a.datasets {
        let ds = Arc::new(Dataset::open(path)?);
        let name = path
            .file_stem()
            .map_or("dataset".into(), |s| s.to_string_lossy().to_string());
        let mut scene = Scene::open(ds.clone(), usize::MAX, usize::MAX);
        // The reference images sample every point: every node known.
        scene.read_every_page(&ds);
        let total = scene.hierarchy.points();
        if a.positions_only {
            println!("\n{name}: {} points", myriad_core::units::thousands(total));
            positions::compare(&mut scene, &ds, &gpu, &mut raster, &a)?;
            continue;
        }
        println!(
            "\n{name}: {} points\n{:<10} {:<9} {:>12} {:>10} {:>10} {:>8} {:>14}",
            myriad_core::units::thousands(total),
            "view",
            "size",
            "points",
            "ours dB",
            "random dB",
            "gain",
            "blocks"
        );
        let views = Camera::standard_views(&scene.view_bounds, a.width, a.height);
        for (view, mut cam) in views {
            cam.fit_depth(&ds.meta.bounds);
            for (mode, size) in [
                ("fixed:1", PointSize::Fixed(1.0)),
                (
                    "adaptive",
                    PointSize::Adaptive {
                        scale: a.scale,
                        max: 32.0,
                    },
                ),
            ] {
                let style = Style {
                    size,
                    ..Style::default()
                };
                let q = quality(&mut scene, &gpu, &raster, &cam, &style, a.budget)
                    .map_err(|e| anyhow::anyhow!("{name}: {view}: {e}"))?;
                let (full, lod, points) = (q.full, q.lod, q.points);
                let random = random_image(&gpu, &raster, &scene, &cam, &style, points, a.seed)?;
                let (ours, theirs) = (q.psnr, psnr(&random, &full));
                if ours <= theirs {
                    lost += 1;
                }
                let w = a.width as usize;
                // Tiles with a block at the budget where the image of every point has none, and
                // the image of every point's.
                let every = blocks(&full, w);
                let squares = format!(
                    "{}/{}",
                    blocks(&lod, w).difference(&every).count(),
                    every.len()
                );
                println!(
                    "{view:<10} {mode:<9} {:>12} {ours:>10.2} {theirs:>10.2} {:>+8.2} {squares:>14}",
                    myriad_core::units::thousands(points),
                    ours - theirs
                );
                if let Some(dir) = &a.images {
                    for (kind, img) in [("full", &full), ("lod", &lod), ("random", &random)] {
                        let mode = mode.replace(':', "");
                        let file = dir.join(format!("{name}-{view}-{kind}-{mode}.png"));
                        write_png(&file, a.width, a.height, img)?;
                    }
                }
            }
        }

        // Frame time at the frame budget, in the overview, once converged; no pixel threshold,
        // so that the budget is what stops the selection.
        let (_, cam) = views[0];
        let mut cam = cam;
        cam.fit_depth(&ds.meta.bounds);
        for (mode, size) in [
            ("adaptive", PointSize::adaptive()),
            ("fixed:1", PointSize::Fixed(1.0)),
        ] {
            let style = Style {
                size,
                ..Style::default()
            };
            let (times, points) = frame_times(
                &mut scene,
                &gpu,
                &raster,
                &cam,
                &style,
                a.frame_budget,
                a.frames,
            );
            let (frame, select, draw) = times[times.len() / 2];
            println!(
                "frame, {mode} size, budget {}: {} points in {} frames: median {:.1} ms (selection \
                 {:.1} ms, drawing and readback {:.1} ms; min {:.1}, max {:.1}), {:.1} M points/s",
                myriad_core::units::thousands(a.frame_budget),
                myriad_core::units::thousands(points),
                times.len(),
                frame * 1e3,
                select * 1e3,
                draw * 1e3,
                times[0].0 * 1e3,
                times[times.len() - 1].0 * 1e3,
                points as f64 / frame / 1e6,
            );
        }
        positions::compare(&mut scene, &ds, &gpu, &mut raster, &a)?;
    }
    if lost > 0 {
        println!("\nthe random baseline was as good or better in {lost} of the views");
    } else {
        println!("\nlevel of detail better than the random baseline in every view");
    }
    Ok(())
}

/// A view's image at a point budget next to its image of every point.
pub struct Quality {
    pub full: Vec<u8>,
    pub lod: Vec<u8>,
    /// Points drawn at the budget.
    pub points: u64,
    /// Of `lod` against `full`, dB.
    pub psnr: f64,
}

/// Draws `cam`'s view with every point and at `budget` (both converged) and compares them.
pub fn quality(
    scene: &mut Scene,
    gpu: &Gpu,
    raster: &Rasterizer,
    cam: &Camera,
    style: &Style,
    budget: u64,
) -> Result<Quality> {
    let full_options = SelectOptions {
        budget: u64::MAX,
        min_pixels: 0.0,
    };
    // The reference: every point, nothing culled.
    let occlusion = std::mem::replace(&mut scene.occlusion, myriad_lod::Occlusion::Off);
    scene.converge(cam, &full_options, style.clip);
    let (full, _) = scene.frame(gpu, raster, cam, &full_options, style);
    scene.occlusion = occlusion;
    let options = SelectOptions {
        budget,
        min_pixels: 1.0,
    };
    scene.converge(cam, &options, style.clip);
    // The frame selects again: with occlusion culling, nodes culled that show are drawn in it
    // too (more points than the converged selection counted: the indoor scene's close view).
    let (lod, stats) = scene.frame(gpu, raster, cam, &options, style);
    if !stats.complete {
        bail!("drew {} of {} points", stats.points, stats.selected_points);
    }
    let psnr = psnr(&lod, &full);
    Ok(Quality {
        full,
        lod,
        points: stats.points,
        psnr,
    })
}

/// Times `frames` frames of `cam`'s view at `budget` once converged, with no pixel threshold (so
/// that the budget is what stops the selection): (whole frame, selection, drawing and readback)
/// in seconds, sorted by the whole frame; and the points drawn.
pub fn frame_times(
    scene: &mut Scene,
    gpu: &Gpu,
    raster: &Rasterizer,
    cam: &Camera,
    style: &Style,
    budget: u64,
    frames: usize,
) -> (Vec<(f64, f64, f64)>, u64) {
    let options = SelectOptions {
        budget,
        min_pixels: 0.0,
    };
    scene.converge(cam, &options, style.clip);
    scene.frame(gpu, raster, cam, &options, style);
    let mut times = Vec::new();
    let mut points = 0;
    for _ in 0..frames.max(1) {
        let t = Instant::now();
        let (img, stats) = scene.frame(gpu, raster, cam, &options, style);
        times.push((
            t.elapsed().as_secs_f64(),
            stats.select.as_secs_f64(),
            stats.draw.as_secs_f64(),
        ));
        points = stats.points;
        std::hint::black_box(img);
    }
    times.sort_by(|x, y| x.0.total_cmp(&y.0));
    (times, points)
}

/// `k` points picked uniformly at random from every point of the scene (all resident), drawn
/// with `style`.
fn random_image(
    gpu: &Gpu,
    raster: &Rasterizer,
    scene: &Scene,
    cam: &Camera,
    style: &Style,
    k: u64,
    seed: u64,
) -> Result<Vec<u8>> {
    let total = scene.hierarchy.points();
    let mut rng = Rng(seed.wrapping_mul(0x9e3779b97f4a7c15) | 1);
    let (mut seen, mut chosen) = (0u64, 0u64);
    let mut keys: Vec<_> = scene.hierarchy.keys().collect();
    keys.sort();
    let mut sets = Vec::new();
    let grow = (total as f64 / k.max(1) as f64).sqrt();
    for key in keys {
        let entry = scene.hierarchy.get(&key).expect("listed");
        // Original points only (mwkd's aggregates are not among them).
        if entry.points == 0 || entry.aggregate() {
            continue;
        }
        let Some(batch) = scene.loader.get(&key) else {
            bail!("node {key} not resident");
        };
        // Selection sampling (Knuth's algorithm S): exactly k of the total, each equally likely.
        let mut pick = Vec::new();
        for i in 0..batch.len() {
            if ((total - seen) as f64) * rng.next_f64() < (k - chosen) as f64 {
                pick.push(i);
                chosen += 1;
            }
            seen += 1;
        }
        if pick.is_empty() {
            continue;
        }
        let c = colours(
            &batch,
            batch.len(),
            scene.colour(),
            scene.z_range,
            key.level,
        );
        let positions: Vec<[f64; 3]> = pick.iter().map(|&i| batch.positions[i]).collect();
        let c: Vec<[u8; 4]> = pick.iter().map(|&i| c[i]).collect();
        let spacing = point_spacing(entry).last().copied().unwrap_or(0.0) * grow;
        sets.push((Points::upload(gpu, scene.origin, &positions, &c), spacing));
    }
    if chosen != k {
        bail!("random baseline picked {chosen} of {k} points");
    }
    let draws: Vec<_> = sets.iter().map(|(p, s)| p.all(*s)).collect();
    Ok(raster.render(gpu, cam, &draws, &[], style))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_are_squares_of_one_colour_six_pixels_wide() {
        let (w, h) = (64, 40);
        let mut img = vec![0u8; w * h * 4];
        let mut fill = |x0: usize, y0: usize, s: usize, c: [u8; 4]| {
            for y in y0..y0 + s {
                for x in x0..x0 + s {
                    img[(y * w + x) * 4..][..4].copy_from_slice(&c);
                }
            }
        };
        // A 6-pixel square, a 5-pixel one, a 6-pixel one of two colours (split down the middle),
        // and a 12-pixel one across tiles.
        fill(1, 1, 6, [200, 10, 10, 255]);
        fill(20, 1, 5, [10, 200, 10, 255]);
        fill(40, 1, 6, [10, 10, 200, 255]);
        fill(43, 1, 3, [10, 10, 201, 255]);
        fill(10, 20, 12, [90, 90, 90, 255]);
        // The first tile; of the big square (10..21 by 20..31), the tiles where a 6 x 6 square
        // of it ends (x 15..21, y 25..31: two tiles).
        let b = blocks(&img, w);
        assert_eq!(b.len(), 1 + 2, "{b:?}");
        assert!(b.contains(&(0, 0)) && b.contains(&(0, 1)) && b.contains(&(1, 1)));
        // Black is the background.
        assert!(blocks(&vec![0u8; w * h * 4], w).is_empty());
    }

    #[test]
    fn psnr_of_known_differences() {
        let a = vec![10u8, 20, 30, 255, 40, 50, 60, 255];
        assert_eq!(psnr(&a, &a), f64::INFINITY);
        // One channel of six off by 255: MSE 255^2 / 6, PSNR 10 log10(6).
        let mut b = a.clone();
        b[0] = 255;
        let mse = (245.0f64 * 245.0) / 6.0;
        assert!((psnr(&a, &b) - 10.0 * (255.0 * 255.0 / mse).log10()).abs() < 1e-9);
        // Alpha is not compared.
        let mut c = a.clone();
        c[3] = 0;
        assert_eq!(psnr(&a, &c), f64::INFINITY);
    }

    #[test]
    fn selection_sampling_takes_exactly_k() {
        let mut rng = Rng(7);
        let (total, k) = (10_000u64, 1234u64);
        let (mut seen, mut chosen) = (0, 0);
        let mut first_half = 0;
        for i in 0..total {
            if ((total - seen) as f64) * rng.next_f64() < (k - chosen) as f64 {
                chosen += 1;
                first_half += (i < total / 2) as u64;
            }
            seen += 1;
        }
        assert_eq!(chosen, k);
        // Uniform: about half from each half (±5 %).
        assert!((first_half as f64 - k as f64 / 2.0).abs() < k as f64 * 0.05);
    }
}
