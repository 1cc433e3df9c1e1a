//! `myriad render DATASET -o OUT.png`: a headless image through the LOD selection and the
//! compute rasterizer.

use anyhow::{Context, Result, bail};
use clap::Args;
use myriad_format::Dataset;
use myriad_lod::{Camera, Hierarchy, Loader, SelectOptions, converge};
use myriad_render::{ColorBy, Gpu, PointSize, Points, Rasterizer, colours};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

fn parse_floats<const N: usize>(s: &str) -> Result<[f64; N], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("\"{s}\": expected {N} comma-separated numbers"))?;
    v.try_into()
        .map_err(|v: Vec<f64>| format!("\"{s}\": expected {N} numbers, got {}", v.len()))
}

fn parse_color(s: &str) -> Result<ColorBy, String> {
    ColorBy::parse(s).ok_or_else(|| {
        format!("\"{s}\": one of rgb, intensity, elevation, classification, return, source, level")
    })
}

fn parse_point_size(s: &str) -> Result<PointSize, String> {
    if s == "adaptive" {
        return Ok(PointSize::Adaptive { max: 32.0 });
    }
    s.strip_prefix("fixed:")
        .and_then(|v| v.parse::<f32>().ok())
        .filter(|v| (1.0..=64.0).contains(v))
        .map(PointSize::Fixed)
        .ok_or_else(|| format!("\"{s}\": expected adaptive or fixed:PX with PX from 1 to 64"))
}

#[derive(Args)]
pub struct RenderArgs {
    /// The dataset (.myr)
    dataset: PathBuf,
    /// The image to write (.png)
    #[arg(short, long)]
    output: PathBuf,
    #[arg(long, default_value_t = 1280)]
    width: u32,
    #[arg(long, default_value_t = 720)]
    height: u32,
    /// Eye and target: EX,EY,EZ,TX,TY,TZ [default: the whole dataset from above at 45 degrees]
    #[arg(long, value_parser = parse_floats::<6>)]
    camera: Option<[f64; 6]>,
    /// Up direction
    #[arg(long, value_parser = parse_floats::<3>, default_value = "0,0,1")]
    up: [f64; 3],
    /// Vertical field of view in degrees
    #[arg(long, default_value_t = 60.0)]
    fov: f64,
    /// Most points drawn
    #[arg(long, value_parser = crate::synth::parse_count, default_value = "5M")]
    budget: u64,
    /// Draw every point of the dataset (the reference image)
    #[arg(long)]
    full: bool,
    /// Colour: rgb, intensity, elevation, classification, return, source, level
    #[arg(long, value_parser = parse_color, default_value = "rgb")]
    color: ColorBy,
    /// Point size: fixed:PX, or adaptive (the spacing of the level of detail drawn, as seen)
    #[arg(long, value_parser = parse_point_size, default_value = "adaptive")]
    point_size: PointSize,
    /// Replace an existing output
    #[arg(long)]
    force: bool,
}

pub fn run(a: RenderArgs) -> Result<()> {
    if a.output.exists() && !a.force {
        bail!(
            "{}: output exists (use --force to replace it)",
            a.output.display()
        );
    }
    if a.width == 0 || a.height == 0 || a.width > 16384 || a.height > 16384 {
        bail!("--width and --height must be 1 to 16384");
    }
    if !(a.fov > 0.0 && a.fov < 180.0) {
        bail!("--fov must be between 0 and 180 degrees");
    }
    let t0 = Instant::now();
    let ds = Arc::new(Dataset::open(&a.dataset)?);
    let (nodes, damage) = ds.nodes();
    for d in &damage {
        eprintln!("warning: {}", ds.damage_error(d));
    }
    let h = Hierarchy::new(ds.meta.root, nodes);
    let b = ds.meta.bounds;
    let mut cam = Camera::framing(&b, a.width, a.height, a.fov);
    if let Some(c) = a.camera {
        let size = b.size();
        let reach = (size[0] * size[0] + size[1] * size[1] + size[2] * size[2]).sqrt();
        let eye = [c[0], c[1], c[2]];
        let far = (0..3)
            .map(|k| (eye[k] - b.center()[k]).abs())
            .fold(0.0, f64::max)
            * 2.0
            + reach;
        cam = Camera {
            position: eye,
            target: [c[3], c[4], c[5]],
            up: a.up,
            near: (far * 1e-5).max(1e-3),
            far,
            ..cam
        };
    } else {
        cam.up = a.up;
    }
    let gpu = Gpu::headless().map_err(anyhow::Error::msg)?;
    let raster = Rasterizer::new(&gpu);
    let options = SelectOptions {
        budget: if a.full { u64::MAX } else { a.budget },
        min_pixels: if a.full { 0.0 } else { 1.0 },
    };
    let mut loader = Loader::new(ds.clone(), 2, usize::MAX);
    let origin = b.center();
    let z = (b.min[2], b.max[2]);
    // The drawn prefixes of the resident selected nodes, relative to the dataset's centre.
    let upload = |selection: &myriad_lod::Selection, loader: &Loader| -> Vec<Points> {
        let mut sets = Vec::new();
        for n in &selection.nodes {
            let Some(batch) = loader.get(&n.key) else {
                continue;
            };
            let k = (n.points as usize).min(batch.len());
            let c = colours(&batch, k, a.color, z, n.key.level);
            let mut p = Points::upload(&gpu, origin, &batch.positions[..k], &c);
            p.spacing = n.spacing;
            sets.push(p);
        }
        sets
    };
    // First image: as soon as the first selected node (the root) is in.
    let first = myriad_lod::select(&h, &cam, &options);
    let wanted: Vec<_> = first
        .nodes
        .iter()
        .filter_map(|n| h.get(&n.key).cloned())
        .collect();
    loader.request(&wanted);
    if let Some(root) = first.nodes.first() {
        while !loader.is_resident(&root.key) && !loader.failed().contains_key(&root.key) {
            if loader.poll() == 0 {
                std::thread::sleep(std::time::Duration::from_millis(1));
            }
        }
    }
    let sets = upload(&first, &loader);
    let refs: Vec<&Points> = sets.iter().collect();
    raster.render(&gpu, &cam, &refs, [0, 0, 0, 255], a.point_size);
    let first_image = t0.elapsed();

    let selection = converge(&mut loader, &h, &cam, &options);
    let sets = upload(&selection, &loader);
    let refs: Vec<&Points> = sets.iter().collect();
    let img = raster.render(&gpu, &cam, &refs, [0, 0, 0, 255], a.point_size);
    let converged = t0.elapsed();
    let t = Instant::now();
    let img2 = raster.render(&gpu, &cam, &refs, [0, 0, 0, 255], a.point_size);
    let frame = t.elapsed();
    debug_assert_eq!(img, img2);
    write_png(&a.output, a.width, a.height, &img2)?;
    println!(
        "{}: {} points in {} nodes, frame {:.1} ms, first image after {:.2} s, converged after {:.2} s ({})",
        a.output.display(),
        crate::info::thousands(selection.points),
        selection.nodes.len(),
        frame.as_secs_f64() * 1e3,
        first_image.as_secs_f64(),
        converged.as_secs_f64(),
        gpu.adapter.name
    );
    Ok(())
}

fn write_png(path: &std::path::Path, w: u32, h: u32, rgba: &[u8]) -> Result<()> {
    let file = myriad_io::atomic::AtomicFile::create(path, true)?;
    {
        let f = file.open_write()?;
        let mut enc = png::Encoder::new(std::io::BufWriter::new(f), w, h);
        enc.set_color(png::ColorType::Rgba);
        enc.set_depth(png::BitDepth::Eight);
        let mut writer = enc.write_header().context("PNG header")?;
        writer.write_image_data(rgba).context("PNG data")?;
        writer.finish().context("PNG end")?;
    }
    file.commit()?;
    Ok(())
}
