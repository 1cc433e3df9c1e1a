//! `myriad bench baselines SCAN`: Scheiblauer 2006's tables 6.1-6.4, the nested octree against the
//! baselines Scheiblauer measured it against, from three viewpoints (the model at a distance,
//! from its border, from its centre), all points in memory:
//!
//! - every point drawn as one buffer (Scheiblauer 2006's "VBO");
//! - one sequential point tree (SPT, Dachsbacher et al. 2003) over the whole scan, with
//!   Scheiblauer 2006's simpler error metric (a node's projected size): an octree's occupied cells
//!   of more than one point get a new point (their points' mean position and colour) with the
//!   interval [its side, its parent's side); every original point [0, the side of the smallest cell
//!   it shares); sorted by the interval's top. A frame processes the prefix whose tops project to
//!   more than the threshold at the model's nearest distance, then keeps a point where its own
//!   distance puts the threshold inside its interval (the GPU's vertex test, here on the CPU);
//! - one MOSPT (`myriad_build::mospt`) over the whole scan: the prefix of the levels the
//!   nearest distance needs, each point kept where its own distance needs its level;
//! - the nested octree (`convert`'s default structure) without a budget, with culling off and
//!   with `checked` (the software test and the queries).
//!
//! Per structure and view: the points in memory and their bytes (16 a point: position and colour;
//! the SPT's 24 with its interval), points processed (Scheiblauer 2006, table 6.3), points drawn,
//! and the frame on this machine's path with 1-pixel points (Scheiblauer 2006, tables 6.2, 6.4: fps
//! and vertices a second).

use crate::median;
use anyhow::{Result, bail};
use clap::Args;
use myriad_core::{Aabb, PointBatch};
use myriad_format::Dataset;
use myriad_lod::{Camera, Occlusion, SelectOptions};
use myriad_render::{PointSize, Points, Rasterizer, Scene, Style};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

#[derive(Args)]
pub struct BaselinesBenchArgs {
    /// The scan (all its points are held in memory)
    file: PathBuf,
    /// Pixels a node's (or level's) size must project to for finer detail to be drawn
    #[arg(long, default_value_t = 1.0)]
    pixels: f64,
    #[arg(long, default_value_t = 1280)]
    width: u32,
    #[arg(long, default_value_t = 720)]
    height: u32,
    /// Timed frames per structure and view
    #[arg(long, default_value_t = 5)]
    frames: usize,
    #[command(flatten)]
    device: crate::render::Device,
}

/// One SPT entry: a point (original or made) and its interval of node sizes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Entry {
    pub position: [f64; 3],
    pub colour: [u8; 4],
    pub r_min: f64,
    pub r_max: f64,
}

/// A sequential point tree of `positions` in the cube `cube`: entries sorted by `r_max`,
/// largest first; `depth` octree levels below the cube.
pub fn spt(positions: &[[f64; 3]], colours: &[[u8; 4]], cube: &Aabb, depth: u32) -> Vec<Entry> {
    let side0 = cube.size()[0];
    let side = |l: u32| side0 / (1u64 << l) as f64;
    let cell = |p: [f64; 3], l: u32| -> [u64; 3] {
        let n = (1u64 << l) as f64;
        std::array::from_fn(|a| {
            (((p[a] - cube.min[a]) / side0 * n).floor().max(0.0) as u64).min((1u64 << l) - 1)
        })
    };
    // Per level, the occupied cells: count, position sums, colour sums.
    type Acc = (u64, [f64; 3], [u64; 4]);
    let mut levels: Vec<std::collections::HashMap<[u64; 3], Acc>> = Vec::new();
    for l in 0..=depth {
        let mut m: std::collections::HashMap<[u64; 3], Acc> = Default::default();
        for (p, c) in positions.iter().zip(colours) {
            let e = m.entry(cell(*p, l)).or_insert((0, [0.0; 3], [0; 4]));
            e.0 += 1;
            for a in 0..3 {
                e.1[a] += p[a];
            }
            for k in 0..4 {
                e.2[k] += c[k] as u64;
            }
        }
        levels.push(m);
    }
    let mut out = Vec::new();
    for (l, m) in levels.iter().enumerate() {
        let l = l as u32;
        for (n, s, c) in m.values().filter(|v| v.0 > 1) {
            let k = *n as f64;
            out.push(Entry {
                position: s.map(|v| v / k),
                colour: std::array::from_fn(|i| ((c[i] + n / 2) / n) as u8),
                r_min: side(l),
                r_max: if l == 0 { f64::INFINITY } else { side(l - 1) },
            });
        }
    }
    for (p, c) in positions.iter().zip(colours) {
        // The smallest cell it shares with another point.
        let shared = (0..=depth)
            .rev()
            .find(|&l| levels[l as usize][&cell(*p, l)].0 > 1);
        out.push(Entry {
            position: *p,
            colour: *c,
            r_min: 0.0,
            r_max: shared.map_or(f64::INFINITY, side),
        });
    }
    out.sort_by(|a, b| b.r_max.total_cmp(&a.r_max));
    out
}

/// The distance from `eye` to `b` (0 inside).
fn distance_to(eye: [f64; 3], b: &Aabb) -> f64 {
    let d: [f64; 3] = std::array::from_fn(|a| (b.min[a] - eye[a]).max(0.0).max(eye[a] - b.max[a]));
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// An SPT frame: the entries processed (the prefix) and the indices of those drawn. A size
/// `s` at distance `d` projects to `s * focal / d` pixels.
pub fn spt_frame(
    entries: &[Entry],
    eye: [f64; 3],
    bounds: &Aabb,
    focal: f64,
    px: f64,
) -> (usize, Vec<u32>) {
    let near = distance_to(eye, bounds);
    // Tops that project to more than px at the nearest distance (all, from inside).
    let prefix = entries.partition_point(|e| e.r_max * focal > px * near);
    let drawn = (0..prefix as u32)
        .filter(|&i| {
            let e = &entries[i as usize];
            let d = dist(e.position, eye).max(1e-12);
            e.r_min * focal / d <= px && px < e.r_max * focal / d
        })
        .collect();
    (prefix, drawn)
}

/// A MOSPT frame: the points processed (levels the nearest distance needs) and those drawn (a
/// point where its own distance needs its level), as indices into the input. A level is needed
/// while the level above it is spaced more than `px` pixels. `ordered`: the positions in the
/// MOSPT's order (as its buffer holds them).
pub fn mospt_frame(
    m: &myriad_build::mospt::Mospt,
    ordered: &[[f64; 3]],
    eye: [f64; 3],
    bounds: &Aabb,
    focal: f64,
    px: f64,
) -> (usize, Vec<u32>) {
    let levels = m.prefix.len();
    // Levels 0..=l where l is the first spaced at most px apart at distance d.
    let needed = |d: f64| -> usize {
        (0..levels)
            .find(|&l| m.spacing[l] * focal <= px * d)
            .unwrap_or(levels - 1)
    };
    let top = needed(distance_to(eye, bounds));
    let processed = m.prefix[top] as usize;
    // Level l (> 0) is needed nearer than where the level above it is spaced px apart.
    let reach: Vec<f64> = (0..levels)
        .map(|l| {
            if l == 0 {
                f64::INFINITY
            } else {
                m.spacing[l - 1] * focal / px
            }
        })
        .collect();
    let mut level = 0;
    let drawn = (0..processed)
        .filter(|&i| {
            while i as u64 >= m.prefix[level] {
                level += 1;
            }
            dist(ordered[i], eye) < reach[level]
        })
        .map(|i| m.order[i])
        .collect();
    (processed, drawn)
}

struct Row {
    name: &'static str,
    view: &'static str,
    memory: usize,
    bytes: usize,
    processed: usize,
    drawn: usize,
    select_ms: f64,
    frame_ms: f64,
}

pub fn run(a: BaselinesBenchArgs) -> Result<()> {
    let gpu = a.device.gpu()?;
    let raster = Rasterizer::new(&gpu);
    let style = Style {
        size: PointSize::Fixed(1.0),
        passes: myriad_render::Passes::default(),
        ..Style::default()
    };
    eprintln!("reading {}", a.file.display());
    let mut src = myriad_io::open(&a.file, &Default::default())?;
    let mut all: Option<PointBatch> = None;
    let mut positions = Vec::new();
    let mut colours = Vec::new();
    let z = src
        .info()
        .bounds
        .map_or((0.0, 1.0), |b| (b.min[2], b.max[2]));
    while let Some(b) = src.read_batch(1 << 16)? {
        positions.extend_from_slice(&b.positions);
        // RGB (the elevation ramp where there is none).
        let scheme = myriad_render::ColorBy::Rgb;
        colours.extend(myriad_render::colours(&b, b.len(), scheme, z, 0));
        match &mut all {
            Some(all) => all.append(&b),
            None => all = Some(b),
        }
    }
    let Some(all) = all else {
        bail!("{}: no points", a.file.display());
    };
    let mut bounds = Aabb::EMPTY;
    for p in &positions {
        bounds.extend(*p);
    }
    let c = bounds.center();
    let half = bounds.size().iter().fold(0.0f64, |m, v| m.max(*v)) / 2.0 * 1.0001;
    let cube = Aabb::new(
        [c[0] - half, c[1] - half, c[2] - half],
        [c[0] + half, c[1] + half, c[2] + half],
    );
    let s = bounds.size();
    let views: Vec<(&'static str, Camera)> = {
        let far = Camera::framing(&bounds, a.width, a.height, 60.0);
        let mut border = far;
        border.position = [c[0], bounds.min[1] + 0.05 * s[1], c[2]];
        border.target = c;
        let mut centre = far;
        centre.position = c;
        centre.target = [c[0] + s[0], c[1], c[2]];
        let mut v = vec![("distance", far), ("border", border), ("centre", centre)];
        for (_, cam) in &mut v {
            cam.up = [0.0, 0.0, 1.0];
            cam.fit_depth(&bounds);
        }
        v
    };
    let n = positions.len();
    let time_draw = |pos: &[[f64; 3]], col: &[[u8; 4]], cam: &Camera| -> f64 {
        if pos.is_empty() {
            return 0.0;
        }
        let points = Points::upload(&gpu, c, pos, col);
        let times: Vec<f64> = (0..a.frames.max(1))
            .map(|_| {
                let t = Instant::now();
                let img = raster.render(&gpu, cam, &[points.all(0.0)], &[], &style);
                std::hint::black_box(img);
                t.elapsed().as_secs_f64() * 1e3
            })
            .collect();
        median(times)
    };
    let mut rows = Vec::new();
    eprintln!("building the SPT");
    let depth = (((n as f64).log2() / 3.0).ceil() as u32 + 3).min(20);
    let entries = spt(&positions, &colours, &cube, depth);
    eprintln!("building the MOSPT");
    let m = myriad_build::mospt::build(&all, &cube, depth);
    let ordered: Vec<[f64; 3]> = m.order.iter().map(|&i| positions[i as usize]).collect();
    for (view, cam) in &views {
        let focal = cam.focal();
        rows.push(Row {
            name: "all points",
            view,
            memory: n,
            bytes: 16 * n,
            processed: n,
            drawn: n,
            select_ms: 0.0,
            frame_ms: time_draw(&positions, &colours, cam),
        });
        let t = Instant::now();
        let (processed, drawn) = spt_frame(&entries, cam.position, &bounds, focal, a.pixels);
        let select_ms = t.elapsed().as_secs_f64() * 1e3;
        let pos: Vec<[f64; 3]> = drawn
            .iter()
            .map(|&i| entries[i as usize].position)
            .collect();
        let col: Vec<[u8; 4]> = drawn.iter().map(|&i| entries[i as usize].colour).collect();
        rows.push(Row {
            name: "SPT",
            view,
            memory: entries.len(),
            bytes: 24 * entries.len(),
            processed,
            drawn: drawn.len(),
            select_ms,
            frame_ms: time_draw(&pos, &col, cam),
        });
        let t = Instant::now();
        let (processed, drawn) = mospt_frame(&m, &ordered, cam.position, &bounds, focal, a.pixels);
        let select_ms = t.elapsed().as_secs_f64() * 1e3;
        let pos: Vec<[f64; 3]> = drawn.iter().map(|&i| positions[i as usize]).collect();
        let col: Vec<[u8; 4]> = drawn.iter().map(|&i| colours[i as usize]).collect();
        rows.push(Row {
            name: "one MOSPT",
            view,
            memory: n,
            bytes: 16 * n,
            processed,
            drawn: drawn.len(),
            select_ms,
            frame_ms: time_draw(&pos, &col, cam),
        });
    }
    drop(entries);
    // The nested octree, converted by this binary.
    let dir = std::env::temp_dir().join(format!("myriad-bench-baselines-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let out = dir.join("nested.myr");
    eprintln!("converting (nested octree)");
    let o = std::process::Command::new(std::env::current_exe()?)
        .arg("convert")
        .arg(&a.file)
        .arg("-o")
        .arg(&out)
        .arg("--force")
        .output()?;
    if !o.status.success() {
        bail!(
            "convert failed: {}",
            String::from_utf8_lossy(&o.stderr).trim()
        );
    }
    let ds = Arc::new(Dataset::open(&out)?);
    for (name, occlusion) in [
        ("nested octree", Occlusion::Off),
        ("nested, culled", Occlusion::Checked),
    ] {
        let mut scene = Scene::open(ds.clone(), usize::MAX, usize::MAX);
        scene.occlusion = occlusion;
        let options = SelectOptions {
            budget: u64::MAX,
            min_pixels: a.pixels,
        };
        for (view, cam) in &views {
            scene.converge(cam, &options, None);
            for _ in 0..3 {
                scene.frame(&gpu, &raster, cam, &options, &style);
            }
            let mut times = Vec::new();
            let mut selects = Vec::new();
            let mut stats = None;
            for _ in 0..a.frames.max(1) {
                let t = Instant::now();
                let (img, s) = scene.frame(&gpu, &raster, cam, &options, &style);
                times.push(t.elapsed().as_secs_f64() * 1e3);
                selects.push(s.select.as_secs_f64() * 1e3);
                std::hint::black_box(img);
                stats = Some(s);
            }
            let s = stats.expect("a frame");
            let select_ms = median(selects);
            rows.push(Row {
                name,
                view,
                memory: s.selected_points as usize,
                bytes: 16 * s.selected_points as usize,
                processed: s.selected_points as usize,
                drawn: s.points as usize,
                // The frame's time less its selection (the other rows' frame is the drawing).
                select_ms,
                frame_ms: median(times) - select_ms,
            });
        }
    }
    drop(ds);
    std::fs::remove_dir_all(&dir).ok();
    println!(
        "{}: {} points; {} ({:?} path), {}x{}, 1-pixel points, threshold {} px; views: the \
         model framed at a distance, from its border, from its centre; frame: median of {}",
        a.file.display(),
        myriad_core::units::thousands(n as u64),
        gpu.name,
        raster.path,
        a.width,
        a.height,
        a.pixels,
        a.frames
    );
    println!(
        "{:<15} {:<9} {:>12} {:>9} {:>12} {:>12} {:>10} {:>9} {:>12}",
        "structure",
        "view",
        "in memory",
        "MB",
        "processed",
        "drawn",
        "select ms",
        "frame ms",
        "M points/s"
    );
    for r in &rows {
        println!(
            "{:<15} {:<9} {:>12} {:>9.1} {:>12} {:>12} {:>10.1} {:>9.1} {:>12.1}",
            r.name,
            r.view,
            myriad_core::units::thousands(r.memory as u64),
            r.bytes as f64 / 1e6,
            myriad_core::units::thousands(r.processed as u64),
            myriad_core::units::thousands(r.drawn as u64),
            r.select_ms,
            r.frame_ms,
            r.processed as f64 / ((r.select_ms + r.frame_ms).max(1e-9) * 1e3),
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two pairs of close points far apart: the SPT makes a point per pair and one for all
    /// four; far away the one point stands for them, close up the four originals.
    #[test]
    fn an_spt_draws_made_points_far_and_originals_near() {
        let positions = [
            [0.0, 0.0, 0.0],
            [0.1, 0.0, 0.0],
            [8.0, 8.0, 8.0],
            [8.1, 8.0, 8.0],
        ];
        let colours = [
            [10, 0, 0, 255],
            [30, 0, 0, 255],
            [0, 0, 100, 255],
            [0, 0, 100, 255],
        ];
        let cube = Aabb::new([0.0; 3], [16.0; 3]);
        let e = spt(&positions, &colours, &cube, 6);
        // Made: the root (16) and the cells of each pair down to side 0.25 (levels 1-6 for
        // the first pair, which shares cells to side 0.25; ...): every made point has r_min > 0.
        let made = e.iter().filter(|x| x.r_min > 0.0).count();
        assert!(made >= 3, "{e:?}");
        assert_eq!(e.len() - made, 4);
        assert!(e.windows(2).all(|w| w[0].r_max >= w[1].r_max));
        let root = e[0];
        assert_eq!(root.r_max, f64::INFINITY);
        assert_eq!(root.position, [4.05, 4.0, 4.0]);
        assert_eq!(root.colour, [10, 0, 50, 255]);
        let b = Aabb::new([0.0; 3], [8.1, 8.0, 8.0]);
        // From 20,000 units with a focal length of 1,000 px the root's 16 units are 0.8 px:
        // it alone; its children (8 units, 16 units up) are not even processed.
        let (processed, drawn) = spt_frame(&e, [0.0, 0.0, -20_000.0], &b, 1000.0, 1.0);
        assert_eq!((processed, drawn.len()), (1, 1), "{drawn:?}");
        assert_eq!(e[drawn[0] as usize].r_max, f64::INFINITY);
        // From 10,000: the root is 1.6 px, its two children 0.8: the pairs' made points.
        let (_, drawn) = spt_frame(&e, [0.0, 0.0, -10_000.0], &b, 1000.0, 1.0);
        let mut got: Vec<_> = drawn.iter().map(|&i| e[i as usize].position).collect();
        got.sort_by(|a, b| a.partial_cmp(b).unwrap());
        assert_eq!(got, [[0.05, 0.0, 0.0], [8.05, 8.0, 8.0]]);
        // Up close: the four originals.
        let (processed, drawn) = spt_frame(&e, [4.0, 4.0, -1.0], &b, 1000.0, 1.0);
        assert_eq!(processed, e.len());
        let mut got: Vec<_> = drawn.iter().map(|&i| e[i as usize].position).collect();
        got.sort_by(|a, b| a.partial_cmp(b).unwrap());
        assert_eq!(got, positions.to_vec());
    }
}
