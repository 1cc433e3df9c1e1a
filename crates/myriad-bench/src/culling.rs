//! `myriad bench culling DATASET...`: what occlusion culling saves and costs.
//!
//! Two views per dataset: inside (the eye at the middle of the data, a third of the way up,
//! looking level along its longer horizontal axis: in a building, a room with walls between it
//! and the rest) and outside (the standard overview from above at 45 degrees). For each view,
//! each method (`off`, `software`, `queries`: occlusion queries of each frame, hardware ones
//! on a GPU, the culled nodes that show drawn in the same frame; `checked`: the software test
//! with its culls queried; the last two drawn until the selection settles) and each `--budgets`
//! (then the 1-pixel threshold alone, no budget), once converged: nodes and points selected,
//! nodes culled, the median selection, query and frame time of `--frames` frames, and the PSNR
//! against the image of every point with culling off ("viewer": checked culling in the frame
//! `view` draws on the CPU, `frame_many`). `--walk N`: a walk from the inside view,
//! each frame of each method (queries acting in the same frame and from the next one) against
//! culling off's.

use crate::render::psnr;
use anyhow::Result;
use clap::Args;
use myriad_format::Dataset;
use myriad_io::image::write_png;
use myriad_lod::hierarchy::DetailContour;
use myriad_lod::{Camera, Occlusion, SelectOptions};
use myriad_render::{ColorBy, Rasterizer, Scene, Style};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

#[derive(Args)]
pub struct CullingBenchArgs {
    #[arg(required = true)]
    datasets: Vec<PathBuf>,
    /// Point budgets, comma-separated (then the threshold alone, without a budget)
    #[arg(long, default_value = "500k,1M,2M")]
    budgets: String,
    /// Timed frames per configuration
    #[arg(long, default_value_t = 5)]
    frames: usize,
    #[arg(long, default_value_t = 1280)]
    width: u32,
    #[arg(long, default_value_t = 720)]
    height: u32,
    /// Colour scheme of every image (elevation: scans without colours still show)
    #[arg(long, value_parser = myriad_render::args::parse_color, default_value = "elevation")]
    color: ColorBy,
    #[command(flatten)]
    device: crate::render::Device,
    /// Write the images into this folder (NAME-VIEW-METHOD-BUDGET.png and -full)
    #[arg(long)]
    images: Option<PathBuf>,
    /// Which contour sizes a layered node's detail: subtree (its subtree's, as datasets built
    /// before own contours were stored), own (its own points', Kanzok et al. 2015) or tighter (the
    /// flat one of the two covering fewer pixels: the default)
    #[arg(long, value_parser = parse_detail_contour, default_value = "tighter")]
    detail_contour: DetailContour,
    /// Also walk N steps from the inside view (forward along its axis, turning a quarter
    /// turn), without a budget: per method, the frames that differ from culling off's (holes:
    /// a node showing that was culled), queries in the same frame and from the next one
    #[arg(long, default_value_t = 0)]
    walk: usize,
}

fn parse_detail_contour(s: &str) -> std::result::Result<DetailContour, String> {
    DetailContour::ALL
        .into_iter()
        .find(|d| d.name() == s)
        .ok_or_else(|| format!("{s}: subtree, own or tighter"))
}

/// The eye in the middle of `b`, a third of the way up, looking level along the longer
/// horizontal axis.
pub fn inside_view(b: &myriad_core::Aabb, width: u32, height: u32) -> Camera {
    let c = b.center();
    let s = b.size();
    let eye = [c[0], c[1], b.min[2] + s[2] / 3.0];
    let axis = if s[0] >= s[1] { 0 } else { 1 };
    let mut target = eye;
    target[axis] += s[axis].max(1e-6);
    Camera {
        position: eye,
        target,
        up: [0.0, 0.0, 1.0],
        fov_y: 60.0,
        width,
        height,
        near: 0.05,
        far: 1.0,
    }
}

pub fn run(a: CullingBenchArgs) -> Result<()> {
    let gpu = a.device.gpu()?;
    let raster = Rasterizer::new(&gpu);
    let mut budgets: Vec<u64> = a
        .budgets
        .split(',')
        .map(|b| myriad_core::units::parse_count(b.trim()).map_err(anyhow::Error::msg))
        .collect::<Result<_>>()?;
    budgets.push(u64::MAX);
    println!("{}, {:?} path", gpu.name, raster.path);
    if let Some(dir) = &a.images {
        std::fs::create_dir_all(dir)?;
    }
    let style = Style::default();
    for path in &a.datasets {
        let ds = Arc::new(Dataset::open(path)?);
        let name = path
            .file_stem()
            .map_or("dataset".into(), |s| s.to_string_lossy().to_string());
        let mut scene = Scene::open(ds.clone(), 4 << 30, 2 << 30);
        scene.set_colour(a.color);
        Arc::make_mut(&mut scene.hierarchy).detail_contour = a.detail_contour;
        println!(
            "\n{name}: {} points, {} nodes; {}x{}, frame times median of {}; detail by the {} contour",
            myriad_core::units::thousands(ds.meta.points),
            ds.meta.nodes,
            a.width,
            a.height,
            a.frames,
            a.detail_contour.name()
        );
        println!(
            "{:<8} {:<9} {:>9} {:>7} {:>11} {:>7} {:>10} {:>9} {:>9} {:>7}",
            "view",
            "method",
            "budget",
            "nodes",
            "points",
            "culled",
            "select ms",
            "query ms",
            "frame ms",
            "PSNR"
        );
        let mut inside = inside_view(&scene.view_bounds, a.width, a.height);
        inside.fit_depth(&ds.meta.bounds);
        inside.near = inside.near.min(0.05);
        let mut outside = Camera::standard_views(&scene.view_bounds, a.width, a.height)[0].1;
        outside.fit_depth(&ds.meta.bounds);
        for (view, cam) in [("inside", inside), ("outside", outside)] {
            // The reference: every point, nothing culled.
            scene.occlusion = Occlusion::Off;
            let all = SelectOptions {
                budget: u64::MAX,
                min_pixels: 0.0,
            };
            scene.converge(&cam, &all, None);
            let (full, _) = scene.frame(&gpu, &raster, &cam, &all, &style);
            let save = |label: &str, img: &[u8]| -> Result<()> {
                if let Some(dir) = &a.images {
                    let file = dir.join(format!("{name}-{view}-{label}.png"));
                    write_png(&file, a.width, a.height, img)?;
                }
                Ok(())
            };
            save("full", &full)?;
            for &budget in &budgets {
                for (method, occlusion) in [
                    ("off", Occlusion::Off),
                    ("software", Occlusion::Software),
                    // After "software", which leaves no query's answer behind.
                    ("viewer", Occlusion::Checked),
                    ("queries", Occlusion::Queries),
                    ("checked", Occlusion::Checked),
                ] {
                    scene.occlusion = occlusion;
                    let o = SelectOptions {
                        budget,
                        min_pixels: 1.0,
                    };
                    // "viewer": checked culling as `view` draws on the CPU (`frame_many`, the
                    // frame the datasets shown together share).
                    let viewer = method == "viewer";
                    let frame = |scene: &mut Scene| {
                        if viewer {
                            let (image, mut stats) = myriad_render::frame_many(
                                &mut [scene],
                                &gpu,
                                &raster,
                                &cam,
                                &o,
                                &style,
                            );
                            (image, stats.remove(0))
                        } else {
                            scene.frame(&gpu, &raster, &cam, &o, &style)
                        }
                    };
                    // Queries act from the frame after theirs: drawn until the selection
                    // settles (the viewer's frames as the viewer draws them).
                    if viewer {
                        scene.converge(&cam, &o, None);
                        for _ in 0..8 {
                            frame(&mut scene);
                        }
                    } else {
                        scene.settle(&gpu, &raster, &cam, &o, &style);
                    }
                    let mut frames = Vec::new();
                    let mut image = Vec::new();
                    let mut stats = myriad_render::FrameStats::default();
                    for _ in 0..a.frames.max(1) {
                        let t = Instant::now();
                        (image, stats) = frame(&mut scene);
                        frames.push((
                            t.elapsed().as_secs_f64(),
                            stats.select.as_secs_f64(),
                            stats.query.as_secs_f64(),
                        ));
                    }
                    let median = |k: usize| {
                        let mut v: Vec<f64> = frames.iter().map(|f| [f.0, f.1, f.2][k]).collect();
                        v.sort_by(f64::total_cmp);
                        v[v.len() / 2] * 1e3
                    };
                    let b = if budget == u64::MAX {
                        "none".to_string()
                    } else {
                        myriad_core::units::thousands(budget)
                    };
                    println!(
                        "{view:<8} {method:<9} {b:>9} {:>7} {:>11} {:>7} {:>10.2} {:>9.2} {:>9.1} {:>7.2}",
                        stats.nodes,
                        myriad_core::units::thousands(stats.points),
                        stats.culled,
                        median(1),
                        median(2),
                        median(0),
                        psnr(&image, &full),
                    );
                    save(&format!("{method}-{}", b.replace(',', "")), &image)?;
                }
            }
        }
        if a.walk > 0 {
            walk(&a, &ds, &gpu, &raster, &style, &inside)?;
        }
    }
    Ok(())
}

/// `--walk`: `a.walk` steps from `start`, each frame of each method against culling off's.
fn walk(
    a: &CullingBenchArgs,
    ds: &Arc<Dataset>,
    gpu: &myriad_render::Gpu,
    raster: &Rasterizer,
    style: &Style,
    start: &Camera,
) -> Result<()> {
    let methods = [
        ("off", Occlusion::Off, true),
        ("queries, next frame", Occlusion::Queries, false),
        ("queries, same frame", Occlusion::Queries, true),
        ("checked, next frame", Occlusion::Checked, false),
        ("checked, same frame", Occlusion::Checked, true),
    ];
    let mut scenes: Vec<Scene> = methods
        .iter()
        .map(|&(_, occlusion, same_frame)| {
            let mut s = Scene::open(ds.clone(), 1 << 30, 1 << 30);
            s.set_colour(a.color);
            Arc::make_mut(&mut s.hierarchy).detail_contour = a.detail_contour;
            s.occlusion = occlusion;
            s.same_frame = same_frame;
            s
        })
        .collect();
    let o = SelectOptions {
        budget: u64::MAX,
        min_pixels: 1.0,
    };
    // Forward along the view's axis over a third of the data's extent there, turning a
    // quarter turn to the left.
    let forward: [f64; 3] = std::array::from_fn(|i| start.target[i] - start.position[i]);
    let reach = (forward[0].powi(2) + forward[1].powi(2)).sqrt() / 3.0;
    let yaw0 = forward[1].atan2(forward[0]);
    let n = a.walk;
    let mut holes = vec![0usize; methods.len()];
    let mut points = vec![0u64; methods.len()];
    let mut revealed = vec![0usize; methods.len()];
    let mut loading = vec![0usize; methods.len()];
    let mut query_ms = vec![Vec::new(); methods.len()];
    for step in 0..n {
        let t = step as f64 / (n - 1).max(1) as f64;
        let mut cam = *start;
        let ahead = [yaw0.cos(), yaw0.sin()];
        cam.position[0] = start.position[0] + ahead[0] * reach * t;
        cam.position[1] = start.position[1] + ahead[1] * reach * t;
        let yaw = yaw0 + std::f64::consts::FRAC_PI_2 * t;
        cam.target = [
            cam.position[0] + yaw.cos(),
            cam.position[1] + yaw.sin(),
            cam.position[2],
        ];
        cam.fit_depth(&ds.meta.bounds);
        cam.near = cam.near.min(0.05);
        let mut want = Vec::new();
        for (k, scene) in scenes.iter_mut().enumerate() {
            scene.converge(&cam, &o, None);
            let (img, stats) = scene.frame(gpu, raster, &cam, &o, style);
            if k == 0 {
                want = img;
                continue;
            }
            holes[k] += usize::from(img != want);
            // A hole where what the frame selected was not all loaded yet (nodes revealed in
            // the frame come with their subtrees, which a frame does not wait for).
            loading[k] += usize::from(img != want && !stats.complete);
            points[k] += stats.points;
            revealed[k] += stats.revealed;
            query_ms[k].push(stats.query.as_secs_f64() * 1e3);
        }
    }
    println!("walk of {n} frames, no budget: frames with a hole (differing from off's)");
    for (k, (label, _, _)) in methods.iter().enumerate().skip(1) {
        let q = &mut query_ms[k];
        q.sort_by(f64::total_cmp);
        println!(
            "  {label:<20} {:>3} of {n} ({} with nodes still loading), {} nodes drawn in the \
             frame that found them, {} points a frame, query ms median {:.2}",
            holes[k],
            loading[k],
            revealed[k],
            myriad_core::units::thousands(points[k] / n as u64),
            q[q.len() / 2]
        );
    }
    Ok(())
}
