//! `myriad bench surface DATASET...`: table 1 and figure 4 of Schiffner et al. 2015, on the CPU
//! (`--cpu`) or with the steps and the frames on the GPU (`--gpu`).
//!
//! For each dataset, the points a standard view selects at `--budget` (`--all`: every point) are
//! clustered in the `--grid` frustum grid by each variant: the full method (move to 3
//! neighbours, tensor normals), move to 1 neighbour, cluster only (no move), cells' normals,
//! planarity as the density, and the paper's baseline, the two levels of an octree over the same
//! points whose cells bracket the full method's in number. Per variant, medians of `--runs`:
//! cells, milliseconds of cluster, move, reduce, reconstruct and the frame (the quads drawn and
//! shaded); the distance from each point to its cell's quad (RMS and 95th percentile); and the
//! holes: the fraction of the pixels the points cover (as `render` draws them) that the surface
//! leaves empty. Then, as table 1's last columns, the frame of the points and of each kind of
//! surface element.

use crate::median;
use anyhow::Result;
use clap::Args;
use myriad_core::Aabb;
use myriad_render::surface::{self, Built, Density, Grid, Kind, Normals, Surface};
use myriad_render::{ColorBy, Gpu, Rasterizer, Style};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args)]
pub struct SurfaceBenchArgs {
    #[arg(required = true)]
    datasets: Vec<PathBuf>,
    /// Points clustered: what the view selects within this budget
    #[arg(long, value_parser = myriad_core::units::parse_count, default_value = "5M")]
    budget: u64,
    /// The full method's options (the variants change one each)
    #[command(flatten)]
    options: myriad_render::args::SurfaceArgs,
    /// Cluster every point of the dataset in view, not a level of detail
    #[arg(long)]
    all: bool,
    /// The standard view
    #[arg(long, default_value = "overview", value_parser = ["overview", "top", "close"])]
    view: String,
    #[arg(long, default_value_t = 1280)]
    width: u32,
    #[arg(long, default_value_t = 720)]
    height: u32,
    /// Runs per variant (medians)
    #[arg(long, default_value_t = 5)]
    runs: usize,
    /// Cluster, move and reduce on the GPU (`--gpu`, lavapipe too) or the CPU (`--cpu`); the
    /// octree baseline is always the CPU's
    #[command(flatten)]
    device: crate::render::Device,
    /// Write the images (points, each variant's quads, the full method's boxes and splats) here
    #[arg(long)]
    images: Option<PathBuf>,
}

/// The scene the standard view `view` selects from `path` at `budget`, loaded, and its camera
/// (what `myriad mesh --view` clusters).
fn drawn(
    path: &std::path::Path,
    view: &str,
    (w, h): (u32, u32),
    budget: u64,
) -> Result<(myriad_render::Scene, myriad_lod::Camera)> {
    let found = myriad_build::cached::dataset_for(path, &myriad_build::convert::Silent)?;
    let ds = std::sync::Arc::new(myriad_format::Dataset::open(&found)?);
    let all = ds.meta.bounds;
    let (scene, cam) = surface::drawn_scene(ds, budget, ColorBy::Rgb, |bounds| {
        let mut cam = myriad_lod::Camera::view(Some(view), bounds, &all, w, h)
            .ok_or_else(|| format!("no standard view \"{view}\""))?;
        cam.fov_y = 60.0;
        Ok(cam)
    })
    .map_err(anyhow::Error::msg)?;
    for why in scene.loader.failed_pages().values() {
        eprintln!("warning: {why}");
    }
    Ok((scene, cam))
}

struct Row {
    name: String,
    cells: usize,
    moved: usize,
    ms: [f64; 5],
    rms: f64,
    p95: f64,
    holes: f64,
}

pub fn run(a: SurfaceBenchArgs) -> Result<()> {
    let runs = a.runs.max(1);
    if let Some(dir) = &a.images {
        std::fs::create_dir_all(dir)?;
    }
    // The points' image (for the holes) on the CPU; the surface's steps and every timed frame on
    // the device asked for.
    let gpu = Gpu::cpu();
    let raster = Rasterizer::new(&gpu);
    let device = a.device.gpu()?;
    // The surface's frames on the same device (the triangles by a render pipeline on a GPU).
    let drawer = (!device.is_cpu()).then(|| surface::Drawer::new(&device));
    let draw = |cam: &myriad_lod::Camera, mesh: &myriad_core::Mesh| match &drawer {
        Some(d) => d.draw(&device, cam, mesh, &Style::default()),
        None => surface::draw(cam, mesh, &Style::default()),
    };
    let draw_built = |cam: &myriad_lod::Camera, built: &Built| match &drawer {
        Some(d) => d.draw_built(&device, cam, built, &Style::default()),
        None => surface::draw(cam, &built.mesh, &Style::default()),
    };
    println!(
        "{}; {:?}; {} view at {}x{}, budget {}, medians of {runs} runs",
        device.name,
        a.options.surface(Kind::Quads).map_err(anyhow::Error::msg)?,
        a.view,
        a.width,
        a.height,
        a.budget
    );
    for path in &a.datasets {
        let budget = if a.all { u64::MAX } else { a.budget };
        let (mut scene, cam) = drawn(path, &a.view, (a.width, a.height), budget)?;
        let (points, colours) = surface::drawn_points(&scene, None);
        // The points as `render` draws them, on a transparent background: what they cover.
        let style = Style {
            background: [0, 0, 0, 0],
            ..Style::default()
        };
        let options = myriad_lod::SelectOptions {
            budget: if a.all { u64::MAX } else { a.budget },
            min_pixels: if a.all { 0.0 } else { 1.0 },
        };
        let mut point_ms = Vec::new();
        let mut image = Vec::new();
        for _ in 0..runs {
            let t = Instant::now();
            image = scene.frame(&gpu, &raster, &cam, &options, &style).0;
            point_ms.push(t.elapsed().as_secs_f64() * 1e3);
        }
        let covered: Vec<bool> = image.chunks(4).map(|p| p[3] > 0).collect();
        // The points' frame as table 1 compares it: on the device the surfaces are drawn on
        // (uploaded there first: one untimed frame).
        if !device.is_cpu() {
            scene.buffers.clear();
            let device_raster = Rasterizer::new(&device);
            scene.frame(&device, &device_raster, &cam, &options, &style);
            point_ms.clear();
            for _ in 0..runs {
                let t = Instant::now();
                scene.frame(&device, &device_raster, &cam, &options, &style);
                point_ms.push(t.elapsed().as_secs_f64() * 1e3);
            }
        }
        let name = path
            .file_stem()
            .map_or("dataset".into(), |s| s.to_string_lossy().to_string());
        if let Some(dir) = &a.images {
            myriad_io::image::write_png(
                &dir.join(format!("{name}-points.png")),
                a.width,
                a.height,
                &image,
            )?;
        }
        let full = a.options.surface(Kind::Quads).map_err(anyhow::Error::msg)?;
        let variants: [(&str, Surface); 5] = [
            ("full", full),
            (
                "move to 1 neighbour",
                Surface {
                    neighbours: 1,
                    ..full
                },
            ),
            (
                "cluster only (no move)",
                Surface {
                    neighbours: 0,
                    ..full
                },
            ),
            (
                "cells' normals",
                Surface {
                    normals: Normals::Cells,
                    ..full
                },
            ),
            (
                "planarity density",
                Surface {
                    density: Density::Planarity,
                    ..full
                },
            ),
        ];
        let Some(frustum) = Grid::frustum(&cam, full.grid, &points) else {
            println!("{name}: no point in view");
            continue;
        };
        let mut rows = Vec::new();
        let mut full_cells = 0;
        let measure = |label: String,
                       grid: &Grid,
                       s: &Surface,
                       pts: &[[f64; 3]],
                       cols: &[[u8; 4]]|
         -> Result<(Row, Built)> {
            let mut ms = vec![Vec::new(); 5];
            let mut built = Built::default();
            for _ in 0..runs {
                built = Built::in_grid_on(&device, &cam, grid, pts, cols, s)
                    .map_err(anyhow::Error::msg)?;
                let c = &built.clustering;
                for (k, d) in [c.cluster, c.moving, c.reduce, built.reconstruct]
                    .iter()
                    .enumerate()
                {
                    ms[k].push(d.as_secs_f64() * 1e3);
                }
                let t = Instant::now();
                let img = draw_built(&cam, &built);
                ms[4].push(t.elapsed().as_secs_f64() * 1e3);
                drop(img);
            }
            let mut d = surface::distances(&cam, grid, &built.clustering, pts, Kind::Quads);
            d.sort_by(f64::total_cmp);
            let rms = (d.iter().map(|v| v * v).sum::<f64>() / d.len().max(1) as f64).sqrt();
            let p95 = d.get(d.len() * 95 / 100).copied().unwrap_or(0.0);
            let surface_covers = surface::coverage(&cam, &built.mesh);
            let want = covered.iter().filter(|&&c| c).count();
            let empty = covered
                .iter()
                .zip(&surface_covers)
                .filter(|(p, s)| **p && !**s)
                .count();
            if let Some(dir) = &a.images {
                let img = draw_built(&cam, &built);
                let slug: String = label
                    .chars()
                    .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
                    .collect();
                let file = format!("{name}-{slug}.png");
                myriad_io::image::write_png(&dir.join(file), a.width, a.height, &img)?;
            }
            let row = Row {
                name: label,
                cells: built.clustering.cells.len(),
                moved: built.clustering.moved,
                ms: std::array::from_fn(|k| median(ms[k].clone())),
                rms,
                p95,
                holes: 100.0 * empty as f64 / want.max(1) as f64,
            };
            Ok((row, built))
        };
        let mut full_built = Built::default();
        for (label, s) in variants {
            let (row, built) = measure(label.to_string(), &frustum, &s, &points, &colours)?;
            if rows.is_empty() {
                full_cells = row.cells;
                full_built = built;
            }
            rows.push(row);
        }
        // The baseline: an octree level over the points in view (those the full method
        // clustered), about as many cells.
        let inside: Vec<usize> = (0..points.len())
            .filter(|&i| full_built.clustering.of_point[i] != u32::MAX)
            .collect();
        let in_points: Vec<[f64; 3]> = inside.iter().map(|&i| points[i]).collect();
        let in_colours: Vec<[u8; 4]> = inside.iter().map(|&i| colours[i]).collect();
        let mut cube = Aabb::new(in_points[0], in_points[0]);
        for &p in &in_points {
            cube.extend(p);
        }
        let side = cube.size().into_iter().fold(0.0f64, f64::max);
        let cube = Aabb::new(cube.min, cube.min.map(|v| v + side));
        let mut levels = Vec::new();
        for octree in Grid::cubes_around(&cube, &in_points, full_cells) {
            let level = octree.dims()[0].trailing_zeros();
            levels.push(level.to_string());
            let (row, _) = measure(
                format!("octree level {level} (baseline)"),
                &octree,
                &Surface {
                    neighbours: 0,
                    ..full
                },
                &in_points,
                &in_colours,
            )?;
            rows.push(row);
        }
        let level = levels.join(" and ");

        println!(
            "\n{name}: {} points drawn, {} in view (octree levels {level})",
            myriad_core::units::thousands(points.len() as u64),
            myriad_core::units::thousands(full_built.clustering.inside as u64)
        );
        println!(
            "| variant | cells | moved | cluster ms | move ms | reduce ms | reconstruct ms | frame ms | RMS | p95 | holes % |"
        );
        println!("|---|---|---|---|---|---|---|---|---|---|---|");
        for r in &rows {
            println!(
                "| {} | {} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.4} | {:.4} | {:.2} |",
                r.name,
                myriad_core::units::thousands(r.cells as u64),
                myriad_core::units::thousands(r.moved as u64),
                r.ms[0],
                r.ms[1],
                r.ms[2],
                r.ms[3],
                r.ms[4],
                r.rms,
                r.p95,
                r.holes
            );
        }
        // Table 1's last columns: elements and the frame of each kind, against the points.
        println!("\n| drawn | elements | triangles | frame ms |");
        println!("|---|---|---|---|");
        println!(
            "| points | {} | - | {:.1} |",
            myriad_core::units::thousands(points.len() as u64),
            median(point_ms)
        );
        for kind in [Kind::Splats, Kind::Boxes, Kind::Quads] {
            let frustum_grid = full_built.grid.unwrap_or(frustum);
            let mesh =
                surface::reconstruct(&cam, &frustum_grid, &full_built.clustering.cells, kind);
            let mut ms = Vec::new();
            let mut img = Vec::new();
            for _ in 0..runs {
                let t = Instant::now();
                img = draw(&cam, &mesh);
                ms.push(t.elapsed().as_secs_f64() * 1e3);
            }
            if let Some(dir) = &a.images {
                myriad_io::image::write_png(
                    &dir.join(format!("{name}-full-{kind:?}.png").to_lowercase()),
                    a.width,
                    a.height,
                    &img,
                )?;
            }
            println!(
                "| {kind:?} | {} | {} | {:.1} |",
                myriad_core::units::thousands(full_built.clustering.cells.len() as u64),
                myriad_core::units::thousands(mesh.triangles.len() as u64),
                median(ms)
            );
        }
    }
    Ok(())
}
